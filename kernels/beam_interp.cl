/* Beam-sampled imaging: the sums on the beam grid interpolated to the output
 * grid along angle (clbeam/imaging/engine/beams.py has the derivation).
 *
 * One work-item per output cell inside the output window [win_first,
 * win_end) of its angle (range fastest, so neighbouring work-items read
 * neighbouring beam samples); the cells are written packed, angle after
 * angle from out_first[a], the window's first cell (the whole range axis
 * for every angle is the plain grid layout; the host spreads a seabed
 * band's cells onto its zeroed grid).  For output angle a the host gives the
 * first beam of its support, tap0[a], and TAPS weights (a Kaiser-windowed
 * sinc summing to 1); the coherent sum S (complex) and the incoherent sum Q
 * are interpolated, and intensity |S|^2 and CF = |S|^2 / (M Q) (W Q with
 * apodization) are formed from them.  M, the channel signature G (and W)
 * must be the same on every tap (beam_ok, computed by the host per support
 * start): otherwise different channels made the taps' sums, the cell is not
 * interpolated but flagged (flag = 1) for the host to image directly.
 *
 * Compile-time macros (-D): REAL_T, REAL_IS_DOUBLE, TAPS, N_RANGE, APODIZE,
 * WANT_INTENSITY, WANT_CF, WANT_SUMS, MIN_CHANNELS (CF is 0 where M is below it).
 */
#include "common.h"

__kernel void beam_to_grid(
    __global const real_t *restrict beam_s,   /* [2][n_beam][N_RANGE]: re plane, im plane */
    __global const real_t *restrict beam_q,   /* [n_beam][N_RANGE] */
    __global const int *restrict beam_m,      /* [n_beam][N_RANGE] */
    __global const real_t *restrict beam_w,   /* [n_beam][N_RANGE], APODIZE */
    __global const uchar *restrict beam_ok,   /* [n_beam][N_RANGE] the TAPS beams from here agree */
    const int n_beam,
    __global const int *restrict tap0,        /* [n_angle] first beam of each output angle */
    __global const real_t *restrict tap_w,    /* [n_angle][TAPS] */
    __global const int *restrict win_first,   /* [n_angle] */
    __global const int *restrict win_end,     /* [n_angle] */
    __global const int *restrict out_first,   /* [n_angle] packed index of each window's first cell */
    __global real_t *restrict out_intensity,  /* [n_cells] packed */
    __global real_t *restrict out_cf,
    __global real_t *restrict out_s,          /* [2][n_cells] */
    __global real_t *restrict out_q,
    __global int *restrict out_m,
    __global real_t *restrict out_w,
    __global uchar *restrict out_flag,        /* [n_cells] */
    const int n_angle,
    const int n_cells)
{
    const int ia = get_global_id(1);
    if (ia >= n_angle)
        return;
    const int ir = win_first[ia] + (int)get_global_id(0);
    if (ir >= win_end[ia] || ir >= N_RANGE)
        return;
    const size_t cell = (size_t)out_first[ia] + (size_t)(ir - win_first[ia]);
    const size_t plane = (size_t)n_beam * N_RANGE;
    const size_t first = (size_t)tap0[ia] * N_RANGE + ir;
    const int m0 = beam_m[first];
#if APODIZE
    const real_t w0 = beam_w[first];
#endif
    const int same = beam_ok[first];
    real_t sr = 0, si = 0, q = 0;
    for (int k = 0; k < TAPS; ++k) {
        const size_t b = first + (size_t)k * N_RANGE;
        const real_t wk = tap_w[ia * TAPS + k];
        sr += wk * beam_s[b];
        si += wk * beam_s[plane + b];
        q += wk * beam_q[b];
    }
    const int keep = same;
    sr = keep ? sr : (real_t)0;
    si = keep ? si : (real_t)0;
    q = keep ? q : (real_t)0;
    const real_t inten = sr * sr + si * si;
#if APODIZE
    const real_t denom = (keep ? w0 : (real_t)0) * q;
#else
    const real_t denom = (real_t)(keep ? m0 : 0) * q;
#endif
    out_flag[cell] = (uchar)!same;
#if WANT_INTENSITY
    out_intensity[cell] = inten;
#endif
#if WANT_CF
    out_cf[cell] = denom > (real_t)0 && m0 >= MIN_CHANNELS ? fmin(inten / denom, (real_t)1) : (real_t)0;
#endif
#if WANT_SUMS
    out_s[cell] = sr;
    out_s[(size_t)n_cells + cell] = si;
    out_q[cell] = q;
    out_m[cell] = keep ? m0 : 0;
#if APODIZE
    out_w[cell] = keep ? w0 : (real_t)0;
#endif
#endif
}
