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

#if INTERP == 3 && !REAL_IS_DOUBLE
/* Lanczos in float32: the weight of tap m (x = t + A - 1 - m) as a polynomial in
 * s = t - 1/2, least-squares fitted to L(x) on Chebyshev nodes of s in
 * [-1/2, 1/2] (clbeam.imaging.engine.lanczos.lanczos_polynomials; within
 * 1.6e-7 of L evaluated in float32, tests/imaging/test_lanczos_poly.py).
 * Taps m and 2A-1-m are mirror images, L(x(s)) and L(x(-s)): they share the
 * even part E(s^2) and the odd part s O(s^2), each 5 coefficients, lowest
 * power first. */
#if LANCZOS_A == 4
__constant float LANCZOS_EVEN[4][5] = {
    {-1.266088150e-02f, 4.956601560e-02f, 1.181860454e-02f, -3.282438591e-02f, 1.116170734e-02f},
    {5.990948528e-02f, -2.697713077e-01f, 1.186467111e-01f, 9.790795855e-03f, -8.977108635e-03f},
    {-1.664152294e-01f, 7.228512764e-01f, -2.318049073e-01f, 1.086122449e-02f, 5.252889358e-03f},
    {6.203830242e-01f, -5.134930015e-01f, 1.300910115e-01f, -8.581606671e-03f, -1.628354425e-03f}
};
__constant float LANCZOS_ODD[4][5] = {
    {3.124131262e-02f, -1.518085003e-01f, 1.153080389e-01f, -3.287123889e-02f, 4.524598364e-03f},
    {-6.741748750e-02f, 3.247850537e-01f, -2.359011173e-01f, 6.400899589e-02f, -8.986481465e-03f},
    {1.677483320e-01f, -7.656253576e-01f, 4.019331634e-01f, -9.692156315e-02f, 1.320733782e-02f},
    {-1.305212140e+00f, 1.348976493e+00f, -5.413550138e-01f, 1.193249002e-01f, -1.582613029e-02f}
};
#endif
#if LANCZOS_A == 8
__constant float LANCZOS_EVEN[8][5] = {
    {-2.811276121e-03f, 1.245998032e-02f, -4.449369851e-03f, -1.899929601e-03f, 1.037716400e-03f},
    {1.065865718e-02f, -5.073596910e-02f, 3.409486637e-02f, -6.806269754e-03f, 1.927872363e-04f},
    {-2.227979712e-02f, 1.073288843e-01f, -7.756935060e-02f, 1.941148564e-02f, -1.956652850e-03f},
    {3.925899416e-02f, -1.895833015e-01f, 1.390176862e-01f, -3.636208549e-02f, 4.194688983e-03f},
    {-6.489751488e-02f, 3.122637570e-01f, -2.245565802e-01f, 5.708432198e-02f, -6.547898985e-03f},
    {1.078342199e-01f, -5.113306046e-01f, 3.382266760e-01f, -7.500726730e-02f, 8.000211790e-03f},
    {-2.001459002e-01f, 8.930900693e-01f, -3.874611855e-01f, 7.148963958e-02f, -6.995046511e-03f},
    {6.325370073e-01f, -5.748716593e-01f, 1.863632947e-01f, -3.058546968e-02f, 2.834845101e-03f}
};
__constant float LANCZOS_ODD[8][5] = {
    {6.299781613e-03f, -3.096586652e-02f, 2.496515773e-02f, -7.901598699e-03f, 1.235298347e-03f},
    {-9.543845430e-03f, 4.691066593e-02f, -3.781745955e-02f, 1.197406836e-02f, -1.875300426e-03f},
    {1.394780818e-02f, -6.848897785e-02f, 5.493618175e-02f, -1.724995673e-02f, 2.676671371e-03f},
    {-2.051506378e-02f, 1.004840657e-01f, -7.957807183e-02f, 2.445724979e-02f, -3.704093164e-03f},
    {3.201496974e-02f, -1.559031904e-01f, 1.198195815e-01f, -3.504591435e-02f, 5.042013247e-03f},
    {-5.797241256e-02f, 2.779824436e-01f, -1.966164708e-01f, 5.065466464e-02f, -6.693799049e-03f},
    {1.492322981e-01f, -6.736132503e-01f, 3.236276209e-01f, -6.966158748e-02f, 8.383027278e-03f},
    {-1.281373501e+00f, 1.230428576e+00f, -4.401114583e-01f, 8.387032896e-02f, -9.505508468e-03f}
};
#endif

static inline vreal poly5(__constant const float *c, vreal u)
{
    return (((c[4] * u + c[3]) * u + c[2]) * u + c[1]) * u + c[0];
}
#endif

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

#if INTERP == 3
/* The Lanczos sum of the taps re[], im[] at fraction t. */
static inline void lanczos_sum(const vreal *re, const vreal *im, vreal t, vreal *out_re, vreal *out_im)
{
#if !REAL_IS_DOUBLE
    /* no division and no transcendental function: 4-5x cheaper than the exact form below on a CPU; on a
     * sample (t = 0) the weights are 1 and 0 to within 3e-8, below float32's rounding */
    const vreal s = t - (real_t)0.5, u = s * s;
    vreal sr = (vreal)0, si = (vreal)0;
#pragma unroll
    for (int m = 0; m < LANCZOS_A; ++m) {
        const vreal e = poly5(LANCZOS_EVEN[m], u), o = s * poly5(LANCZOS_ODD[m], u);
        const vreal w_lo = e + o, w_hi = e - o;   /* taps m and NTAPS - 1 - m */
        sr += w_lo * re[m] + w_hi * re[NTAPS - 1 - m];
        si += w_lo * im[m] + w_hi * im[NTAPS - 1 - m];
    }
    *out_re = sr;
    *out_im = si;
#else
    /* Lanczos (float64, exact): L(x) = A sin(pi x) sin(pi x / A) / (pi x)^2 for |x| < A.
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
    lanczos_sum(re, im, t, out_re, out_im);
#endif
}

#endif
