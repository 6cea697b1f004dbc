"""``clbeam survey``: image a whole survey into coherence peaks (and images), resumable and parallel."""

from __future__ import annotations

from clbeam.cli.options import (
    add_grid_options,
    add_imaging_options,
    grid_from_args,
    options_from_args,
    progress,
    require_extra,
)
from clbeam.constants import MAP_THRESHOLD
from clbeam.errors import require
from clbeam.survey.line_options import LineOptions

NAME = "survey"
HELP = "image a whole survey into coherence peaks (and images): resumable, parallel"
DESCRIPTION = ("Image every ping of the input files; write the coherence peaks (Zarr, CSV, GeoJSON), the "
               "persistence map, the associated objects and the lines (pipelines and the rest, scored); resume "
               "after any interruption.  See clbeam docs survey and clbeam docs lines.")


def add_arguments(p) -> None:
    """The arguments of ``clbeam survey``."""
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="ping files in survey order (clbeam docs ping-format)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.zarr",
                   help="survey store; products OUT.peaks.csv, OUT.peaks.geojson, OUT.objects.csv, "
                        "OUT.objects.geojson, OUT.lines.csv, OUT.lines.geojson, OUT.map.png, OUT.persistence.png "
                        "beside it")
    add_grid_options(p)
    # the lines tell pipelines from the seabed's scatterers across pings: every hit counts (docs/survey.md)
    add_imaging_options(p, min_contrast_db=None)
    g = p.add_argument_group("survey")
    g.add_argument("--images", action="store_true", help="also write the images (one compressed chunk per ping)")
    g.add_argument("--workers", type=int, default=None, metavar="N", help="start a local Dask cluster of N processes")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS", help="use the Dask scheduler at ADDRESS (tcp://host:8786)")
    g.add_argument("--block-pings", type=int, default=8, metavar="N", help="pings per Dask task (default 8)")
    g.add_argument("--restart", action="store_true",
                   help="discard the existing survey output and its products and start again (needed when the "
                        "parameters differ; a folder that is not a survey output is never removed)")
    g.add_argument("--stop-on-error", action="store_true",
                   help="stop at the first unreadable file or ping (default: report it, skip it, go on)")
    a = p.add_argument_group("persistence map and objects")
    a.add_argument("--map-threshold", type=float, default=MAP_THRESHOLD, metavar="CF",
                   help="CF threshold of the map and the association (default 0.4, paper Figs. 9-10)")
    a.add_argument("--link-distance", type=float, default=3.0, metavar="M",
                   help="largest cross-track separation of detections linked across pings (m, default 3)")
    a.add_argument("--link-depth", type=float, default=3.0, metavar="M",
                   help="largest depth difference of linked detections (m, default 3)")
    a.add_argument("--max-gap", type=int, default=2, metavar="N", help="pings an object may skip (default 2)")
    a.add_argument("--min-pings", type=int, default=5, metavar="N", help="pings an object needs (default 5)")
    a.add_argument("--speed", type=float, default=None, metavar="M/S",
                   help="ship speed (m/s) for the along-track distance of pings without navigation")
    add_line_options(p)


def add_line_options(p) -> None:
    """The options of the lines (products only: a rerun may change them without re-imaging)."""
    d = LineOptions()
    a = p.add_argument_group("lines (clbeam docs lines)")
    a.add_argument("--line-min-score", type=float, default=d.min_score, metavar="S",
                   help=f"score a line needs: -log10 of the expected chance lines as good per km "
                        f"(default {d.min_score:g}: no false pipeline line in the simulated clutter: clbeam docs lines)")
    a.add_argument("--line-gate", type=float, default=d.across_gate_m, metavar="M",
                   help=f"largest cross-track distance of a detection from its line (m, default {d.across_gate_m:g})")
    a.add_argument("--line-max-gap", type=int, default=d.max_gap_pings, metavar="N",
                   help=f"imaged pings in a row without a detection a line may bridge (default {d.max_gap_pings})")
    a.add_argument("--line-join-gap", type=float, default=d.join_gap_m, metavar="M",
                   help=f"longest stretch along the track between two pipeline lines end to end that are joined "
                        f"when they line up and agree in burial (m, default {d.join_gap_m:g})")
    a.add_argument("--line-max-angle", type=float, default=d.max_angle_deg, metavar="DEG",
                   help=f"largest heading of a line relative to the track (degree, default {d.max_angle_deg:g})")
    a.add_argument("--truth", action="store_true",
                   help="score the lines against the truth the simulator wrote in the input files "
                        "(pipelines found, fragments, position and burial errors, false lines per km)")


def line_options_from_args(args):
    """:class:`LineOptions` from parsed arguments."""
    return LineOptions(min_score=args.line_min_score, across_gate_m=args.line_gate,
                       max_gap_pings=args.line_max_gap, join_gap_m=args.line_join_gap,
                       max_angle_deg=args.line_max_angle)


def options_from_survey_args(args, scan):
    """:class:`SurveyOptions` from parsed ``clbeam survey`` arguments."""
    from clbeam.survey import AssociationOptions, SurveyOptions

    return SurveyOptions(
        grid=grid_from_args(args, scan.max_range_m), imaging=options_from_args(args), backend=args.backend,
        device=args.device, images=args.images, block_pings=args.block_pings,
        association=AssociationOptions(threshold=args.map_threshold, link_distance_m=args.link_distance,
                                       depth_tolerance_m=args.link_depth, max_gap_pings=args.max_gap,
                                       min_pings=args.min_pings),
        lines=line_options_from_args(args), speed_m_s=args.speed)


def summary_lines(res) -> list:
    """The summary ``clbeam survey`` prints."""
    pr = res.products
    lines = [f"survey: {res.n_pings} ping(s); {res.n_imaged} imaged now, {res.n_done_before} done before"
             + (f", {pr.n_imaged} in the output" if pr else "")
             + (f"; {res.pings_per_s:.2f} pings/s" if res.n_imaged else "")
             + (f" on {res.workers} Dask worker(s)" if res.workers else "")]
    if res.n_timed:
        split = ", ".join(f"{k[:-2]} {v * 1e3:.1f}" for k, v in res.time_per_ping_s.items())
        lines.append(f"time per ping (ms): {split}")
    if pr:
        f = pr.files
        lines.append(f"peaks: {pr.n_peaks} -> {res.output.name} (group peaks), {f['peaks_csv'].name}"
                     + (f", {f['peaks_geojson'].name}" if pr.navigation else " (no navigation: no GeoJSON)"))
        lines.append(f"objects: {len(pr.objects)} from {pr.n_detections} detections -> {f['objects_csv'].name}"
                     + (f", {f['objects_geojson'].name}" if pr.navigation else "")
                     + f"; map -> {f['map_png'].name}, {f['persistence_png'].name}")
        lines.append(f"lines: {pr.n_pipelines} pipeline(s) among {len(pr.lines.rows)} line(s) scoring "
                     f">= {pr.lines.min_score:g} -> {f['lines_csv'].name}"
                     + (f", {f['lines_geojson'].name}" if pr.lines.geo_paths is not None else ""))
        if pr.lines.too_few_pings:
            lines.append(f"lines: none: {pr.lines.too_few_pings}")
    if res.failures:
        by_file = {}
        for fl in res.failures:
            by_file.setdefault(fl.file, []).append(fl)
        for name, fls in by_file.items():
            if fls[0].ping is None:
                lines.append(f"skipped: {name}: {fls[0].message}")
            else:
                lines.append(f"skipped: {name}: {len(fls)} ping(s) not imaged (ping {fls[0].ping}: {fls[0].message})")
        lines.append("incomplete: rerun the same command to retry the pings not imaged")
    return lines


def run(args) -> int:
    """``clbeam survey``: returns 0 when every ping is imaged, 1 when some
    input was skipped (listed in the summary)."""
    require_extra("dask", "survey", "survey")
    require_extra("pyproj", "survey", "survey")
    from clbeam.survey import SurveyError, run_survey, scan_inputs

    scan = scan_inputs(args.inputs, stop_on_error=args.stop_on_error)
    require(bool(scan.files), SurveyError,
            "no readable input file" + (f" ({'; '.join(map(str, scan.failures))})" if scan.failures else ""))
    options = options_from_survey_args(args, scan)
    res = run_survey(scan, args.output, options, workers=args.workers, scheduler=args.scheduler,
                     restart=args.restart, stop_on_error=args.stop_on_error,
                     progress=lambda total: progress(None, total=total, desc="survey", quiet=args.quiet))
    if not args.quiet or res.failures:
        print("\n".join(summary_lines(res)))
    if args.truth and res.products:
        print("\n".join(_truth_lines(res.products, [f.path for f in scan.files])))
    return 0 if res.complete else 1


def _truth_lines(products, paths) -> list:
    """The ``--truth`` report, or why there is none (or why it finds no line)."""
    from clbeam.evaluation.line_truth import score_survey, truth_summary

    scored = score_survey(products, paths)
    if scored is None:
        return ["truth: the inputs hold no line targets' truth (truth_target_* variables of a simulation)"]
    report = truth_summary(*scored)
    if products.lines.too_few_pings:  # the truth's rows say "line -1", NaN errors: say why first
        report.insert(0, f"truth: no line to score the targets on: {products.lines.too_few_pings}")
    return report
