/* Spherical-wave delay-and-sum on a polar grid: coherent and incoherent sums
 * giving intensity and coherence factor (Holland et al. 2024, eqs. 1-2).
 *
 * Work decomposition: a work-item computes VEC cells, consecutive angles at
 * one range row, as vector lanes (vector.h); a work-group holds LOCAL such
 * work-items.  The host launches a list of tiles (VEC * LOCAL angles at one
 * range row each) and leaves out tiles with no cell to compute.  The body
 * has no early return and no branch in the channel loop: record bounds and
 * finiteness are lane masks, so SIMD lanes stay converged.
 *
 * Compile-time macros (-D):
 *   REAL_T, REAL_IS_DOUBLE  float or double (double needs cl_khr_fp64)
 *   VEC                 cells per work-item (1, 2, 4, 8, 16)
 *   INTERP, LANCZOS_A   interpolation mode (interp.h)
 *   BASEBAND            1: data are basebanded by the carrier; the kernel
 *                       restores the carrier phase after interpolation
 *   N_SAMPLES, N_RANGE  record length and range cells
 *   WANT_INTENSITY, WANT_CF, WANT_SUMS   which outputs are written
 *   TRAVEL_TABLE        1: ray-traced travel times (a sound-speed profile,
 *                       clbeam/raytrace.py): per cell, the centre's two-way
 *                       time (split like base), the ray's launch direction u
 *                       and wavefront radius rho replace 2R/c, the cell's
 *                       direction and R; each point adds d(o) with rho for R
 *                       (exact formula, no Fresnel branch).  Unreachable
 *                       cells carry an integer tap far before the record.
 *   APODIZE             1: receive weights w_n (clbeam/apodization.py):
 *                       S = sum w p, Q = sum w |p|^2, W = sum w,
 *                       CF = |S|^2 / (W Q) in [0, 1] (Cauchy-Schwarz)
 *   MIN_CHANNELS        CF is 0 in cells summed from fewer channels (default 1)
 *   WANT_SIGNATURE      1: also G = sum g_n over the contributing channels,
 *                       g_n a distinct number per channel: cells with equal G
 *                       summed the same channels (beam-sampled imaging)
 *
 * Travel time in samples of cell r for channel n, with every position an
 * offset o from the grid centre and u the unit vector of the cell's angle:
 *   pos = base(ir) + (d(o_src) + d(o_n)) * fs / c,
 *   base(ir) = (2 R - c t0) fs / c   (float64 on the host, split into an
 *              integer and a fraction so float32 keeps sub-sample precision
 *              at kilometre ranges),
 *   d(o) = |R u - o| - R = (|o|^2 - 2 R u.o) / (|R u - o| + R)
 * which has no cancellation at any range (cells lie in the plane x = 0).
 * Beyond fresnel_min_range_m (chosen by the host so the truncation error is
 * below 1e-5 sample) the element offsets use the expansion
 *   d(o) = -p + (q - p^2) / (2 R) + p (q - p^2) / (2 R^2),  p = u.o, q = |o|^2.
 */
#include "common.h"

#include "vector.h"
#include "interp.h"

/* u.o: the plane-wave part of an offset's delay */
#define pp_(sn, cs, oy, oz) ((sn) * (oy) + (cs) * (oz))

static inline vreal offset_delay_m(vreal R, vreal sn, vreal cs, real_t oy, real_t oz, real_t ox2, real_t q)
{
    /* |R u - o| from its components (accurate even where a cell sits on an
     * element, unlike R^2 - 2 R u.o + |o|^2); numerator without cancellation */
    const vreal dy = R * sn - oy, dz = R * cs - oz;
    const vreal num = q - (real_t)2 * R * (sn * oy + cs * oz);
    const vreal den = sqrt(dy * dy + dz * dz + ox2) + R;
    return select((vreal)0, num / den, RMASK(den > (real_t)0));
}

__kernel void beamform(
    __global const real_t *restrict data,      /* [n_chan][N_SAMPLES][2] */
    __global const real_t *restrict chan,      /* [n_chan][4]: o_y, o_z, |o|^2, o_x^2 (m, m, m^2, m^2) */
    const int n_chan,
    __global const real_t *restrict weights,   /* [n_chan] receive apodization, APODIZE */
    __global const int *restrict tiles,        /* [n_tiles][2]: first angle, range row */
    __global const real_t *restrict angle_sin, /* [n_angle_padded] */
    __global const real_t *restrict angle_cos, /* [n_angle_padded] */
    __global const int *restrict win_first,    /* [n_angle_padded] first range index computed */
    __global const int *restrict win_end,      /* [n_angle_padded] end range index computed */
    __global const real_t *restrict range_m,   /* [N_RANGE] */
    __global const int *restrict base_int,     /* [N_RANGE] */
    __global const real_t *restrict base_frac, /* [N_RANGE] */
    __global const real_t *restrict base_phase,/* [N_RANGE] carrier phase of base_int (rad), BASEBAND */
    const real_t src_oy, const real_t src_oz, const real_t src_ox2, const real_t src_q,
    const real_t samples_per_m,                /* fs / c */
    const real_t fresnel_min_range_m,          /* ranges from which the expansion is accurate */
    const real_t carrier_rad_per_sample,       /* 2 pi fc / fs, BASEBAND */
    __global real_t *restrict out_intensity,   /* [n_angle_padded][N_RANGE] */
    __global real_t *restrict out_cf,
    __global real_t *restrict out_s,           /* [2][n_angle_padded][N_RANGE]: re plane, im plane */
    __global real_t *restrict out_q,
    __global int *restrict out_m,
    __global real_t *restrict out_w,           /* [n_angle_padded][N_RANGE] W, APODIZE with WANT_SUMS */
    __global const real_t *restrict signature, /* [n_chan] g_n, WANT_SIGNATURE */
    __global real_t *restrict out_g,           /* [n_angle_padded][N_RANGE] G, WANT_SIGNATURE */
    const int n_angle_padded,
    /* TRAVEL_TABLE: [N_RANGE][n_angle_padded] per cell */
    __global const int *restrict tab_int,      /* integer sample of (2 T - t0) fs */
    __global const real_t *restrict tab_frac,  /* its fraction */
    __global const real_t *restrict tab_phase, /* carrier phase of tab_int (rad), BASEBAND */
    __global const real_t *restrict tab_sin,   /* launch direction u at the centre */
    __global const real_t *restrict tab_cos,
    __global const real_t *restrict tab_rho)   /* wavefront radius (m) */
{
    const int tile = get_group_id(0);
    const int ia = tiles[2 * tile] + get_local_id(0) * VEC;  /* first lane's angle */
    const int ir = tiles[2 * tile + 1];

    const vmask active = TO_VMASK(IMASK(ir >= VLOAD_I(0, win_first + ia)) & IMASK(ir < VLOAD_I(0, win_end + ia)));
#if TRAVEL_TABLE
    const size_t tc = (size_t)ir * n_angle_padded + ia;
    const vreal sn = VLOAD_R(0, tab_sin + tc), cs = VLOAD_R(0, tab_cos + tc);
    const vreal R = VLOAD_R(0, tab_rho + tc);
    const vint k0 = VLOAD_I(0, tab_int + tc);
    const vreal frac0 = VLOAD_R(0, tab_frac + tc)
        + offset_delay_m(R, sn, cs, src_oy, src_oz, src_ox2, src_q) * samples_per_m;
#if BASEBAND
    const vreal phase0 = VLOAD_R(0, tab_phase + tc);
#endif
#else
    const vreal sn = VLOAD_R(0, angle_sin + ia), cs = VLOAD_R(0, angle_cos + ia);
    const real_t R = range_m[ir];
    const int far = R >= fresnel_min_range_m;
    const real_t inv2R = (real_t)0.5 / R;
    const int k0 = base_int[ir];
    const vreal frac0 = base_frac[ir]
        + offset_delay_m((vreal)R, sn, cs, src_oy, src_oz, src_ox2, src_q) * samples_per_m;
#if BASEBAND
    const real_t phase0 = base_phase[ir];
#endif
#endif
    vreal sr = (vreal)0, si = (vreal)0, q = (vreal)0, m = (vreal)0;
#if APODIZE
    vreal wsum = (vreal)0;
#endif
#if WANT_SIGNATURE
    vreal gsum = (vreal)0;
#endif
    for (int n = 0; n < n_chan; ++n) {
        const real_t oy = chan[4 * n], oz = chan[4 * n + 1], oq = chan[4 * n + 2], ox2 = chan[4 * n + 3];
        /* far cells (a uniform branch: R is one per work-item) use the
         * Fresnel expansion of d(o) to third order, no sqrt or division */
#if TRAVEL_TABLE
        const vreal pos = frac0 + samples_per_m * offset_delay_m(R, sn, cs, oy, oz, ox2, oq);
#else
        const vreal pos = frac0 + samples_per_m * (far
            ? (oq - pp_(sn, cs, oy, oz) * pp_(sn, cs, oy, oz)) * inv2R
                  * ((real_t)1 + (real_t)2 * inv2R * pp_(sn, cs, oy, oz)) - pp_(sn, cs, oy, oz)
            : offset_delay_m((vreal)R, sn, cs, oy, oz, ox2, oq));
#endif
        vreal t;
        const vint k = k0 + split_position(pos, &t);
        const vmask inside = TO_VMASK(IMASK(k >= TAPS_BEFORE) & IMASK(k < N_SAMPLES - TAPS_AFTER));
        /* read clamped taps (always inside the buffer), discard them when
         * outside; min/max with vector bounds rather than clamp(vector,
         * scalar, scalar), which Oclgrind evaluates wrongly for 16 lanes */
        const vint kc = min(max(k, (vint)TAPS_BEFORE), (vint)(N_SAMPLES - 1 - TAPS_AFTER));
        vreal re, im;
        interpolate(data, n * (2 * N_SAMPLES) + 2 * (kc - TAPS_BEFORE), t, &re, &im);
#if BASEBAND
        {
            const vreal ph = phase0 + carrier_rad_per_sample * pos;
            const vreal s = sin(ph), c = cos(ph);
            const vreal r2 = re * c - im * s;
            im = re * s + im * c;
            re = r2;
        }
#endif
        const vmask ok = active & inside & RMASK(isfinite(re)) & RMASK(isfinite(im));
        re = select((vreal)0, re, ok);
        im = select((vreal)0, im, ok);
#if APODIZE
        const real_t w = weights[n];
        sr += w * re;
        si += w * im;
        q += w * (re * re + im * im);
        wsum += select((vreal)0, (vreal)w, ok);
#else
        sr += re;
        si += im;
        q += re * re + im * im;
#endif
        m += select((vreal)0, (vreal)1, ok);
#if WANT_SIGNATURE
        gsum += select((vreal)0, (vreal)signature[n], ok);
#endif
    }
    const vreal inten = sr * sr + si * si;
#if APODIZE
    const vreal denom_w = wsum;
#else
    const vreal denom_w = m;
#endif
    const size_t cell = (size_t)ia * N_RANGE + ir;
#if WANT_INTENSITY
    SCATTER(real_t, out_intensity, cell, N_RANGE, inten);
#endif
#if WANT_CF
    SCATTER(real_t, out_cf, cell, N_RANGE, select((vreal)0, inten / (denom_w * q),
                                                  RMASK(denom_w > (real_t)0) & RMASK(q > (real_t)0)
                                                  & RMASK(m >= (real_t)MIN_CHANNELS)));
#endif
#if WANT_SUMS
    SCATTER(real_t, out_s, cell, N_RANGE, sr);
    SCATTER(real_t, out_s, cell + (size_t)n_angle_padded * N_RANGE, N_RANGE, si);
    SCATTER(real_t, out_q, cell, N_RANGE, q);
    SCATTER(int, out_m, cell, N_RANGE, CONVERT_VINT(m));
#if APODIZE
    SCATTER(real_t, out_w, cell, N_RANGE, wsum);
#endif
#endif
#if WANT_SIGNATURE
    SCATTER(real_t, out_g, cell, N_RANGE, gsum);
#endif
}
