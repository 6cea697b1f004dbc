/* Frequency-domain beams: the steering sums of one range zone
 * (clbeam/imaging/engine/fdbeams.py derives the zones and their error bound):
 *
 *   B[b][k] = sum_n X[n][k] exp(i 2 pi (K_FIRST + k) d[b][n]),
 *
 * X the channels' spectra (receive weights applied) on the zone's kept bins, d[b][n] the delay of
 * channel n for beam b at the zone's focus over the transform length (cycles per bin).
 *
 * Work decomposition: one work-item per (VEC bin columns k .. k + VEC - 1 as vector lanes, beam b),
 * vector.h; it sums the bins k + j * stride, j < BINS (the host pads the bins to BINS * stride with
 * zeros), so that the lanes and neighbouring work-items read neighbouring bins.  Per channel turn()
 * gives the phasor of each column's first bin
 * (its phase reduced to [-1/2, 1/2] cycle first: |K_FIRST + k| d stays below a few hundred cycles, so
 * float32 keeps it to 1e-5 cycle) and the host's step phasor exp(i 2 pi stride d) turns it from bin to
 * bin (BINS - 1 complex products: a few ulp).  The channel loop is uniform across work-items and has no
 * branch; the arithmetic is plain real_t (PoCL vectorises it across work-items).  The host launches
 * exactly stride x n_beam work-items (stride padded to a multiple of the work-group size, the padding
 * bins zero): no work-item returns early, which would keep PoCL from vectorising.
 *
 * Compile-time macros (-D): REAL_T, REAL_IS_DOUBLE (double needs cl_khr_fp64, checked by the host),
 * VEC (lanes: 1, 2, 4, 8, 16), BINS (bins per lane: 4, 8 or 16).
 */
#include "common.h"

#include "vector.h"

#ifndef BINS
#define BINS 8
#endif
/* REPEAT(F) expands to F(0) F(1) ... F(BINS - 1) */
#if BINS == 4
#define REPEAT(F) F(0) F(1) F(2) F(3)
#elif BINS == 8
#define REPEAT(F) F(0) F(1) F(2) F(3) F(4) F(5) F(6) F(7)
#elif BINS == 16
#define REPEAT(F) F(0) F(1) F(2) F(3) F(4) F(5) F(6) F(7) F(8) F(9) F(10) F(11) F(12) F(13) F(14) F(15)
#else
#error "BINS must be 4, 8 or 16"
#endif

#define TWO_PI_R ((real_t)6.28318530717958647692)

/* cos and sin of 2 pi x for x in [-1/2, 1/2] (cycles): Taylor polynomials at an eighth of the angle
 * (|theta| <= pi/8: truncation below 1e-9 in float, 1e-18 in double) squared three times as a complex
 * number.  Plain arithmetic, no call (the builtin sincos is a call on PoCL). */
static inline vreal turn(const vreal x, vreal *c_out)
{
    const vreal t = x * (TWO_PI_R / (real_t)8);
    const vreal t2 = t * t;
#if REAL_IS_DOUBLE
    vreal s = t * (1 + t2 * (-1.0 / 6 + t2 * (1.0 / 120 + t2 * (-1.0 / 5040 + t2 * (1.0 / 362880
              + t2 * (-1.0 / 39916800 + t2 * (1.0 / 6227020800.0)))))));
    vreal c = 1 + t2 * (-0.5 + t2 * (1.0 / 24 + t2 * (-1.0 / 720 + t2 * (1.0 / 40320 + t2 * (-1.0 / 3628800
              + t2 * (1.0 / 479001600 + t2 * (-1.0 / 87178291200.0)))))));
#else
    vreal s = t * (1 + t2 * (-1.0f / 6 + t2 * (1.0f / 120 + t2 * (-1.0f / 5040))));
    vreal c = 1 + t2 * (-0.5f + t2 * (1.0f / 24 + t2 * (-1.0f / 720 + t2 * (1.0f / 40320))));
#endif
    for (int k = 0; k < 3; ++k) {
        const vreal c2 = c * c - s * s;
        s = (real_t)2 * c * s;
        c = c2;
    }
    *c_out = c;
    return s;
}

#if VEC == 1
#define VSTORE_R(v, p) (*(p) = (v))
#else
#define VSTORE_R(v, p) CAT(vstore, VEC)((v), 0, (p))
#endif

__kernel void fd_steer(
    __global const real_t *restrict spec,   /* [n_chan][2][BINS * stride]: re plane, im plane */
    __global const real_t *restrict delay,  /* [n_beam][n_chan] cycles per bin */
    __global const real_t *restrict step,   /* [n_beam][n_chan][2] cos, sin of 2 pi stride d */
    __global const real_t *restrict lanes,  /* [VEC] 0, 1, .., VEC - 1 */
    const int n_chan,
    const int stride,                       /* a multiple of VEC times the work-group size */
    const int k_first,
    __global real_t *restrict out)          /* [n_beam][2][BINS * stride] */
{
    const int k = get_global_id(0) * VEC;
    const int b = get_global_id(1);
    const size_t n_pad = (size_t)BINS * stride;
    /* BINS accumulators as named vectors (REPEAT unrolls by the preprocessor: no private array) */
#define ACC_DECL(j) vreal re##j = (vreal)0, im##j = (vreal)0;
    REPEAT(ACC_DECL)
    const vreal bin = (real_t)(k_first + k) + VLOAD_R(0, lanes);
    __global const real_t *chan_re = spec + k;
    for (int n = 0; n < n_chan; ++n, chan_re += 2 * n_pad) {
        const size_t bn = (size_t)b * n_chan + n;
        vreal x = bin * delay[bn];
        x -= floor(x + (real_t)0.5);                  /* to [-1/2, 1/2] cycle */
        vreal c;
        vreal s = turn(x, &c);
        const real_t step_c = step[2 * bn], step_s = step[2 * bn + 1];
        __global const real_t *chan_im = chan_re + n_pad;
#define ACC_STEP(j)                                                       \
        {                                                                 \
            const vreal xr = VLOAD_R(0, chan_re + (size_t)(j) * stride);  \
            const vreal xi = VLOAD_R(0, chan_im + (size_t)(j) * stride);  \
            re##j += xr * c - xi * s;                                     \
            im##j += xr * s + xi * c;                                     \
            const vreal c2 = c * step_c - s * step_s;                     \
            s = c * step_s + s * step_c;                                  \
            c = c2;                                                       \
        }
        REPEAT(ACC_STEP)
    }
    __global real_t *o = out + (size_t)b * 2 * n_pad + k;
#define ACC_STORE(j) VSTORE_R(re##j, o + (size_t)(j) * stride); VSTORE_R(im##j, o + n_pad + (size_t)(j) * stride);
    REPEAT(ACC_STORE)
}
