#pragma once
// Bit-for-bit comparison of two stain states, for the determinism tests
// (thread counts, adaptive threads, repeated runs): every field, and the
// first field and vertex that differ when they do.
#include <blot/stain/stain_state.h>

#include <gtest/gtest.h>

#include <cstring>

namespace blot::stain::testing {

template <typename Field>
::testing::AssertionResult sameFieldBits(const char* name, const Field& a, const Field& b) {
  if (a.size() != b.size())
    return ::testing::AssertionFailure() << name << ": " << a.size() << " against " << b.size() << " values";
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (std::memcmp(&a[i], &b[i], sizeof(a[i])) != 0)
      return ::testing::AssertionFailure() << name << " differs first at vertex " << i << ": " << a[i] << " against "
                                           << b[i];
  return ::testing::AssertionSuccess();
}

/// Success when every field of `a` and `b` holds the same bits.
inline ::testing::AssertionResult sameBits(const StainState& a, const StainState& b) {
  for (const auto& result :
       {sameFieldBits("solvent", a.solvent, b.solvent), sameFieldBits("solute", a.solute, b.solute),
        sameFieldBits("velocities", a.velocities, b.velocities),
        sameFieldBits("absorbedSolvent", a.absorbedSolvent, b.absorbedSolvent),
        sameFieldBits("absorbedSolute", a.absorbedSolute, b.absorbedSolute),
        sameFieldBits("adsorbedSolute", a.adsorbedSolute, b.adsorbedSolute)})
    if (!result) return result;
  return ::testing::AssertionSuccess();
}

}  // namespace blot::stain::testing
