"""Checks of output paths, before anything is written or removed."""

from __future__ import annotations

from pathlib import Path

from clbeam.errors import OptionError, require


def check_output_path(output, *inputs, what: str = "output", zarr_ok: bool = True) -> Path:
    """Refuse an output that cannot be written or would destroy an input.

    Parameters
    ----------
    output : path-like
        The file to write.
    *inputs : path-like
        Files the command reads: the output may not be one of them.
    what : str
        What the output is, for the message ("output", "figure", ...).
    zarr_ok : bool
        An existing ``.zarr`` folder may be overwritten (a Zarr store is a folder).

    Returns
    -------
    pathlib.Path
        ``output`` as a path.

    Raises
    ------
    OptionError
        One line naming the path: it is an input, an existing folder, or in a
        folder that does not exist.
    """
    out = Path(output)
    for inp in inputs:
        require(not (out.exists() and Path(inp).exists() and out.resolve() == Path(inp).resolve()), OptionError,
                f"{what} {out} is the input file; choose another name")
    require(not (out.is_dir() and not (zarr_ok and out.suffix == ".zarr")), OptionError,
            f"{what} {out} is an existing folder; give a file name")
    parent = out.parent if str(out.parent) else Path(".")
    require(parent.is_dir(), OptionError, f"{what} {out}: output folder {parent} does not exist")
    return out
