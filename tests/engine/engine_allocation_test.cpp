// The game-loop contract: Engine::step allocates no heap memory after the
// first call, for static, rigid and Bullet (two-way) sources. The Bullet scene
// has no colliders: Bullet allocates contact lists when contacts appear, which
// a cloth without colliders never has (docs/scene-format.md says so). It also
// raises the strain tolerance, so that it measures the steps without a metric
// rebuild (this Bullet flag strains 1-4 % per step: at 1e-3 it rebuilds on
// most steps) and checks that none happened; MetricRebuildsAllocateNothing
// measures the steps that rebuild.
#include <blot/engine/engine.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>

#include <string>
#include <tuple>

#include "allocation_counter.h"  // counts every allocation while gCountAllocations is set

namespace blot::engine {
namespace {

EngineDef patchWithDrop(MotionSource source) {
  EngineDef def;
  def.mesh = stain::gridMesh(24, 24, 0.6, 0.6);
  def.source = source;
  def.timeStep = 0.01;
  def.rigid.angularVelocity = Eigen::Vector3d(0, 0.5, 2);
  def.rigid.pivot = Eigen::Vector3d(0.3, 0.3, 0);
  if (source == MotionSource::Bullet) {
    // A flag hanging in the xz plane, pinned at its two top corners.
    def.mesh.vertexPositions.col(2) = def.mesh.vertexPositions.col(1);
    def.mesh.vertexPositions.col(1).setZero();
    def.cloth.pins = {{24 * 25, {}}, {24 * 25 + 24, {}}};
    def.coupling = coupling::CouplingMode::TwoWay;
    def.stain.strainTolerance = 0.5;
  }
  TimedDrop drop;
  drop.drop.centerVertex = 12 * 25 + 12;
  drop.drop.radius = 0.12;
  drop.drop.solventMass = 0.03;
  drop.drop.soluteMass = 0.01;
  def.drops.push_back(drop);
  return def;
}

long allocationsOverSteps(Engine& engine) {
  // Uneven frame times: whole steps, carried remainders and idle calls all
  // go through the same path.
  const double frames[] = {0.01, 0.016, 0.004, 0.0, 0.033, 0.017, 0.01, 0.02};
  gAllocations = 0;
  gCountAllocations = true;
  for (int repeat = 0; repeat < 3; ++repeat)
    for (double dt : frames) engine.step(dt);
  gCountAllocations = false;
  return gAllocations.load();
}

// Each source with one and with two engine threads: an OpenMP region that
// runs on one thread allocates in libgomp (stain/src/numerics/threads.h), so a
// one-thread engine is where a stray region shows.
class EngineAllocationTest : public ::testing::TestWithParam<std::tuple<MotionSource, int>> {};

TEST_P(EngineAllocationTest, StepAllocatesNothingAfterTheFirstCall) {
  if (!kCountsAllocations) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const MotionSource source = std::get<0>(GetParam());
  Engine engine(patchWithDrop(source));
  engine.setThreadCount(std::get<1>(GetParam()));
  ASSERT_EQ(engine.step(0.01).status, stain::StepStatus::Ok);  // the first call may allocate
  const std::int64_t before = engine.stepCount();
  EXPECT_EQ(allocationsOverSteps(engine), 0);
  EXPECT_EQ(engine.stepCount() - before, 33);  // 0.33 s of frames at h = 0.01
  EXPECT_GT(engine.statistics().lastProfile.wetVertices, 0);  // the stain was live throughout
  EXPECT_EQ(engine.statistics().intrinsicRefreshes, 0);
  if (source != MotionSource::Static) {
    EXPECT_GT(engine.liquidVelocities().rowwise().norm().maxCoeff(), 0.0);  // inertia acted
  }
}

// A deforming cloth rebuilds its metric (the strain past a tolerance of
// 1e-3, on most steps): the steps that rebuild allocate nothing either. (The
// first call may already rebuild; that the very first rebuild allocates
// nothing once prepared is SurfaceGeometry's test.)
TEST(EngineAllocation, MetricRebuildsAllocateNothing) {
  if (!kCountsAllocations) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  EngineDef def = patchWithDrop(MotionSource::Bullet);
  def.stain.strainTolerance = 1e-3;
  for (const int threads : {1, 2}) {
    Engine engine(def);
    engine.setThreadCount(threads);
    ASSERT_EQ(engine.step(0.01).status, stain::StepStatus::Ok);  // the first call may allocate
    const std::int64_t rebuildsBefore = engine.statistics().intrinsicRefreshes;
    EXPECT_EQ(allocationsOverSteps(engine), 0) << threads << " threads";
    EXPECT_GE(engine.statistics().intrinsicRefreshes - rebuildsBefore, 10) << threads << " threads";
    EXPECT_GT(engine.statistics().lastProfile.wetVertices, 0);
  }
}

INSTANTIATE_TEST_SUITE_P(Sources, EngineAllocationTest,
                         ::testing::Combine(::testing::Values(MotionSource::Static, MotionSource::Rigid,
                                                              MotionSource::Bullet),
                                            ::testing::Values(1, 2)),
                         [](const ::testing::TestParamInfo<std::tuple<MotionSource, int>>& param) {
                           return std::string(motionSourceName(std::get<0>(param.param))) + "_" +
                                  std::to_string(std::get<1>(param.param)) + "_threads";
                         });

}  // namespace
}  // namespace blot::engine
