// The AVX2 kernels of vector_trig.cpp: libmvec's 4-lane atan2, sin and cos.
// This file alone is built with -mavx2 (stain/CMakeLists.txt) and runs only
// where the CPU has AVX2 (trig::activeKernel). It includes nothing but the
// intrinsics and defines no inline or template function with external
// linkage, so no AVX2 copy of shared code can reach a caller on another CPU.
//
// Design note: docs/design-notes.md, "stain/src/numerics/vector_trig.cpp".
#if defined(BLOT_HAVE_LIBMVEC)
#include <immintrin.h>

extern "C" {
__m256d _ZGVdN4vv_atan2(__m256d y, __m256d x);
__m256d _ZGVdN4v_sin(__m256d x);
__m256d _ZGVdN4v_cos(__m256d x);
}

namespace blot::stain::trig::avx2 {
namespace {

// (cos, sin) pairs of the four angles at a into to[0..7].
void storePhases4(const double* a, double* to) {
  const __m256d angles = _mm256_loadu_pd(a);
  double c[4], s[4];
  _mm256_storeu_pd(c, _ZGVdN4v_cos(angles));
  _mm256_storeu_pd(s, _ZGVdN4v_sin(angles));
  for (int m = 0; m < 4; ++m) {
    to[2 * m] = c[m];
    to[2 * m + 1] = s[m];
  }
}

}  // namespace

// The tails are padded to a full vector (inputs (0, 1) for atan2, 0 for the
// phases), never finished by scalar calls: the same bits in any batch.
void atan2(const double* y, const double* x, double* out, int count) {
  int k = 0;
  for (; k + 4 <= count; k += 4)
    _mm256_storeu_pd(out + k, _ZGVdN4vv_atan2(_mm256_loadu_pd(y + k), _mm256_loadu_pd(x + k)));
  if (k == count) return;
  double yy[4], xx[4], r[4];
  for (int m = 0; m < 4; ++m) {
    yy[m] = k + m < count ? y[k + m] : 0.0;
    xx[m] = k + m < count ? x[k + m] : 1.0;
  }
  _mm256_storeu_pd(r, _ZGVdN4vv_atan2(_mm256_loadu_pd(yy), _mm256_loadu_pd(xx)));
  for (int m = 0; k + m < count; ++m) out[k + m] = r[m];
}

void unitPhases(const double* angles, double* out, int count) {
  int k = 0;
  for (; k + 4 <= count; k += 4) storePhases4(angles + k, out + 2 * k);
  if (k == count) return;
  double a[4], phases[8];
  for (int m = 0; m < 4; ++m) a[m] = k + m < count ? angles[k + m] : 0.0;
  storePhases4(a, phases);
  for (int m = 0; m < 2 * (count - k); ++m) out[2 * k + m] = phases[m];
}

}  // namespace blot::stain::trig::avx2
#endif
