"""Layered coherent forward model of the sub-bottom echo (Rakotonarivo et al., SPEC §6).

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

from clbeam.seabed.forward.attenuation import (
                          DB_TO_NP,
                          LinearAttenuation,
                          PowerLawAttenuation,
                          as_linear,
                          attenuation_np_per_m,
                          linearise_attenuation,
)
from clbeam.seabed.forward.config import (
                          BUNDLED,
                          LayoutFileError,
                          load_seabed,
                          seabed_from_dict,
                          table2_layout,
)
from clbeam.seabed.forward.inversion import (
                          EchoEstimate,
                          InversionResult,
                          LayerEstimate,
                          UnresolvableError,
                          invert_trace,
)
from clbeam.seabed.forward.layers import (
                          Interface,
                          Layer,
                          Seabed,
                          layer_from_grain_size,
                          water_column,
)
from clbeam.seabed.forward.reflection import (
                          fluid_interface,
                          rayleigh_reflection,
                          snell_cosines,
)
from clbeam.seabed.forward.response import (
                          EchoSet,
                          echo_times,
                          layer_echoes,
                          specular_echoes,
                          transfer_function,
)
from clbeam.seabed.forward.roughness import (
                          rayleigh_parameter,
                          reflection_roughness_factor,
                          transmission_parameter,
                          transmission_roughness_factor,
)
from clbeam.seabed.forward.trace import (
                          CHIRPS,
                          HIGH_CHIRP,
                          LOW_CHIRP,
                          Chirp,
                          ForwardTrace,
                          compress_circular,
                          simulate_trace,
)
from clbeam.seabed.forward.transition import (
                          transition_coefficients,
                          transition_reflection_drop_db,
                          transition_threshold,
)

__all__ = [
    "DB_TO_NP", "LinearAttenuation", "PowerLawAttenuation", "as_linear", "attenuation_np_per_m",
    "linearise_attenuation",
    "BUNDLED", "LayoutFileError", "load_seabed", "seabed_from_dict", "table2_layout",
    "EchoEstimate", "InversionResult", "LayerEstimate", "UnresolvableError", "invert_trace",
    "Interface", "Layer", "Seabed", "layer_from_grain_size", "water_column",
    "fluid_interface", "rayleigh_reflection", "snell_cosines",
    "EchoSet", "echo_times", "layer_echoes", "specular_echoes", "transfer_function",
    "rayleigh_parameter", "reflection_roughness_factor", "transmission_parameter", "transmission_roughness_factor",
    "CHIRPS", "HIGH_CHIRP", "LOW_CHIRP", "Chirp", "ForwardTrace", "compress_circular", "simulate_trace",
    "transition_coefficients", "transition_reflection_drop_db", "transition_threshold",
]
