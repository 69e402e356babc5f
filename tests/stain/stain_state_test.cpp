// StainState::resize sizes every field for a mesh and zeroes fields and totals.
#include <blot/stain/stain_state.h>

#include <gtest/gtest.h>

#include <stdexcept>

namespace blot::stain {
namespace {

TEST(StainState, ResizeZeroesEveryFieldAndTotal) {
  StainState state;
  state.resize(3);
  state.solvent.setConstant(1.0);
  state.velocities.setConstant(Complex(1.0, -2.0));
  state.evaporatedSolvent = 0.5;
  state.addedSolvent = 2.0;
  state.addedSolute = 1.0;
  state.resize(7);
  EXPECT_EQ(state.vertexCount(), 7);
  for (const Vector* field : {&state.solvent, &state.solute, &state.absorbedSolvent, &state.absorbedSolute,
                              &state.adsorbedSolute}) {
    ASSERT_EQ(field->size(), 7);
    EXPECT_EQ(field->cwiseAbs().maxCoeff(), 0.0);
  }
  ASSERT_EQ(state.velocities.size(), 7);
  EXPECT_EQ(state.velocities.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(state.evaporatedSolvent, 0.0);
  EXPECT_EQ(state.addedSolvent, 0.0);
  EXPECT_EQ(state.addedSolute, 0.0);
  EXPECT_THROW(state.resize(-1), std::invalid_argument);
}

}  // namespace
}  // namespace blot::stain
