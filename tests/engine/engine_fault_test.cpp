// Numerical faults in a whole engine step: a NaN after any stage —
// the Bullet cloth, each stain stage, the coupling — stops the step with a
// report naming the stage, the internal step and the vertex, and the engine
// keeps the last good state: the same state hash as before the failed step.
// The faults are real: a 1e30 N·s impulse makes Bullet itself blow up; the
// stain and coupling faults write a NaN where the stage just wrote.
#include <blot/engine/engine.h>

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "bullet_flag_def.h"

namespace blot::engine {
namespace {

constexpr int kDropVertex = kBulletFlagDropVertex;

/// The engine tests' Bullet flag, two-way or one-way, without metric rebuilds
/// in the failing step (its rescaled densities keep each vertex's mass but not
/// the bits: tests/stain/stage_fault_test.cpp), so the kept state can be
/// compared by its hash.
EngineDef flag(coupling::CouplingMode mode) {
  EngineDef def = bulletFlag(mode);
  def.stain.strainTolerance = 0.5;
  return def;
}

/// The same mesh turning rigidly about z (a prescribed motion).
EngineDef spinning() {
  EngineDef def = flag(coupling::CouplingMode::OneWay);
  def.source = MotionSource::Rigid;
  def.rigid.angularVelocity = Eigen::Vector3d(0, 0, 2);
  def.cloth.pins.clear();
  return def;
}

bool sameBits(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

struct Case {
  const char* name;
  EngineDef (*def)();
  const char* stage;
};

EngineDef twoWay() { return flag(coupling::CouplingMode::TwoWay); }
EngineDef oneWay() { return flag(coupling::CouplingMode::OneWay); }

TEST(EngineFault, EachStageFailsNamingItselfAndTheEngineKeepsTheLastGoodState) {
  const Case cases[] = {
      {"two-way flag", twoWay, "cloth"},         {"two-way flag", twoWay, "forces"},
      {"two-way flag", twoWay, "advect-velocity"}, {"two-way flag", twoWay, "coriolis"},
      {"two-way flag", twoWay, "advect-density"}, {"two-way flag", twoWay, "diffuse"},
      {"two-way flag", twoWay, "interact"},      {"two-way flag", twoWay, "coupling"},
      {"one-way flag", oneWay, "cloth"},         {"one-way flag", oneWay, "diffuse"},
      {"spinning patch", spinning, "coriolis"},  {"spinning patch", spinning, "diffuse"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.name) + ", stage " + c.stage);
    Engine engine(c.def());
    ASSERT_EQ(engine.advanceSteps(5).status, stain::StepStatus::Ok);
    const std::uint64_t hash = engine.stateHash();
    const Eigen::MatrixX3d positions = engine.positions();
    const Eigen::MatrixX3d colors = engine.colors();
    stain::Stage stage = stain::Stage::Guard;
    ASSERT_TRUE(stain::parseStage(c.stage, stage));
    engine.injectFaultForTesting({stage, 6, kDropVertex});

    const stain::StepReport r = engine.advanceSteps(3);
    EXPECT_EQ(r.status, stain::StepStatus::NonFinite);
    EXPECT_STREQ(r.stageName(), c.stage) << r.message;
    EXPECT_GE(r.vertex, 0) << r.message;
    if (std::string(c.stage) != "cloth") {
      EXPECT_EQ(r.vertex, kDropVertex);  // (Bullet may spread the cloth's within the step)
    }
    EXPECT_NE(r.message.find("internal step 6"), std::string::npos) << r.message;
    EXPECT_EQ(engine.stepCount(), 5);
    EXPECT_EQ(engine.stateHash(), hash) << "the engine must keep the state of the last good step";
    EXPECT_TRUE(sameBits(engine.positions(), positions));
    EXPECT_TRUE(sameBits(engine.colors(), colors)) << "views show the kept state";
    EXPECT_TRUE(engine.positions().allFinite() && engine.solvent().allFinite());

    // The fault fired once: the engine goes on from the kept state.
    const stain::StepReport again = engine.advanceSteps(5);
    EXPECT_EQ(again.status, stain::StepStatus::Ok) << again.stageName() << ": " << again.message;
    EXPECT_EQ(engine.stepCount(), 10);
    EXPECT_LT(engine.statistics().massBudget.solventError(), 1e-12);
  }
}

TEST(EngineFault, AOneWayClothGoesOnBitIdenticallyAfterARolledBackStep) {
  // One-way: the cloth does not feel the stain, so after the failed step is
  // undone it must follow exactly the path of a run that never failed
  // (BulletCloth::rollBack restores every node to the bit).
  Engine uninterrupted(oneWay());
  ASSERT_EQ(uninterrupted.advanceSteps(12).status, stain::StepStatus::Ok);
  for (const stain::Stage stage : {stain::Stage::Cloth, stain::Stage::Diffuse}) {
    SCOPED_TRACE(stain::stageName(stage));
    Engine engine(oneWay());
    engine.injectFaultForTesting({stage, 6, kDropVertex});
    EXPECT_EQ(engine.advanceSteps(12).status, stain::StepStatus::NonFinite);
    ASSERT_EQ(engine.stepCount(), 5);
    ASSERT_EQ(engine.advanceSteps(7).status, stain::StepStatus::Ok);
    EXPECT_TRUE(sameBits(engine.positions(), uninterrupted.positions()));
  }
}

TEST(EngineFault, BadInjectionsAreRefusedNamingTheProblem) {
  Engine rigid(spinning());
  try {
    rigid.injectFaultForTesting({stain::Stage::Cloth, 1, 0});
    FAIL() << "a prescribed motion has no Bullet cloth to break";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("Bullet"), std::string::npos) << e.what();
  }
  EXPECT_THROW(rigid.injectFaultForTesting({stain::Stage::Coupling, 1, 0}), std::invalid_argument);
  EXPECT_THROW(rigid.injectFaultForTesting({stain::Stage::Geometry, 1, 0}), std::invalid_argument)
      << "only stages that check their output can carry a fault";
  stain::Stage stage = stain::Stage::Guard;
  EXPECT_FALSE(stain::parseStage("difuse", stage));
  EXPECT_THROW(rigid.injectFaultForTesting({stain::Stage::Diffuse, 1, rigid.vertexCount()}), std::invalid_argument);
}

}  // namespace
}  // namespace blot::engine
