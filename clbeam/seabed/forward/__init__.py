"""Layered coherent forward model of the sub-bottom echo (Rakotonarivo et al.; docs/forward.md).

A seabed of fluid layers (:mod:`.layers`, read from TOML by :mod:`.config`)
with attenuation laws and their linearisation (:mod:`.attenuation`, eqs.
3–4), rough interfaces (:mod:`.roughness`, eqs. 5–8), transitional beds of
exponential density (:mod:`.transition`, eqs. 9–14) and sharp fluid
interfaces (:mod:`.reflection`) gives the echo sum of eqs. 15–18
(:mod:`.response`), the received and compressed traces for a chirp
(:mod:`.trace`, eq. 19), their figures (:mod:`.figures`, imported on
demand), and back: layer times, reflection coefficients and attenuation
from a compressed trace (:mod:`.inversion`).  :mod:`.cli` holds the
``clbeam forward`` subcommand.
"""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.seabed.forward.attenuation": (
        "DB_TO_NP", "LinearAttenuation", "PowerLawAttenuation", "as_linear", "attenuation_np_per_m",
        "linearise_attenuation",
    ),
    "clbeam.seabed.forward.config": ("BUNDLED", "LayoutFileError", "load_seabed", "seabed_from_dict", "table2_layout"),
    "clbeam.seabed.forward.inversion": (
        "EchoEstimate", "InversionResult", "LayerEstimate", "UnresolvableError", "invert_trace",
    ),
    "clbeam.seabed.forward.layers": ("Interface", "Layer", "Seabed", "layer_from_grain_size", "water_column"),
    "clbeam.seabed.forward.reflection": ("fluid_interface", "rayleigh_reflection", "snell_cosines"),
    "clbeam.seabed.forward.response": ("EchoSet", "echo_times", "layer_echoes", "specular_echoes", "transfer_function"),
    "clbeam.seabed.forward.roughness": (
        "rayleigh_parameter", "reflection_roughness_factor", "transmission_parameter", "transmission_roughness_factor",
    ),
    "clbeam.seabed.forward.trace": (
        "CHIRPS", "HIGH_CHIRP", "LOW_CHIRP", "Chirp", "ForwardTrace", "compress_circular", "simulate_trace",
    ),
    "clbeam.seabed.forward.transition": (
        "transition_coefficients", "transition_reflection_drop_db", "transition_threshold",
    ),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
