"""Layered seabed description for the coherent forward model (Rakotonarivo Fig. 7, Table 2).

A :class:`Seabed` is a stack of fluid :class:`Layer` s.  ``layers[0]`` is the
water column (the paper's medium 1): its thickness is the height of the
source above the seafloor.  The last layer is a half-space (infinite
thickness).  Each layer below the water carries the :class:`Interface` at
its top: the roughness of that interface and, optionally, a transitional
bed just below it in which the density grows exponentially from the
density above to the layer's own (paper §3.4, Fig. 7).

Units: thickness and roughness in metres, sound speed in m/s, density in
kg/m³ (never a ratio; :func:`layer_from_grain_size` turns the grain-size
ratios into kg/m³ with the water density it is given).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from clbeam.errors import OptionError, require

# the same grain-size regressions as the AVO inversion
from clbeam.seabed.avo import sediment as grain
from clbeam.seabed.forward.attenuation import (
    Attenuation,
    LinearAttenuation,
    PowerLawAttenuation,
)

#: Roughness regimes: Eckart's small roughness (eqs. 5–6) and the paper's
#: empirical fair roughness (eqs. 7–8).
ROUGHNESS_REGIMES = ("small", "fair")


@dataclass(frozen=True)
class Interface:
    """The top interface of a layer: roughness and optional transitional bed.

    Attributes
    ----------
    roughness_m : float
        Standard deviation ``sigma`` of the Gaussian interface heights (m).
    roughness_regime : {"small", "fair"}
        ``"small"``: Eckart factors ``exp(-P^2/2)``, ``exp(-P_T^2/2)``
        (eqs. 5–6); ``"fair"``: the same with ``4/3 P`` and ``5/2 P_T``
        (eqs. 7–8, for ``P`` near 1).
    transition_m : float
        Thickness ``dx`` of the transitional bed below the interface (m);
        0 for a sharp interface.
    transition_top_density_kg_m3 : float or None
        Density at the top of the transitional bed; ``None`` takes the
        density of the medium above (Table 2 layout 2: 1 to 1.3 g/cm³).  The
        bed's density grows exponentially to the layer's density; its sound
        speed and attenuation are the layer's (paper §3.4).
    """

    roughness_m: float = 0.0
    roughness_regime: str = "small"
    transition_m: float = 0.0
    transition_top_density_kg_m3: float | None = None

    def __post_init__(self) -> None:
        require(math.isfinite(self.roughness_m) and self.roughness_m >= 0, OptionError,
                f"interface roughness_m must be finite and >= 0 m, got {self.roughness_m!r}")
        require(self.roughness_regime in ROUGHNESS_REGIMES, OptionError,
                f"roughness_regime must be one of {', '.join(ROUGHNESS_REGIMES)}, got {self.roughness_regime!r}")
        require(math.isfinite(self.transition_m) and self.transition_m >= 0, OptionError,
                f"interface transition_m must be finite and >= 0 m, got {self.transition_m!r}")
        rho = self.transition_top_density_kg_m3
        require(rho is None or (math.isfinite(rho) and rho > 0), OptionError,
                f"transition_top_density_kg_m3 must be > 0 kg/m^3, got {rho!r}")

    @property
    def is_rough(self) -> bool:
        """True when the interface has a non-zero roughness."""
        return self.roughness_m > 0

    @property
    def has_transition(self) -> bool:
        """True when a transitional bed lies below the interface."""
        return self.transition_m > 0


@dataclass(frozen=True)
class Layer:
    """One homogeneous fluid layer (or the water column, or the bottom half-space).

    Attributes
    ----------
    thickness_m : float
        Thickness of the homogeneous part (m), below any transitional bed;
        ``math.inf`` for the bottom half-space.  For the water column: the
        source height above the seafloor.
    sound_speed_m_s : float
        Compressional sound speed (m/s).
    density_kg_m3 : float
        Density (kg/m³).
    attenuation : PowerLawAttenuation or LinearAttenuation
        Attenuation law (dB/m, ``f`` in kHz); lossless by default.
    top : Interface
        The interface at the top of this layer (ignored for the water).
    name : str
        Label for tables and plots.
    """

    thickness_m: float
    sound_speed_m_s: float
    density_kg_m3: float
    attenuation: Attenuation = field(default_factory=PowerLawAttenuation)
    top: Interface = field(default_factory=Interface)
    name: str = ""

    def __post_init__(self) -> None:
        label = self.name or "layer"
        require(self.thickness_m == math.inf or (math.isfinite(self.thickness_m) and self.thickness_m > 0),
                OptionError, f"{label} thickness_m must be > 0 m (or inf for the half-space), got {self.thickness_m!r}")
        require(math.isfinite(self.sound_speed_m_s) and self.sound_speed_m_s > 0, OptionError,
                f"{label} sound_speed_m_s must be > 0 m/s, got {self.sound_speed_m_s!r}")
        require(math.isfinite(self.density_kg_m3) and self.density_kg_m3 > 0, OptionError,
                f"{label} density_kg_m3 must be > 0 kg/m^3, got {self.density_kg_m3!r}")
        require(isinstance(self.attenuation, (PowerLawAttenuation, LinearAttenuation)), OptionError,
                f"{label} attenuation must be a PowerLawAttenuation or LinearAttenuation, got {self.attenuation!r}")
        require(isinstance(self.top, Interface), OptionError, f"{label} top must be an Interface, got {self.top!r}")

    @property
    def impedance(self) -> float:
        """Characteristic impedance ``rho c`` (kg m^-2 s^-1, rayl)."""
        return self.density_kg_m3 * self.sound_speed_m_s


@dataclass(frozen=True)
class Seabed:
    """Water column over a stack of sediment layers over a half-space.

    Attributes
    ----------
    layers : tuple of Layer
        ``layers[0]`` the water column (finite thickness = source height),
        ``layers[1:-1]`` sediment layers (finite), ``layers[-1]`` the
        half-space (``thickness_m = inf``).  At least two layers.
    name : str
        Label.
    """

    layers: tuple[Layer, ...]
    name: str = ""

    def __post_init__(self) -> None:
        layers = tuple(self.layers)
        object.__setattr__(self, "layers", layers)
        require(len(layers) >= 2, OptionError,
                f"a seabed needs the water and at least one layer below it, got {len(layers)} layer(s)")
        for i, layer in enumerate(layers[:-1]):
            require(math.isfinite(layer.thickness_m), OptionError,
                    f"layer {i} ({layer.name or 'unnamed'}) thickness_m must be finite above the half-space, "
                    f"got {layer.thickness_m!r}")
        require(layers[-1].thickness_m == math.inf, OptionError,
                f"the last layer ({layers[-1].name or 'unnamed'}) is the half-space: thickness_m must be inf, "
                f"got {layers[-1].thickness_m!r}")

    @property
    def water(self) -> Layer:
        """The water column (medium 1)."""
        return self.layers[0]

    @property
    def n_interfaces(self) -> int:
        """Number of interfaces, hence of echoes (one per layer below the water)."""
        return len(self.layers) - 1

    def with_layer(self, index: int, **changes) -> "Seabed":
        """A copy with ``layers[index]`` changed (``dataclasses.replace`` keywords)."""
        layers = list(self.layers)
        layers[index] = replace(layers[index], **changes)
        return replace(self, layers=tuple(layers))

    def with_interface(self, index: int, **changes) -> "Seabed":
        """A copy with the top interface of ``layers[index]`` changed."""
        return self.with_layer(index, top=replace(self.layers[index].top, **changes))


def water_column(depth_m: float, *, sound_speed_m_s: float = 1500.0, density_kg_m3: float = 1000.0,
                 attenuation: Attenuation | None = None) -> Layer:
    """The water layer: ``depth_m`` is the source height above the seafloor (m).

    Parameters
    ----------
    depth_m : float
        Source height above the seafloor (m).
    sound_speed_m_s : float
        Water sound speed (m/s), default 1500.
    density_kg_m3 : float
        Water density (kg/m³), default 1000.
    attenuation : PowerLawAttenuation or LinearAttenuation, optional
        Water absorption (dB/m); lossless by default.
    """
    return Layer(depth_m, sound_speed_m_s, density_kg_m3, attenuation or PowerLawAttenuation(), name="water")


def layer_from_grain_size(mz_phi: float, thickness_m: float, *, water_sound_speed_m_s: float = 1500.0,
                          water_density_kg_m3: float = 1000.0, top: Interface | None = None,
                          name: str = "") -> Layer:
    """A sediment layer from its mean grain size (APL-UW TR 9407 regressions).

    Density ``rho(Mz) * rho_w``, sound speed ``nu(Mz) * c_w`` and attenuation
    ``k_p(Mz) f`` (dB/m, ``n = 1``) from the regressions used by the AVO
    module (:mod:`clbeam.seabed.avo.sediment`), which gives both modules one set of
    sediment properties per grain size.

    Parameters
    ----------
    mz_phi : float
        Mean grain size ``Mz`` (phi), ``-1 <= Mz <= 9``.
    thickness_m : float
        Layer thickness (m), ``inf`` for a half-space.
    water_sound_speed_m_s, water_density_kg_m3 : float
        The water the ratios refer to (m/s, kg/m³).
    top : Interface, optional
        Interface at the top of the layer.
    name : str
        Label; default ``"Mz <value>"``.
    """
    rho_ratio, nu_ratio = grain.density_ratio(mz_phi), grain.sound_speed_ratio(mz_phi)
    k_p = grain.attenuation_db_per_m_khz(mz_phi)
    return Layer(thickness_m, nu_ratio * water_sound_speed_m_s, rho_ratio * water_density_kg_m3,
                 PowerLawAttenuation(k_p, 1.0), top or Interface(), name or f"Mz {mz_phi:g}")
