"""The eigenray iteration: the ray ``X(p, z) = |y|`` for every target of a block.

A safeguarded Newton iteration on ``t = tan(chi / 2)``, ``chi`` the
elevation above the horizontal of the ray launched with
``p = cos(chi) / c_max`` (see :mod:`clbeam.imaging.raytrace`), and the
quantities of the rays it finds.  The tolerances below are read at each
call, so a test may change them here.
"""

from __future__ import annotations

import logging

import numpy as np

from clbeam.imaging.raytrace.layers import Block, View, ray_cos

log = logging.getLogger(__name__)

#: eigenray convergence: |X(p) - |y|| at most this times the distance to the
#: target (1e-6 m at 1 km): the first-order time error p |X - y| is then below
#: 1e-9 s at 1.3 km, the returned (stationary) time's error far below, and the
#: launch direction is good to ~1e-9
X_TOL_REL = 1e-9
#: relative residual below which one more Newton step is taken without
#: checking it in the loop (the final evaluation checks it)
LOOSE_TOL_REL = 3e-7
#: Newton (or bisection) iterations before a target is given up as NaN
MAX_ITERATIONS = 80


class _Work:
    """Work arrays of the targets still iterating: ``live`` (indices into the
    block), their ``t``, bracket ``[lo, hi]``, ``c_max``, ``y``, ``dz^2`` and
    distance ``rho`` (m)."""

    def __init__(self, block: Block, t: np.ndarray, live: np.ndarray):
        a = block.arr
        y, dz, cmax = a["y"], a["dz"], block.cmax
        self.live = live
        if live.size == block.n:
            self.view, self.t, self.cm, self.y, self.dz2 = block.view_all, t.copy(), cmax, y, dz * dz
        else:
            self.view, self.t, self.cm, self.y, self.dz2 = View(block, live), t[live], cmax[live], y[live], (dz * dz)[live]
        self.lo, self.hi = np.zeros(self.t.size), np.ones(self.t.size)
        self.rho = np.sqrt(self.dz2 + self.y * self.y)

    def step(self, block: Block, loose: bool) -> tuple[np.ndarray, np.ndarray]:
        """One safeguarded Newton step of every live target: the masks of the
        converged ones (``t`` kept) and of those whose step is taken unchecked."""
        p, om, inv = _ray(self.t, self.cm)
        x, xp = block.sums(self.view, p, om)
        r = x - self.y
        self.lo = np.where(r > 0, self.t, self.lo)
        self.hi = np.where(r < 0, self.t, self.hi)
        conv = (np.abs(r) <= X_TOL_REL * self.rho) | (self.hi - self.lo <= 4e-16 * self.hi)
        # -dX/dt = X_p |dp/dt| = X_p 4 t inv^2 / c_max
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            new = self.t + r * (self.dz2 + x * self.y) * self.cm / (
                xp * (4.0 * self.t * inv * inv) * (self.dz2 + self.y * self.y))
        inside = (new > self.lo) & (new < self.hi)
        new = np.where(inside, new, 0.5 * (self.lo + self.hi))
        last = (inside & (np.abs(r) <= LOOSE_TOL_REL * self.rho) & ~conv) if loose else np.zeros(conv.size, dtype=bool)
        self.t = np.where(conv, self.t, new)
        return conv, last

    def retire(self, done: np.ndarray, last: np.ndarray, t: np.ndarray, ok: np.ndarray, pending: np.ndarray) -> None:
        """Write the live ``t`` into ``t``; mark the ``done`` ones solved, the ``last`` ones pending."""
        t[self.live] = self.t
        ok[self.live[done]] = True
        pending[self.live[last]] = True

    def keep(self, block: Block, keep: np.ndarray) -> None:
        """Go on with the live targets ``keep`` only."""
        self.live = self.live[keep]
        self.view = View(block, self.live)
        for name in ("t", "cm", "y", "dz2", "lo", "hi", "rho"):
            setattr(self, name, getattr(self, name)[keep])


def _ray(t: np.ndarray, cmax: np.ndarray):
    """``p`` and ``1 - sin(phi)`` of the ray whose elevation ``chi = pi/2 - phi``
    (from the horizontal, relative to ``c_max``) has ``t = tan(chi / 2)``, and
    ``1 / (1 + t^2)``: rational in ``t``, so no trigonometry and no
    cancellation near the horizontal (``t -> 0``)."""
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    return (1.0 - t2) * inv / cmax, 2.0 * t2 * inv, inv


def newton_solve(block: Block, t: np.ndarray, *, subset: np.ndarray | None = None, loose: bool = True):
    """``t = tan(chi / 2)`` of the ray with ``X = y`` for the targets of the
    block (or ``subset``), starting from ``t``.

    Returns ``t``, the mask of targets solved and, with ``loose``, the mask of
    those solved by a last Newton step taken without checking its result
    (taken once ``|X - y| <= LOOSE_TOL_REL * distance``, where a step leaves
    a residual orders of magnitude below ``X_TOL_REL * distance``; the
    caller checks it).

    The unknown is (a function of) the elevation from the horizontal so that
    rays close to horizontal keep full precision; ``X`` decreases with ``t``.
    Each step is Newton's on ``tan(atan(X/dz) - atan(y/dz))``, i.e. on
    ``dz (X - y) / (dz^2 + X y)`` (damped where ``X < y``, so a step does not
    run past the horizon), kept inside the bracket, else a bisection.
    """
    t = t.copy()
    ok = np.zeros(block.n, dtype=bool)
    pending = np.zeros(block.n, dtype=bool)
    reach = block.arr["y"] <= block.x_max()
    work = _Work(block, t, np.flatnonzero(reach) if subset is None else subset[reach[subset]])
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        if work.t.size == 0:
            break
        conv, last = work.step(block, loose)
        done = conv | last
        # record and compact once most are done, and at the last iteration
        if done.all() or 4 * np.count_nonzero(~done) < done.size or it == MAX_ITERATIONS:
            work.retire(done, last, t, ok, pending)
            if done.all():
                break
            work.keep(block, ~done)
    log.debug("eigenrays: %d targets, %d iterations", block.n if subset is None else subset.size, it)
    left = np.count_nonzero(reach & ~ok) if subset is None else np.count_nonzero(reach[subset] & ~ok[subset])
    if left:
        log.warning("eigenrays: %d of %d targets did not converge in %d iterations (set to NaN)",
                    left, block.n, MAX_ITERATIONS)
    return t, ok, pending


def fill_rays(block: Block, t: np.ndarray, idx: np.ndarray, pending: np.ndarray, fields) -> tuple[dict, np.ndarray]:
    """The ``fields`` of the targets ``idx`` of the block (unsigned, in the
    order of ``idx``), and those of the ``pending`` ones whose residual is
    too large (indices into the block)."""
    view = View(block, idx)
    cm = block.cmax[idx]
    p, om, _ = _ray(t[idx], cm)
    x, xp, tt, length = block.sums(view, p, om, final=True)
    y = view.arr["y"]
    bad = idx[pending[idx] & ~(np.abs(x - y) <= X_TOL_REL * np.hypot(y, view.arr["dz"]))]
    c0, ct = view.arr["c_za"], view.arr["c_zb"]
    out = {}
    for k in fields:
        if k == "time_s":
            out[k] = tt + p * (y - x)
        elif k == "launch_sin":
            out[k] = np.minimum(p * c0, 1.0)
        elif k == "launch_cos":
            out[k] = ray_cos(c0, p * c0, cm, om)
        elif k == "arrival_sin":
            out[k] = np.minimum(p * ct, 1.0)
        elif k == "arrival_cos":
            out[k] = ray_cos(ct, p * ct, cm, om)
        elif k == "path_length_m":
            out[k] = length
        elif k == "ray_parameter_s_m":
            out[k] = p
        elif k == "wavefront_radius_m":
            cos0 = ray_cos(c0, p * c0, cm, om)
            out[k] = cos0 * cos0 * xp / c0
    return out, bad
