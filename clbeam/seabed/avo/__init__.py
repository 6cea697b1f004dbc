"""Seafloor characterisation from the backscatter angular response (docs/avo.md).

Fonseca, Mayer & Kraft (2005): stack per-ping angular responses into
patches (:mod:`.stack`), compute AVO attributes and the gradient–intercept
analysis (:mod:`.attributes`), invert the APL-UW TR 9407 backscatter model
(:mod:`.model`, :mod:`.sediment`) for grain size, impedance and roughness
(:mod:`.inversion`; jointly with the nadir reflection coefficient and the
self-calibration of :mod:`clbeam.seabed.nadir`: :mod:`.calibration`,
:mod:`.joint`), write the per-patch table (:mod:`.table`) and the
figures (:mod:`.plot`, imported on demand because it loads matplotlib).
"""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.seabed.avo.attributes": (
        "AngularAttributes", "angular_attributes", "background_trend", "fluid_factor", "gradient_intercept", "product",
        "range_mask",
    ),
    "clbeam.seabed.avo.calibration": ("Calibration", "survey_calibration"),
    "clbeam.seabed.avo.inversion": ("InversionResult", "invert_attributes", "invert_response"),
    "clbeam.seabed.avo.joint": ("JointResult", "invert_joint", "nadir_model_reflection"),
    "clbeam.seabed.avo.model": (
        "backscatter_cross_section", "backscatter_strength_db", "critical_angle_deg", "kirchhoff_cross_section",
        "kirchhoff_integral", "lambert_strength_db", "perturbation_cross_section", "reflection_coefficient",
        "reflection_loss_db", "roughness_cross_section", "volume_cross_section",
    ),
    "clbeam.seabed.avo.response": (
        "AngularResponse", "ResponseOptions", "SeabedLine", "along_track_positions_m", "angular_responses",
        "francois_garrison_db_per_km", "incidence_angle_deg", "insonified_area_m2", "pick_seabed", "ping_response",
        "strength_from_intensity_db",
    ),
    "clbeam.seabed.avo.sediment": ("SedimentParams", "sediment_from_grain_size", "sediment_named", "sediment_names"),
    "clbeam.seabed.avo.stack": ("Patch", "stack_linear_db", "stack_pings", "stack_sides"),
    "clbeam.seabed.avo.table": ("COLUMNS", "PatchRecord", "survey_records", "write_csv"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
