/* Spherical-wave delay-and-sum on a polar grid: coherent and incoherent sums
 * giving intensity and coherence factor (Holland et al. 2024, eqs. 1-2).
 *
 * One work-item per cell.  The host launches a list of tiles: a tile is
 * LOCAL_A consecutive angles at one range row, one work-group, so that
 * neighbouring work-items read neighbouring samples; tiles with no cell to
 * compute are not launched.  The body has no early return and no branch in
 * the channel loop (bounds and finiteness become selects) so that PoCL's
 * work-item loop vectoriser and GPU SIMD lanes stay converged.
 *
 * Compile-time macros (-D):
 *   REAL_T          float or double (double needs cl_khr_fp64)
 *   INTERP, LANCZOS_A   interpolation mode (see interp.h)
 *   BASEBAND        1: data are basebanded by the carrier; the kernel restores
 *                   the carrier phase after interpolation
 *   N_SAMPLES, N_RANGE  record length and range cells
 *   WANT_INTENSITY, WANT_CF, WANT_SUMS   which outputs are written
 *   CHANNEL_BARRIER 1 on CPU devices (see the channel loop)
 *
 * Travel time in samples of cell r for channel n, with every position an
 * offset o from the grid centre and u the unit vector of the cell's angle:
 *   pos = base(ir) + (d(o_src) + d(o_n)) * fs / c,
 *   base(ir) = (2 R - c t0) fs / c   (float64 on the host, split into an
 *              integer and a fraction so float32 keeps sub-sample precision
 *              at kilometre ranges),
 *   d(o) = |R u - o| - R = (|o|^2 - 2 R u.o) / (|R u - o| + R)
 * which has no cancellation at any range (cells at the grid's x = 0 plane).
 */
#if REAL_IS_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif
typedef REAL_T real_t;

#include "interp.h"

inline real_t offset_delay_m(real_t R, real_t sn, real_t cs, real_t oy, real_t oz, real_t ox2, real_t q)
{
    /* |R u - o| from its components (accurate even where a cell sits on an
     * element, unlike R^2 - 2 R u.o + |o|^2), numerator without cancellation */
    const real_t dy = R * sn - oy, dz = R * cs - oz;
    const real_t num = q - (real_t)2 * R * (sn * oy + cs * oz);
    const real_t den = sqrt(dy * dy + dz * dz + ox2) + R;
    return den > (real_t)0 ? num / den : (real_t)0;
}

__kernel void beamform(
    __global const real_t *restrict data,      /* [n_chan][N_SAMPLES][2] */
    __global const real_t *restrict chan,      /* [n_chan][4]: o_y, o_z, |o|^2, o_x^2 (m, m, m^2, m^2) */
    const int n_chan,
    __global const int *restrict tiles,        /* [n_tiles][2]: first angle, range row */
    __global const real_t *restrict angle_tab, /* [n_angle_padded][2]: sin, cos */
    __global const int *restrict window,       /* [n_angle_padded][2]: first, end range index computed */
    __global const real_t *restrict range_m,   /* [N_RANGE] */
    __global const int *restrict base_int,     /* [N_RANGE] */
    __global const real_t *restrict base_frac, /* [N_RANGE] */
    __global const real_t *restrict base_phase,/* [N_RANGE] carrier phase of base_int (rad), BASEBAND */
    const real_t src_oy, const real_t src_oz, const real_t src_ox2, const real_t src_q,
    const real_t samples_per_m,                /* fs / c */
    const real_t carrier_rad_per_sample,       /* 2 pi fc / fs, BASEBAND */
    __global real_t *restrict out_intensity,   /* [n_angle_padded][N_RANGE] */
    __global real_t *restrict out_cf,
    __global real_t *restrict out_s,           /* [n_angle_padded][N_RANGE][2] */
    __global real_t *restrict out_q,
    __global int *restrict out_m)
{
    const int tile = get_group_id(0);
    const int ia = tiles[2 * tile] + get_local_id(0);
    const int ir = tiles[2 * tile + 1];
    const size_t cell = (size_t)ia * N_RANGE + ir;
    const int active = ir >= window[2 * ia] && ir < window[2 * ia + 1];

    const real_t sn = angle_tab[2 * ia], cs = angle_tab[2 * ia + 1];
    const real_t R = range_m[ir];
    const int k0 = base_int[ir];
    const real_t frac0 = base_frac[ir]
        + offset_delay_m(R, sn, cs, src_oy, src_oz, src_ox2, src_q) * samples_per_m;
#if BASEBAND
    const real_t phase0 = base_phase[ir];
#endif
    real_t sr = 0, si = 0, q = 0;
    int m = 0;
    for (int n = 0; n < n_chan; ++n) {
#if CHANNEL_BARRIER
        /* CPU drivers (PoCL) turn a uniform loop holding a barrier into
         * work-item loops inside it, which their vectoriser then vectorises
         * across cells; every work-item reaches it (no early return) */
        barrier(CLK_LOCAL_MEM_FENCE);
#endif
        const real_t oy = chan[4 * n], oz = chan[4 * n + 1], oq = chan[4 * n + 2], ox2 = chan[4 * n + 3];
        const real_t pos = frac0 + offset_delay_m(R, sn, cs, oy, oz, ox2, oq) * samples_per_m;
        real_t t;
        const int k = k0 + split_position(pos, &t);
        const int inside = k - TAPS_BEFORE >= 0 && k + TAPS_AFTER < N_SAMPLES;
        /* read a clamped tap (always in the buffer), discard it when outside */
        const int kc = clamp(k, TAPS_BEFORE, N_SAMPLES - 1 - TAPS_AFTER);
        real_t re, im;
        interpolate(data, n * (2 * N_SAMPLES) + 2 * kc, t, &re, &im);
#if BASEBAND
        {
            /* sin and cos rather than sincos: no private-memory out
             * argument, which some implementations and Oclgrind mishandle */
            const real_t ph = phase0 + carrier_rad_per_sample * pos;
            const real_t s = sin(ph), c = cos(ph);
            const real_t r2 = re * c - im * s;
            im = re * s + im * c;
            re = r2;
        }
#endif
        const int ok = active && inside && isfinite(re) && isfinite(im);
        re = ok ? re : (real_t)0;
        im = ok ? im : (real_t)0;
        sr += re;
        si += im;
        q += re * re + im * im;
        m += ok;
    }
    const real_t inten = sr * sr + si * si;
#if WANT_INTENSITY
    out_intensity[cell] = inten;
#endif
#if WANT_CF
    out_cf[cell] = (m > 0 && q > (real_t)0) ? inten / ((real_t)m * q) : (real_t)0;
#endif
#if WANT_SUMS
    out_s[2 * cell] = sr;
    out_s[2 * cell + 1] = si;
    out_q[cell] = q;
    out_m[cell] = m;
#endif
}
