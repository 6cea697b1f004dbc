/* What every kernel file starts with: the precision (REAL_T, REAL_IS_DOUBLE,
 * double needs cl_khr_fp64) and the default of MIN_CHANNELS (CF is 0 in cells
 * summed from fewer channels). */
#if REAL_IS_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif
#ifndef MIN_CHANNELS
#define MIN_CHANNELS 1
#endif
typedef REAL_T real_t;
