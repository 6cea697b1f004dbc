"""The ``clbeam forward`` subcommand: model a layered seabed's trace, write figures and the trace.

``clbeam forward --layers FILE.toml [--chirp low|high|F0,F1,DUR] [-o DIR]``
writes ``<name>_compressed.png``, ``<name>_spectra.png`` and the trace
(``<name>_trace.csv`` or ``.nc``) into ``DIR`` and prints one line.
:func:`add_parser` registers it on an ``argparse`` subparsers object;
:func:`run` executes parsed arguments.
"""

from __future__ import annotations

import argparse
import csv
import re
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.seabed.forward.config import BUNDLED, load_seabed
from clbeam.seabed.forward.trace import Chirp, simulate_trace


def add_parser(subparsers, add_common=None) -> argparse.ArgumentParser:
    """Add the ``forward`` subcommand to an ``argparse`` subparsers object.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        From ``ArgumentParser.add_subparsers()``.
    add_common : callable, optional
        ``add_common(parser)`` adds the options shared by all subcommands
        (``-q/--quiet``); without it this function adds ``-q`` itself.  The
        signature also fits :data:`clbeam.cli.commands.REGISTRARS`.

    Returns
    -------
    argparse.ArgumentParser
        The subcommand's parser (its ``func`` default is :func:`run`).
    """
    p = subparsers.add_parser(
        "forward", help="model the echo of a layered seabed (Rakotonarivo coherent model)",
        description="Coherent layered-seabed model: compressed nadir trace and echo spectra for a chirp.")
    p.add_argument("--layers", required=True, metavar="FILE.toml",
                   help=f"seabed layout (TOML file, or one of {', '.join(BUNDLED)})")
    p.add_argument("--chirp", default="low", metavar="low|high|F0,F1,DUR",
                   help="emission: 'low' (1.7-5.2 kHz), 'high' (5-15 kHz), both 10 ms, or F0,F1,DUR in Hz, Hz, s "
                        "(default low)")
    p.add_argument("-o", "--output", default="forward-output", metavar="DIR",
                   help="folder for the figures and the trace (default forward-output)")
    p.add_argument("--sample-rate", type=float, default=48000.0, metavar="HZ", help="sample rate (Hz, default 48000)")
    p.add_argument("--incidence", type=float, default=0.0, metavar="DEG",
                   help="incidence of the specular ray from the vertical (degree, default 0: nadir)")
    p.add_argument("--snr", type=float, default=None, metavar="DB",
                   help="add white noise: strongest echo's power over noise power before compression (dB)")
    p.add_argument("--seed", type=int, default=None, help="noise seed")
    p.add_argument("--format", choices=["csv", "netcdf"], default="csv", help="trace file format (default csv)")
    if add_common is not None:
        add_common(p)
    else:
        p.add_argument("-q", "--quiet", action="store_true", help="no summary line")
    p.set_defaults(func=run)
    return p


#: Registrar form for :data:`clbeam.cli.commands.REGISTRARS`.
register = add_parser


def _write_csv(path: Path, trace) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "received_pa", "compressed_pa", "envelope_pa"])
        for t, y, c in zip(trace.time_s, trace.received, trace.compressed):
            w.writerow([f"{t:.9g}", f"{y:.9g}", f"{c.real:.9g}", f"{abs(c):.9g}"])


def _write_netcdf(path: Path, trace, attrs: dict) -> None:
    import xarray as xr

    ds = xr.Dataset(
        {"received": ("time", trace.received, {"units": "Pa", "long_name": "received pressure y(t) (eq. 19)"}),
         "compressed": ("time", trace.compressed.real, {"units": "Pa", "long_name": "compressed trace y_c"}),
         "envelope": ("time", np.abs(trace.compressed), {"units": "Pa", "long_name": "envelope of y_c"}),
         "echo_time": ("echo", trace.echoes.times_s, {"units": "s", "long_name": "two-way echo time"})},
        coords={"time": ("time", trace.time_s, {"units": "s", "long_name": "time from transmission start"}),
                "echo": ("echo", np.arange(trace.echoes.times_s.size))},
        attrs=attrs)
    ds.to_netcdf(path)


def run(args) -> int:
    """Run ``clbeam forward`` on parsed arguments; returns the exit status (0).

    Raises :class:`clbeam.errors.ClbeamError` subclasses on bad input, which
    the ``clbeam`` entry point prints as one line.
    """
    from clbeam.seabed.forward.figures import plot_spectra, plot_trace

    seabed = load_seabed(args.layers)
    chirp = Chirp.parse(args.chirp)
    require(np.isfinite(args.incidence) and 0 <= args.incidence < 90, OptionError,
            f"--incidence must lie in [0, 90) degree, got {args.incidence!r}")
    trace = simulate_trace(seabed, chirp, sample_rate_hz=args.sample_rate, incidence_deg=args.incidence,
                           snr_db=args.snr, rng=args.seed)
    out = Path(args.output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OptionError(f"output folder {str(out)!r} cannot be created: {exc}") from None
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(str(args.layers)).stem) or "forward"
    title = f"{seabed.name or stem}, chirp {chirp.f0_hz:g}-{chirp.f1_hz:g} Hz"
    plot_trace(trace, out / f"{stem}_compressed.png", title=title)
    plot_spectra(trace, out / f"{stem}_spectra.png", title=title)
    if args.format == "netcdf":
        data = out / f"{stem}_trace.nc"
        _write_netcdf(data, trace, {"seabed": seabed.name, "chirp_f0_hz": chirp.f0_hz, "chirp_f1_hz": chirp.f1_hz,
                                    "chirp_duration_s": chirp.duration_s, "incidence_deg": args.incidence,
                                    "sample_rate_hz": args.sample_rate})
    else:
        data = out / f"{stem}_trace.csv"
        _write_csv(data, trace)
    if not getattr(args, "quiet", False):
        times = ", ".join(f"{t * 1e3:.3f}" for t in trace.echoes.times_s if np.isfinite(t))
        n = int(np.isfinite(trace.echoes.times_s).sum())
        print(f"forward: {n} echo(es) at {times} ms ({seabed.name or stem}, chirp {chirp.f0_hz:g}-{chirp.f1_hz:g} Hz "
              f"{chirp.duration_s * 1e3:g} ms, incidence {args.incidence:g} deg) -> {data}")
    return 0
