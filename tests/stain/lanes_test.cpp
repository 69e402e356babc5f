// Four lanes of doubles (stain/src/numerics/lanes.h): each lane gets the bits
// of the scalar operation, whatever the other lanes hold, so the rotation
// fits written on them keep the bits of their scalar form.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "numerics/lanes.h"

namespace blot::stain {
namespace {

std::uint64_t bits(double x) {
  std::uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// Same bits, or both NaN (a NaN's payload is not part of the claim).
bool same(double a, double b) { return bits(a) == bits(b) || (std::isnan(a) && std::isnan(b)); }

// Random finite values over many binades, and every special a fit can meet.
std::vector<double> operands() {
  std::vector<double> values = {0.0,
                                -0.0,
                                1.0,
                                -1.0,
                                0.5,
                                std::numeric_limits<double>::denorm_min(),
                                -std::numeric_limits<double>::min(),
                                std::numeric_limits<double>::max(),
                                std::numeric_limits<double>::infinity(),
                                -std::numeric_limits<double>::infinity(),
                                std::numeric_limits<double>::quiet_NaN()};
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-60, 60);
  for (int k = 0; k < 400; ++k) values.push_back(std::ldexp(mantissa(random), exponent(random)));
  return values;
}

TEST(Lanes, EachLaneIsTheScalarOperationWhateverItsCompanions) {
  using lanes::Lanes;
  const std::vector<double> v = operands();
  const size_t n = v.size();
  size_t checked = 0;
  // Lane l of a and b takes the pair (i, j) shifted by l, so every pair meets
  // every lane with other pairs beside it.
  for (size_t i = 0; i < n; ++i)
    for (size_t j = 0; j < n; j += 7) {
      double a[lanes::kLanes], b[lanes::kLanes];
      for (int l = 0; l < lanes::kLanes; ++l) {
        a[l] = v[(i + static_cast<size_t>(l)) % n];
        b[l] = v[(j + 3 * static_cast<size_t>(l)) % n];
      }
      const Lanes x = lanes::load(a), y = lanes::gather(b[0], b[1], b[2], b[3]);
      double sum[lanes::kLanes], difference[lanes::kLanes], product[lanes::kLanes], quotient[lanes::kLanes],
          root[lanes::kLanes], scaled[lanes::kLanes], shifted[lanes::kLanes], inverse[lanes::kLanes],
          below[lanes::kLanes], plusOne[lanes::kLanes], thirds[lanes::kLanes], negated[lanes::kLanes],
          magnitude[lanes::kLanes], larger[lanes::kLanes], smaller[lanes::kLanes];
      lanes::store(x + y, sum);
      lanes::store(x - y, difference);
      lanes::store(x * y, product);
      lanes::store(x / y, quotient);
      lanes::store(lanes::sqrt(x), root);
      lanes::store(-0.5 * y, scaled);
      lanes::store(1.0 + y, shifted);
      lanes::store(1.0 / x, inverse);
      lanes::store(0.25 - x, below);
      lanes::store(x + 1.0, plusOne);
      lanes::store(x / 3.0, thirds);
      lanes::store(-x, negated);
      lanes::store(lanes::abs(x), magnitude);
      lanes::store(lanes::max(x, y), larger);
      lanes::store(lanes::min(x, y), smaller);
      for (int l = 0; l < lanes::kLanes; ++l) {
        ASSERT_TRUE(same(sum[l], a[l] + b[l])) << a[l] << " + " << b[l];
        ASSERT_TRUE(same(difference[l], a[l] - b[l])) << a[l] << " - " << b[l];
        ASSERT_TRUE(same(product[l], a[l] * b[l])) << a[l] << " * " << b[l];
        ASSERT_TRUE(same(quotient[l], a[l] / b[l])) << a[l] << " / " << b[l];
        ASSERT_TRUE(same(root[l], std::sqrt(a[l]))) << "sqrt " << a[l];
        ASSERT_TRUE(same(scaled[l], -0.5 * b[l])) << b[l];
        ASSERT_TRUE(same(shifted[l], 1.0 + b[l])) << b[l];
        ASSERT_TRUE(same(inverse[l], 1.0 / a[l])) << a[l];
        ASSERT_TRUE(same(below[l], 0.25 - a[l])) << a[l];
        ASSERT_TRUE(same(plusOne[l], a[l] + 1.0)) << a[l];
        ASSERT_TRUE(same(thirds[l], a[l] / 3.0)) << a[l];
        ASSERT_TRUE(same(negated[l], -a[l])) << a[l];
        ASSERT_TRUE(same(magnitude[l], std::abs(a[l]))) << a[l];
        // Which of two zeros, and a NaN on either side, as std::max and std::min.
        ASSERT_TRUE(same(larger[l], std::max(a[l], b[l]))) << "max " << a[l] << ", " << b[l];
        ASSERT_TRUE(same(smaller[l], std::min(a[l], b[l]))) << "min " << a[l] << ", " << b[l];
        ++checked;
      }
    }
  EXPECT_EQ(checked, n * ((n + 6) / 7) * lanes::kLanes);
}

// lanes_portable_test builds this file with BLOT_LANES_PORTABLE: the plain
// arrays a CPU without SSE2 gets, checked by the same tests.
TEST(Lanes, TheFormBuiltIsTheOneAskedFor) {
#if defined(__SSE2__) && !defined(BLOT_LANES_PORTABLE)
  EXPECT_TRUE(lanes::kSse2);
#else
  EXPECT_FALSE(lanes::kSse2);
#endif
}

TEST(Lanes, SplatLoadAndGatherPutEachValueInItsLane) {
  const double values[lanes::kLanes] = {1.5, -2.0, 0.0, 7.25};
  double out[lanes::kLanes];
  lanes::store(lanes::load(values), out);
  for (int l = 0; l < lanes::kLanes; ++l) EXPECT_EQ(bits(out[l]), bits(values[l]));
  lanes::store(lanes::gather(values[0], values[1], values[2], values[3]), out);
  for (int l = 0; l < lanes::kLanes; ++l) EXPECT_EQ(bits(out[l]), bits(values[l]));
  lanes::store(lanes::splat(-0.0), out);
  for (int l = 0; l < lanes::kLanes; ++l) EXPECT_EQ(bits(out[l]), bits(-0.0));
}

// The rotation fits' frames U F̄ are formed in lanes; the SVD fallback and
// the SVD method form them with Eigen's product. Both must give one bit
// pattern, whatever Eigen's version does with the sums' association.
TEST(Lanes, Product3HasTheBitsOfEigensMatrix3Product) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  int mismatches = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Eigen::Matrix3d a[lanes::kLanes], b[lanes::kLanes];
    for (int l = 0; l < lanes::kLanes; ++l)
      for (int k = 0; k < 9; ++k) {
        a[l].data()[k] = std::ldexp(entry(random), trial % 7 - 3);
        b[l].data()[k] = entry(random);
      }
    lanes::Lanes A[9], B[9], P[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        A[3 * r + c] = lanes::gather(a[0](r, c), a[1](r, c), a[2](r, c), a[3](r, c));
        B[3 * r + c] = lanes::gather(b[0](r, c), b[1](r, c), b[2](r, c), b[3](r, c));
      }
    lanes::product3(A, B, P);
    for (int e = 0; e < 9; ++e) {
      double p[lanes::kLanes];
      lanes::store(P[e], p);
      for (int l = 0; l < lanes::kLanes; ++l) {
        Eigen::Matrix3d expected;
        expected.noalias() = a[l] * b[l];
        mismatches += bits(p[l]) == bits(expected(e / 3, e % 3)) ? 0 : 1;
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
}

}  // namespace
}  // namespace blot::stain
