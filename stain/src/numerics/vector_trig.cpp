// Batched atan2, sin and cos (vector_trig.h).
//
// Design note: docs/design-notes.md, "stain/src/numerics/vector_trig.cpp".
#include "numerics/vector_trig.h"

#include <cmath>
#include <stdexcept>
#include <string>

#if defined(BLOT_HAVE_LIBMVEC)
#include <immintrin.h>

// libmvec's SSE entry points (x86-64 vector function ABI names: b = SSE, 2
// lanes; v = a vector argument). glibc 2.35 added atan2.
extern "C" {
__m128d _ZGVbN2vv_atan2(__m128d y, __m128d x);
__m128d _ZGVbN2v_sin(__m128d x);
__m128d _ZGVbN2v_cos(__m128d x);
}

// The AVX2 kernels: vector_trig_avx2.cpp, the one file built with -mavx2
// (passing ymm registers needs the whole file's ABI to be AVX's: clang
// otherwise passes them in memory, whatever the function's target).
namespace blot::stain::trig::avx2 {
void atan2(const double* y, const double* x, double* out, int count);
void unitPhases(const double* angles, double* out, int count);
}  // namespace blot::stain::trig::avx2
#endif

namespace blot::stain::trig {
namespace {

void atan2Scalar(const double* y, const double* x, double* out, int count) {
  for (int k = 0; k < count; ++k) out[k] = std::atan2(y[k], x[k]);
}

void unitPhasesScalar(const double* angles, double* out, int count) {
  for (int k = 0; k < count; ++k) {
    const double a = angles[k];
    out[2 * k] = std::cos(a);
    out[2 * k + 1] = std::sin(a);
  }
}

#if defined(BLOT_HAVE_LIBMVEC)
void atan2Sse2(const double* y, const double* x, double* out, int count) {
  int k = 0;
  for (; k + 2 <= count; k += 2) _mm_storeu_pd(out + k, _ZGVbN2vv_atan2(_mm_loadu_pd(y + k), _mm_loadu_pd(x + k)));
  if (k == count) return;
  // The tail padded to a full vector with (0, 1), never a scalar call: the
  // same bits in any batch (as vector_trig_avx2.cpp).
  const double yy[2] = {y[k], 0.0}, xx[2] = {x[k], 1.0};
  double r[2];
  _mm_storeu_pd(r, _ZGVbN2vv_atan2(_mm_loadu_pd(yy), _mm_loadu_pd(xx)));
  out[k] = r[0];
}

// (cos, sin) of two angles into out[0..3].
inline void storePhases2(__m128d a, double* out) {
  const __m128d c = _ZGVbN2v_cos(a), s = _ZGVbN2v_sin(a);
  _mm_storeu_pd(out, _mm_unpacklo_pd(c, s));
  _mm_storeu_pd(out + 2, _mm_unpackhi_pd(c, s));
}

void unitPhasesSse2(const double* angles, double* out, int count) {
  int k = 0;
  for (; k + 2 <= count; k += 2) storePhases2(_mm_loadu_pd(angles + k), out + 2 * k);
  if (k == count) return;
  const double a[2] = {angles[k], 0.0};  // the tail padded, as above
  double phases[4];
  storePhases2(_mm_loadu_pd(a), phases);
  out[2 * k] = phases[0];
  out[2 * k + 1] = phases[1];
}

#endif

Kernel bestKernel() {
#if defined(BLOT_HAVE_LIBMVEC)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") ? Kernel::Avx2 : Kernel::Sse2;
#else
  return Kernel::Scalar;
#endif
}

}  // namespace

Kernel activeKernel() {
  static const Kernel kernel = bestKernel();
  return kernel;
}

bool available(Kernel kernel) {
  switch (kernel) {
    case Kernel::Scalar: return true;
    case Kernel::Sse2: return activeKernel() != Kernel::Scalar;
    case Kernel::Avx2: return activeKernel() == Kernel::Avx2;
  }
  return false;
}

const char* name(Kernel kernel) {
  switch (kernel) {
    case Kernel::Scalar: return "scalar libm";
    case Kernel::Sse2: return "libmvec SSE, 2 lanes";
    case Kernel::Avx2: return "libmvec AVX2, 4 lanes";
  }
  return "unknown";
}

namespace {

void runAtan2(Kernel kernel, const double* y, const double* x, double* out, int count) {
  switch (kernel) {
#if defined(BLOT_HAVE_LIBMVEC)
    case Kernel::Avx2: avx2::atan2(y, x, out, count); return;
    case Kernel::Sse2: atan2Sse2(y, x, out, count); return;
#endif
    default: atan2Scalar(y, x, out, count); return;
  }
}

void runUnitPhases(Kernel kernel, const double* angles, Complex* out, int count) {
  double* to = reinterpret_cast<double*>(out);  // [complex.numbers]: array-compatible
  switch (kernel) {
#if defined(BLOT_HAVE_LIBMVEC)
    case Kernel::Avx2: avx2::unitPhases(angles, to, count); return;
    case Kernel::Sse2: unitPhasesSse2(angles, to, count); return;
#endif
    default: unitPhasesScalar(angles, to, count); return;
  }
}

void requireAvailable(Kernel kernel, const char* function) {
  if (!available(kernel))
    throw std::invalid_argument(std::string("trig::") + function + ": kernel \"" + name(kernel) +
                                "\" is not available on this CPU or build (expected one of those available()" +
                                " accepts)");
}

}  // namespace

void atan2With(Kernel kernel, const double* y, const double* x, double* out, int count) {
  requireAvailable(kernel, "atan2With");
  runAtan2(kernel, y, x, out, count);
}

void unitPhasesWith(Kernel kernel, const double* angles, Complex* out, int count) {
  requireAvailable(kernel, "unitPhasesWith");
  runUnitPhases(kernel, angles, out, count);
}

void atan2(const double* y, const double* x, double* out, int count) { runAtan2(activeKernel(), y, x, out, count); }

void unitPhases(const double* angles, Complex* out, int count) { runUnitPhases(activeKernel(), angles, out, count); }

double atan2(double y, double x) {
  double out;
  atan2(&y, &x, &out, 1);
  return out;
}

Complex unitPhase(double angle) {
  Complex out;
  unitPhases(&angle, &out, 1);
  return out;
}

}  // namespace blot::stain::trig
