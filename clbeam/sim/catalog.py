"""Scene files: the built-in TOML scenes and the loader that turns TOML into a :class:`~clbeam.sim.scene.Scene`.

The built-in scenes are package data in ``clbeam/sim/scenes/*.toml`` (the
data package ``clbeam.sim.scenes``, found with :mod:`importlib.resources`,
so they travel with an installed wheel).  :func:`load_scene` reads one of
them or any ``.toml`` file, applies dotted-key overrides and builds the
scene through :func:`scene_from_mapping`, which converts each value to the
type its dataclass field is annotated with.  Every problem is a one-line
:class:`clbeam.errors.OptionError` naming the scene key.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import math
import os
import tomllib
import types
import typing
from pathlib import Path

from clbeam.errors import OptionError, require
from clbeam.sim.scene import TARGET_KINDS, Scene, Water

SCENES_PACKAGE = "clbeam.sim.scenes"
"""The data package that holds the built-in ``*.toml`` scenes."""


def _convert(hint, value, where: str):
    """Convert a TOML value to the annotated type ``hint`` (one-line errors)."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        return _convert(args[0], value, where)
    if dataclasses.is_dataclass(hint):
        require(isinstance(value, dict), OptionError, f"scene key '{where}' must be a table, got {value!r}")
        return _from_mapping(hint, value, where)
    if hint is bool:
        require(isinstance(value, bool), OptionError, f"scene key '{where}' must be true or false, got {value!r}")
        return value
    if hint is int:
        require(isinstance(value, int) and not isinstance(value, bool) or (isinstance(value, float) and value.is_integer()),
                OptionError, f"scene key '{where}' must be an integer, got {value!r}")
        return int(value)
    if hint is float:
        require(isinstance(value, (int, float)) and not isinstance(value, bool), OptionError,
                f"scene key '{where}' must be a number, got {value!r}")
        require(math.isfinite(value), OptionError, f"scene key '{where}' must be finite, got {value!r}")
        return float(value)
    if hint is str:
        require(isinstance(value, str), OptionError, f"scene key '{where}' must be a string, got {value!r}")
        return value
    if origin is tuple and typing.get_args(hint) and dataclasses.is_dataclass(typing.get_args(hint)[0]):
        cls = typing.get_args(hint)[0]
        require(isinstance(value, (list, tuple)) and all(isinstance(v, dict) for v in value), OptionError,
                f"scene key '{where}' must be a list of tables, got {value!r}")
        return tuple(_from_mapping(cls, v, f"{where}[{i}]") for i, v in enumerate(value))
    if hint is tuple:
        require(isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value), OptionError,
                f"scene key '{where}' must be a list of numbers, got {value!r}")
        return tuple(float(v) for v in value)
    raise OptionError(f"scene key '{where}': unsupported type {hint}")  # pragma: no cover - a programming error


def _from_mapping(cls, mapping: dict, where: str):
    """Build dataclass ``cls`` from a TOML table found at key ``where``."""
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in mapping.items():
        here = f"{where}.{key}" if where else key
        require(key in names, OptionError, f"unknown scene key '{here}' (expected one of: {', '.join(names)})")
        kwargs[key] = _convert(hints[key], value, here)
    return cls(**kwargs)


def scene_from_mapping(data: dict, *, name: str | None = None) -> Scene:
    """Build a :class:`~clbeam.sim.scene.Scene` from parsed TOML.

    Parameters
    ----------
    data : dict
        Nested tables as :func:`tomllib.loads` returns them; ``target`` is a
        list of tables, each with ``kind = "point"`` or ``"line"``.
    name : str, optional
        The scene's name, in place of ``data["name"]``.

    Returns
    -------
    Scene

    Raises
    ------
    clbeam.errors.OptionError
        On an unknown key, a value of the wrong type or out of range.
    """
    data = dict(data)
    targets = []
    for i, t in enumerate(data.pop("target", [])):
        require(isinstance(t, dict), OptionError, f"scene key 'target[{i}]' must be a table")
        t = dict(t)
        kind = t.pop("kind", None)
        require(kind in TARGET_KINDS, OptionError,
                f"scene key 'target[{i}].kind' must be one of {sorted(TARGET_KINDS)}, got {kind!r}")
        targets.append(_from_mapping(TARGET_KINDS[kind], t, f"target[{i}]"))
    if data.get("water") is not None and "sound_speed_m_s" not in data:
        # the transducers' speed follows from the profile
        water = _convert(Water, data["water"], "water")
        data["sound_speed_m_s"] = water.transducer_speed_m_s
    scene = _from_mapping(Scene, data, "")
    scene = dataclasses.replace(scene, targets=tuple(targets))
    if name is not None:
        scene = dataclasses.replace(scene, name=name)
    return scene


def list_scenes() -> list[str]:
    """Names of the built-in scenes (``clbeam/sim/scenes/*.toml``)."""
    root = importlib.resources.files(SCENES_PACKAGE)
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(source: str | os.PathLike) -> tuple[dict, str]:
    """Parsed TOML of a built-in scene name or a file, and the scene's default name."""
    text_source = str(source)
    if text_source in list_scenes():
        text = importlib.resources.files(SCENES_PACKAGE).joinpath(f"{text_source}.toml").read_text()
        origin = text_source
    else:
        path = Path(source)
        require(path.suffix == ".toml" or path.exists(), OptionError,
                f"unknown scene '{text_source}': not a built-in scene ({', '.join(list_scenes())}) nor a .toml file")
        require(path.is_file(), OptionError, f"scene file {path}: no such file")
        text = path.read_text()
        origin = path.stem
    try:
        return tomllib.loads(text), origin
    except tomllib.TOMLDecodeError as exc:
        raise OptionError(f"scene {origin}: invalid TOML ({exc})") from None


_UNSET = object()


def load_scene(source: str | os.PathLike | Scene, *, pings: int | None = None, max_range_m: float | None = None,
               snr_db=_UNSET, overrides: dict | None = None) -> Scene:
    """Load a scene by built-in name or TOML path, with options overridden.

    Parameters
    ----------
    source : str, path-like or Scene
        ``"line1"``, ``"line4"``, ``"point"``, ``"avo2"``, ``"avo3"``, ``"svp1km"`` (see :func:`list_scenes`), a
        ``.toml`` file, or a :class:`~clbeam.sim.scene.Scene` (overrides applied to it).
    pings : int, optional
        Number of pings on the line.
    max_range_m : float, optional
        Largest fully recorded slant range (m).
    snr_db : float or None, optional
        Noise level (see :class:`~clbeam.sim.scene.Scene`); ``None`` switches the noise off.
    overrides : dict, optional
        Dotted TOML keys and values, e.g. ``{"motion.roll_mean_deg": 5.0,
        "seabed.scattering.per_cell": 2}``; ``"target"`` replaces the target
        list (a list of tables).  ``None`` values remove a key.

    Returns
    -------
    Scene
    """
    if isinstance(source, Scene):
        data, origin = source.to_dict(), source.name
        data = _drop_none(data)
    else:
        data, origin = _read_toml(source)
    items = dict(overrides or {})
    if pings is not None:
        items["survey.pings"] = pings
    if max_range_m is not None:
        items["record.max_range_m"] = max_range_m
    if snr_db is not _UNSET:
        items["snr_db"] = snr_db
    for key, value in items.items():
        _set_dotted(data, key, value)
    data.setdefault("name", origin)
    return scene_from_mapping(data)


def _drop_none(d):
    """``d`` without its ``None`` values (TOML has no null)."""
    if isinstance(d, dict):
        return {k: _drop_none(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_drop_none(v) for v in d]
    return d


def _set_dotted(data: dict, key: str, value) -> None:
    """Set (or, for ``None``, remove) the dotted ``key`` in nested tables."""
    parts = key.split(".")
    node = data
    for p in parts[:-1]:
        nxt = node.get(p)
        if nxt is None:
            nxt = node[p] = {}
        require(isinstance(nxt, dict), OptionError, f"scene override '{key}': '{p}' is not a table")
        node = nxt
    if value is None:
        node.pop(parts[-1], None)
    else:
        node[parts[-1]] = value
