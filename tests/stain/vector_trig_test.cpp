// The metric rebuild's batched atan2, sin and cos (stain/src/numerics/
// vector_trig.h): within glibc's stated 4 ulp of a long-double reference on
// the ranges the rebuild uses, and a value's bits independent of the batch it
// comes in (what lets a partial rebuild, a whole one and any thread count
// agree), for every kernel this CPU can run.
#include "numerics/vector_trig.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <limits>
#include <random>
#include <vector>

namespace blot::stain {
namespace {

using trig::Kernel;

std::vector<Kernel> availableKernels() {
  std::vector<Kernel> kernels;
  for (const Kernel k : {Kernel::Scalar, Kernel::Sse2, Kernel::Avx2})
    if (trig::available(k)) kernels.push_back(k);
  return kernels;
}

// |value − reference| in units in the last place of the double nearest the reference.
double ulpError(double value, long double reference) {
  const double nearest = static_cast<double>(reference);
  const double ulp = std::nextafter(std::abs(nearest), std::numeric_limits<double>::infinity()) - std::abs(nearest);
  return static_cast<double>(std::abs(static_cast<long double>(value) - reference) / ulp);
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// (4A, b² + c² − a²) pairs as the corner angles give them: y >= 0, x of
// either sign, magnitudes from a hair-thin sliver to a metre-sized face, and
// the exact cases (right angle, flat corners).
void cornerInputs(std::vector<double>& y, std::vector<double>& x) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), exponent(-14.0, 2.0);
  for (int k = 0; k < 20000; ++k) {
    const double scale = std::pow(10.0, exponent(random));
    y.push_back(std::abs(unit(random)) * scale * (k % 7 == 0 ? 1e-6 : 1.0));
    x.push_back(unit(random) * scale);
  }
  const double exact[][2] = {{0.0, 1.0}, {0.0, -1.0}, {1.0, 0.0}, {1.0, 1.0}, {1.0, -1.0}, {3.0, 1e-300}};
  for (const auto& e : exact) {
    y.push_back(e[0]);
    x.push_back(e[1]);
  }
}

TEST(VectorTrig, Atan2IsWithinFourUlpOnCornerAngleInputs) {
  std::vector<double> y, x;
  cornerInputs(y, x);
  const int n = static_cast<int>(y.size());
  for (const Kernel kernel : availableKernels()) {
    std::vector<double> theta(y.size());
    trig::atan2With(kernel, y.data(), x.data(), theta.data(), n);
    double worst = 0.0;
    for (int k = 0; k < n; ++k) {
      const long double reference = std::atan2(static_cast<long double>(y[k]), static_cast<long double>(x[k]));
      ASSERT_TRUE(std::isfinite(theta[k])) << trig::name(kernel) << ": atan2(" << y[k] << ", " << x[k] << ")";
      worst = std::max(worst, reference == 0 ? std::abs(theta[k]) : ulpError(theta[k], reference));
    }
    EXPECT_LE(worst, 4.0) << trig::name(kernel);
    // The exact corners: flat (0 and π) and the right angle.
    EXPECT_EQ(theta[static_cast<size_t>(n - 6)], 0.0) << trig::name(kernel);
    EXPECT_NEAR(theta[static_cast<size_t>(n - 5)], M_PI, 4e-16 * M_PI) << trig::name(kernel);
    EXPECT_NEAR(theta[static_cast<size_t>(n - 4)], M_PI / 2, 4e-16 * M_PI) << trig::name(kernel);
    std::string key = std::string("max_ulp ") + trig::name(kernel);
    for (char& c : key)
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    RecordProperty(key, std::to_string(worst));
  }
}

TEST(VectorTrig, UnitPhasesAreWithinFourUlpOnTransportAngles) {
  // The transport angles lie in [−3π, 3π] (wrapAngle's range and sums of two).
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> angle(-3 * M_PI, 3 * M_PI);
  std::vector<double> angles(20000);
  for (double& a : angles) a = angle(random);
  angles.insert(angles.end(), {0.0, M_PI / 2, -M_PI, 1e-300});
  const int n = static_cast<int>(angles.size());
  for (const Kernel kernel : availableKernels()) {
    std::vector<Complex> phases(angles.size());
    trig::unitPhasesWith(kernel, angles.data(), phases.data(), n);
    double worst = 0.0;
    for (int k = 0; k < n; ++k) {
      const long double a = angles[static_cast<size_t>(k)];
      const Complex& z = phases[static_cast<size_t>(k)];
      // Near a zero of sin or cos an ulp of the result is tiny: the error is
      // measured in ulps of the result or of 2^-53 (the unit's), the larger.
      for (const auto& [value, reference] : {std::pair<double, long double>{z.real(), std::cos(a)},
                                             std::pair<double, long double>{z.imag(), std::sin(a)}}) {
        const double absolute = static_cast<double>(std::abs(static_cast<long double>(value) - reference));
        worst = std::max(worst, std::min(ulpError(value, reference), absolute / std::ldexp(1.0, -53)));
      }
    }
    EXPECT_LE(worst, 4.0) << trig::name(kernel);
    EXPECT_EQ(phases[static_cast<size_t>(n - 4)], Complex(1.0, 0.0)) << trig::name(kernel);
  }
}

TEST(VectorTrig, AValuesBitsDoNotDependOnItsBatch) {
  std::vector<double> y, x;
  cornerInputs(y, x);
  y.resize(257);
  x.resize(257);
  const int n = static_cast<int>(y.size());
  for (const Kernel kernel : availableKernels()) {
    std::vector<double> whole(y.size());
    std::vector<Complex> wholePhases(y.size());
    trig::atan2With(kernel, y.data(), x.data(), whole.data(), n);
    trig::unitPhasesWith(kernel, x.data(), wholePhases.data(), n);
    // Every batch length from 1 to 9 and every starting offset: the values
    // land in every lane and in padded tails.
    for (int length = 1; length <= 9; ++length) {
      for (int start = 0; start + length <= n; start += length) {
        double part[9];
        Complex partPhases[9];
        trig::atan2With(kernel, y.data() + start, x.data() + start, part, length);
        trig::unitPhasesWith(kernel, x.data() + start, partPhases, length);
        for (int m = 0; m < length; ++m) {
          const size_t k = static_cast<size_t>(start + m);
          ASSERT_TRUE(sameBits(part[m], whole[k])) << trig::name(kernel) << " length " << length << " start " << start;
          ASSERT_TRUE(sameBits(partPhases[m].real(), wholePhases[k].real()) &&
                      sameBits(partPhases[m].imag(), wholePhases[k].imag()))
              << trig::name(kernel) << " length " << length << " start " << start;
        }
      }
    }
  }
}

TEST(VectorTrig, TheDefaultEntryPointsUseTheActiveKernel) {
  const Kernel active = trig::activeKernel();
  ASSERT_TRUE(trig::available(active));
  std::vector<double> y, x;
  cornerInputs(y, x);
  const int n = 101;
  std::vector<double> viaDefault(n), viaKernel(n);
  trig::atan2(y.data(), x.data(), viaDefault.data(), n);
  trig::atan2With(active, y.data(), x.data(), viaKernel.data(), n);
  for (int k = 0; k < n; ++k) {
    EXPECT_TRUE(sameBits(viaDefault[static_cast<size_t>(k)], viaKernel[static_cast<size_t>(k)])) << k;
    EXPECT_TRUE(sameBits(trig::atan2(y[static_cast<size_t>(k)], x[static_cast<size_t>(k)]), viaKernel[static_cast<size_t>(k)]))
        << k;
    const Complex one = trig::unitPhase(x[static_cast<size_t>(k)]);
    Complex batch;
    trig::unitPhasesWith(active, &x[static_cast<size_t>(k)], &batch, 1);
    EXPECT_TRUE(sameBits(one.real(), batch.real()) && sameBits(one.imag(), batch.imag())) << k;
  }
}

TEST(VectorTrig, NonFiniteInputsStayVisible) {
  // A degenerate metric must not turn into a finite angle: the rebuild's
  // checks look for the NaN.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Kernel kernel : availableKernels()) {
    const double y[3] = {nan, 1.0, 1.0}, x[3] = {1.0, nan, 1.0};
    double theta[3];
    trig::atan2With(kernel, y, x, theta, 3);
    EXPECT_TRUE(std::isnan(theta[0]) && std::isnan(theta[1])) << trig::name(kernel);
    EXPECT_NEAR(theta[2], M_PI / 4, 1e-15) << trig::name(kernel);
    const double angles[2] = {nan, std::numeric_limits<double>::infinity()};
    Complex phases[2];
    trig::unitPhasesWith(kernel, angles, phases, 2);
    EXPECT_TRUE(std::isnan(phases[0].real()) && std::isnan(phases[0].imag())) << trig::name(kernel);
    EXPECT_TRUE(std::isnan(phases[1].real()) && std::isnan(phases[1].imag())) << trig::name(kernel);
  }
}

TEST(VectorTrig, AKernelThisCpuCannotRunIsRefusedByName) {
  for (const Kernel kernel : {Kernel::Sse2, Kernel::Avx2}) {
    if (trig::available(kernel)) continue;
    double out;
    const double one = 1.0;
    try {
      trig::atan2With(kernel, &one, &one, &out, 1);
      ADD_FAILURE() << trig::name(kernel) << " ran although not available";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(trig::name(kernel)), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(trig::available(Kernel::Scalar));
}

}  // namespace
}  // namespace blot::stain
