"""Whole surveys: many pings imaged into georeferenced coherence peaks, a persistence map and objects.

The flow of one ping (:class:`clbeam.imaging.imager.Imager`) mapped over
every ping of many ping files (SPEC §7), one ping at a time so that memory
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

from clbeam.errors import SurveyError
from clbeam.io.survey_store import done_pings, is_survey_store, ledger_path, open_survey, product_paths
from clbeam.survey.association import associate, describe_objects
from clbeam.survey.georef import course_over_ground_deg, peak_positions, to_utm, utm_epsg
from clbeam.survey.inputs import Failure, InputFile, ScanResult, scan_inputs
from clbeam.survey.options import AssociationOptions, SurveyOptions, survey_parameters
from clbeam.survey.plots import plot_survey_map
from clbeam.survey.products import SurveyProducts, finalize_survey
from clbeam.survey.run import STAGES, BlockTask, SurveyResult, process_block, run_survey

__all__ = ["STAGES", "AssociationOptions", "BlockTask", "Failure", "InputFile", "ScanResult", "SurveyError",
           "SurveyOptions", "SurveyProducts", "SurveyResult", "associate", "course_over_ground_deg",
           "describe_objects", "done_pings", "finalize_survey", "is_survey_store", "ledger_path", "open_survey", "peak_positions",
           "plot_survey_map", "process_block", "product_paths", "run_survey", "scan_inputs", "survey_parameters",
           "to_utm", "utm_epsg"]
