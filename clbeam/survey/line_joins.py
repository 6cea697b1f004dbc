"""Pieces of one pipeline reported as one line: two ``pipeline`` lines end to end, one taking up where the
other stops, on one path and at one burial.

A pipe's echoes can change their nature along it: its diffuse echo where it
crosses the plane over some pings and its specular image, moved to the
crossing (:mod:`clbeam.survey.line_duplicates`), over others; or the
search seeds two tracks either side of a few pings without a detection,
or of a stretch where the pipe is not seen at all (up to ``join_gap_m``
along the track: a missing or deeper section).
:func:`joined_end_to_end` joins such pieces; the joined line itself is
made by the caller (it needs the navigation).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from clbeam.survey.line_duplicates import END_PINGS, effective_gates, end_value
from clbeam.survey.line_options import LineOptions
from clbeam.survey.lines import TrackFrame


def joined_end_to_end(lines: list, frame: TrackFrame, options: LineOptions,
                      join: Callable[[tuple, tuple], tuple]) -> list:
    """The lines with every pair of ``pipeline`` lines that lie end to end (:func:`end_to_end`) joined,
    ``join(first, second) -> line`` (lines as :func:`clbeam.survey.line_products._describe` gives them, with
    their tracks), until no pair is left; in line order."""
    lines = list(lines)
    while True:
        pair = next(((a, b) for a in range(len(lines)) for b in range(len(lines))
                     if a != b and end_to_end(lines[a], lines[b], frame, options)), None)
        if pair is None:
            return sorted(lines, key=lambda d: (d[0].first, d[1]["mean_y_m"]))
        a, b = pair
        joined = join(lines[a], lines[b])
        lines = [d for k, d in enumerate(lines) if k not in pair] + [joined]


def end_to_end(first: tuple, second: tuple, frame: TrackFrame, options: LineOptions) -> bool:
    """Whether ``second`` takes up where ``first`` stops: both ``pipeline`` lines; ``second`` starts after
    ``first`` does, ends after it, and starts no more than ``max_gap_pings + 1`` imaged pings, or ``join_gap_m``
    along the track, after its end (a pipe's echoes can stop for longer than the search bridges: the survey
    families' gaps of 30-80 m), overlapping it by no more than ``max_gap_pings``; at the junction (halfway
    between the end of one and the start of the other) their paths, each a straight line through its
    :data:`~clbeam.survey.line_duplicates.END_PINGS` pings nearest it, lie within two gates across (the wider
    line's, :func:`effective_gates`), and their burials within twice their combined standard error."""
    tr1, row1, (ext1, y1), *_ = first
    tr2, row2, (ext2, y2), *_ = second
    if row1["kind"] != "pipeline" or row2["kind"] != "pipeline":
        return False
    if not (tr2.first > tr1.first and tr2.last > tr1.last):
        return False
    s1, s2 = frame.ping_s[tr1.first:tr1.last + 1], frame.ping_s[tr2.first:tr2.last + 1]
    gap_pings = tr2.first - tr1.last
    if not (-options.max_gap_pings <= gap_pings
            and (gap_pings <= options.max_gap_pings + 1 or s2[0] - s1[-1] <= options.join_gap_m)):
        return False
    at = 0.5 * (s1[-1] + s2[0])
    dy = end_value(s1[-END_PINGS:], y1[-END_PINGS:], at) - end_value(s2[:END_PINGS], y2[:END_PINGS], at)
    gate = max(effective_gates(frame, tr1, y1, options)[0], effective_gates(frame, tr2, y2, options)[0])
    se = math.hypot(row1["burial_se_m"], row2["burial_se_m"])
    return bool(abs(dy) <= 2 * gate and abs(row1["burial_m"] - row2["burial_m"]) <= 2 * se)
