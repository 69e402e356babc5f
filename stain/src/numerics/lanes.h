#pragma once
// Four doubles that go through each operation together: the rotation fits'
// lanes (geometry/surface_geometry.cpp). On x86-64 they sit in two SSE2
// registers, the baseline of every such CPU, so no dispatch is needed;
// elsewhere in a plain array. +, −, ×, ÷ and √ are IEEE 754's correctly
// rounded operations in a register as in a scalar, and nothing here fuses a
// multiply with an add, so each lane gets the bits of the same expression
// written for one double, in the same order (the callers write their
// expressions as the scalar code did, operation for operation).

#include <cmath>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace blot::stain::lanes {

inline constexpr int kLanes = 4;

struct Lanes {
#ifdef __SSE2__
  __m128d lo, hi;
#else
  double v[kLanes];
#endif
};

#ifdef __SSE2__

inline Lanes load(const double* p) { return {_mm_loadu_pd(p), _mm_loadu_pd(p + 2)}; }
inline void store(const Lanes& a, double* p) {
  _mm_storeu_pd(p, a.lo);
  _mm_storeu_pd(p + 2, a.hi);
}
inline Lanes splat(double x) { return {_mm_set1_pd(x), _mm_set1_pd(x)}; }
/// Lane l from values[l].
inline Lanes gather(double a, double b, double c, double d) { return {_mm_set_pd(b, a), _mm_set_pd(d, c)}; }
inline Lanes operator+(const Lanes& a, const Lanes& b) { return {_mm_add_pd(a.lo, b.lo), _mm_add_pd(a.hi, b.hi)}; }
inline Lanes operator-(const Lanes& a, const Lanes& b) { return {_mm_sub_pd(a.lo, b.lo), _mm_sub_pd(a.hi, b.hi)}; }
inline Lanes operator*(const Lanes& a, const Lanes& b) { return {_mm_mul_pd(a.lo, b.lo), _mm_mul_pd(a.hi, b.hi)}; }
inline Lanes operator/(const Lanes& a, const Lanes& b) { return {_mm_div_pd(a.lo, b.lo), _mm_div_pd(a.hi, b.hi)}; }
inline Lanes sqrt(const Lanes& a) { return {_mm_sqrt_pd(a.lo), _mm_sqrt_pd(a.hi)}; }

#else

inline Lanes load(const double* p) { return {{p[0], p[1], p[2], p[3]}}; }
inline void store(const Lanes& a, double* p) {
  for (int l = 0; l < kLanes; ++l) p[l] = a.v[l];
}
inline Lanes splat(double x) { return {{x, x, x, x}}; }
inline Lanes gather(double a, double b, double c, double d) { return {{a, b, c, d}}; }
template <class Op>
Lanes each(const Lanes& a, const Lanes& b, Op op) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r.v[l] = op(a.v[l], b.v[l]);
  return r;
}
inline Lanes operator+(const Lanes& a, const Lanes& b) { return each(a, b, [](double x, double y) { return x + y; }); }
inline Lanes operator-(const Lanes& a, const Lanes& b) { return each(a, b, [](double x, double y) { return x - y; }); }
inline Lanes operator*(const Lanes& a, const Lanes& b) { return each(a, b, [](double x, double y) { return x * y; }); }
inline Lanes operator/(const Lanes& a, const Lanes& b) { return each(a, b, [](double x, double y) { return x / y; }); }
inline Lanes sqrt(const Lanes& a) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r.v[l] = std::sqrt(a.v[l]);
  return r;
}

#endif

// A double on either side: the same operation with it in every lane.
inline Lanes operator+(double a, const Lanes& b) { return splat(a) + b; }
inline Lanes operator-(double a, const Lanes& b) { return splat(a) - b; }
inline Lanes operator*(double a, const Lanes& b) { return splat(a) * b; }
inline Lanes operator/(double a, const Lanes& b) { return splat(a) / b; }

}  // namespace blot::stain::lanes
