"""``clbeam forward``: model a layered seabed's trace, write figures and the trace.

``clbeam forward --layers FILE.toml [--chirp low|high|F0,F1,DUR] [-o DIR]``
writes ``<name>_compressed.png``, ``<name>_spectra.png`` and the trace
(``<name>_trace.csv`` or ``.nc``) into ``DIR`` and prints one line.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.seabed.forward.config import BUNDLED

NAME = "forward"
HELP = "model the echo of a layered seabed (Rakotonarivo coherent model)"
DESCRIPTION = "Coherent layered-seabed model: compressed nadir trace and echo spectra for a chirp."


def add_arguments(p) -> None:
    """The arguments of ``clbeam forward``."""
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


def run(args) -> int:
    """Run ``clbeam forward`` on parsed arguments; returns the exit status (0).

    Raises :class:`clbeam.errors.ClbeamError` subclasses on bad input, which
    the ``clbeam`` entry point prints as one line.
    """
    from clbeam.seabed.forward.config import load_seabed
    from clbeam.seabed.forward.figures import plot_spectra, plot_trace
    from clbeam.seabed.forward.output import write_trace_csv, write_trace_netcdf
    from clbeam.seabed.forward.trace import Chirp, simulate_trace

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
        write_trace_netcdf(data, trace, {"seabed": seabed.name, "chirp_f0_hz": chirp.f0_hz, "chirp_f1_hz": chirp.f1_hz,
                                    "chirp_duration_s": chirp.duration_s, "incidence_deg": args.incidence,
                                    "sample_rate_hz": args.sample_rate})
    else:
        data = out / f"{stem}_trace.csv"
        write_trace_csv(data, trace)
    if not args.quiet:
        times = ", ".join(f"{t * 1e3:.3f}" for t in trace.echoes.times_s if np.isfinite(t))
        n = int(np.isfinite(trace.echoes.times_s).sum())
        print(f"forward: {n} echo(es) at {times} ms ({seabed.name or stem}, chirp {chirp.f0_hz:g}-{chirp.f1_hz:g} Hz "
              f"{chirp.duration_s * 1e3:g} ms, incidence {args.incidence:g} deg) -> {data}")
    return 0
