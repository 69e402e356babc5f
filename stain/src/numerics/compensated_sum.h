// Neumaier-compensated sum, shared by the Krylov solver and the diffusion
// stage's mass fixes (moved from stages/diffusion.cpp).
#pragma once

#include <cmath>

namespace blot::stain::diffusion_internal {

// Σ x_i in index order with Neumaier's compensation: the sum's own rounding
// stays at ~1 ulp whatever #V, so the mass fix below does not drift by
// ~sqrt(#V) ε per step. Adding a zero of either sign changes no bit (the sum
// and the compensation are never −0: each starts at +0 and a sum of two
// doubles is −0 only when both are), so a caller may skip zeros.
class CompensatedSum {
 public:
  void add(double x) {
    const double t = sum_ + x;
    compensation_ += std::abs(sum_) >= std::abs(x) ? (sum_ - t) + x : (x - t) + sum_;
    sum_ = t;
  }
  double value() const { return sum_ + compensation_; }

 private:
  double sum_ = 0.0, compensation_ = 0.0;
};

}  // namespace blot::stain::diffusion_internal
