"""``clbeam import-segy``: a sonar's multichannel SEG-Y export into a ping file (docs/ping-format.md)."""

from __future__ import annotations

from clbeam.cli.options import progress, require_extra

NAME = "import-segy"
HELP = "convert multichannel SEG-Y (one trace per element, one ensemble per ping) into a ping file"
DESCRIPTION = ("Read a multichannel SEG-Y file, one trace per receive element and one ensemble per ping, and write "
               "a ping file (see clbeam docs ping-format).  The trace-header mapping (see clbeam docs import) says "
               "where the sample interval, t0, element positions, motion, navigation and sound speed sit; --mapping "
               "replaces entries of it.  "
               "The pulse and the source position come from the options, else from name=value lines of the "
               "textual header (as clbeam writes them), else (the pulse) from the binary header's sweep fields.")


def add_arguments(p) -> None:
    """The arguments of ``clbeam import-segy``."""
    p.add_argument("segy", metavar="IN.sgy", help="multichannel SEG-Y file")
    p.add_argument("-o", "--output", required=True, metavar="PINGS.nc",
                   help="ping file to write (.nc or .zarr; see clbeam docs ping-format)")
    p.add_argument("--mapping", default=None, metavar="MAP.toml",
                   help="TOML file of trace-header mapping entries replacing the defaults (see clbeam docs import)")
    p.add_argument("--pulse", type=float, nargs=3, default=None, metavar=("F0", "F1", "DURATION"),
                   help="LFM pulse: start and end frequency (Hz) and length (s)")
    p.add_argument("--tx-delay", type=float, default=None, metavar="S",
                   help="time of the replica's first sample after transmit start (s, default: the textual header's, else 0)")
    p.add_argument("--source", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="transmit acoustic centre in the vessel frame (m; default: the textual header's, else 0 0 0)")
    p.add_argument("--sound-speed", type=float, default=None, metavar="M/S",
                   help="sound speed of every ping (m/s), replacing the headers'")
    p.add_argument("--element-pitch", type=float, default=None, metavar="M",
                   help="elements evenly spaced across-track by this pitch (m), centred, in channel order, "
                        "replacing the headers' positions")


def run(args) -> int:
    """Run ``clbeam import-segy``; returns the exit status (0).

    Raises :class:`~clbeam.errors.ClbeamError` subclasses on bad input, which
    the ``clbeam`` entry point prints as one line (exit 2).
    """
    require_extra("segyio", "segy", "import-segy")
    from clbeam.io.paths import check_output_path
    from clbeam.io.segy_import import SegyImportOptions, import_segy
    from clbeam.io.segy_mapping import load_mapping

    check_output_path(args.output, args.segy)
    mapping = load_mapping(args.mapping)
    options = SegyImportOptions(pulse=None if args.pulse is None else tuple(args.pulse), tx_delay_s=args.tx_delay,
                                source_m=None if args.source is None else tuple(args.source),
                                sound_speed_m_s=args.sound_speed, element_pitch_m=args.element_pitch)
    res = import_segy(args.segy, args.output, mapping=mapping, options=options,
                      progress=lambda it, total: progress(it, total=total, desc="import", quiet=args.quiet))
    if not args.quiet:
        origins = ", ".join(f"{k} from the {v}" if v in ("textual header", "binary header sweep") else f"{k}: {v}"
                            for k, v in res.origins.items())
        print(f"imported {res.n_pings} ping(s) of {res.n_channels} channels x {res.n_samples} samples "
              f"({res.sample_rate_hz:g} Hz; {origins}) in {res.seconds:.1f} s -> {res.path}")
    return 0
