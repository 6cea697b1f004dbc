"""Whole surveys: many pings imaged into georeferenced coherence peaks, a persistence map and objects.

The flow of one ping (:class:`clbeam.imaging.imager.Imager`) mapped over
every ping of many ping files (docs/ping-format.md), one ping at a time so that memory
does not grow with the survey, resumable after any interruption, in one
process or on a Dask cluster (Holland et al. 2024, Section III and
Figs. 9-10).  See ``docs/survey.md``.

Modules
-------
inputs
    The ping files, scanned and numbered (:func:`scan_inputs`).
options
    :class:`SurveyOptions`, :class:`AssociationOptions` and the parameters
    a survey store is bound to.
run
    :func:`run_survey`: the ledger of committed pings, the local and the
    Dask runner.
georef
    Peak positions on the WGS84 ellipsoid, UTM, course over ground.
association
    Detections linked across pings into objects.
products
    :func:`finalize_survey`: peak and object tables rebuilt from the ledger.
plots
    The plan-view map and the persistence figure.

The store's layout is :mod:`clbeam.io.survey_store`, its tables
:mod:`clbeam.io.survey_products`.
"""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.errors": ("SurveyError",),
    "clbeam.io.survey_store": ("done_pings", "is_survey_store", "ledger_path", "open_survey", "product_paths"),
    "clbeam.survey.association": ("associate", "describe_objects"),
    "clbeam.survey.georef": ("course_over_ground_deg", "peak_positions", "to_utm", "utm_epsg"),
    "clbeam.survey.inputs": ("Failure", "InputFile", "ScanResult", "scan_inputs"),
    "clbeam.survey.line_options": ("LineOptions",),
    "clbeam.survey.line_products": ("LINE_KINDS", "SurveyLines", "survey_lines"),
    "clbeam.survey.options": ("AssociationOptions", "SurveyOptions", "survey_parameters"),
    "clbeam.survey.plots": ("plot_survey_map",),
    "clbeam.survey.products": ("SurveyProducts", "finalize_survey"),
    "clbeam.survey.run": ("STAGES", "BlockTask", "SurveyResult", "process_block", "run_survey"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
