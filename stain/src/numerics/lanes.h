#pragma once
// Four doubles that go through each operation together: the rotation fits'
// lanes (geometry/surface_geometry.cpp), the operators' refill, four faces
// at a time (geometry/operators.cpp), and the step's scans for a value out
// of range (stain_solver.cpp). On x86-64 they sit in two SSE2
// registers, the baseline of every such CPU, so no dispatch is needed;
// elsewhere in a plain array. +, −, ×, ÷ and √ are IEEE 754's correctly
// rounded operations in a register as in a scalar, and nothing here fuses a
// multiply with an add, so each lane gets the bits of the same expression
// written for one double, in the same order (the callers write their
// expressions as the scalar code did, operation for operation).
// BLOT_LANES_PORTABLE selects the array form on x86-64 too (lanes_test is
// built both ways, so the form other CPUs get is compiled and checked here);
// each form is in an inline namespace of its own, so a test built with one
// and a library built with the other never share a definition.

#include <cmath>

#if defined(__SSE2__) && !defined(BLOT_LANES_PORTABLE)
#define BLOT_LANES_SSE2 1
#include <emmintrin.h>
#endif

namespace blot::stain::lanes {
#ifdef BLOT_LANES_SSE2
inline namespace sse2 {
#else
inline namespace portable {
#endif

inline constexpr int kLanes = 4;
/// Whether the lanes are SSE2 registers (else plain arrays).
#ifdef BLOT_LANES_SSE2
inline constexpr bool kSse2 = true;
#else
inline constexpr bool kSse2 = false;
#endif

struct Lanes {
#ifdef BLOT_LANES_SSE2
  __m128d lo, hi;
#else
  double v[kLanes];
#endif
};

#ifdef BLOT_LANES_SSE2

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
/// −a and |a|: the sign bit flipped or cleared, as the scalar − and std::abs (a zero keeps its magnitude).
inline Lanes operator-(const Lanes& a) {
  const __m128d sign = _mm_set1_pd(-0.0);
  return {_mm_xor_pd(a.lo, sign), _mm_xor_pd(a.hi, sign)};
}
inline Lanes abs(const Lanes& a) {
  const __m128d sign = _mm_set1_pd(-0.0);
  return {_mm_andnot_pd(sign, a.lo), _mm_andnot_pd(sign, a.hi)};
}
/// std::max(a, b) and std::min(a, b) in each lane: b where it compares above
/// (below) a, else a. So a NaN b leaves a, and of two zeros a is kept, as
/// in a scalar reduction `m = std::max(m, v)` (MAXPD and MINPD return their
/// second operand unless the first compares above or below it).
inline Lanes max(const Lanes& a, const Lanes& b) { return {_mm_max_pd(b.lo, a.lo), _mm_max_pd(b.hi, a.hi)}; }
inline Lanes min(const Lanes& a, const Lanes& b) { return {_mm_min_pd(b.lo, a.lo), _mm_min_pd(b.hi, a.hi)}; }

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
inline Lanes operator-(const Lanes& a) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r.v[l] = -a.v[l];
  return r;
}
inline Lanes abs(const Lanes& a) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r.v[l] = std::abs(a.v[l]);
  return r;
}
inline Lanes max(const Lanes& a, const Lanes& b) {
  return each(a, b, [](double x, double y) { return x < y ? y : x; });  // std::max(x, y)
}
inline Lanes min(const Lanes& a, const Lanes& b) {
  return each(a, b, [](double x, double y) { return y < x ? y : x; });  // std::min(x, y)
}

#endif

// A double on either side: the same operation with it in every lane.
inline Lanes operator+(double a, const Lanes& b) { return splat(a) + b; }
inline Lanes operator-(double a, const Lanes& b) { return splat(a) - b; }
inline Lanes operator*(double a, const Lanes& b) { return splat(a) * b; }
inline Lanes operator/(double a, const Lanes& b) { return splat(a) / b; }
inline Lanes operator+(const Lanes& a, double b) { return a + splat(b); }
inline Lanes operator-(const Lanes& a, double b) { return a - splat(b); }
inline Lanes operator*(const Lanes& a, double b) { return a * splat(b); }
inline Lanes operator/(const Lanes& a, double b) { return a / splat(b); }

/// P = A B for a 3 × 3 matrix in each lane, entry (r, c) of each in
/// [3r + c], with the sums associated as Eigen 3.4's fixed-size product of
/// two Matrix3d (SSE2, no fused multiply-add) associates them: rows 0 and 1
/// left to right, row 2 with its last two terms first. So a lane's product
/// has the bits of `a * b` on Eigen matrices (lanes_test checks it against
/// the Eigen this is built with).
inline void product3(const Lanes (&A)[9], const Lanes (&B)[9], Lanes (&P)[9]) {
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 2; ++r) P[3 * r + c] = A[3 * r] * B[c] + A[3 * r + 1] * B[3 + c] + A[3 * r + 2] * B[6 + c];
    P[6 + c] = A[6] * B[c] + (A[7] * B[3 + c] + A[8] * B[6 + c]);
  }
}

}  // inline namespace sse2 or portable
}  // namespace blot::stain::lanes
