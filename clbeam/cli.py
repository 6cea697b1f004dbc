"""The ``clbeam`` command (placeholder until the subcommands land)."""
def main(argv=None):
    return 0
