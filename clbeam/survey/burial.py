"""Where a detection lies relative to the seabed of its ping.

**The seabed of a ping** is picked from its own coherence peaks: most of
them are seabed scatterers, whatever lies below (a horizon's, a pipeline's)
is deeper, and nothing lies above it but noise.  :func:`seabed_line` fits
``z = z0 + slope y`` to the upper edge of them: the two shallowest peaks of
each bin across, candidate lines through pairs of those (RANSAC, Fischler &
Bolles 1981) scored by how many of them lie within ``tolerance_m`` (a
horizon may hold twice the seabed's peaks, it never lies above it); a
Tukey-weighted least-squares fit of all peaks refines the best.  The
peaks are first raised by the depth their echoes from off the ping's plane
add (:func:`offplane_deepening_m`).  The seabed is taken as a plane across
the swath: over a seabed that bends across the swath (a channel, a ridge),
burials are off by the bend.

**Positions along the arc.** A peak's range is good to centimetres, its
angle is not: away from nadir the array's beam widens as ``1 / cos(theta)``
and a peak slides along its arc of constant range over metres (Holland et
al. 2024, the main-lobe arcs).  :func:`arc_constrained` moves each peak
along its arc to the most likely point given that slide (standard deviation
``arc_sigma_rad / cos(theta)`` of angle) and a prior that the target lies
``prior_burial_m`` below the seabed (standard deviation
``prior_sigma_m``): near nadir the peak stays where it is, near endfire it
moves onto the seabed's neighbourhood, where its cross-track offset is
then good to about ``(z / y)`` times the burial's error.
"""

from __future__ import annotations

import math

import numpy as np

#: angle slide of a coherence peak along its arc at broadside (rad) when its SNR is unknown: 0.2 degree measured
#: on line1 and line4 at the paper's grid, 0.3 on coarser grids (0.25 degree, 0.5 m)
ARC_SIGMA_RAD = math.radians(0.3)
#: a peak's angle error at broadside in receive beam widths (``lambda / W``) times ``sqrt(SNR)``, the Cramer-Rao
#: bound's form for an array: the bound is 0.39 (``sqrt(6) / 2 pi``), the simulated pipelines measure 0.17-0.38
#: against their peaks' SNR (``docs/lines.md``)
SLIDE_PER_BEAM = 0.5
#: a peak's angle error at broadside at high SNR (rad): 0.01 degree measured on clean pipes above 37 dB, more
#: where a pipe's echo mixes with boulders or smears as it crosses; at 0.02-0.03 one of Line 4's seven surveys
#: put A 0.66 m and B 1.42 m off, at 0.05 none more than 0.61 m
SLIDE_FLOOR_RAD = math.radians(0.05)
#: spread of the prior on a specular line's ``k`` about 1 (:func:`specular_fit`): with the echoes moved by range to
#: the pipe's depth (:func:`clbeam.survey.specular.offsets_at_depth`) the nearest point lies ``h sin a*`` off the
#: plane for a curved pipe too, so ``dz`` is the geometry's and ``k`` is 1 but for the beam's pull; at 0.5 (when
#: ``dz`` came from echoes moved part of the way, ``k`` 0.6-1.4 on Line 4's far pipes) the tuning draw family:4's
#: A, smooth and exposed at 10 degrees, had ``k`` 0.67 and its burial 1.1 m deep; at 0.1 it is 0.12 m deep, and
#: Line 4's burials over seven seeds move by 0.03 m RMS or less
SPECULAR_K_SIGMA = 0.1
#: a line's burial takes its standard error from its own burials' scatter about the fit (as the Birge ratio) when it
#: has at least this many (:func:`clbeam.survey.lines.line_burial`, :func:`specular_fit`); with fewer, from the
#: slides alone.  The slides are conservative far from nadir (2-3 times the scatter at Line 4's pipes)
MIN_SCATTER_N = 5
#: the standard error of the seabed's depth at a line, added to its burial's (m): the fitted seabed's mean error at
#: the simulated pipes, over each line, came to 0.05-0.18 m RMS over noise seeds (0.18 m at 920 m)
SEABED_SE_M = 0.15
#: the model error of a line's burial reading, added in quadrature to its standard error (m): what the corrections
#: leave (a smooth pipe's specular migration, a smeared line's deepening, a rough pipe echoing from its whole upper
#: half) is the same along the line and does not average out over its pings.  Over the tuning surveys' 82 pipes
#: with a line (both physics, 3 seeds of heading245 and rough245) the burial errors fell within two reported
#: standard errors for 87 % without it, 93 % at 0.1-0.2 m and 96 % at 0.25 m (95 % nominal)
BURIAL_MODEL_SE_M = 0.25
#: width across of the bins whose two shallowest peaks stand for a ping's seabed (m, :func:`seabed_line`): over
#: the tuning surveys the single-ping fit's RMS error 500 m out was at worst 1.34, 1.21, 1.02, 1.00 m and in the
#: median 0.45, 0.43, 0.45, 0.47 m at 30, 50, 75, 100 m; the earlier rule (the shallowest candidate holding half
#: the best count) 4.7 m at worst (a horizon 7 m down, 7 dB brighter than the seabed), 0.65 m in the median
SEABED_BIN_M = 50.0
#: the floor on coarse grids, in grid angle steps (0.19 measured at 0.5 degree)
SLIDE_PER_STEP = 0.3
#: SNR below which the slide stops growing (dB): a peak that weak lies anywhere in the beam's main lobe
MIN_SLIDE_SNR_DB = 0.0


def receive_beam_width_rad(band_hz, array_width_m, sound_speed_m_s: float = 1500.0) -> float:
    """The receive array's beam width at broadside, ``lambda / W`` at the band's centre (rad; NaN when the band
    or the width is unknown or not positive).

    Parameters
    ----------
    band_hz : sequence of float or None
        The pulse's band ``(f0, f1)`` (Hz).
    array_width_m : float or None
        The array's width ``W`` (m).
    sound_speed_m_s : float
        Sound speed at the array (m/s).
    """
    if band_hz is None or array_width_m is None:
        return math.nan
    centre = 0.5 * (float(band_hz[0]) + float(band_hz[1]))
    width = float(array_width_m)
    if not (centre > 0 and width > 0 and sound_speed_m_s > 0):
        return math.nan
    return sound_speed_m_s / centre / width


def peak_slide_rad(snr_db, beam_width_rad: float, angle_step_rad: float = 0.0) -> np.ndarray:
    """Standard deviation of a coherence peak's angle at broadside (rad) from its SNR.

    ``sqrt((SLIDE_PER_BEAM beam_width_rad)^2 / SNR + floor^2)``, the floor
    the larger of :data:`SLIDE_FLOOR_RAD` and ``SLIDE_PER_STEP`` grid steps:
    noise moves a peak by a fraction of the beam over the square root of its
    SNR (linear), the SNR taken as at least :data:`MIN_SLIDE_SNR_DB`; the
    larger of :data:`ARC_SIGMA_RAD` and the floor where the SNR or the beam
    width is unknown (NaN).  Away from broadside :func:`arc_constrained`
    divides it by ``cos(theta)``.  The noise term holds from about 10 dB
    up; nearer the detection threshold a peak can jump to a noise peak
    elsewhere in the main lobe and scatters more.

    Parameters
    ----------
    snr_db : array_like
        ``(n,)`` the peaks' intensities over the noise floor (dB).
    beam_width_rad : float
        The receive array's beam width at broadside, ``lambda / W`` at the band's centre (rad).
    angle_step_rad : float
        The image grid's angle step (rad).
    """
    snr_db = np.atleast_1d(np.asarray(snr_db, dtype=np.float64))
    # a peak weaker than MIN_SLIDE_SNR_DB slides as one at it: about half the beam
    snr = 10.0 ** (np.clip(snr_db, MIN_SLIDE_SNR_DB, None) / 10.0)
    floor = max(SLIDE_FLOOR_RAD, SLIDE_PER_STEP * angle_step_rad)
    slide = np.hypot(SLIDE_PER_BEAM * beam_width_rad / np.sqrt(snr), floor)
    return np.where(np.isnan(snr_db) | ~np.isfinite(slide), max(ARC_SIGMA_RAD, floor), slide)


#: mean square of ``u = pi L phi / lambda`` over a uniform aperture's one-way main lobe, ``sinc^2``, over ``pi^2``:
#: ``(integral of sin^2 / integral of sin^2 u / u^2, over |u| < pi) / pi^2`` (the mean square angle in ``(lambda/L)^2``)
MAIN_LOBE_MEAN_SQUARE = 0.11223


def offplane_deepening_m(range_m, angle_rad, beam_width_rad: float, band_hz=None) -> np.ndarray:
    """How much deeper than the seabed a seabed scatterer's peak lies on average (m), from the transmit beam's
    width along the track.

    The imager takes each echo from the ping's plane: a scatterer at range
    ``R`` seen ``phi`` off the plane along the track images
    ``R phi^2 / (2 cos theta)`` deeper (``z = sqrt(z^2 + x^2)``, ``x = R phi``).
    Seabed scatterers fill the transmit beam, so their peaks lie deeper by
    the mean of that over the echo energy they return: ``phi^2`` averaged
    over each frequency's main lobe (``MAIN_LOBE_MEAN_SQUARE (lambda /
    L)^2``) and over a flat band, each frequency weighted by its lobe's
    energy (its width, ``lambda / L``): ``lambda^2`` becomes
    ``c^2 (f0^-2 - f1^-2) / (2 ln(f1 / f0))``, 1.42 times the band's plain
    mean ``c^2 / (f0 f1)`` at 2-9 kHz.  A pipe along the track echoes from
    the plane and does not.

    Parameters
    ----------
    range_m, angle_rad : array_like
        The peaks' ranges (m) and angles from nadir (rad).
    beam_width_rad : float
        The transmit beam's width along the track at the band's centre, ``lambda_c / L`` (rad).
    band_hz : sequence of float or None
        The pulse's band ``(f0, f1)`` (Hz); ``None``: one frequency, the centre.
    """
    band_factor = 1.0
    if band_hz is not None and float(band_hz[0]) > 0 and float(band_hz[1]) > 0:
        f0, f1 = sorted((float(band_hz[0]), float(band_hz[1])))
        if f1 > f0:  # lambda^2 weighted by 1 / f over the band, in units of the centre's
            band_factor = (0.5 * (f0 + f1)) ** 2 * (f0 ** -2 - f1 ** -2) / (2.0 * math.log(f1 / f0))
    return _mean_deepening_m(range_m, angle_rad, MAIN_LOBE_MEAN_SQUARE * beam_width_rad ** 2 * band_factor)


def _mean_deepening_m(range_m, angle_rad, mean_square_rad2: float) -> np.ndarray:
    """``R E[phi^2] / (2 cos theta)`` (m): how much deeper echoes from off the ping's plane, at mean square
    angle ``E[phi^2]`` (rad^2) from it, lie on average at range ``R`` (m) and angle ``theta`` (rad, its cosine
    held at 0.05 at least)."""
    cos_t = np.maximum(np.abs(np.cos(np.asarray(angle_rad, dtype=np.float64))), 0.05)
    return np.asarray(range_m, dtype=np.float64) * mean_square_rad2 / (2.0 * cos_t)


#: mean square of ``v = L phi / lambda`` over the half of a uniform aperture's one-way main lobe nearest its axis,
#: ``|v| <= 1/2`` (to about its -4 dB point), weighted by ``sinc^2``: ``integral of v^2 sinc^2 v / integral of
#: sinc^2 v`` there (the mean square angle in ``(lambda/L)^2`` of the stretch a line's echoes come from)
SMEAR_MEAN_SQUARE = 0.065479


def smear_deepening_m(range_m, angle_rad, beam_width_rad: float) -> np.ndarray:
    """How much deeper than a line's crossing its echoes from its stretch inside the transmit beam lie on
    average (m): ``R E[phi^2] / (2 cos theta)``, the seabed's off-plane depth
    (:func:`offplane_deepening_m`) over the stretch a line's smear holds.

    A pipe at a heading ``a`` to the track whose echo comes from its whole stretch inside the transmit beam
    (rough, or of discrete scatterers) images a scatterer ``x = R phi`` off the ping's plane ``x tan a``
    across and ``sqrt(z^2 + x^2) - z`` deeper.  A line's gates take its echoes from half the beam's width
    either side of the plane (:func:`clbeam.survey.lines.smear_half_width`), its energy weighted by the
    pattern ``sinc^2(L phi / lambda)`` at the band's centre: ``E[phi^2] = SMEAR_MEAN_SQUARE (lambda / L)^2``,
    0.24 times the seabed's band average over the whole main lobe at 2-9 kHz.

    Parameters
    ----------
    range_m, angle_rad : array_like
        The echoes' slant ranges (m) and angles from nadir (rad).
    beam_width_rad : float
        The transmit beam's width along the track at the band's centre, ``lambda_c / L`` (rad).
    """
    return _mean_deepening_m(range_m, angle_rad, SMEAR_MEAN_SQUARE * beam_width_rad ** 2)


def seabed_line(y_m, z_m, *, tolerance_m: float = 1.0, max_slope: float = 0.27,
                bin_width_m: float = SEABED_BIN_M) -> tuple[float, float] | None:
    """The seabed of one ping from its peaks: ``(z0, slope)`` of ``z = z0 + slope y`` (m, 1), or ``None``.

    The seabed is the upper edge of the peaks: in each ``bin_width_m`` across, the two shallowest peaks stand
    for it (a stray peak above the seabed takes one of them).  Of the lines through pairs of those, the one
    holding most of them within ``tolerance_m`` wins (of equal counts, the shallowest at the middle of the
    swath); a Tukey-weighted least-squares fit of all peaks refines it.  A horizon below that holds more peaks
    than the seabed never wins, nor a line tilted across from the seabed on one side to the horizon on the other.

    Parameters
    ----------
    y_m, z_m : array_like
        ``(n,)`` peak positions, earth frame (m).
    tolerance_m : float
        Distance in depth that makes a peak an inlier (m).
    max_slope : float
        Largest slope tried (0.27: 15 degrees).
    bin_width_m : float
        Width across of the bins whose shallowest peaks stand for the seabed (m).

    Returns
    -------
    (float, float) or None
        ``None`` with fewer than 5 peaks or no line through 3 of the shallowest.
    """
    y = np.asarray(y_m, dtype=np.float64)
    z = np.asarray(z_m, dtype=np.float64)
    ok = np.isfinite(y) & np.isfinite(z)
    y, z = y[ok], z[ok]
    if y.size < 5:
        return None
    order = np.lexsort((z, np.floor(y / bin_width_m)))
    cell = np.floor(y[order] / bin_width_m)
    rank = np.arange(order.size) - np.searchsorted(cell, cell)  # depth order of each peak within its bin
    top = order[rank < 2]
    ey, ez = y[top], z[top]
    i, j = np.triu_indices(ey.size, 1)
    dy = ey[j] - ey[i]
    good = np.abs(dy) > 1.0
    slope = np.where(good, (ez[j] - ez[i]) / np.where(good, dy, 1.0), 0.0)
    good &= np.abs(slope) <= max_slope
    if not good.any():
        return None
    slope = slope[good]
    z0 = ez[i[good]] - slope * ey[i[good]]
    count = (np.abs(ez[None, :] - (z0[:, None] + slope[:, None] * ey[None, :])) <= tolerance_m).sum(axis=1)
    if count.max() < 3:
        return None
    best = np.flatnonzero(count == count.max())
    k = best[np.argmin(z0[best] + slope[best] * float(np.median(y)))]
    return _refine(y, z, float(z0[k]), float(slope[k]), tolerance_m)


#: imaged pings either side whose peaks join a ping's own in its seabed fit (:func:`pooled_seabed_lines`)
SEABED_POOL_PINGS = 4


def pooled_seabed_lines(peaks: list, half_window: int = SEABED_POOL_PINGS, tolerance_m: float = 1.0) -> np.ndarray:
    """Each ping's seabed ``(z0, slope)`` (m, 1): its own fit (:func:`seabed_line`), or where that lies more than
    twice ``tolerance_m`` off the fit to its peaks and those of ``half_window`` imaged pings either side, the
    pooled fit.

    The seabed is the upper edge of the peaks, drawn from the two shallowest of each bin across: where the
    seabed is weak off nadir (a slow, smooth sediment) and a horizon a few metres down brighter, one ping's
    bins hold mostly the horizon's peaks and its fit can be the horizon; over several pings the seabed's few
    echoes fill the top of the bins.  The seabed moves little over a few pings, and the peaks' depths are
    the earth frame's (heave taken out by the imaging): on the tuning surveys the pooled fits' depths at
    nadir scatter 0.01-0.13 m from ping to ping, one ping's 0.05-0.56 m (moving each pooled fit to its own
    ping's peaks near it scattered them 0.05-0.28 m: the sediment below the seabed pulls).

    Parameters
    ----------
    peaks : list
        Per survey ping ``(y, z)`` arrays of its peaks (m, earth frame), or ``None`` (not imaged).
    half_window : int
        Imaged pings either side pooled.
    tolerance_m : float
        :func:`seabed_line`'s.

    Returns
    -------
    numpy.ndarray
        ``(n_pings, 2)``; NaN where no seabed was found.
    """
    out = np.full((len(peaks), 2), np.nan)
    have = [i for i, p in enumerate(peaks) if p is not None and len(p[0])]
    for j, i in enumerate(have):
        window = have[max(0, j - half_window):j + half_window + 1]
        pooled = seabed_line(np.concatenate([peaks[w][0] for w in window]),
                             np.concatenate([peaks[w][1] for w in window]), tolerance_m=tolerance_m)
        fit = _own_or_pooled(seabed_line(*peaks[i], tolerance_m=tolerance_m), pooled, tolerance_m)
        if fit is not None:
            out[i] = fit
    return out


#: offsets across, in depths, at which a ping's own seabed fit is held to the pooled one (:func:`_own_or_pooled`):
#: out at the swath's ends a small difference in slope parts them by metres without either being another layer
POOL_CHECK_DEPTHS = np.array([-0.4, 0.0, 0.4])


def _own_or_pooled(own: tuple | None, pooled: tuple | None, tolerance_m: float) -> tuple | None:
    """A ping's own seabed fit where it lies within ``2 tolerance_m`` of the pooled one at nadir and 0.4 depths
    either side (:data:`POOL_CHECK_DEPTHS`), else the pooled one; either where the other is ``None``.
    The pooling mends a ping that took another layer and leaves the rest as their own peaks have them."""
    if own is None or pooled is None:
        return pooled if own is None else own
    return own if planes_apart_m(own, pooled) <= 2 * tolerance_m else pooled


def planes_apart_m(a, b) -> float:
    """How far apart two seabed fits ``(z0, slope)`` (m, 1) lie (m): the largest difference in depth at nadir
    and 0.4 of ``b``'s depth either side (:data:`POOL_CHECK_DEPTHS`)."""
    at = POOL_CHECK_DEPTHS * abs(float(b[0]))
    return float(np.abs((a[0] - b[0]) + (a[1] - b[1]) * at).max())


#: iterations of :func:`refined_seabed_lines`' reweighting: from a fit tilted by a metre at the swath's ends the
#: weights move a little each time (the discrete tuning survey ``family:17``: 0.3-0.5 m of its 0.7-1.1 m error
#: left after 5, under 0.1 m after 20)
REFINE_ITERATIONS = 20


def refined_seabed_lines(peaks: list, seabed: np.ndarray, tolerance_m: float = 1.0) -> np.ndarray:
    """Each ping's seabed ``(z0, slope)`` (m, 1) of ``seabed`` (``(n_pings, 2)``) refined on its ``peaks`` as
    :func:`seabed_line` ends, by Tukey-weighted least squares from it (:data:`REFINE_ITERATIONS` of them),
    where the refined fit stays within ``tolerance_m`` of where it was at nadir and 0.4 depths either side
    (:data:`POOL_CHECK_DEPTHS`: a tilt moves the swath's ends, not its middle; the weights reach ``2
    tolerance_m``, and a horizon that close below a weak seabed can draw the fit down to it); as it was
    otherwise, where a ping has no fit, or fewer than 5 peaks (``peaks`` as :func:`pooled_seabed_lines` takes
    them)."""
    out = np.array(seabed, dtype=np.float64, copy=True)
    for g, p in enumerate(peaks):
        if p is None or not np.isfinite(out[g]).all():
            continue
        y, z = np.asarray(p[0], dtype=np.float64), np.asarray(p[1], dtype=np.float64)
        ok = np.isfinite(y) & np.isfinite(z)
        if ok.sum() < 5:
            continue
        refined = _refine(y[ok], z[ok], float(out[g, 0]), float(out[g, 1]), tolerance_m, REFINE_ITERATIONS)
        if planes_apart_m(refined, out[g]) <= tolerance_m:
            out[g] = refined
    return out


def _refine(y: np.ndarray, z: np.ndarray, z0: float, slope: float, tolerance_m: float,
            iterations: int = 5) -> tuple[float, float]:
    """Tukey-biweight least squares from a starting line (``iterations`` of it)."""
    c = 2.0 * tolerance_m
    for _ in range(iterations):
        r = z - (z0 + slope * y)
        w = np.where(np.abs(r) < c, (1 - (r / c) ** 2) ** 2, 0.0)
        if w.sum() < 3 or np.ptp(y[w > 0]) <= 0:
            break
        a = np.stack([np.ones_like(y), y], axis=1) * np.sqrt(w)[:, None]
        z0, slope = np.linalg.lstsq(a, z * np.sqrt(w), rcond=None)[0]
    return float(z0), float(slope)


def arc_constrained(y_m, z_m, centre_yz_m, seabed: tuple[float, float], *, prior_burial_m: float = 1.0,
                    prior_sigma_m: float = 2.0, arc_sigma_rad=ARC_SIGMA_RAD) -> tuple:
    """Peaks moved along their arcs to the most likely point (module docstring).

    Parameters
    ----------
    y_m, z_m : array_like
        ``(n,)`` peak positions, earth frame (m).
    centre_yz_m : array_like
        ``(n, 2)`` or ``(2,)`` centre of each peak's arc: its grid centre (m).
    seabed : array_like
        ``(z0, slope)`` of the ping's seabed (:func:`seabed_line`), or ``(n, 2)`` one per peak.
    prior_burial_m, prior_sigma_m : float
        Burial the prior expects and its spread (m).
    arc_sigma_rad : float or array_like
        Slide of a peak's angle at broadside (rad): one for all or ``(n,)`` (:func:`peak_slide_rad`).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Cross-track offsets of the moved peaks (m), burials below the
        seabed as measured (``z - seabed(y)``, m), the standard deviation of
        those burials from the angle's slide (m), the burials of the
        moved peaks (m: near endfire, close to the prior's), and the
        standard deviation of the moved offsets (m).
    """
    y = np.asarray(y_m, dtype=np.float64)
    z = np.asarray(z_m, dtype=np.float64)
    c = np.broadcast_to(np.asarray(centre_yz_m, dtype=np.float64), (y.size, 2))
    sb = np.broadcast_to(np.asarray(seabed, dtype=np.float64), (y.size, 2))
    z0, slope = sb[:, 0], sb[:, 1]
    theta = np.arctan2(y - c[:, 0], z - c[:, 1])
    rng = np.hypot(y - c[:, 0], z - c[:, 1])
    sigma_t = rng * np.asarray(arc_sigma_rad, dtype=np.float64) / np.maximum(np.abs(np.cos(theta)), 0.05)
    # moving t along the arc (towards larger angle): dy = cos(theta) t, dz = -sin(theta) t
    k = -np.sin(theta) - slope * np.cos(theta)
    burial = z - (z0 + slope * y)
    resid = burial - prior_burial_m
    shrink = prior_sigma_m ** 2 / (prior_sigma_m ** 2 + (k * sigma_t) ** 2)
    t = -resid * k * sigma_t ** 2 / (prior_sigma_m ** 2 + (k * sigma_t) ** 2)
    sigma_y = np.abs(np.cos(theta)) * sigma_t * np.sqrt(shrink)
    return y + np.cos(theta) * t, burial, np.abs(k) * sigma_t, burial + k * t, sigma_y


def specular_fit(y_m, burial_m, sigma_m, slope, centre_yz_m, seabed, prior_burial_m: float = 1.0,
                 k_prior_sigma: float | None = None, max_offplane_rad: float | None = None) -> dict:
    """Whether a line's echoes are a smooth pipe's specular echo, migrated off the ping's plane.

    A straight pipe crossing the ping's plane at ``y_c`` at an angle ``a`` to the track returns its echo
    from its point nearest the source, ``x = y_c sin a cos a`` off the plane (offsets from the grid
    centre); the imager shows it at that range and cone angle, ``y_c cos^2 a`` across and
    ``dz = sqrt(z^2 + x^2) - z`` deeper than the pipe.  Moved along its arc to the pipe's depth
    (:func:`arc_constrained`) it lands at ``y_c cos a``, so along the line ``dy/ds = sin a``.  A rough
    pipe's diffuse echo comes from the plane itself: ``y_c``, no extra depth, ``dy/ds = tan a``.  The
    measured burials ``b_i`` tell them apart: fitted as ``b + k dz_i`` (weights ``1 / sigma^2``), ``k``
    near 1 is the specular echo, near 0 the diffuse one.

    Parameters
    ----------
    y_m, burial_m, sigma_m : array_like
        ``(n,)`` the line's detections moved along their arcs (m), their
        measured burials and those burials' standard deviations (m).
    slope : array_like
        ``(n,)`` the line's ``dy/ds`` at each detection's ping.
    centre_yz_m : array_like
        ``(n, 2)`` grid centres (m).
    seabed : array_like
        ``(n, 2)`` the pings' seabeds ``(z0, slope)``.
    prior_burial_m : float
        Burial used for the extra depth (m; its effect is second order).
    k_prior_sigma : float or None
        With it, ``k`` is drawn towards 1, a specular echo's, by a Gaussian
        prior of that standard deviation (:data:`SPECULAR_K_SIGMA`: for the
        burial of a line known to be specular); ``None``: ``k`` is free.
    max_offplane_rad : float or None
        With it, only the detections whose nearest point the source sees within that angle of the
        plane (rad) are fitted, when at least three with a burial are: past the transmit beam's edge
        the echo fades and its ``b - dz`` scatters far more than ``sigma`` says (Line 4's C, 7 seeds:
        1.4-2.1 m inside 2.25 degrees, 2.8-13 m beyond, ``sigma`` 1.4-2.8 times larger).  ``None``: all.

    Returns
    -------
    dict
        ``k``, ``k_error``, ``burial_m``, ``burial_error_m`` (the fit's intercept and its standard error,
        with the prior on ``k`` from the burials' scatter, :func:`_scatter_error`), ``y_crossing_m`` (``(n,)``:
        the offsets moved back to the plane, ``y_c``, as if specular),
        ``extra_depth_m`` (the mean ``dz`` over the detections with a burial, weighted by ``1 / sigma^2``,
        m) and ``offplane_rad`` (the median angle ``x / R`` at which the source sees the nearest point, rad).
    """
    yc, x_off, r, dz = _nearest_point(y_m, slope, centre_yz_m, seabed, prior_burial_m)
    b = np.asarray(burial_m, dtype=np.float64)
    sig = np.maximum(np.asarray(sigma_m, dtype=np.float64), 0.3)
    ok = np.isfinite(b) & np.isfinite(sig)
    out = {"k": np.nan, "k_error": np.nan, "burial_m": np.nan, "burial_error_m": np.nan, "y_crossing_m": yc,
           "extra_depth_m": float(np.average(dz[ok], weights=sig[ok] ** -2)) if ok.any() else np.nan,
           "offplane_rad": float(np.median(np.abs(x_off[ok]) / r[ok])) if ok.any() else np.nan}
    ok = _within_beam(ok, np.abs(x_off) / r, max_offplane_rad)
    if (ok.sum() < 3 or np.ptp(dz[ok]) <= 0) if k_prior_sigma is None else not ok.any():  # free k: 3 over dz
        return out
    coef, cov, data = _intercept_and_k(dz[ok], b[ok], sig[ok] ** -2, k_prior_sigma)
    se = np.sqrt(cov[0, 0]) if k_prior_sigma is None else _scatter_error(dz[ok], b[ok], sig[ok] ** -2, coef, cov, data)
    out.update(burial_m=float(coef[0]), k=float(coef[1]), burial_error_m=float(se),
               k_error=float(np.sqrt(cov[1, 1])))
    return out


def _scatter_error(dz: np.ndarray, b: np.ndarray, w: np.ndarray, coef: np.ndarray, cov: np.ndarray,
                   data: np.ndarray) -> float:
    """For :func:`specular_fit` with a prior on ``k``: the intercept's standard error (m) from the burials ``b``
    (m, weights ``w``) scattering about the fit ``coef`` (covariance ``N^-1``; the data's normal matrix
    ``A^T W A``).  The data's noise is taken as ``s^2 / w``, ``s^2 = sum w r^2 / (n - t)`` (``t`` the
    trace of ``N^-1 A^T W A``, the parameters the data carry, 1 to 2), and the estimate's covariance is
    ``s^2 N^-1 A^T W A N^-1``: the prior only shrinks, it is not scaled with the data.  With fewer than
    :data:`MIN_SCATTER_N` burials, ``cov``'s."""
    if b.size < MIN_SCATTER_N:
        return float(np.sqrt(cov[0, 0]))
    hat = cov @ data
    s2 = float(np.sum(w * (b - coef[0] - coef[1] * dz) ** 2)) / (b.size - float(np.trace(hat)))
    return float(np.sqrt(s2 * (hat @ cov)[0, 0]))


def _within_beam(ok: np.ndarray, offplane_rad: np.ndarray, max_offplane_rad: float | None) -> np.ndarray:
    """For :func:`specular_fit`: of the detections ``ok``, those whose nearest point lies within
    ``max_offplane_rad`` of the plane when at least three do; else (or without a limit) ``ok``."""
    if max_offplane_rad is None:
        return ok
    inside = ok & (offplane_rad <= max_offplane_rad)
    return inside if np.count_nonzero(inside) >= 3 else ok


def _nearest_point(y_m, slope, centre_yz_m, seabed, prior_burial_m: float) -> tuple:
    """For :func:`specular_fit`: the crossings ``y_c`` (m), the nearest points' distances ``x`` off the plane
    (m), the crossings' slant ranges (m) and the extra depths ``dz`` (m) of a straight pipe at ``dy/ds =
    slope`` with its echoes at ``y_m``."""
    y = np.asarray(y_m, dtype=np.float64)
    c = np.asarray(centre_yz_m, dtype=np.float64).reshape(-1, 2)
    sb = np.asarray(seabed, dtype=np.float64).reshape(-1, 2)
    sin_a = np.clip(np.asarray(slope, dtype=np.float64), -0.95, 0.95)
    cos_a = np.sqrt(1 - sin_a ** 2)
    yc = (y - c[:, 0]) / cos_a + c[:, 0]
    x_off = (yc - c[:, 0]) * sin_a * cos_a
    z = sb[:, 0] + sb[:, 1] * yc + prior_burial_m - c[:, 1]
    return yc, x_off, np.hypot(yc - c[:, 0], z), np.sqrt(z ** 2 + x_off ** 2) - z


def _intercept_and_k(dz: np.ndarray, b: np.ndarray, w: np.ndarray, k_prior_sigma: float | None) -> tuple:
    """Weighted least squares of ``b = intercept + k dz`` (weights ``w``), with a Gaussian prior ``k = 1`` of
    standard deviation ``k_prior_sigma`` as one more observation (``None``: none): coefficients, covariance and
    the data's normal matrix ``A^T W A`` (without the prior)."""
    a = np.stack([np.ones(dz.size), dz], axis=1)
    data, rhs = (a * w[:, None]).T @ a, (a * w[:, None]).T @ b
    normal = data.copy()
    if k_prior_sigma is not None:
        normal[1, 1] += k_prior_sigma ** -2
        rhs[1] += k_prior_sigma ** -2
    cov = np.linalg.pinv(normal)
    return cov @ rhs, cov, data
