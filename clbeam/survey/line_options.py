"""The options of the line search (:mod:`clbeam.survey.lines`): light, so the command line can show their defaults."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from clbeam.errors import OptionError, require


@dataclass(frozen=True)
class LineOptions:
    """How detections become lines (:mod:`clbeam.survey.lines`) and which lines are kept.

    Attributes
    ----------
    across_gate_m : float
        Largest cross-track distance of a detection from the line's
        prediction (m).
    burial_gate_m : float
        Largest burial difference from the line's (m).
    max_angle_deg : float
        Largest heading of a line relative to the track (degree).
    window_pings : int
        Pings per Hough window (half-overlapping windows).
    seed_hits : int
        Distinct pings a Hough cell needs to seed a line.
    min_hits : int
        Pings with a detection a line needs.
    max_gap_pings : int
        Imaged pings in a row without a detection a line may bridge.
    join_gap_m : float
        Longest stretch along the track (m) between two ``pipeline`` lines
        end to end that are still joined into one when they line up across
        it and agree in burial (:mod:`clbeam.survey.line_joins`): a pipe
        whose echoes stop for a while (a missing or deeper section, a
        stretch in dense clutter); at least ``max_gap_pings + 1`` imaged
        pings are joined whatever the distance.
    fit_hits : int
        Hits of the local fit that predicts the line's next ping.
    fit_length_m : float
        Along-track extent of that fit (m).
    min_score : float
        Score a line needs (``-log10`` of the expected number of chance
        lines as good per km of survey line, :mod:`clbeam.survey.line_score`;
        the default 4 is set from clutter-only simulated surveys, where
        clutter is not independent from ping to ping: ``docs/lines.md``).
    min_burial_m : float
        Burial below which a line counts as not buried (m): a smooth
        pipe's specular correction applies to buried lines only, and a
        line at nadir buried deeper is a horizon's echo (``subbottom-nadir``).
    max_burial_m, max_exposure_m : float
        A ``pipeline`` lies from ``max_exposure_m`` above the seabed (its
        axis: a radius for an exposed pipe, up to a metre more for a free
        span) to ``max_burial_m`` below it (m).
    burial_resolution_m : float
        Largest standard error of a line's burial that counts as measured (m).
    nadir_angle_deg : float
        Lines within this angle of nadir (median over their pings) are nadir echoes
        (kinds ``seabed-nadir``, ``subbottom-nadir``).
    beam_width_deg : float
        Along-track width of the transmit beam, ``lambda / L`` at the band's
        centre (degree; the SBP29's 3.5 m column at the 2-9 kHz band's
        centre: about 4.5; the main lobe's first null, half of it about its
        -4 dB point): a line crossing the track is seen over half of it either
        side, smeared across each ping; each ping's seabed is fitted to its
        peaks raised by the depth echoes from across the beam add
        (:func:`clbeam.survey.burial.offplane_deepening_m`); a line at a steady
        heading whose nearest point, were it a smooth pipe, would lie within
        half of it gets its burial halfway between a smooth and a rough pipe's.
    nominal_spacing_m : float
        Along-track distance between pings assumed when a survey has neither
        navigation nor ping times and a ship speed (m; the paper's 4 kn at
        4 s: 8.2); a warning says so, and lengths and headings are not
        reported.
    """

    across_gate_m: float = 1.5
    burial_gate_m: float = 0.5
    max_angle_deg: float = 60.0
    window_pings: int = 16
    seed_hits: int = 8
    min_hits: int = 5
    max_gap_pings: int = 6
    join_gap_m: float = 100.0
    fit_hits: int = 8
    fit_length_m: float = 120.0
    min_score: float = 4.0
    min_burial_m: float = 0.5
    max_burial_m: float = 10.0
    max_exposure_m: float = 1.5
    burial_resolution_m: float = 0.5
    nadir_angle_deg: float = 10.0
    beam_width_deg: float = 4.5
    nominal_spacing_m: float = 8.2

    def __post_init__(self):
        for name in ("across_gate_m", "burial_gate_m", "fit_length_m", "max_burial_m", "max_exposure_m",
                     "burial_resolution_m", "nominal_spacing_m", "join_gap_m"):
            v = getattr(self, name)
            require(isinstance(v, numbers.Real) and math.isfinite(v) and v > 0, OptionError,
                    f"line option {name} must be a number > 0, got {v!r}")
        require(self.across_gate_m <= 20, OptionError,
                f"line gate must be at most 20 m (a line is narrow; the clutter around it is counted beyond), "
                f"got {self.across_gate_m!r}")
        for name, least in (("window_pings", 2), ("seed_hits", 2), ("min_hits", 2), ("fit_hits", 3),
                            ("max_gap_pings", 0)):
            v = getattr(self, name)
            require(isinstance(v, numbers.Real) and math.isfinite(v) and int(v) == v
                    and v >= least, OptionError, f"line option {name} must be an integer >= {least}, got {v!r}")
        require(0 < self.max_angle_deg < 89, OptionError,
                f"line option max_angle_deg must be within 0-89 degrees, got {self.max_angle_deg!r}")
        require(self.seed_hits <= self.window_pings, OptionError,
                f"line option seed_hits ({self.seed_hits}) exceeds window_pings ({self.window_pings})")
        require(0 <= self.min_burial_m < self.max_burial_m, OptionError,
                f"line burial range must satisfy 0 <= min < max, got {self.min_burial_m!r}-{self.max_burial_m!r}")
        require(math.isfinite(self.min_score), OptionError, f"line min score must be finite, got {self.min_score!r}")
        require(0 <= self.beam_width_deg < 90, OptionError,
                f"line beam width must be within 0-90 degrees, got {self.beam_width_deg!r}")
        require(0 <= self.nadir_angle_deg < 90, OptionError,
                f"line nadir angle must be within 0-90 degrees, got {self.nadir_angle_deg!r}")
