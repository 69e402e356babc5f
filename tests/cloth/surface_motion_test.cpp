// Rigid motion is exact: distances are preserved, velocities match the
// derivative of the positions, and half a revolution maps points as expected.
#include <blot/cloth/surface_motion.h>

#include <gtest/gtest.h>

#include <cmath>

namespace blot::cloth {
namespace {

Eigen::MatrixX3d somePoints() {
  Eigen::MatrixX3d p(4, 3);
  p << 0, 0, 0, 1, 0, 0, 0, 2, 0, 0.3, -0.4, 0.5;
  return p;
}

TEST(RigidMotion, PreservesDistancesAndMatchesDerivative) {
  RigidMotionDef def;
  def.angularVelocity = {0.3, -1.2, 2.0};
  def.pivot = {0.1, 0.2, 0.3};
  def.linearVelocity = {1, 0, -1};
  def.linearAcceleration = {0, 0, -9.8};
  const Eigen::MatrixX3d rest = somePoints();
  RigidMotion motion(rest, def);
  for (int step = 0; step < 50; ++step) motion.advance(0.013);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      EXPECT_NEAR((motion.positions().row(i) - motion.positions().row(j)).norm(),
                  (rest.row(i) - rest.row(j)).norm(), 1e-13);
  // Central difference of positions against the analytic velocity (O(h²) error).
  const double h = 1e-5;
  RigidMotion ahead(rest, def), behind(rest, def);
  ahead.advance(motion.time() + h);
  behind.advance(motion.time() - h);
  const Eigen::MatrixX3d fd = (ahead.positions() - behind.positions()) / (2 * h);
  EXPECT_LT((fd - motion.velocities()).cwiseAbs().maxCoeff(), 1e-7);
}

TEST(RigidMotion, HalfRevolutionAboutZ) {
  RigidMotionDef def;
  def.angularVelocity = {0, 0, 2.0};
  RigidMotion motion(somePoints(), def);
  motion.advance(std::acos(-1.0) / 2.0);  // t = π/2 s at 2 rad/s: half a turn
  EXPECT_NEAR(motion.positions()(1, 0), -1.0, 1e-14);
  EXPECT_NEAR(motion.positions()(1, 1), 0.0, 1e-14);
  EXPECT_NEAR(motion.positions()(2, 1), -2.0, 1e-14);
  EXPECT_NEAR(motion.velocities()(1, 1), -2.0, 1e-13);  // ω × r = 2 ẑ × (−1, 0, 0)
}

TEST(SurfaceMotion, StaticSurfaceStaysAndRejectsBadStep) {
  StaticSurface still(somePoints());
  still.advance(0.5);
  EXPECT_DOUBLE_EQ(still.time(), 0.5);
  EXPECT_EQ((still.positions() - somePoints()).norm(), 0.0);
  EXPECT_THROW(still.advance(0.0), std::invalid_argument);
  EXPECT_THROW(still.advance(std::nan("")), std::invalid_argument);
}

// Which motions change the surface's shape (what sizes a stain's metric
// rebuilds at load): not the static or rigid ones, whatever their state;
// a caller-supplied surface can be anything.
TEST(SurfaceMotion, OnlyStaticAndRigidMotionsKeepTheirShape) {
  StaticSurface still(somePoints());
  RigidMotionDef def;
  def.angularVelocity = {0, 0, 2.0};
  RigidMotion turning(somePoints(), def);
  turning.advance(0.3);
  CallerMotion supplied(somePoints());
  EXPECT_FALSE(still.deforms());
  EXPECT_FALSE(turning.deforms());
  EXPECT_TRUE(supplied.deforms());
}

}  // namespace
}  // namespace blot::cloth
