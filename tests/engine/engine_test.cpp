// blot::Engine: the accumulator policy, runtime drops (vertex and world point),
// views, statistics, determinism across frame-time splits, and save/load.
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>
#include <blot/stain/content_hash.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/io/mesh_io.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "bullet_flag_def.h"

namespace blot::engine {
namespace {

/// A 0.5 m patch (21 x 21 vertices) centred on the origin, spinning at 2 rad/s
/// about z: inertia, Coriolis, advection, diffusion and interaction all run.
EngineDef rotatingPatch(int resolution = 20) {
  EngineDef def;
  def.mesh = stain::gridMesh(resolution, resolution, 0.5, 0.5);
  def.mesh.vertexPositions.col(0).array() -= 0.25;
  def.mesh.vertexPositions.col(1).array() -= 0.25;
  def.source = MotionSource::Rigid;
  def.rigid.angularVelocity = Eigen::Vector3d(0, 0, 2);
  def.timeStep = 0.01;
  def.stain.liquid.absorptionRate = 0.4;
  TimedDrop drop;
  drop.drop.centerPoint = Eigen::Vector3d(0.08, 0, 0);
  drop.drop.radius = 0.06;
  drop.drop.solventMass = 0.02;
  drop.drop.soluteMass = 0.01;
  def.drops.push_back(drop);
  return def;
}

std::string temporaryPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("blot_engine_test_" + name)).string();
}

/// Two saved files hold the same bytes (and are not empty).
void expectSameNonEmptyFiles(const std::string& a, const std::string& b) {
  const auto bytesOf = [](const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const std::string first = bytesOf(a);
  EXPECT_FALSE(first.empty()) << a;
  EXPECT_TRUE(first == bytesOf(b)) << a << " and " << b << " differ";
}

TEST(EngineTest, InitialDropShowsInTheFirstViewsAndMassIsConserved) {
  Engine engine(rotatingPatch());
  const int n = engine.vertexCount();
  ASSERT_EQ(n, 21 * 21);
  EXPECT_EQ(engine.positions().rows(), n);
  EXPECT_EQ(engine.normals().rows(), n);
  EXPECT_EQ(engine.colors().rows(), n);
  // The drop is applied at construction: the mass budget already holds it, and
  // the stained vertices are darker than the clean cloth.
  EXPECT_NEAR(engine.statistics().massBudget.addedSolvent, 0.02, 1e-15);
  EXPECT_LT(engine.colors().col(1).minCoeff(), 0.9 * engine.colors().col(1).maxCoeff());
  // Normals of the flat patch are ±z, unit.
  EXPECT_NEAR(engine.normals().col(2).cwiseAbs().minCoeff(), 1.0, 1e-12);

  ASSERT_EQ(engine.advanceSteps(20).status, stain::StepStatus::Ok);
  const EngineStatistics s = engine.statistics();
  EXPECT_EQ(s.steps, 20);
  EXPECT_DOUBLE_EQ(s.time, 0.2);
  EXPECT_LT(s.massBudget.solventError(), 1e-12);
  EXPECT_LT(s.massBudget.soluteError(), 1e-12);
  EXPECT_GT(s.totals.stain, 0.0);
  EXPECT_GT(s.stepsPerSecond, 0.0);
  // The liquid view is tangent to the surface (z = 0 on a flat patch).
  EXPECT_LT(engine.liquidVelocities().col(2).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT(engine.liquidVelocities().rowwise().norm().maxCoeff(), 0.0);
}

// Where no free liquid is left (soaked vertices: the fibres hold it), the
// views show liquid moving with the cloth: relative velocity exactly 0, world
// velocity the cloth's own (the spin ω × p, up to the step's chord, ωh/2 off
// the tangent). The stored u of such a vertex is the centripetal kick of its
// last step, not a velocity of any liquid (shown until this change).
TEST(EngineTest, VerticesWithoutFreeLiquidShowLiquidMovingWithTheCloth) {
  Engine engine(rotatingPatch());  // absorption 0.4/s: the drop's thin edge is soaked within a few steps
  ASSERT_EQ(engine.advanceSteps(20).status, stain::StepStatus::Ok);
  int soaked = 0, withFreeLiquid = 0;
  for (int i = 0; i < engine.vertexCount(); ++i) {
    if (engine.solvent()[i] + engine.solute()[i] > 0.0) {
      ++withFreeLiquid;
      continue;
    }
    if (engine.absorbedSolvent()[i] > 0.0) ++soaked;
    EXPECT_EQ(engine.liquidVelocities().row(i).norm(), 0.0) << "vertex " << i;
    const Eigen::Vector3d p = engine.positions().row(i).transpose();
    const Eigen::Vector3d cloth = Eigen::Vector3d(0, 0, 2).cross(p);
    EXPECT_LE((engine.liquidWorldVelocities().row(i).transpose() - cloth).norm(), 0.01 * cloth.norm() + 1e-12)
        << "vertex " << i;
  }
  std::printf("after 20 steps: %d vertices with free liquid, %d soaked without\n", withFreeLiquid, soaked);
  EXPECT_GT(soaked, 10);
  EXPECT_GT(withFreeLiquid, 10);
}

TEST(EngineTest, AccumulatorRunsWholeStepsAndCarriesTheRemainder) {
  Engine engine(rotatingPatch(8));
  EXPECT_EQ(engine.step(0.004).status, stain::StepStatus::Ok);
  EXPECT_EQ(engine.stepCount(), 0);
  EXPECT_NEAR(engine.accumulator(), 0.004, 1e-15);
  engine.step(0.007);  // 0.011: one step, 0.001 carried
  EXPECT_EQ(engine.stepCount(), 1);
  EXPECT_NEAR(engine.accumulator(), 0.001, 1e-12);
  engine.step(0.009);  // exactly 0.01 more: the remainder snaps to zero
  EXPECT_EQ(engine.stepCount(), 2);
  EXPECT_EQ(engine.accumulator(), 0.0);
}

TEST(EngineTest, FrameTimeBeyondTheCapIsDroppedAndReported) {
  EngineDef def = rotatingPatch(8);
  def.maxStepsPerCall = 3;
  Engine engine(def);
  engine.step(0.1);  // ten steps due, three run
  EXPECT_EQ(engine.stepCount(), 3);
  EXPECT_NEAR(engine.statistics().droppedTime, 0.07, 1e-12);
  EXPECT_EQ(engine.accumulator(), 0.0);
}

TEST(EngineTest, VariableFrameTimesWithTheSameTotalGiveIdenticalState) {
  Engine fixed(rotatingPatch());
  Engine variable(rotatingPatch());
  for (int k = 0; k < 12; ++k) fixed.step(0.01);
  // Twelve steps' worth, split unevenly (and in amounts not exact in binary).
  for (double dt : {0.016, 0.004, 0.013, 0.007, 0.0, 0.02, 0.001, 0.029, 0.03}) variable.step(dt);
  EXPECT_EQ(fixed.stepCount(), 12);
  EXPECT_EQ(variable.stepCount(), 12);
  EXPECT_EQ(variable.accumulator(), 0.0);
  EXPECT_EQ(fixed.stateHash(), variable.stateHash());
  EXPECT_EQ((fixed.solvent() - variable.solvent()).cwiseAbs().maxCoeff(), 0.0);
  // And a different sequence of steps does change the hash (the test can fail).
  variable.step(0.01);
  EXPECT_NE(fixed.stateHash(), variable.stateHash());
}

TEST(EngineTest, RuntimeDropLandsAtTheNextInternalStep) {
  EngineDef def = rotatingPatch(10);
  def.drops.clear();
  Engine engine(def);
  stain::DropDef drop;
  drop.centerVertex = 60;
  drop.radius = 0.08;
  drop.solventMass = 0.004;
  drop.soluteMass = 0.001;
  engine.addDrop(drop);
  engine.step(0.0);  // no internal step: nothing applied yet
  EXPECT_EQ(engine.statistics().massBudget.addedSolvent, 0.0);
  engine.step(0.01);
  EXPECT_NEAR(engine.statistics().massBudget.addedSolvent, 0.004, 1e-15);
  EXPECT_NEAR(engine.statistics().massBudget.addedSolute, 0.001, 1e-15);
  EXPECT_EQ(engine.statistics().dropsApplied, 1);
  drop.centerVertex = 10000;
  EXPECT_THROW(engine.addDrop(drop), std::invalid_argument);
}

TEST(EngineTest, WorldPointDropHitsTheNearestSurfacePoint) {
  EngineDef def = rotatingPatch(10);
  def.drops.clear();
  def.source = MotionSource::Static;
  Engine engine(def);
  stain::DropDef drop;
  drop.radius = 0.05;
  // Above the patch: lands straight below, inside a face.
  const SurfaceHit hit = engine.addDropAtPoint(Eigen::Vector3d(0.013, -0.021, 0.3), drop);
  ASSERT_GE(hit.face, 0);
  EXPECT_NEAR(hit.point.x(), 0.013, 1e-14);
  EXPECT_NEAR(hit.point.y(), -0.021, 1e-14);
  EXPECT_NEAR(hit.point.z(), 0.0, 1e-15);
  EXPECT_NEAR(hit.distance, 0.3, 1e-14);
  EXPECT_NEAR(hit.barycentric.sum(), 1.0, 1e-14);
  EXPECT_GE(hit.barycentric.minCoeff(), 0.0);
  // Beyond the edge: lands on the boundary.
  const SurfaceHit edge = engine.nearestSurfacePoint(Eigen::Vector3d(0.4, 0.0, 0.0));
  EXPECT_NEAR(edge.point.x(), 0.25, 1e-14);
  EXPECT_NEAR(edge.distance, 0.15, 1e-14);
  engine.step(0.01);
  EXPECT_NEAR(engine.statistics().massBudget.addedSolvent, drop.solventMass, 1e-15);
}

TEST(EngineTest, ScheduledDropLandsAtItsTime) {
  EngineDef def = rotatingPatch(8);
  def.drops[0].time = 0.05;
  Engine engine(def);
  EXPECT_EQ(engine.statistics().massBudget.addedSolvent, 0.0);
  engine.advanceSteps(5);  // steps starting at t = 0 .. 0.04
  EXPECT_EQ(engine.statistics().massBudget.addedSolvent, 0.0);
  engine.advanceSteps(1);  // starts at t = 0.05
  EXPECT_NEAR(engine.statistics().massBudget.addedSolvent, 0.02, 1e-15);
}

TEST(EngineTest, BadFrameTimeIsAStatusNotAnException) {
  Engine engine(rotatingPatch(4));
  EXPECT_EQ(engine.step(-1.0).status, stain::StepStatus::InvalidArgument);
  EXPECT_EQ(engine.step(std::nan("")).status, stain::StepStatus::InvalidArgument);
  EXPECT_EQ(engine.stepCount(), 0);
}

TEST(EngineTest, BadDefinitionsNameTheField) {
  EngineDef def = rotatingPatch(4);
  def.timeStep = 0;
  try {
    Engine engine(def);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("timeStep"), std::string::npos) << e.what();
  }
  def = rotatingPatch(4);
  def.drops[0].drop.centerVertex = 999;
  try {
    Engine engine(def);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("drops[0]"), std::string::npos) << e.what();
  }
}

TEST(EngineTest, SaveThenLoadContinuesBitIdentically) {
  const std::string path = temporaryPath("rigid.state");
  Engine original(rotatingPatch());
  original.advanceSteps(15);
  // A runtime drop still pending at save time must land after the load, too.
  stain::DropDef drop;
  drop.centerVertex = 100;
  drop.solventMass = 0.003;
  original.addDrop(drop);
  original.step(0.004);  // a carried remainder is part of the state
  original.save(path);
  original.advanceSteps(10);
  original.step(0.016);
  const std::uint64_t expected = original.stateHash();

  Engine restored(rotatingPatch());
  restored.advanceSteps(3);  // whatever it did before is replaced
  restored.load(path);
  EXPECT_EQ(restored.stepCount(), 15);
  EXPECT_NEAR(restored.accumulator(), 0.004, 1e-15);
  restored.advanceSteps(10);
  restored.step(0.016);
  EXPECT_EQ(restored.stepCount(), original.stepCount());
  EXPECT_EQ(restored.stateHash(), expected);
  EXPECT_EQ((restored.positions() - original.positions()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((restored.adsorbedSolute() - original.adsorbedSolute()).cwiseAbs().maxCoeff(), 0.0);
  // And what each saves now, to the byte: a game comparing checkpoints to
  // find a desync must not see one (the restored solver used to mark its
  // liquid as written from outside).
  const std::string originalPath = temporaryPath("rigid_original.state");
  const std::string restoredPath = temporaryPath("rigid_restored.state");
  original.save(originalPath);
  restored.save(restoredPath);
  expectSameNonEmptyFiles(originalPath, restoredPath);
  for (const std::string& file : {path, originalPath, restoredPath}) std::remove(file.c_str());
}

// A static surface restored from a state file: the geometry's still-surface
// shortcut did not resume (restore clears "strain measured", which a rigid
// slot never measures again), so the resumed run re-shifted its buffers every
// step, 10-20 % slower, and its checkpoints differed from the uninterrupted
// run's in the count of unchanged refreshes.
TEST(EngineTest, AStaticSurfaceResumesItsStillShortcutAndSavesTheSameBytes) {
  EngineDef def = rotatingPatch(8);
  def.source = MotionSource::Static;
  const std::string path = temporaryPath("static.state");
  const std::string originalPath = temporaryPath("static_original.state");
  const std::string restoredPath = temporaryPath("static_restored.state");
  Engine original(def);
  ASSERT_EQ(original.advanceSteps(5).status, stain::StepStatus::Ok);
  original.save(path);
  ASSERT_EQ(original.advanceSteps(10).status, stain::StepStatus::Ok);
  original.save(originalPath);
  Engine restored(def);
  restored.load(path);
  ASSERT_EQ(restored.advanceSteps(10).status, stain::StepStatus::Ok);
  restored.save(restoredPath);
  EXPECT_EQ(restored.stateHash(), original.stateHash());
  expectSameNonEmptyFiles(originalPath, restoredPath);
  for (const std::string& file : {path, originalPath, restoredPath}) std::remove(file.c_str());
}

// A cloth accelerating rigidly at a is, for the liquid on it, a still cloth
// under gravity g − a: the same stain to rounding, from the first step on.
// With p(−h) = p(0) − h v(0) the first step's centred acceleration would be
// a / 2: the liquid landing at t = 0 would miss half a kick, a difference of
// 1.5e-2 of the peak density at h = 0.01 that never decays. The rigid motion
// gives its exact p(−h).
TEST(EngineTest, AnAcceleratingClothIsAStillOneUnderShiftedGravityFromTheFirstStep) {
  const Eigen::Vector3d a(2.0, 1.5, -4.0), g(0.0, 0.0, -9.8);
  EngineDef accelerating = rotatingPatch(16);
  accelerating.rigid.angularVelocity.setZero();
  accelerating.rigid.linearAcceleration = a;
  accelerating.stain.gravity = g;
  EngineDef still = accelerating;
  still.source = MotionSource::Static;
  still.stain.gravity = g - a;
  Engine moving(accelerating), resting(still);
  ASSERT_EQ(moving.advanceSteps(40).status, stain::StepStatus::Ok);
  ASSERT_EQ(resting.advanceSteps(40).status, stain::StepStatus::Ok);
  const double peak = resting.absorbedSolvent().maxCoeff();
  ASSERT_GT(peak, 0.0);
  EXPECT_LT((moving.absorbedSolvent() - resting.absorbedSolvent()).cwiseAbs().maxCoeff(), 1e-10 * peak);
  EXPECT_LT((moving.solvent() - resting.solvent()).cwiseAbs().maxCoeff(), 1e-10 * peak);
}

/// A two-way Bullet flag (xz plane) pinned at its two top corners, with a heavy drop.
EngineDef twoWayFlag() { return bulletFlag(coupling::CouplingMode::TwoWay); }

TEST(EngineTest, TwoWayBulletSaveThenLoadContinuesBitIdentically) {
  const std::string path = temporaryPath("bullet.state");
  Engine original(twoWayFlag());
  original.advanceSteps(12);
  original.save(path);
  original.advanceSteps(12);
  Engine restored(twoWayFlag());
  restored.load(path);
  restored.advanceSteps(12);
  EXPECT_EQ(restored.stateHash(), original.stateHash());
  EXPECT_EQ((restored.positions() - original.positions()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((restored.solvent() - original.solvent()).cwiseAbs().maxCoeff(), 0.0);
  // The cloth really moved after the save (the comparison is not vacuous).
  EXPECT_GT((original.positions() - original.definition().mesh.vertexPositions).cwiseAbs().maxCoeff(), 1e-4);
  std::remove(path.c_str());
}

// Two engines built alike in one process give the same bits, also when the
// second one reuses heap memory the first one freed (a read of uninitialised
// scratch would show up here as a different hash).
TEST(EngineTest, EnginesBuiltAlikeInOneProcessAgree) {
  std::uint64_t first = 0;
  {
    Engine warmUp(rotatingPatch(24));
    warmUp.advanceSteps(10);
    Engine engine(twoWayFlag());
    engine.advanceSteps(24);
    first = engine.stateHash();
  }
  Engine again(twoWayFlag());
  again.advanceSteps(24);
  EXPECT_EQ(again.stateHash(), first);
}

/// writeBendingSequence's folder: this process's (ctest runs two tests that
/// write it at once).
std::filesystem::path bendingSequenceFolder() {
  return std::filesystem::temp_directory_path() / ("blot_engine_sequence_" + std::to_string(::getpid()));
}

/// Three frames of a 6 x 6 patch bending upward, written as OBJ files, and a
/// scene playing them at 10 frames/s with a drop; returns the scene's path.
std::filesystem::path writeBendingSequence() {
  const std::filesystem::path dir = bendingSequenceFolder();
  std::filesystem::create_directories(dir);
  const stain::TriangleMesh grid = stain::gridMesh(6, 6, 0.5, 0.5);
  for (int k = 0; k < 3; ++k) {
    std::ofstream obj(dir / ("f_" + std::to_string(k) + ".obj"));
    obj.precision(17);
    for (Eigen::Index i = 0; i < grid.vertexPositions.rows(); ++i) {
      const double x = grid.vertexPositions(i, 0);
      obj << "v " << x << " " << grid.vertexPositions(i, 1) << " " << 0.2 * k * x * x << "\n";
    }
    for (Eigen::Index f = 0; f < grid.faces.rows(); ++f)
      obj << "f " << grid.faces(f, 0) + 1 << " " << grid.faces(f, 1) + 1 << " " << grid.faces(f, 2) + 1 << "\n";
  }
  std::ofstream scene(dir / "s.json");
  scene << R"({"mesh": {"file": "f_0.obj"}, "cloth": {"source": "sequence", "pattern": "f_%d.obj", "frame_rate": 10},
               "time_step": 0.01, "drops": [{"vertex": 24, "radius": 0.1, "solvent_mass": 0.002}]})";
  return dir / "s.json";
}

TEST(EngineTest, MeshSequenceSceneMovesAndSavesBitIdentically) {
  const std::filesystem::path scene = writeBendingSequence();
  const std::string path = temporaryPath("sequence.state");
  std::unique_ptr<Engine> original = Engine::fromSceneFile(scene.string());
  original->advanceSteps(7);
  original->save(path);
  original->advanceSteps(9);
  EXPECT_GT(original->positions().col(2).maxCoeff(), 0.001);  // the surface bent
  std::unique_ptr<Engine> restored = Engine::fromSceneFile(scene.string());
  restored->load(path);
  restored->advanceSteps(9);
  EXPECT_EQ(restored->stateHash(), original->stateHash());
  std::remove(path.c_str());
  std::filesystem::remove_all(bendingSequenceFolder());
}

TEST(EngineTest, LoadingAnotherMeshsStateNamesTheMismatch) {
  const std::string path = temporaryPath("mismatch.state");
  Engine small(rotatingPatch(8));
  small.advanceSteps(2);
  small.save(path);
  Engine large(rotatingPatch(10));
  const std::uint64_t before = large.stateHash();
  try {
    large.load(path);
    FAIL() << "no error";
  } catch (const StateFileError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find("81 vertices"), std::string::npos) << message;
    EXPECT_NE(message.find("121 vertices"), std::string::npos) << message;
  }
  EXPECT_EQ(large.stateHash(), before);  // unchanged on error

  // Same sizes, different rest shape: the fingerprint catches it.
  EngineDef moved = rotatingPatch(8);
  moved.mesh.vertexPositions.col(2).array() += 0.1;
  Engine other(moved);
  try {
    other.load(path);
    FAIL() << "no error";
  } catch (const StateFileError& e) {
    EXPECT_NE(std::string(e.what()).find("fingerprint"), std::string::npos) << e.what();
  }

  // Truncated file.
  {
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  try {
    small.load(path);
    FAIL() << "no error";
  } catch (const StateFileError& e) {
    EXPECT_NE(std::string(e.what()).find("cut short"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

// A tampered state file is refused with a message naming the file and the
// field before anything reaches CHOLMOD, Bullet or the engine: corrupt sparse
// index arrays (a segfault inside CHOLMOD before), NaN densities, negative or
// inconsistent step counts, an endless stream. The engine is unchanged.
TEST(EngineTest, TamperedStateFilesAreRefusedBeforeAnythingIsBuilt) {
  const std::string path = temporaryPath("tampered.state");
  Engine engine(rotatingPatch(8));
  engine.advanceSteps(3);
  engine.save(path);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto find = [&](const void* pattern, std::size_t size) {
    const auto at = bytes.find(std::string(static_cast<const char*>(pattern), size));
    EXPECT_NE(at, std::string::npos);
    return at;
  };
  const auto errorOfLoading = [&](const std::string& tampered) {
    {
      std::ofstream out(path, std::ios::binary | std::ios::trunc);
      out.write(tampered.data(), static_cast<std::streamsize>(tampered.size()));
    }
    Engine target(rotatingPatch(8));
    const std::uint64_t before = target.stateHash();
    std::string message;
    try {
      target.load(path);
    } catch (const StateFileError& e) {
      message = e.what();
    }
    EXPECT_EQ(target.stateHash(), before);
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    return message;
  };
  // A poked file with its checksum recomputed (what a writer with a bug
  // would produce): the fields' own checks must refuse it.
  const auto seal = [](std::string& file) {
    std::uint64_t checksum = stain::kContentHashBasis;
    stain::hashBytes(checksum, file.data(), file.size() - sizeof checksum);
    std::memcpy(&file[file.size() - sizeof checksum], &checksum, sizeof checksum);
  };
  const auto poke = [&](std::size_t at, const auto& value) {
    std::string tampered = bytes;
    std::memcpy(&tampered[at], &value, sizeof value);
    seal(tampered);
    return tampered;
  };
  // The header: magic, version, source, #V, #F, fingerprint, h, then the step count.
  constexpr std::size_t kSteps = 8 + 4 + 4 + 8 + 8 + 8 + 8;
  // Unsealed, any changed byte is refused by the checksum first: a flipped
  // bit in the middle of a density is a finite state of another run.
  {
    std::string flipped = bytes;
    flipped[bytes.size() / 2] ^= 0x04;
    EXPECT_NE(errorOfLoading(flipped).find("checksum mismatch"), std::string::npos);
    std::string cut = bytes.substr(0, bytes.size() - 3);
    EXPECT_NE(errorOfLoading(cut).find("checksum mismatch"), std::string::npos);
  }
  EXPECT_NE(errorOfLoading(poke(kSteps, std::int64_t(-5))).find("step count -5 is outside [0, 2^52]"), std::string::npos);
  EXPECT_NE(errorOfLoading(poke(kSteps, std::int64_t(30))).find("stain step count 3 differs from the engine's 30"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(kSteps + 8, std::nan(""))).find("engine.accumulator is not finite"), std::string::npos);

  // A NaN and a negative density in the stain's solvent field.
  const stain::Vector& solvent = engine.surface().stain().state().solvent;
  Eigen::Index wettest = 0;
  solvent.maxCoeff(&wettest);
  const double largest = solvent[wettest];
  const std::size_t density = find(&largest, sizeof largest);
  EXPECT_NE(errorOfLoading(poke(density, std::nan(""))).find("solvent: entry " + std::to_string(wettest) + " of 81 is not finite"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(density, -largest)).find("state.solvent[" + std::to_string(wettest) + "] = "),
            std::string::npos);
  // The velocity is stored complex: a NaN in its real part loaded, and every
  // step after it failed.
  const stain::ComplexVector& velocities = engine.surface().stain().state().velocities;
  Eigen::Index fastest = 0;
  velocities.cwiseAbs().maxCoeff(&fastest);
  const std::complex<double> velocity = velocities[fastest];
  ASSERT_NE(velocity.real(), 0.0);
  const std::size_t u = find(&velocity, sizeof velocity);
  EXPECT_NE(errorOfLoading(poke(u, std::nan(""))).find("velocities: entry " + std::to_string(fastest) + " of 81 is not finite"),
            std::string::npos);

  // The density stiffness matrix: rows, cols, nnz, column pointers, row indices, values.
  const stain::SparseMatrix& stiffness = engine.surface().stain().geometry().intrinsic().densityStiffness;
  const std::int64_t header[3] = {81, 81, stiffness.nonZeros()};
  const std::size_t matrix = find(header, sizeof header);
  const std::size_t outer = matrix + sizeof header, inner = outer + 4 * 82;
  EXPECT_NE(errorOfLoading(poke(inner + 4 * 5, std::int32_t(1 << 30))).find("corrupt sparse matrix densityStiffness: column"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(inner, std::int32_t(-1))).find("has row index -1 (entry 0)"), std::string::npos);
  EXPECT_NE(errorOfLoading(poke(outer + 4 * 10, std::int32_t(0))).find("column pointer 10 (0) is below"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(outer + 4 * 81, std::int32_t(7))).find("column pointers run from 0 to 7"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(matrix + 16, std::int64_t(1) << 40)).find("bad shape of densityStiffness"),
            std::string::npos);
  EXPECT_NE(errorOfLoading(poke(inner + 4 * stiffness.nonZeros(), std::numeric_limits<double>::infinity()))
                .find("densityStiffness: entry 0 is not finite"),
            std::string::npos);

  // Not a file, or an endless one: refused by the byte budget, not by bad_alloc.
  Engine target(rotatingPatch(8));
  try {
    target.load("/dev/zero");
    ADD_FAILURE() << "/dev/zero loaded";
  } catch (const StateFileError& e) {
    // 1 MiB + 16 KiB for each of the 81 vertices and 128 faces.
    EXPECT_NE(std::string(e.what()).find("/dev/zero: the state file has more than the limit of 4472832 bytes"),
              std::string::npos)
        << e.what();
  }
  std::remove(path.c_str());
}

// A pattern used in its own units (no patch diffusivity) is a diffusivity in
// m²/s: pair coefficients of 1e20 loaded, then failed at the first step's
// factorization (NotPositiveDefinite). Held to a scene's range at construction.
TEST(EngineTest, APatternOutsideTheDiffusivityRangeIsRefusedAtConstruction) {
  const std::string pattern = temporaryPath("huge_pattern.json");
  std::ofstream(pattern) << R"({"cells": ["WF", "FW"], "pair_coefficients": {"WW": 1e20, "FF": 1e20, "FW": 1e20}})";
  const std::string json = R"({"mesh": {"patch": {"size": [0.1, 0.1], "resolution": [6, 6]}},
    "cloth": {"source": "static"}, "fabric": {"patches": [{"pattern": ")" + pattern + R"("}]}})";
  try {
    Engine::fromSceneJson(json);
    ADD_FAILURE() << "a 1e20 m^2/s pattern was taken";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("EngineDef.fabricPatches[0]: a mean diffusivity of 1e+20 m^2/s (the "
                                         "pattern's own units), outside [1e-12, 1e6]"),
              std::string::npos)
        << e.what();
  }
  std::remove(pattern.c_str());
}

// A weft normal to the cloth is named as the scene wrote it: the patch's
// "weft" (which the engine holds on every face), or the constraint's index
// in "weft_constraints" as JSON counts it.
TEST(EngineTest, AWeftNormalToTheClothIsNamedAsTheSceneWroteIt) {
  const auto errorOf = [](const std::string& patch) {
    const std::string json = R"({"mesh": {"patch": {"size": [1, 1], "resolution": [4, 4]}}, "cloth": {"source": "static"},
      "fabric": {"patches": [{"tensor": [[2e-4, 0], [0, 1e-4]], )" + patch + "}]}}";
    try {
      Engine::fromSceneJson(json);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string weft = errorOf(R"("weft": [0, 0, 1])");
  EXPECT_NE(weft.find("patch \"fabric.patches[0]\": weft: direction (0, 0, 1) has no component in the plane of face 0"),
            std::string::npos)
      << weft;
  const std::string constraint =
      errorOf(R"("weft_constraints": [{"face": 3, "direction": [1, 0, 0]}, {"face": 5, "direction": [0, 0, -2]}])");
  EXPECT_NE(constraint.find("weft_constraints[1]: direction (0, 0, -2) has no component in the plane of face 5"),
            std::string::npos)
      << constraint;
}

TEST(EngineTest, BuildsFromSceneJsonWithFabricPatches) {
  const std::string json = R"({
    "mesh": {"patch": {"size": [0.4, 0.4], "resolution": [12, 12]}},
    "cloth": {"source": "static"},
    "fabric": {"viscosity": 0.001, "patches": [{"preset": "twill-2-1", "diffusivity": 0.005, "weft": [1, 0, 0]}]},
    "time_step": 0.01,
    "drops": [{"point": [0, 0, 0.2], "radius": 0.08, "solvent_mass": 0.01, "solute_mass": 0.004}]})";
  std::unique_ptr<Engine> engine = Engine::fromSceneJson(json);
  EXPECT_EQ(engine->vertexCount(), 13 * 13);
  // trace / 2 of every face's density tensor is the requested diffusivity.
  const stain::FabricField& fabric = engine->surface().stain().geometry().fabric();
  EXPECT_NEAR(0.5 * (fabric.densityTensors(0, 0) + fabric.densityTensors(0, 2)), 0.005, 1e-12);
  EXPECT_NE(fabric.densityTensors(0, 0), fabric.densityTensors(0, 2));  // anisotropic
  engine->advanceSteps(10);
  EXPECT_LT(engine->statistics().massBudget.soluteError(), 1e-12);
}

TEST(EngineTest, FabricGivesTheWeftOfPatternedFacesAndNoneOnIsotropicOnes) {
  const std::string json = R"({
    "mesh": {"patch": {"size": [0.4, 0.4], "resolution": [8, 8]}},
    "cloth": {"source": "static"},
    "fabric": {"patches": [{"tensor": [[0.005, 0], [0, 0.001]], "weft": [1, 1, 0]}]},
    "time_step": 0.01})";
  std::unique_ptr<Engine> engine = Engine::fromSceneJson(json);
  const stain::FabricField& fabric = engine->fabric();
  ASSERT_EQ(fabric.weftDirections.rows(), engine->faces().rows());
  const Eigen::Vector3d diagonal = Eigen::Vector3d(1, 1, 0).normalized();
  for (int f = 0; f < fabric.weftDirections.rows(); ++f)  // flat patch: the constraint everywhere, up to sign
    EXPECT_NEAR(std::abs(fabric.weftDirections.row(f).dot(diagonal)), 1.0, 1e-9) << "face " << f;
  const stain::FabricField& used = engine->surface().stain().geometry().fabric();  // the field the stain runs on
  EXPECT_TRUE(fabric.weftDirections == used.weftDirections);
  EXPECT_TRUE(fabric.densityTensors == used.densityTensors);

  EngineDef isotropic = rotatingPatch(6);
  Engine plain(isotropic);
  EXPECT_EQ(plain.fabric().weftDirections.rows(), plain.faces().rows());
  EXPECT_EQ(plain.fabric().weftDirections.cwiseAbs().maxCoeff(), 0.0);
}

TEST(EngineTest, StatisticsCountTheStepsEachTermRanIn) {
  Engine engine(rotatingPatch());
  ASSERT_EQ(engine.advanceSteps(20).status, stain::StepStatus::Ok);
  const auto& ran = engine.statistics().totals.termSteps;
  const auto steps = [&](stain::StepTerm term) {
    for (int k = 0; k < stain::kStepTermCount; ++k)
      if (static_cast<unsigned>(term) == 1u << k) return ran[static_cast<size_t>(k)];
    return std::int64_t{-1};
  };
  // Spinning and wet every step: frames, inertia, Coriolis, transport, the
  // film's pressure and friction (the default model) and absorption each ran
  // 20 times; sources (none) never.
  EXPECT_EQ(steps(stain::StepTerm::RigidFrames), 20);
  EXPECT_EQ(steps(stain::StepTerm::LinearInertia), 20);
  EXPECT_EQ(steps(stain::StepTerm::Coriolis), 20);
  EXPECT_EQ(steps(stain::StepTerm::DensityAdvection), 20);
  EXPECT_EQ(steps(stain::StepTerm::Absorption), 20);
  EXPECT_EQ(steps(stain::StepTerm::FilmPressure), 20);
  EXPECT_EQ(steps(stain::StepTerm::FilmFriction), 20);
  EXPECT_EQ(steps(stain::StepTerm::Sources), 0);
  EXPECT_EQ(steps(stain::StepTerm::IntrinsicRebuild), 0) << "a rigid motion keeps the metric";
}

// A caller-supplied surface (MotionSource::Caller) fed, step by step, the
// positions and velocities of a mesh-sequence player reproduces the engine
// that plays the same sequence itself: the whole state hash (surface, every
// density and velocity, time) is equal after every step.
TEST(EngineTest, CallerSuppliedFramesReproduceAMeshSequenceRunBitIdentically) {
  std::unique_ptr<Engine> sequenceRun = Engine::fromSceneFile(writeBendingSequence().string());
  const EngineDef& played = sequenceRun->definition();
  const cloth::FrameReader read = [](const std::string& path, Eigen::MatrixX3d& positions, Eigen::MatrixX3i& faces) {
    stain::TriangleMesh frame = stain::loadMesh(path);
    positions = std::move(frame.vertexPositions);
    faces = std::move(frame.faces);
  };
  cloth::MeshSequence player(played.sequence, read);  // the caller's own animation
  EngineDef def = played;
  def.source = MotionSource::Caller;
  def.callerInitialVelocities = player.velocities();
  Engine callerRun(def);
  ASSERT_EQ(callerRun.stateHash(), sequenceRun->stateHash());
  for (int k = 1; k <= 25; ++k) {
    player.advance(def.timeStep);
    callerRun.setSurfaceFrame(player.positions(), &player.velocities());
    ASSERT_EQ(callerRun.advanceSteps(1).status, stain::StepStatus::Ok);
    ASSERT_EQ(sequenceRun->advanceSteps(1).status, stain::StepStatus::Ok);
    ASSERT_EQ(callerRun.stateHash(), sequenceRun->stateHash()) << "step " << k;
  }
  EXPECT_GT(callerRun.positions().col(2).maxCoeff(), 0.001);  // the surface moved
  // and carries the stain (free or absorbed: the drop is absorbed completely
  // around step 24, so the free part alone depends on the diffusion scheme)
  EXPECT_GT(callerRun.solvent().sum() + callerRun.absorbedSolvent().sum(), 0.0);
  // Without velocities the finite difference is used, and a step without a
  // frame holds the surface still.
  const Eigen::MatrixX3d before = callerRun.positions();
  ASSERT_EQ(callerRun.advanceSteps(1).status, stain::StepStatus::Ok);
  EXPECT_EQ(callerRun.positions(), before);
  Eigen::MatrixX3d lifted = before;
  lifted.col(2).array() += 0.001;
  callerRun.setSurfaceFrame(lifted);
  ASSERT_EQ(callerRun.advanceSteps(1).status, stain::StepStatus::Ok);
  EXPECT_NEAR(callerRun.surface().motion().velocities()(0, 2), 0.001 / def.timeStep, 1e-9);
  // Bad frames name the problem; other sources refuse frames.
  EXPECT_THROW(callerRun.setSurfaceFrame(Eigen::MatrixX3d::Zero(3, 3)), std::invalid_argument);
  lifted(4, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(callerRun.setSurfaceFrame(lifted), std::invalid_argument);
  lifted(4, 1) = 1e300;  // finite, but no scene's: it failed later as a collapsed face
  try {
    callerRun.setSurfaceFrame(lifted);
    ADD_FAILURE() << "a 1e300 m frame was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("must be at most 1e6 in size"), std::string::npos) << e.what();
  }
  EXPECT_THROW(sequenceRun->setSurfaceFrame(before), std::invalid_argument);
  std::filesystem::remove_all(bendingSequenceFolder());
}

// A pin moved at runtime drags its node there within one internal step and
// holds it; the cloth follows (the node below the pin moves the same way),
// the same calls give the same bits, and a save taken after the move
// continues bit-identically.
TEST(EngineTest, PinMovedAtRuntimeDragsTheClothDeterministically) {
  const std::string path = temporaryPath("moved_pin.state");
  const int pin = 16 * 17, below = 15 * 17;  // the top-left corner and the vertex under it
  Engine still(twoWayFlag()), moved(twoWayFlag()), again(twoWayFlag());
  for (Engine* e : {&still, &moved, &again}) ASSERT_EQ(e->advanceSteps(20).status, stain::StepStatus::Ok);
  const Eigen::Vector3d target = moved.positions().row(pin).transpose() + Eigen::Vector3d(0.1, 0.2, 0.05);
  moved.setPinTarget(pin, target);
  again.setPinTarget(pin, target);
  ASSERT_EQ(moved.advanceSteps(1).status, stain::StepStatus::Ok);
  EXPECT_LT((moved.positions().row(pin).transpose() - target).norm(), 1e-6);  // float rounding
  moved.save(path);
  for (Engine* e : {&still, &moved}) ASSERT_EQ(e->advanceSteps(40).status, stain::StepStatus::Ok);
  ASSERT_EQ(again.advanceSteps(41).status, stain::StepStatus::Ok);
  EXPECT_LT((moved.positions().row(pin).transpose() - target).norm(), 1e-6) << "held at the target";
  // The cloth followed toward +y (out of the flag's plane); the unmoved one did not.
  const double followed = moved.positions()(below, 1) - still.positions()(below, 1);
  EXPECT_GT(followed, 0.1);
  EXPECT_EQ(again.stateHash(), moved.stateHash());
  Engine restored(twoWayFlag());
  restored.load(path);
  ASSERT_EQ(restored.advanceSteps(40).status, stain::StepStatus::Ok);
  EXPECT_EQ(restored.stateHash(), moved.stateHash());
  std::remove(path.c_str());
  // Not a pin, not finite, not a Bullet cloth: named errors.
  EXPECT_THROW(moved.setPinTarget(below, target), std::invalid_argument);
  EXPECT_THROW(moved.setPinTarget(pin, Eigen::Vector3d(0, std::nan(""), 0)), std::invalid_argument);
  Engine rigid(rotatingPatch(6));
  EXPECT_THROW(rigid.setPinTarget(0, target), std::invalid_argument);
}

// A pin target past what Bullet's floats hold (1e39) was accepted; the step
// failed and its rollback, restoring that target with the rest, failed too,
// leaving NaN positions, a state every later step refused, and a checkpoint
// the library would not load. Targets past a scene's magnitudes are refused
// and the engine steps on as before.
TEST(EngineTest, APinTargetBeyondASceneMagnitudeIsRefusedAndChangesNothing) {
  const int pin = 16 * 17;
  Engine engine(twoWayFlag()), reference(twoWayFlag());
  ASSERT_EQ(engine.advanceSteps(3).status, stain::StepStatus::Ok);
  ASSERT_EQ(reference.advanceSteps(3).status, stain::StepStatus::Ok);
  for (const double far : {1e300, 1e39, 2e6}) {
    try {
      engine.setPinTarget(pin, Eigen::Vector3d(far, 0, 0.5));
      ADD_FAILURE() << far << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("within 1e+06 m"), std::string::npos) << e.what();
    }
  }
  ASSERT_EQ(engine.advanceSteps(3).status, stain::StepStatus::Ok);
  ASSERT_EQ(reference.advanceSteps(3).status, stain::StepStatus::Ok);
  EXPECT_EQ(engine.stateHash(), reference.stateHash());
}

// The definition's time step, rigid motion and a Bullet cloth's gravity are
// held to a scene's ranges, and a drop's splash speed to a scene's bound, each
// refused with the field's name (before, 1e300 rad/s was reported as "non-finite
// rest position", Bullet gravity -1e39 failed every step, a 1e300 m/s splash
// failed every step after it was queued).
TEST(EngineTest, DefinitionsBeyondASceneRangeNameTheField) {
  const auto errorOf = [](const EngineDef& def) {
    try {
      Engine engine(def);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  for (const double h : {1e300, 2.0, 1e-7, -1e-9}) {
    EngineDef def = rotatingPatch(4);
    def.timeStep = h;
    EXPECT_NE(errorOf(def).find("EngineDef.timeStep must be in [1e-06, 1] s, got"), std::string::npos) << h;
  }
  EngineDef spin = rotatingPatch(4);
  spin.rigid.angularVelocity = Eigen::Vector3d(0, 0, 1e300);
  EXPECT_NE(errorOf(spin).find("EngineDef.rigid.angularVelocity = (0, 0, 1e+300)"), std::string::npos) << errorOf(spin);
  EngineDef far = rotatingPatch(4);
  far.mesh.vertexPositions(3, 1) = 2.5e39;
  EXPECT_NE(errorOf(far).find("EngineDef.mesh.vertexPositions[3]"), std::string::npos) << errorOf(far);
  EngineDef queue = rotatingPatch(4);
  queue.dropQueueCapacity = 2000000000;  // reserved up front: it ended in bad_alloc
  EXPECT_NE(errorOf(queue).find("EngineDef.dropQueueCapacity must be in [0, 1000000], got 2000000000"),
            std::string::npos)
      << errorOf(queue);
  EngineDef dark = rotatingPatch(4);
  dark.colors.soluteAbsorbance[1] = std::numeric_limits<double>::infinity();
  EXPECT_NE(errorOf(dark).find("EngineDef.colors.soluteAbsorbance = (0.77, inf, 2.4): each channel must be in [0, 1000000]"),
            std::string::npos)
      << errorOf(dark);
  EngineDef heavy = twoWayFlag();
  heavy.stain.gravity = Eigen::Vector3d(0, 0, -1e39);
  EXPECT_NE(errorOf(heavy).find("EngineDef.stain.gravity = (0, 0, -1e+39)"), std::string::npos)
      << errorOf(heavy);
  Engine engine(rotatingPatch(4));
  stain::DropDef drop;
  drop.centerVertex = 3;
  drop.splashSpeed = 1e300;
  try {
    engine.addDrop(drop);
    ADD_FAILURE() << "a 1e300 m/s splash was queued";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("splashSpeed must be finite and at most 1000000"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(engine.advanceSteps(2).status, stain::StepStatus::Ok);
  const stain::StepReport negative = engine.advanceSteps(-5);  // returned Ok before
  EXPECT_EQ(negative.status, stain::StepStatus::InvalidArgument);
  EXPECT_NE(negative.message.find("count -5 is negative"), std::string::npos) << negative.message;
  EXPECT_EQ(engine.stepCount(), 2);
}

// Per-engine threads: the two-way flag gives the same bits with 1 and 2
// threads (adaptive, the default, and every step on both), and two engines
// with different counts stepped in turn in one process give the
// single-engine results.
TEST(EngineTest, TwoWayFlagIsBitIdenticalForOneAndTwoThreadsAndTwoEngines) {
  auto run = [](int threads, bool adaptive) {
    Engine engine(twoWayFlag());
    EXPECT_TRUE(engine.adaptiveThreads());
    engine.setThreadCount(threads);
    engine.setAdaptiveThreads(adaptive);
    EXPECT_EQ(engine.advanceSteps(30).status, stain::StepStatus::Ok);
    return engine.stateHash();
  };
  const std::uint64_t one = run(1, true), two = run(2, true);
  EXPECT_EQ(one, two);
  EXPECT_EQ(run(2, false), one);
  Engine a(twoWayFlag()), b(twoWayFlag());
  a.setThreadCount(1);
  b.setThreadCount(2);
  for (int k = 0; k < 30; ++k) {
    ASSERT_EQ(a.advanceSteps(1).status, stain::StepStatus::Ok);
    ASSERT_EQ(b.advanceSteps(1).status, stain::StepStatus::Ok);
  }
  EXPECT_EQ(a.stateHash(), one);
  EXPECT_EQ(b.stateHash(), two);
  EXPECT_EQ(a.threadCount(), 1);
  EXPECT_EQ(b.threadCount(), 2);
}

// The derived views (normals, liquid velocities, colours) are computed when
// first read after a step. Reading them after every step or never must leave
// the simulation bit-identical, the views read late must equal those read on
// time, and readers on several threads must all see the same complete values.
TEST(EngineTest, ViewsReadEveryStepOrNeverLeaveTheStateBitIdentical) {
  Engine reader(twoWayFlag()), skipper(twoWayFlag());
  Eigen::MatrixX3d normals, velocities, worldVelocities, colors;
  for (int k = 0; k < 30; ++k) {
    ASSERT_EQ(reader.step(1.0 / 60).status, stain::StepStatus::Ok);
    ASSERT_EQ(skipper.step(1.0 / 60).status, stain::StepStatus::Ok);
    normals = reader.normals();
    velocities = reader.liquidVelocities();
    worldVelocities = reader.liquidWorldVelocities();
    colors = reader.colors();
  }
  EXPECT_EQ(skipper.stateHash(), reader.stateHash());
  EXPECT_GT(reader.liquidVelocities().rowwise().norm().maxCoeff(), 0.0);  // liquid is moving
  // The band the step fitted is a part of the flag: the views fit the rest.
  const int band = skipper.statistics().lastProfile.geometryVertices;
  std::printf("last step: %d of %d vertices fitted by the step\n", band, skipper.vertexCount());
  EXPECT_LT(band, skipper.vertexCount());

  std::vector<std::thread> threads;
  std::vector<Eigen::MatrixX3d> seen(4);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&skipper, &seen, t] {
      seen[static_cast<size_t>(t)] = t % 2 == 0 ? skipper.normals() : skipper.liquidWorldVelocities();
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (int t = 0; t < 4; ++t) EXPECT_EQ(seen[static_cast<size_t>(t)], t % 2 == 0 ? normals : worldVelocities) << t;
  EXPECT_EQ(skipper.normals(), normals);
  EXPECT_EQ(skipper.liquidVelocities(), velocities);
  EXPECT_EQ(skipper.liquidWorldVelocities(), worldVelocities);
  EXPECT_EQ(skipper.colors(), colors);
  // Reading them changed nothing that a later step sees.
  for (int k = 0; k < 10; ++k) {
    ASSERT_EQ(reader.step(1.0 / 60).status, stain::StepStatus::Ok);
    ASSERT_EQ(skipper.step(1.0 / 60).status, stain::StepStatus::Ok);
  }
  EXPECT_EQ(skipper.stateHash(), reader.stateHash());
}

}  // namespace
}  // namespace blot::engine

// The fuzz_state target (tests/fuzz/state_fuzz.cpp) compiled into this test, so
// its oracle replays the seed corpus in the normal and the sanitized builds.
#include "../fuzz/state_fuzz.cpp"

namespace blot::engine {
namespace {

// A fuzz_state input (tests/fuzz/state_fuzz.cpp): its first byte chooses the
// engine, the rest is a state file. Reads `input`, writes that state file to
// `scratch` and returns the whole input; the engine is
// stateFuzzEngine(bytes) below.
std::string writeStateFuzzInputAsStateFile(const std::filesystem::path& input, const std::string& scratch) {
  std::ifstream in(input, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() >= 2)
    std::ofstream(scratch, std::ios::binary | std::ios::trunc).write(bytes.data() + 1, static_cast<std::streamsize>(bytes.size() - 1));
  return bytes;
}

EngineDef stateFuzzEngine(const std::string& bytes) {
  return fuzz::stateFuzzEngineDef(static_cast<unsigned char>(bytes[0]) % fuzz::kStateFuzzEngineCount);
}

// The seeds of fuzz_state are saved states of its engines: every one must
// still load (a format change makes them stale, and the fuzzer would then
// spend its time on the header). BLOT_UPDATE_FUZZ_SEEDS=1 rewrites them.
TEST(StateFuzzCorpus, EverySeedLoadsAndPassesTheFuzzOracle) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(BLOT_TEST_DATA_DIR) / ".." / "fuzz" / "corpus" / "state";
  const std::string scratch = (fs::temp_directory_path() / "blot_state_fuzz_seed.state").string();
  if (std::getenv("BLOT_UPDATE_FUZZ_SEEDS") != nullptr) {
    fs::create_directories(folder);
    for (const auto& [name, bytes] : fuzz::stateFuzzSeeds(scratch))
      std::ofstream(folder / name, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  int files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    // The seed as a state file, loaded into a fresh engine of its kind.
    const std::string bytes = writeStateFuzzInputAsStateFile(entry.path(), scratch);
    ASSERT_GE(bytes.size(), 2u) << entry.path();
    ++files;
    Engine engine(stateFuzzEngine(bytes));
    EXPECT_NO_THROW(engine.load(scratch)) << entry.path() << ": stale seed; rerun with BLOT_UPDATE_FUZZ_SEEDS=1";
    // And through the fuzz target's own checks (they abort on a finding).
    LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    // Every truncation of it is refused with a message naming the file.
    for (std::size_t cut : {std::size_t(1), bytes.size() / 3, bytes.size() / 2, bytes.size() - 1})
      LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), cut);
  }
  std::remove(scratch.c_str());
  EXPECT_EQ(files, 3 * fuzz::kStateFuzzEngineCount);
}

// Inputs the fuzzer found (tests/fuzz/regressions/state), replayed through its
// checks in every test build, the sanitized one included: each must now be
// refused with a message naming the file, the engine untouched.
TEST(StateFuzzRegressions, EveryFindingIsRefusedWithTheEngineUntouched) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(BLOT_TEST_DATA_DIR) / ".." / "fuzz" / "regressions" / "state";
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  const std::string scratch = (fs::temp_directory_path() / "blot_state_fuzz_regression.state").string();
  int files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string bytes = writeStateFuzzInputAsStateFile(entry.path(), scratch);
    ASSERT_GE(bytes.size(), 2u) << entry.path();
    ++files;
    Engine engine(stateFuzzEngine(bytes));
    const std::uint64_t before = engine.stateHash();
    try {
      engine.load(scratch);
      ADD_FAILURE() << entry.path() << " loaded";
    } catch (const StateFileError& error) {
      EXPECT_EQ(std::string(error.what()).rfind(scratch + ": ", 0), 0u) << error.what();
      // Refused for what the finding was, not by the version check alone:
      // after a format change the files are converted (docs/reliability.md).
      EXPECT_EQ(std::string(error.what()).find("state file version"), std::string::npos)
          << entry.path() << ": " << error.what();
    }
    EXPECT_EQ(engine.stateHash(), before) << entry.path();
    LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  std::remove(scratch.c_str());
  EXPECT_GE(files, 1);
}

}  // namespace
}  // namespace blot::engine
