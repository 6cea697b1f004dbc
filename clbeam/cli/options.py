"""Option groups and helpers shared by the ``clbeam`` subcommands.

Every subcommand that images pings takes its grid, mode and engine options
from here, so ``--interp``, ``--backend``, ``--device`` and the rest are
defined once and mean the same thing everywhere.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
from pathlib import Path

from clbeam.constants import (
    DEFAULT_MAX_CF_ERROR,
    DEFAULT_MAX_ERROR_DB,
    DEFAULT_MIN_CHANNELS,
    DEFAULT_MIN_CONTRAST_DB,
    DEFAULT_MIN_SNR_DB,
    PEAK_THRESHOLD,
)
from clbeam.errors import ClbeamError, OptionError


def progress(iterable, *, total=None, desc="", quiet=False, unit="ping"):
    """A tqdm progress bar on a terminal, nothing otherwise or with ``quiet``."""
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, disable=quiet or not sys.stderr.isatty(),
                dynamic_ncols=True, leave=False)


def stage_printer(args):
    """A function printing ``"  <stage> …"`` on stderr, silent with ``--quiet``."""
    if args.quiet:
        return lambda msg: None
    return lambda msg: print(f"  {msg} …", file=sys.stderr, flush=True)


def require_extra(module: str, extra: str, command: str) -> None:
    """Raise a one-line :class:`ClbeamError` when ``module`` (of the optional
    dependency group ``extra``) is not installed."""
    try:
        importlib.import_module(module)
    except ImportError:
        raise ClbeamError(f"clbeam {command} needs {module}, which is not installed: "
                          f"pip install 'clbeam[{extra}]'") from None


def add_quiet(p: argparse.ArgumentParser) -> None:
    """``-q/--quiet``: no progress bar or summary (every subcommand has it)."""
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")


#: loggers of the libraries clbeam uses: held at WARNING unless ``--debug`` is given twice
LIBRARY_LOGGERS = ("numba", "matplotlib", "distributed", "dask", "asyncio", "PIL", "fsspec", "h5py", "h5netcdf",
                   "netCDF4", "zarr", "numcodecs", "pyopencl", "pytools", "tornado", "bokeh", "urllib3")
#: format of every log line
LOG_FORMAT = "clbeam: %(levelname)s: %(message)s"


def add_logging_options(p: argparse.ArgumentParser, *, top: bool = False) -> None:
    """``-v/--verbose`` and ``--debug``, and on a subcommand (``top`` false) ``-q/--quiet`` too.

    The main parser's flags (``clbeam --debug image ...``) and a subcommand's
    (``clbeam image ... --debug``) add up; :func:`setup_logging` reads both.
    """
    if not top:
        add_quiet(p)
    prefix = "" if top else "sub_"
    p.add_argument("-v", "--verbose", action="count", default=0, dest=f"{prefix}verbose",
                   help="show clbeam's progress messages (log level INFO)")
    p.add_argument("--debug", action="count", default=0, dest=f"{prefix}debug",
                   help="show clbeam's debug messages and full tracebacks; twice (--debug --debug) also the "
                        "debug messages of the libraries (numba, matplotlib, Dask ...), otherwise held at WARNING")


def setup_logging(args: argparse.Namespace) -> None:
    """Configure logging from the parsed ``-v`` and ``--debug`` counts (main parser and subcommand together).

    Sets ``args.verbose`` and ``args.debug`` to the totals.  clbeam's loggers
    log at WARNING, INFO with ``-v``, DEBUG with ``--debug``; every other
    logger, the libraries' of :data:`LIBRARY_LOGGERS` named, stays at WARNING
    unless ``--debug`` is given twice.
    """
    import logging

    args.verbose = getattr(args, "verbose", 0) + getattr(args, "sub_verbose", 0)
    args.debug = getattr(args, "debug", 0) + getattr(args, "sub_debug", 0)
    everything = args.debug >= 2
    level = logging.DEBUG if args.debug else logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(format=LOG_FORMAT)  # a handler on stderr unless the root logger has one
    logging.getLogger().setLevel(logging.DEBUG if everything else logging.WARNING)
    logging.getLogger("clbeam").setLevel(level)
    for name in LIBRARY_LOGGERS:
        logging.getLogger(name).setLevel(logging.NOTSET if everything else logging.WARNING)


def add_engine_choice(p, *, group=None) -> None:
    """``--interp``, ``--backend`` and ``--device``: which engine and mode image the pings."""
    from clbeam.imaging.engine import INTERP_MODES

    g = group or p.add_argument_group("engine")
    g.add_argument("--interp", default="auto", choices=["auto", *INTERP_MODES],
                   help="interpolation mode (default auto: the cheapest mode, upsampling and beam sampling within "
                        "--max-error-db; a mode given here is used as it is, every cell imaged directly); "
                        "'exact' runs on the reference backend only")
    g.add_argument("--backend", default="opencl", choices=["opencl", "reference"], help="imaging engine (default opencl)")
    g.add_argument("--device", default=None, help="OpenCL device: index or name substring (default: CLBEAM_DEVICE or the first)")


def add_grid_options(p: argparse.ArgumentParser) -> None:
    """The grid options (docs/cli.md)."""
    g = p.add_argument_group("grid")
    g.add_argument("--range-res", type=float, default=0.2, metavar="M", help="range step (m, default 0.2)")
    g.add_argument("--angle-res", type=float, default=0.1, metavar="DEG", help="angle step (degree, default 0.1)")
    g.add_argument("--max-range", type=float, default=None, metavar="M",
                   help="largest range (m, default: the end of the record)")
    g.add_argument("--min-range", type=float, default=0.0, metavar="M", help="smallest range (m, default 0)")
    g.add_argument("--angles", type=float, nargs=2, default=(-80.0, 80.0), metavar=("MIN", "MAX"),
                   help="angle window from nadir (degree, starboard positive, default -80 80)")


def add_imaging_options(p: argparse.ArgumentParser, *, min_contrast_db: float | None = DEFAULT_MIN_CONTRAST_DB) -> None:
    """Engine choice, mode, outputs and the processing options of :class:`~clbeam.imaging.ImagingOptions`
    (``min_contrast_db``: the default of ``--min-contrast-db``)."""
    g = p.add_argument_group("imaging")
    add_engine_choice(p, group=g)
    g.add_argument("--upsample", type=int, default=None, metavar="N",
                   help="FFT upsampling of the analytic signal (default: chosen with --interp auto, else 1)")
    g.add_argument("--max-error-db", type=float, default=DEFAULT_MAX_ERROR_DB, metavar="DB",
                   help=f"error budget of the intensity against the exact image (dB, default {DEFAULT_MAX_ERROR_DB:g}): "
                        "--interp auto picks the cheapest setting that meets it")
    g.add_argument("--max-cf-error", type=float, default=DEFAULT_MAX_CF_ERROR, metavar="DCF",
                   help=f"error budget of the coherence factor (default {DEFAULT_MAX_CF_ERROR:g}): the largest |dCF| "
                        "on cells within 40 dB of an echo, with CF >= 0.99 at an echo on a node, measured on each "
                        "ping geometry's own point echoes; --interp auto holds it too")
    g.add_argument("--beams", default="auto", metavar="auto|off|K[:TAPS[:DOMAIN]]",
                   help="beam-sampled imaging: auto (chosen by the budget with --interp auto), off (every cell "
                        "directly), or an oversampling K of the aperture's band limit with TAPS interpolation taps, "
                        "the beams formed in the time domain (delay-and-sum, the default) or the frequency domain "
                        "(DOMAIN 'frequency': phase ramps on the channels' spectra; straight rays only); with "
                        "--interp auto, the time interpolation and upsampling that go with given beams are measured "
                        "on the ping's geometry")
    g.add_argument("--outputs", default="intensity,cf", metavar="LIST",
                   help="comma-separated outputs: intensity, cf, sums, and cf_smooth (the CF smoothed along range "
                        "that peaks are picked on, written on request) (default intensity,cf)")
    g.add_argument("--precision", default=None, choices=["float32", "float64"],
                   help="kernel arithmetic (default: float32 on OpenCL, float64 on the reference backend)")
    g.add_argument("--sound-speed", type=float, default=None, metavar="M/S", help="override the file's sound speed (m/s)")
    g.add_argument("--threshold", type=float, default=PEAK_THRESHOLD,
                   help=f"coherence-peak threshold on smoothed CF (default {PEAK_THRESHOLD:g})")
    add_min_snr_option(g, min_contrast_db=min_contrast_db)
    g.add_argument("--min-channels", type=float, default=DEFAULT_MIN_CHANNELS, metavar="N",
                   help="CF and peaks only in cells summed from at least N channels: a count, or below 1 a "
                        f"fraction of the ping's usable channels (default {DEFAULT_MIN_CHANNELS:g})")
    g.add_argument("--seabed-band", type=float, nargs=2, default=None, metavar=("ABOVE", "BELOW"),
                   help="compute only cells from ABOVE m above to BELOW m below the seabed (e.g. 5 40)")
    g.add_argument("--seabed-depth", type=float, default=None, metavar="M",
                   help="seabed depth below the transducers for --seabed-band (default: picked per ping)")
    g.add_argument("--apodization", default="rect", metavar="WINDOW",
                   help="receive window across the array: rect, hann, tukey[:alpha], chebyshev[:dB] "
                        "(default rect; CF becomes the weighted CF)")
    g.add_argument("--isospeed", action="store_true",
                   help="straight rays at the file's sound speed even when it has a sound-speed profile (svp_*)")
    g.add_argument("--sediment-speed", type=float, default=None, metavar="M/S",
                   help="sediment interval velocity below the seabed (m/s): rays refract at the seabed "
                        "(--seabed-depth, else picked per ping)")
    g.add_argument("--mlh", action="store_true",
                   help="merge the coherence peaks on one main-lobe arc into one detection (lobe-fitted position)")
    g.add_argument("--no-refine", action="store_true",
                   help="report coherence peaks at their grid cells (default: each moved to its echo's intensity "
                        "maximum from the exact sums, one row per echo, the cell in cell_* columns)")
    g.add_argument("--no-calibration", action="store_true",
                   help="ignore the file's element_gain_db / element_phase_deg (default: remove them)")


def min_snr_db(text: str) -> float | None:
    """``--min-snr-db``: a number of dB, or ``off``."""
    if text.strip().lower() == "off":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of dB or 'off', got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number of dB or 'off', got {text!r}")
    return value


def add_min_snr_option(group, *, min_contrast_db: float | None = DEFAULT_MIN_CONTRAST_DB) -> None:
    """``--min-snr-db`` and ``--min-contrast-db`` (default ``min_contrast_db``): the detection test (image,
    peaks, survey)."""
    group.add_argument("--min-snr-db", type=min_snr_db, default=DEFAULT_MIN_SNR_DB, metavar="DB",
                       help="peaks only this far above the ping's noise floor (default "
                            f"{DEFAULT_MIN_SNR_DB:g} dB; 'off': every peak above the CF threshold)")
    shown = "off" if min_contrast_db is None else f"{min_contrast_db:g} dB"
    group.add_argument("--min-contrast-db", type=min_snr_db, default=min_contrast_db, metavar="DB",
                       help="where the clutter is reverberation, peaks only this far above its mean intensity around "
                            f"them (100 range resolutions and 1.5 beamwidths; default {shown}; 'off': no clutter test)")


def options_from_args(args, **overrides):
    """:class:`~clbeam.imaging.ImagingOptions` from arguments of :func:`add_imaging_options`
    (``overrides``: fields to set otherwise)."""
    from clbeam.imaging.imager import ImagingOptions

    outputs = requested_outputs(args)
    engine_outputs = tuple(o for o in outputs if o != "cf_smooth") + (("cf",) if "cf_smooth" in outputs else ())
    fields = dict(interp=args.interp, upsample=args.upsample, outputs=tuple(dict.fromkeys(engine_outputs)),
                  threshold=args.threshold,
                  max_error_db=args.max_error_db, max_cf_error=args.max_cf_error, beams=parse_beams(args.beams),
                  sound_speed_m_s=args.sound_speed, precision=args.precision,
                  seabed_band_m=tuple(args.seabed_band) if args.seabed_band else None,
                  seabed_depth_m=args.seabed_depth, apodization=args.apodization,
                  calibrate=not args.no_calibration, mlh=args.mlh, use_svp=not args.isospeed,
                  sediment_speed_m_s=args.sediment_speed, refine_peaks=not args.no_refine,
                  min_channels=args.min_channels, min_snr_db=args.min_snr_db,
                  min_contrast_db=args.min_contrast_db)
    return ImagingOptions(**{**fields, **overrides})


def requested_outputs(args) -> tuple:
    """The ``--outputs`` names as given: the engine's (``intensity``, ``cf``, ``sums``) and the image file's
    ``cf_smooth``, which :func:`options_from_args` leaves to the host (it needs ``cf``)."""
    from clbeam.imaging.engine.common import OUTPUTS

    names = tuple(s.strip() for s in args.outputs.split(",") if s.strip())
    known = (*OUTPUTS, "cf_smooth")
    bad = [n for n in names if n not in known]
    if bad:
        raise OptionError(f"output '{bad[0]}' is unknown, expected some of {', '.join(known)}")
    return names


def parse_beams(text: str):
    """``--beams`` as an :class:`~clbeam.imaging.ImagingOptions` value: ``"auto"``, ``None`` or a BeamSampling."""
    from clbeam.imaging.engine.beams import BeamSampling

    if text in ("auto", "off"):
        return None if text == "off" else "auto"
    k, _, rest = text.partition(":")
    taps, _, domain = rest.partition(":")
    try:
        return BeamSampling(float(k), int(taps) if taps else BeamSampling.taps, domain or BeamSampling.domain)
    except ValueError:
        raise OptionError(f"--beams must be auto, off or K[:TAPS[:DOMAIN]] (e.g. 1.5:12 or 2:16:frequency), "
                          f"got {text!r}") from None


def grid_from_args(args, max_range_default: float):
    """:class:`~clbeam.model.grid.PolarGrid` from arguments of :func:`add_grid_options`."""
    from clbeam.model.grid import PolarGrid

    return PolarGrid.regular(range_res_m=args.range_res, angle_res_deg=args.angle_res,
                             max_range_m=args.max_range if args.max_range is not None else max_range_default,
                             min_range_m=args.min_range, angles_deg=tuple(args.angles))


def deflate_level(text: str) -> int:
    """A ``--compress`` level: an integer from 1 to 9."""
    try:
        level = int(text)
    except ValueError:
        level = None
    if level is None or not 1 <= level <= 9:
        raise argparse.ArgumentTypeError(f"the deflate level must be an integer from 1 to 9, got {text!r}")
    return level


def add_compression_options(p: argparse.ArgumentParser) -> None:
    """``--compress [LEVEL]`` and ``--pack-cf``: how the image file's arrays are stored."""
    g = p.add_argument_group("image file size")
    g.add_argument("--compress", type=deflate_level, nargs="?", const=1, default=None, metavar="LEVEL",
                   help="deflate the image arrays (zlib with byte shuffle) at LEVEL 1 (fast, the default) to 9 "
                        "(small); default: uncompressed (Zarr: its default codec)")
    g.add_argument("--pack-cf", action="store_true",
                   help="store cf and cf_smooth as 16-bit integers with a CF scale_factor (error below 8e-6, "
                        "half the bytes before deflate)")


def compression_from_args(args):
    """:class:`~clbeam.io.images.ImageCompression` from :func:`add_compression_options`'s arguments
    (``None``: neither given)."""
    from clbeam.io.images import ImageCompression

    if args.compress is None and not args.pack_cf:
        return None
    return ImageCompression(level=0 if args.compress is None else args.compress, pack_cf=args.pack_cf)


def remove_partial(path: Path) -> None:
    """Delete an output file or Zarr folder left incomplete by an error."""
    import shutil

    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists():
        path.unlink()
