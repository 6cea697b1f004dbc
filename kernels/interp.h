/* Interpolation of complex channels (interleaved re, im) at fractional
 * sample positions, one lane per cell (see vector.h).
 *
 * INTERP selects the mode at compile time:
 *   0 nearest      taps k            (k = floor(pos + 0.5))
 *   1 linear       taps k, k+1       (k = floor(pos))
 *   2 cubic        taps k-1 .. k+2   (Keys, a = -0.5: Catmull-Rom)
 *   3 lanczos      taps k-A+1 .. k+A (A = LANCZOS_A lobes)
 * TAPS_BEFORE / TAPS_AFTER give the support around k; a sample contributes
 * only when its whole support lies inside the record (the reference backend
 * applies the same rule); the kernel clamps k so no read leaves the buffer.
 *
 * The taps of one lane are contiguous (2 NTAPS reals): each lane loads them
 * with one wide vload, far cheaper on CPUs than a gather per tap.
 */
#ifndef CLBEAM_INTERP_H
#define CLBEAM_INTERP_H

#if INTERP == 0
#define TAPS_BEFORE 0
#define TAPS_AFTER 0
#define TAP_REALS 2
#elif INTERP == 1
#define TAPS_BEFORE 0
#define TAPS_AFTER 1
#define TAP_REALS 4
#elif INTERP == 2
#define TAPS_BEFORE 1
#define TAPS_AFTER 2
#define TAP_REALS 8
#elif INTERP == 3
#define TAPS_BEFORE (LANCZOS_A - 1)
#define TAPS_AFTER LANCZOS_A
#if LANCZOS_A == 4
#define TAP_REALS 16
#elif LANCZOS_A == 8
#define TAP_REALS 32
#else
#error "LANCZOS_A must be 4 or 8"
#endif
#else
#error "unknown INTERP"
#endif
#define NTAPS (TAPS_BEFORE + TAPS_AFTER + 1)

#define PI_R ((real_t)3.14159265358979323846)

/* tmp[0 .. TAP_REALS-1] = p[0 .. TAP_REALS-1] with vector loads */
#if TAP_REALS <= 16
#define LOAD_TAP_REALS(tmp, p) CAT(vstore, TAP_REALS)(CAT(vload, TAP_REALS)(0, (p)), 0, (tmp))
#else
#define LOAD_TAP_REALS(tmp, p) \
    do { vstore16(vload16(0, (p)), 0, (tmp)); vstore16(vload16(1, (p)), 0, (tmp) + 16); } while (0)
#endif

/* The NTAPS complex taps starting at data[first] (real part), per lane. */
static inline void load_taps(__global const real_t *restrict data, vint first, vreal *re, vreal *im)
{
#if VEC == 1
    real_t tmp[TAP_REALS];
    LOAD_TAP_REALS(tmp, data + first);
#pragma unroll
    for (int j = 0; j < NTAPS; ++j) {
        re[j] = tmp[2 * j];
        im[j] = tmp[2 * j + 1];
    }
#else
    int ib[VEC];
    real_t r[NTAPS][VEC], m[NTAPS][VEC];
    CAT(vstore, VEC)(first, 0, ib);
#pragma unroll
    for (int l = 0; l < VEC; ++l) {
        real_t tmp[TAP_REALS];
        LOAD_TAP_REALS(tmp, data + ib[l]);
#pragma unroll
        for (int j = 0; j < NTAPS; ++j) {
            r[j][l] = tmp[2 * j];
            m[j][l] = tmp[2 * j + 1];
        }
    }
#pragma unroll
    for (int j = 0; j < NTAPS; ++j) {
        re[j] = VLOAD_R(0, r[j]);
        im[j] = VLOAD_R(0, m[j]);
    }
#endif
}

/* Split sample positions into the integer tap k and the fraction t. */
static inline vint split_position(vreal pos, vreal *t)
{
#if INTERP == 0
    const vreal f = floor(pos + (real_t)0.5);
    *t = (vreal)0;
#else
    const vreal f = floor(pos);
    *t = pos - f;
#endif
    return CONVERT_VINT(f);
}

/* Interpolate at fraction t; first indexes the real part of tap
 * k - TAPS_BEFORE per lane, clamped by the caller so every tap is in the
 * buffer.  Indices are 32-bit: the host checks the buffer fits. */
static inline void interpolate(__global const real_t *restrict data, vint first, vreal t, vreal *out_re, vreal *out_im)
{
    vreal re[NTAPS], im[NTAPS];
    load_taps(data, first, re, im);
#if INTERP == 0
    *out_re = re[0];
    *out_im = im[0];
#elif INTERP == 1
    *out_re = re[0] + t * (re[1] - re[0]);
    *out_im = im[0] + t * (im[1] - im[0]);
#elif INTERP == 2
    /* Keys cubic convolution, a = -0.5, weights for taps k-1, k, k+1, k+2 */
    const vreal t2 = t * t, t3 = t2 * t;
    const vreal w0 = (real_t)-0.5 * t3 + t2 - (real_t)0.5 * t;
    const vreal w1 = (real_t)1.5 * t3 - (real_t)2.5 * t2 + (real_t)1;
    const vreal w2 = (real_t)-1.5 * t3 + (real_t)2 * t2 + (real_t)0.5 * t;
    const vreal w3 = (real_t)0.5 * t3 - (real_t)0.5 * t2;
    *out_re = w0 * re[0] + w1 * re[1] + w2 * re[2] + w3 * re[3];
    *out_im = w0 * im[0] + w1 * im[1] + w2 * im[2] + w3 * im[3];
#elif INTERP == 3
    /* Lanczos: L(x) = A sin(pi x) sin(pi x / A) / (pi x)^2 for |x| < A.
     * With x_m = t - m, sin(pi x_m) = (-1)^m sin(pi t), and sin(pi x_m / A)
     * follows by angle addition, so one sincos pair serves all 2A taps.
     * sinpi keeps sin(pi t) accurate for t near 1, where the tap at x = t - 1
     * has a weight that is the ratio of two small numbers. */
    vreal sr = (vreal)0, si = (vreal)0;
    const vreal s_pt = sinpi(t);
    const real_t cb = cospi((real_t)1 / LANCZOS_A), sb = sinpi((real_t)1 / LANCZOS_A);
    const vreal x0 = t + (real_t)(LANCZOS_A - 1);
    vreal s_a = sinpi(x0 / LANCZOS_A), c_a = cospi(x0 / LANCZOS_A);
    real_t sign = ((LANCZOS_A - 1) & 1) ? (real_t)-1 : (real_t)1;
#pragma unroll
    for (int m = 0; m < NTAPS; ++m) {
        /* x from t directly (not by repeated subtraction): the central
         * taps then get x = t and t - 1 exactly */
        const vreal x = t + (real_t)(LANCZOS_A - 1 - m);
        /* the recurrence's absolute error would dominate the small
         * sin(pi x / A) of the two central taps (|x| < 1): direct there */
        const vreal s_x = (m == LANCZOS_A - 1 || m == LANCZOS_A) ? sinpi(x / LANCZOS_A) : s_a;
        /* L(0) = 1, as a select so lanes stay converged */
        const vreal w = select((real_t)LANCZOS_A * sign * s_pt * s_x / (PI_R * PI_R * x * x), (vreal)1,
                               RMASK(x == (real_t)0));
        sr += w * re[m];
        si += w * im[m];
        /* x -> x - 1: rotate the pi x / A phase back by pi / A */
        const vreal s_n = s_a * cb - c_a * sb;
        c_a = c_a * cb + s_a * sb;
        s_a = s_n;
        sign = -sign;
    }
    *out_re = sr;
    *out_im = si;
#endif
}

#endif
