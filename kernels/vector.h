/* Lane vectors for the beamforming kernel.
 *
 * A work-item computes VEC cells (consecutive angles at one range row) as
 * the lanes of OpenCL vector types: CPU drivers turn them into SIMD code
 * directly, GPUs use VEC = 1 (plain scalars, one cell per work-item).
 *
 *   vreal  real_t lanes          vint  int lanes (sample indices)
 *   vmask  lane masks: -1 true, 0 false, the type relational operators on
 *          vreal return (int for float, long for double vectors)
 */
#ifndef CLBEAM_VECTOR_H
#define CLBEAM_VECTOR_H

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)

#if VEC == 1
typedef real_t vreal;
typedef int vint;
#if REAL_IS_DOUBLE
typedef long vmask;
#else
typedef int vmask;
#endif
/* scalar relational operators give 1, vector ones -1: make both -1 */
#define IMASK(c) (-(int)(c))
#define RMASK(c) (-(vmask)(c))
#define TO_VMASK(m) ((vmask)(m))
#define VLOAD_R(i, p) ((p)[i])
#define VLOAD_I(i, p) ((p)[i])
#define CONVERT_VINT(x) ((int)(x))
#define CONVERT_VREAL_I(x) ((real_t)(x))
#else
typedef CAT(REAL_T, VEC) vreal;
typedef CAT(int, VEC) vint;
#if REAL_IS_DOUBLE
typedef CAT(long, VEC) vmask;
#define TO_VMASK(m) CAT(convert_long, VEC)(m)
#else
typedef CAT(int, VEC) vmask;
#define TO_VMASK(m) (m)
#endif
#define IMASK(c) (c)
#define RMASK(c) (c)
#define VLOAD_R(i, p) CAT(vload, VEC)(i, p)
#define VLOAD_I(i, p) CAT(vload, VEC)(i, p)
#define CONVERT_VINT(x) CAT(convert_int, VEC)(x)
#define CONVERT_VREAL_I(x) CAT(CAT(convert_, REAL_T), VEC)(x)
#endif

/* out[first + l * stride] = v[l] for every lane; T is the element type */
#if VEC == 1
#define SCATTER(T, out, first, stride, v) ((out)[first] = (v))
#else
#define SCATTER(T, out, first, stride, v)                           \
    do {                                                            \
        T a_[VEC];                                                  \
        CAT(vstore, VEC)((v), 0, a_);                               \
        for (int l_ = 0; l_ < VEC; ++l_)                            \
            (out)[(first) + (size_t)l_ * (stride)] = a_[l_];        \
    } while (0)
#endif

#endif
