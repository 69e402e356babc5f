// BulletCloth state capture and restore (save/load): capture → more steps →
// restore → the same steps again gives bit-identical positions, with and
// without colliders, in the same cloth and in a fresh one built from the same
// ClothDef; a state of the wrong shape is refused naming the field.
#include <blot/cloth/bullet_cloth.h>

#include "flag_fixture.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace blot::cloth {
namespace {

constexpr double kFrame = 1.0 / 60;

// Positions after each of `frames` frames; liquid loads change every 10 frames
// (so pending loads and node masses are part of what must be restored).
std::vector<Eigen::MatrixX3d> run(BulletCloth& cloth, int frames, int salt) {
  std::vector<Eigen::MatrixX3d> out;
  const int n = cloth.vertexCount();
  for (int k = 0; k < frames; ++k) {
    if (k % 10 == 3) {
      Eigen::VectorXd masses(n);
      Eigen::MatrixX3d impulses(n, 3);
      for (int i = 0; i < n; ++i) {
        masses[i] = 1e-4 * ((i * 7 + k + salt) % 13);
        impulses.row(i) << 1e-6 * ((i + k) % 5), -1e-6 * ((i * 3 + salt) % 7), 0;
      }
      cloth.setLiquidLoads(masses, impulses);
    }
    cloth.advance(kFrame);
    out.push_back(cloth.positions());
  }
  return out;
}

void expectBitIdentical(const std::vector<Eigen::MatrixX3d>& a, const std::vector<Eigen::MatrixX3d>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    const double diff = (a[k] - b[k]).cwiseAbs().maxCoeff();
    ASSERT_EQ(diff, 0.0) << "frame " << k << " differs by up to " << diff << " m";
  }
}

void checkRoundTrip(const ClothDef& def, int warmup) {
  BulletCloth cloth(def);
  run(cloth, warmup, 1);
  // Loads set but not yet applied are part of the state.
  cloth.setLiquidLoads(Eigen::VectorXd::Constant(cloth.vertexCount(), 2e-4),
                       Eigen::MatrixX3d::Constant(cloth.vertexCount(), 3, 1e-6));
  const BulletClothState saved = cloth.captureState();
  const std::vector<Eigen::MatrixX3d> first = run(cloth, 60, 2);
  const Eigen::VectorXd massesAfter = cloth.nodeMasses();
  cloth.restoreState(saved);
  EXPECT_EQ(cloth.time(), saved.time);
  EXPECT_EQ(cloth.positions(), saved.positions.cast<double>());
  const std::vector<Eigen::MatrixX3d> again = run(cloth, 60, 2);
  {
    SCOPED_TRACE("restored into the same cloth");
    expectBitIdentical(first, again);
  }
  EXPECT_EQ(cloth.nodeMasses(), massesAfter);
  // Load: a fresh cloth from the same definition.
  BulletCloth fresh(def);
  fresh.restoreState(saved);
  const std::vector<Eigen::MatrixX3d> loaded = run(fresh, 60, 2);
  SCOPED_TRACE("restored into a fresh cloth");
  expectBitIdentical(first, loaded);
  EXPECT_TRUE(fresh.isHealthy());
}

TEST(BulletClothState, RestoreRepeatsTheRunBitForBitWithoutColliders) {
  ClothDef def = test::hangingFlag(24);
  def.pins[0].motion.amplitude = Eigen::Vector3d(0, 0.1, 0);  // waving: pins move, moments vary
  def.pins[0].motion.frequency = 1.0;
  def.pins[1].motion.releaseTime = 1.2;                       // released between capture and the end
  def.wind.velocity = Eigen::Vector3d(0, 2, 0);
  def.wind.dragCoefficient = 0.5;
  checkRoundTrip(def, 40);
}

TEST(BulletClothState, RestoreRepeatsTheRunBitForBitWithColliders) {
  ClothDef def = test::flatSheet(24, 0.5);
  def.colliders = {ClothCollider::plane(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()),
                   ClothCollider::sphere(Eigen::Vector3d(0.5, 0.5, 0.1), 0.25)};
  checkRoundTrip(def, 40);  // at frame 40 the sheet lies on the sphere and is reaching the ground
}

TEST(BulletClothState, WrongShapesAreRefusedNamingTheField) {
  BulletCloth cloth(test::hangingFlag(6));
  BulletClothState state = cloth.captureState();
  state.velocities.resize(3, 3);
  try {
    cloth.restoreState(state);
    FAIL() << "a state with 3 velocity rows was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("velocities has 3 rows; expected 49"), std::string::npos) << e.what();
  }
  state = cloth.captureState();
  state.releasedPins.push_back(0);
  EXPECT_THROW(cloth.restoreState(state), std::invalid_argument);
}

}  // namespace
}  // namespace blot::cloth
