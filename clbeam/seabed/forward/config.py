"""Seabed layouts from TOML files, and the two bundled layouts of the paper's Table 2.

File format (SI units; every key optional unless said)::

    name = "my site"

    [water]                      # required
    depth_m = 20.0               # required: source height above the seafloor
    sound_speed_m_s = 1500.0
    density_kg_m3 = 1000.0

    [[layers]]                   # one table per layer, top to bottom
    name = "bed 2"
    thickness_m = 2.0            # required, except in the last layer (half-space)
    sound_speed_m_s = 1600.0     # required unless grain_size_phi is given
    density_kg_m3 = 1300.0       # required unless grain_size_phi is given
    attenuation = { k_p_db_m_khz = 0.1, n = 1.0 }           # k_p f^n (eq. 3)
    # attenuation = { slope_db_m_khz = 0.4, intercept_db_m = -0.08 }   # k_p' f + b (eq. 4)
    # grain_size_phi = 2.5       # instead of speed, density and attenuation
    top = { roughness_m = 0.01, roughness_regime = "fair", transition_m = 0.05 }

``attenuation`` is also accepted in ``[water]``.  Unknown keys are errors,
so a misspelt key does not silently fall back to a default.
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

from clbeam.errors import ClbeamError, OptionError, require
from clbeam.seabed.forward.attenuation import LinearAttenuation, PowerLawAttenuation
from clbeam.seabed.forward.layers import (
    Interface,
    Layer,
    Seabed,
    layer_from_grain_size,
    water_column,
)


class LayoutFileError(ClbeamError):
    """A seabed layout file is missing, unreadable or invalid."""


_WATER_KEYS = {"depth_m", "sound_speed_m_s", "density_kg_m3", "attenuation"}
_LAYER_KEYS = {"name", "thickness_m", "sound_speed_m_s", "density_kg_m3", "attenuation", "grain_size_phi", "top"}
_TOP_KEYS = {"roughness_m", "roughness_regime", "transition_m", "transition_top_density_kg_m3"}
_POWER_KEYS = {"k_p_db_m_khz", "n"}
_LINEAR_KEYS = {"slope_db_m_khz", "intercept_db_m"}

#: Bundled layouts: name -> file in the package folder ``layouts/``.
BUNDLED = {"table2-layout1": "table2_layout1.toml", "table2-layout2": "table2_layout2.toml"}


def _check_keys(where: str, table, allowed: set[str]) -> None:
    require(isinstance(table, dict), LayoutFileError, f"{where} must be a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise LayoutFileError(f"unknown key {unknown[0]!r} in {where}; expected one of {', '.join(sorted(allowed))}")


def _number(where: str, table: dict, key: str, default=None) -> float:
    if key not in table:
        require(default is not None, LayoutFileError, f"{where}.{key} is required")
        return default
    value = table[key]
    require(isinstance(value, (int, float)) and not isinstance(value, bool), LayoutFileError,
            f"{where}.{key} must be a number, got {value!r}")
    return float(value)


def _attenuation(where: str, table):
    _check_keys(where, table, _POWER_KEYS | _LINEAR_KEYS)
    power, linear = set(table) & _POWER_KEYS, set(table) & _LINEAR_KEYS
    require(not (power and linear), LayoutFileError,
            f"{where} mixes the power law (k_p_db_m_khz, n) and the linear law (slope_db_m_khz, intercept_db_m)")
    if linear:
        return LinearAttenuation(_number(where, table, "slope_db_m_khz", 0.0),
                                 _number(where, table, "intercept_db_m", 0.0))
    return PowerLawAttenuation(_number(where, table, "k_p_db_m_khz", 0.0), _number(where, table, "n", 1.0))


def seabed_from_dict(data: dict, *, source: str = "layout") -> Seabed:
    """A :class:`~.layers.Seabed` from the parsed TOML tables (format in the module docstring).

    Parameters
    ----------
    data : dict
        ``{"name": ..., "water": {...}, "layers": [{...}, ...]}``.
    source : str
        Name used in error messages (the file name).
    """
    _check_keys(source, data, {"name", "water", "layers"})
    require("water" in data, LayoutFileError, f"{source}: the [water] table is required")
    water_t = data["water"]
    _check_keys(f"{source}: water", water_t, _WATER_KEYS)
    try:
        c_w = _number(f"{source}: water", water_t, "sound_speed_m_s", 1500.0)
        rho_w = _number(f"{source}: water", water_t, "density_kg_m3", 1000.0)
        water = water_column(_number(f"{source}: water", water_t, "depth_m"), sound_speed_m_s=c_w,
                             density_kg_m3=rho_w,
                             attenuation=_attenuation(f"{source}: water.attenuation", water_t.get("attenuation", {})))
        rows = data.get("layers", [])
        require(isinstance(rows, list) and len(rows) >= 1, LayoutFileError,
                f"{source}: at least one [[layers]] table is required")
        layers = [water]
        for i, row in enumerate(rows):
            where = f"{source}: layers[{i}]"
            _check_keys(where, row, _LAYER_KEYS)
            last = i == len(rows) - 1
            if last:
                require("thickness_m" not in row, LayoutFileError,
                        f"{where} is the half-space: leave thickness_m out")
                thickness = math.inf
            else:
                thickness = _number(where, row, "thickness_m")
            top_t = row.get("top", {})
            _check_keys(f"{where}.top", top_t, _TOP_KEYS)
            top = Interface(roughness_m=_number(f"{where}.top", top_t, "roughness_m", 0.0),
                            roughness_regime=str(top_t.get("roughness_regime", "small")),
                            transition_m=_number(f"{where}.top", top_t, "transition_m", 0.0),
                            transition_top_density_kg_m3=(
                                _number(f"{where}.top", top_t, "transition_top_density_kg_m3")
                                if "transition_top_density_kg_m3" in top_t else None))
            name = str(row.get("name", f"layer {i + 1}"))
            if "grain_size_phi" in row:
                clash = sorted({"sound_speed_m_s", "density_kg_m3", "attenuation"} & set(row))
                if clash:
                    raise LayoutFileError(f"{where} gives grain_size_phi and {clash[0]}: use one or the other")
                layers.append(layer_from_grain_size(_number(where, row, "grain_size_phi"), thickness,
                                                    water_sound_speed_m_s=c_w, water_density_kg_m3=rho_w,
                                                    top=top, name=name))
            else:
                layers.append(Layer(thickness, _number(where, row, "sound_speed_m_s"),
                                    _number(where, row, "density_kg_m3"),
                                    _attenuation(f"{where}.attenuation", row.get("attenuation", {})), top, name))
        return Seabed(tuple(layers), name=str(data.get("name", source)))
    except LayoutFileError:
        raise
    except OptionError as exc:
        raise LayoutFileError(f"{source}: {exc}") from None


def load_seabed(source: str | Path) -> Seabed:
    """Read a seabed layout: a TOML file path or a bundled name (:data:`BUNDLED`).

    Parameters
    ----------
    source : str or pathlib.Path
        ``"table2-layout1"``, ``"table2-layout2"`` or a path to a ``.toml`` file.

    Returns
    -------
    Seabed
    """
    key = str(source)
    if key in BUNDLED:
        text = resources.files(__package__).joinpath("layouts", BUNDLED[key]).read_text(encoding="utf-8")
        name = key
    else:
        path = Path(source)
        require(path.is_file(), LayoutFileError,
                f"layout file {str(path)!r} not found (or give one of {', '.join(BUNDLED)})")
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise LayoutFileError(f"layout file {str(path)!r} is unreadable: {exc}") from None
        name = path.name
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise LayoutFileError(f"layout file {name!r} is not valid TOML: {exc}") from None
    return seabed_from_dict(data, source=name)


def table2_layout(number: int) -> Seabed:
    """Layout 1 or 2 of the paper's Table 2 (bundled TOML files; thicknesses are this package's choice).

    Parameters
    ----------
    number : {1, 2}
    """
    require(number in (1, 2), OptionError, f"Table 2 has layouts 1 and 2, got {number!r}")
    return load_seabed(f"table2-layout{number}")
