"""``clbeam docs``: the documentation that comes with clbeam, by topic.

The pages of the repository's ``docs/`` folder are installed with the
package (``clbeam.docs``, package data like the kernels), so they are there
after a ``pip install``: ``clbeam docs`` lists the topics, ``clbeam docs
TOPIC`` prints one (Markdown), ``clbeam docs TOPIC --path`` prints where
it lies.  A topic is the page's file name without ``.md``
(``ping-format`` is ``docs/ping-format.md``).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from clbeam.errors import OptionError, require

NAME = "docs"
HELP = "the documentation: list its topics, print one (clbeam docs TOPIC) or its path"
DESCRIPTION = ("List the topics of the documentation installed with clbeam, print one topic's page "
               "(Markdown) or, with --path, the page's file.  Topics: the file names of docs/*.md "
               "without .md, e.g. 'clbeam docs ping-format'.")

#: the package the pages are installed as (``docs/`` in the repository)
DOCS_PACKAGE = "clbeam.docs"


def docs_dir() -> Path:
    """The folder holding the documentation's pages.

    Returns
    -------
    pathlib.Path
        The installed package :data:`DOCS_PACKAGE`, or, in a source checkout
        whose install does not map it, the checkout's ``docs/`` folder.

    Raises
    ------
    OptionError
        When neither exists.
    """
    spec = importlib.util.find_spec(DOCS_PACKAGE)
    if spec is not None and spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    checkout = Path(__file__).resolve().parents[2] / "docs"
    require(checkout.is_dir(), OptionError, f"the documentation is not installed (no package {DOCS_PACKAGE})")
    return checkout


def topic_name(text: str) -> str:
    """The topic a user wrote: ``ping-format``, ``ping-format.md`` and ``docs/ping-format.md`` are one."""
    name = text.strip().replace("\\", "/").rsplit("/", 1)[-1]
    return name[:-3] if name.endswith(".md") else name


def topics() -> dict[str, Path]:
    """Every topic and its page, sorted by name.

    Returns
    -------
    dict of str to pathlib.Path
        Topic name (file name without ``.md``) to the Markdown file.
    """
    return {p.stem: p for p in sorted(docs_dir().glob("*.md"))}


def topic_path(topic: str) -> Path:
    """The page of one topic.

    Parameters
    ----------
    topic : str
        A topic name (see :func:`topic_name` for the spellings accepted).

    Returns
    -------
    pathlib.Path
        The Markdown file.

    Raises
    ------
    OptionError
        A one-line error listing the topics when there is no such topic.
    """
    pages = topics()
    name = topic_name(topic)
    require(name in pages, OptionError,
            f"no documentation topic '{topic}'; topics: {', '.join(pages)} (clbeam docs lists them)")
    return pages[name]


def title(path: Path) -> str:
    """The first Markdown heading of a page (its file name when it has none)."""
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("#"):
                return line.lstrip("#").strip()
    return path.stem


def add_arguments(p) -> None:
    """The arguments of ``clbeam docs``."""
    p.add_argument("topic", nargs="?", metavar="TOPIC", help="topic to print (default: list the topics)")
    p.add_argument("--path", action="store_true", help="print the page's file path instead of its text")


def run(args) -> int:
    """Run ``clbeam docs``: list the topics, or print one page or its path; returns 0.

    Raises :class:`~clbeam.errors.OptionError` for an unknown topic, which
    the ``clbeam`` entry point prints as one line (exit 2).
    """
    if args.topic is None:
        pages = topics()
        if args.path:
            print(docs_dir())
            return 0
        width = max(map(len, pages), default=0)
        print("\n".join(f"{name:<{width}}  {title(path)}" for name, path in pages.items()))
        if not args.quiet:
            print("\nclbeam docs TOPIC prints a page; clbeam docs TOPIC --path its file")
        return 0
    path = topic_path(args.topic)
    print(path if args.path else path.read_text(encoding="utf-8"), end="\n" if args.path else "")
    return 0
