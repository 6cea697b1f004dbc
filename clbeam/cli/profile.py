"""``clbeam profile``: a vertical beam per ping, as SEG-Y and a figure."""

from __future__ import annotations

from clbeam.cli.options import add_engine_choice, progress, require_extra

NAME = "profile"
HELP = "along-track profile: a vertical beam per ping, as SEG-Y and a figure"
DESCRIPTION = ("Form a vertical (nadir, earth-referenced) beam per ping and write its envelope |S|/M "
               "(or S/M with --analytic) as SEG-Y, with a figure of the profile.")


def add_arguments(p) -> None:
    """The arguments of ``clbeam profile``."""
    p.add_argument("pings", metavar="PINGS.nc", help="ping file (NetCDF4 or Zarr; see clbeam docs ping-format)")
    p.add_argument("-o", "--output", required=True, metavar="PROFILE.sgy", help="SEG-Y file to write")
    p.add_argument("--max-range", type=float, default=None, metavar="M",
                   help="largest range (m) of the traces (default: the end of the record)")
    p.add_argument("--analytic", action="store_true",
                   help="write the real and imaginary parts of S/M (2 traces per ping) instead of the envelope")
    p.add_argument("--png", default=None, metavar="PATH",
                   help="figure of the profile (default: the SEG-Y path with suffix .png)")
    add_engine_choice(p)


def run(args) -> int:
    """Run ``clbeam profile``; returns the exit status (0).

    Raises :class:`~clbeam.errors.ClbeamError` subclasses on bad input, which
    the ``clbeam`` entry point prints as one line (exit 2).
    """
    require_extra("segyio", "segy", "profile")
    from clbeam.seabed.profile import write_profile

    res = write_profile(args.pings, args.output, png_path=args.png, max_range_m=args.max_range,
                        interp=args.interp, analytic=args.analytic, backend=args.backend, device=args.device,
                        progress=lambda it, total: progress(it, total=total, desc="profile", quiet=args.quiet))
    if not args.quiet:
        ax = res.axis
        print(f"profiled {res.n_pings} ping(s) in {res.seconds:.1f} s: {res.n_pings * res.traces_per_ping} trace(s) "
              f"of {ax.n_samples} samples ({ax.interval_us} us, delay {ax.delay_ms} ms) -> {res.segy_path}"
              + (f"; figure -> {res.png_path}" if res.png_path else ""))
    return 0
