"""Options of a survey run, and the processing parameters a survey store is bound to.

:func:`survey_parameters` lists what a rerun must repeat (the grid, the
imaging options, the backend, the image variables, the readable inputs);
:func:`first_difference` names the first value that changed, for the one-line
refusal of a rerun with other parameters.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field

import numpy as np

from clbeam.constants import MAP_THRESHOLD
from clbeam.errors import OptionError, require
from clbeam.imaging.imager import ImagingOptions
from clbeam.io.schema import image_variables
from clbeam.io.survey_store import SURVEY_FORMAT
from clbeam.model.grid import PolarGrid
from clbeam.survey.inputs import ScanResult
from clbeam.survey.line_options import LineOptions


@dataclass(frozen=True)
class AssociationOptions:
    """How detections are associated across pings into objects.

    Two detections (coherence peaks with CF above ``threshold``) of pings
    ``i < j`` are linked when ``j - i <= max_gap_pings + 1``, their
    horizontal separation measured across the track of ping ``j`` (easting
    and northing projected on ping ``j``'s starboard direction; without
    navigation, the difference of their cross-track offsets ``y``) is at
    most ``link_distance_m`` and their depths ``z`` differ by at most
    ``depth_tolerance_m``.  Linked detections form groups (connected
    components); a group spanning at least ``min_pings`` distinct pings is
    an object, the rest stay isolated (object ``-1``).

    Attributes
    ----------
    threshold : float
        CF threshold (paper Figs. 9-10: 0.4).
    link_distance_m : float
        Largest cross-track separation of linked detections (m).  An object
        crossing the track at an angle ``a`` moves ``spacing tan(a)``
        across per ping: the default 3 m follows lines up to about 20
        degrees off the track at 8 m ping spacing.
    depth_tolerance_m : float
        Largest depth difference of linked detections (m).
    max_gap_pings : int
        Pings without a detection a line may skip.
    min_pings : int
        Distinct pings an object needs.
    """

    threshold: float = MAP_THRESHOLD
    link_distance_m: float = 3.0
    depth_tolerance_m: float = 3.0
    max_gap_pings: int = 2
    min_pings: int = 5

    def __post_init__(self):
        require(0 <= self.threshold <= 1, OptionError, f"map threshold must be within 0-1, got {self.threshold!r}")
        require(self.link_distance_m > 0, OptionError, f"link distance must be > 0 m, got {self.link_distance_m!r}")
        require(self.depth_tolerance_m > 0, OptionError, f"link depth must be > 0 m, got {self.depth_tolerance_m!r}")
        require(int(self.max_gap_pings) == self.max_gap_pings and self.max_gap_pings >= 0, OptionError,
                f"max gap must be an integer >= 0 pings, got {self.max_gap_pings!r}")
        require(int(self.min_pings) == self.min_pings and self.min_pings >= 1, OptionError,
                f"min pings must be an integer >= 1, got {self.min_pings!r}")


@dataclass(frozen=True)
class SurveyOptions:
    """Everything a survey run needs besides its inputs and output.

    Attributes
    ----------
    grid : PolarGrid
        Image grid of every ping.
    imaging : ImagingOptions
        Mode, outputs (must include ``"cf"``), peak threshold, seabed band …
        By default without the clutter test (``min_contrast_db=None``): the
        survey's lines tell pipelines from the seabed's scatterers by their
        arrangement across pings, and need every hit a pipeline gives.
    backend : {"opencl", "reference"}
        Imaging engine.
    device : str or int or None
        OpenCL device (index or name substring); not part of the stored
        parameters (every device runs the same kernels).
    images : bool
        Also write the images (``intensity``, ``cf``, ``cf_smooth``; the raw
        sums with ``"sums"`` in the outputs).
    block_pings : int
        Pings per task (Dask) and per progress step.
    association : AssociationOptions
        Map threshold and association rule (products only: a rerun may
        change them without ``restart``).
    lines : LineOptions
        How detections become lines (products only, as ``association``).
    speed_m_s : float or None
        Ship speed (m/s) for the along-track distance of pings without
        navigation: ``speed x (ping time - first ping time)``.
    """

    grid: PolarGrid
    imaging: ImagingOptions = field(default_factory=lambda: ImagingOptions(min_contrast_db=None))
    backend: str = "opencl"
    device: object = None
    images: bool = False
    block_pings: int = 8
    association: AssociationOptions = field(default_factory=AssociationOptions)
    lines: LineOptions = field(default_factory=LineOptions)
    speed_m_s: float | None = None

    def __post_init__(self):
        require("cf" in self.imaging.outputs, OptionError,
                f"outputs {','.join(self.imaging.outputs)} lack 'cf': a survey always writes the coherence peaks")
        require(self.backend in ("opencl", "reference"), OptionError,
                f"backend '{self.backend}' is unknown, expected 'opencl' or 'reference'")
        require(int(self.block_pings) == self.block_pings and self.block_pings >= 1, OptionError,
                f"block pings must be an integer >= 1, got {self.block_pings!r}")
        require(self.speed_m_s is None or (math.isfinite(self.speed_m_s) and self.speed_m_s > 0), OptionError,
                f"speed must be > 0 m/s, got {self.speed_m_s!r}")

    @property
    def image_variables(self) -> list:
        """Image variables written with ``images=True`` (:func:`clbeam.io.schema.image_variables`)."""
        if not self.images:
            return []
        outputs = set(self.imaging.outputs) | ({"cf_smooth"} if "cf" in self.imaging.outputs else set())
        return image_variables(outputs, apodized=self.imaging.apodization != "rect")


def _axis_summary(a: np.ndarray) -> dict:
    return {"first": float(a[0]), "last": float(a[-1]), "n": int(a.size),
            "sha1": hashlib.sha1(np.ascontiguousarray(a, dtype=np.float64).tobytes()).hexdigest()[:16]}


def survey_parameters(scan: ScanResult, options: SurveyOptions) -> dict:
    """The processing parameters a survey store is bound to.

    A rerun must give the same values (``restart`` otherwise): the grid,
    the imaging options, the backend, whether images are written, and the
    readable inputs (name, pings, size in bytes).  Device, workers, block
    size and the product options are free to change.

    Parameters
    ----------
    scan : ScanResult
        The readable inputs.
    options : SurveyOptions

    Returns
    -------
    dict
        JSON-serialisable parameters.
    """
    g = options.grid
    imaging = {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(options.imaging).items()}
    # the precision the engine will run, not the option's "default" (None): one survey, one stored value
    imaging["precision"] = options.imaging.precision or ("float64" if options.backend == "reference" else "float32")
    return {
        "format": SURVEY_FORMAT,
        "grid": {"ranges_m": _axis_summary(g.ranges_m), "angles_deg": _axis_summary(g.angles_deg),
                 "centre_yz_m": None if g.centre_yz_m is None else list(g.centre_yz_m)},
        "imaging": imaging,
        "backend": options.backend,
        "images": options.image_variables,
        "inputs": [{"name": f.path.name, "n_pings": f.n_pings, "size_bytes": f.size_bytes} for f in scan.files],
    }


def engine_key(params: dict, options: SurveyOptions) -> str:
    """What identifies an imaging engine: grid, imaging options, backend and device (a hash).

    A worker keeps its :class:`~clbeam.imaging.imager.Imager` for later
    tasks with the same key.
    """
    return hashlib.sha1(json.dumps([params["grid"], params["imaging"], options.backend, repr(options.device)],
                                   sort_keys=True).encode()).hexdigest()


def first_difference(stored, now, where: str = "") -> str | None:
    """The first value that differs between two parameter trees, in words.

    Parameters
    ----------
    stored, now : JSON-like
        Parameters of the store and of this run (:func:`survey_parameters`).
    where : str
        Path of this subtree (``imaging.interp``).

    Returns
    -------
    str or None
        ``'<path>: <stored> in the output, <now> now'``, or ``None`` when equal.
    """
    if isinstance(stored, dict) and isinstance(now, dict):
        for k in list(stored) + [k for k in now if k not in stored]:
            d = first_difference(stored.get(k), now.get(k), f"{where}.{k}" if where else k)
            if d:
                return d
        return None
    if isinstance(stored, list) and isinstance(now, list) and len(stored) == len(now):
        for i, (a, b) in enumerate(zip(stored, now)):
            d = first_difference(a, b, f"{where}[{i}]")
            if d:
                return d
        return None
    if stored != now:
        return f"{where}: {_show(stored)} in the output, {_show(now)} now"
    return None


def _show(v) -> str:
    s = json.dumps(v)
    return s if len(s) <= 60 else s[:57] + "..."
