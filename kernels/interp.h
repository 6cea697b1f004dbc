/* Interpolation of a complex (interleaved re, im) channel at a fractional
 * sample position, for the beamforming kernel.
 *
 * INTERP selects the mode at compile time:
 *   0 nearest      taps k            (k = floor(pos + 0.5))
 *   1 linear       taps k, k+1       (k = floor(pos))
 *   2 cubic        taps k-1 .. k+2   (Keys, a = -0.5: Catmull-Rom)
 *   3 lanczos      taps k-A+1 .. k+A (A = LANCZOS_A lobes)
 * TAPS_BEFORE / TAPS_AFTER give the support around k; a sample contributes
 * only when its whole support lies inside the record (the reference backend
 * applies the same rule), so no read ever leaves the buffer.
 */
#ifndef CLBEAM_INTERP_H
#define CLBEAM_INTERP_H

#if INTERP == 0
#define TAPS_BEFORE 0
#define TAPS_AFTER 0
#elif INTERP == 1
#define TAPS_BEFORE 0
#define TAPS_AFTER 1
#elif INTERP == 2
#define TAPS_BEFORE 1
#define TAPS_AFTER 2
#elif INTERP == 3
#define TAPS_BEFORE (LANCZOS_A - 1)
#define TAPS_AFTER LANCZOS_A
#else
#error "unknown INTERP"
#endif

#define PI_R ((real_t)3.14159265358979323846)

/* Split a sample position into the integer tap k and the fraction t. */
inline int split_position(real_t pos, real_t *t)
{
#if INTERP == 0
    real_t f = floor(pos + (real_t)0.5);
    *t = (real_t)0;
#else
    real_t f = floor(pos);
    *t = pos - f;
#endif
    return (int)f;
}

/* Interpolate at fraction t after the sample whose real part is data[i]
 * (channels of interleaved re, im); the caller has checked the support is in
 * the record.  Indices are 32-bit: the host checks the buffer fits. */
inline void interpolate(__global const real_t *restrict data, int i, real_t t,
                        real_t *re, real_t *im)
{
#if INTERP == 0
    *re = data[i];
    *im = data[i + 1];
#elif INTERP == 1
    real_t a = data[i], b = data[i + 1];
    real_t c = data[i + 2], d = data[i + 3];
    *re = a + t * (c - a);
    *im = b + t * (d - b);
#elif INTERP == 2
    /* Keys cubic convolution, a = -0.5, weights for taps k-1, k, k+1, k+2 */
    real_t t2 = t * t, t3 = t2 * t;
    real_t w0 = (real_t)-0.5 * t3 + t2 - (real_t)0.5 * t;
    real_t w1 = (real_t)1.5 * t3 - (real_t)2.5 * t2 + (real_t)1;
    real_t w2 = (real_t)-1.5 * t3 + (real_t)2 * t2 + (real_t)0.5 * t;
    real_t w3 = (real_t)0.5 * t3 - (real_t)0.5 * t2;
    const int j = i - 2;
    *re = w0 * data[j] + w1 * data[j + 2] + w2 * data[j + 4] + w3 * data[j + 6];
    *im = w0 * data[j + 1] + w1 * data[j + 3] + w2 * data[j + 5] + w3 * data[j + 7];
#elif INTERP == 3
    /* Lanczos: L(x) = A sin(pi x) sin(pi x / A) / (pi x)^2 for |x| < A.
     * With x_m = t - m, sin(pi x_m) = (-1)^m sin(pi t), and sin(pi x_m / A)
     * follows by angle addition, so one sincos pair serves all 2A taps. */
    real_t sr = (real_t)0, si = (real_t)0;
    /* sinpi keeps sin(pi t) accurate for t near 1, where tap m = 1 has
     * x = t - 1 near 0 and the weight is the ratio of two small numbers */
    const real_t s_pt = sinpi(t);
    const real_t cb = cospi((real_t)1 / LANCZOS_A), sb = sinpi((real_t)1 / LANCZOS_A);
    /* start at m = -(A-1): x = t + A - 1 */
    const real_t x0 = t + (real_t)(LANCZOS_A - 1);
    real_t s_a = sinpi(x0 / LANCZOS_A), c_a = cospi(x0 / LANCZOS_A);
    real_t sign = ((LANCZOS_A - 1) & 1) ? (real_t)-1 : (real_t)1;
    const int j = i - 2 * (LANCZOS_A - 1);
    for (int m = 0; m < 2 * LANCZOS_A; ++m) {
        /* x from t directly (not by repeated subtraction): the central
         * taps then get x = t and t - 1 exactly */
        const real_t x = t + (real_t)(LANCZOS_A - 1 - m);
        /* the recurrence's absolute error would dominate the small
         * sin(pi x / A) of the two central taps (|x| < 1): direct there */
        const real_t s_x = (m == LANCZOS_A - 1 || m == LANCZOS_A) ? sinpi(x / LANCZOS_A) : s_a;
        /* L(0) = 1: a select, not a branch, keeps the lanes converged */
        const real_t w = x == (real_t)0 ? (real_t)1
                       : (real_t)LANCZOS_A * sign * s_pt * s_x / (PI_R * PI_R * x * x);
        sr += w * data[j + 2 * m];
        si += w * data[j + 2 * m + 1];
        /* x -> x - 1: rotate the pi x / A phase back by pi / A */
        const real_t s_n = s_a * cb - c_a * sb;
        c_a = c_a * cb + s_a * sb;
        s_a = s_n;
        sign = -sign;
    }
    *re = sr;
    *im = si;
#endif
}

#endif
