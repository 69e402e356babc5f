// Numerical faults inside a stain step: every stage is checked, a
// NaN put in after a stage is reported with that stage, the step and the
// vertex, and the solver keeps the state it had before the step (to the bit,
// with the intrinsic tier it had when the failed step rebuilt the metric).
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "waving_flag_motion.h"

namespace blot::stain {
namespace {

bool sameBits(const Vector& a, const Vector& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }  // NaN too

bool sameState(const StainState& a, const StainState& b) {
  return sameBits(a.solvent, b.solvent) && sameBits(a.solute, b.solute) &&
         sameBits(a.absorbedSolvent, b.absorbedSolvent) && sameBits(a.absorbedSolute, b.absorbedSolute) &&
         sameBits(a.adsorbedSolute, b.adsorbedSolute) && a.velocities.size() == b.velocities.size() &&
         std::memcmp(a.velocities.data(), b.velocities.data(), sizeof(Complex) * static_cast<size_t>(a.velocities.size())) == 0 &&
         sameBits(a.evaporatedSolvent, b.evaporatedSolvent) && sameBits(a.addedSolvent, b.addedSolvent) &&
         sameBits(a.addedSolute, b.addedSolute);
}

struct Scene {
  TriangleMesh mesh = gridMesh(20, 14, 1.0, 0.7);
  SurfaceTopology topology{mesh.faces, static_cast<int>(mesh.vertexPositions.rows())};
  int centre = -1;

  /// Every term on: gravity along the flag, film pressure, Coriolis (the
  /// flag moves), absorption, adsorption, evaporation and a held source. The
  /// default strain tolerance keeps the metric (no rebuild: a rolled-back
  /// state is then bit-identical; with a rebuild it keeps each vertex's mass).
  std::unique_ptr<StainSolver> solver(double strainTolerance = 0.5,
                                      DiffusionSolverChoice diffusion = DiffusionSolverChoice::Auto,
                                      bool anisotropic = false,
                                      IntrinsicRefresh refresh = IntrinsicRefresh::Full) const {
    StainSolverDef def;
    def.diffusionSolver = diffusion;
    def.intrinsicRefresh = refresh;
    def.gravity = Vector3(0.3, -9.8, 0);
    def.switches.filmPressure = true;
    def.liquid.evaporationRate = 0.002;
    def.strainTolerance = strainTolerance;
    const int faces = static_cast<int>(mesh.faces.rows());
    // Anisotropic: 4:1 tensors for both fields, the weft at 30° (every face
    // then lays its weft out in the rebuilt metric).
    FabricField fabric = isotropicFabricField(faces, 1e-3, 1e-3);
    if (anisotropic) {
      fabric.densityTensors = Eigen::RowVector3d(2e-3, 0.0, 5e-4).replicate(faces, 1);
      fabric.velocityTensors = fabric.densityTensors;
      fabric.weftDirections = Eigen::RowVector3d(std::sqrt(3.0) / 2, 0.5, 0.0).replicate(faces, 1);
    }
    auto s = std::make_unique<StainSolver>(topology, mesh.vertexPositions, fabric, def);
    DropDef drop;
    drop.centerVertex = centre;
    drop.radius = 0.15;
    drop.solventMass = 0.02;
    drop.soluteMass = 0.002;
    drop.splashSpeed = 0.2;
    s->addDrop(drop);
    HeldRegion held;
    held.vertices = {centre};
    held.solventDensity = 0.5;
    held.soluteDensity = 0.05;
    s->addHeldRegion(held);
    return s;
  }

  Scene() {
    // The vertex nearest the middle: wet from the first step on.
    Eigen::Index best = 0;
    (mesh.vertexPositions.rowwise() - Eigen::RowVector3d(0.5, 0.35, 0)).rowwise().squaredNorm().minCoeff(&best);
    centre = static_cast<int>(best);
  }
};

constexpr double kH = 0.01;

TEST(StageFault, EveryStageIsCheckedAndNamedAndTheStateIsKept) {
  const Scene scene;
  const char* stages[] = {"forces",         "film-pressure", "advect-velocity", "coriolis",
                          "advect-density", "diffuse",       "interact",        "sources"};
  for (const char* stage : stages) {
    SCOPED_TRACE(stage);
    auto solver = scene.solver();
    for (int k = 1; k <= 3; ++k) ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
    const StainState before = solver->state();
    const double timeBefore = solver->time();
    InjectedFault fault;
    ASSERT_TRUE(parseStage(stage, fault.stage));
    fault.step = 4;
    fault.vertex = scene.centre;
    solver->injectFaultForTesting(fault);

    const StepReport r = solver->step(kH, wavingPositions(scene.mesh, 4 * kH));
    ASSERT_EQ(solver->profile().intrinsicRefreshes, 0);
    EXPECT_EQ(r.status, StepStatus::NonFinite);
    EXPECT_STREQ(r.stageName(), stage) << r.message;
    EXPECT_EQ(r.vertex, scene.centre);
    EXPECT_NE(r.message.find("step 4"), std::string::npos) << r.message;
    EXPECT_TRUE(sameState(solver->state(), before)) << "the state before the failed step must be kept";
    EXPECT_EQ(solver->time(), timeBefore);
    EXPECT_EQ(solver->stepCount(), 3);

    // The fault fired once: the step runs again from the same state.
    solver->restartMotion(wavingPositions(scene.mesh, 3 * kH), RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3));
    const StepReport again = solver->step(kH, wavingPositions(scene.mesh, 4 * kH));
    EXPECT_EQ(again.status, StepStatus::Ok) << again.stageName() << ": " << again.message;
    EXPECT_EQ(solver->stepCount(), 4);
  }
}

// The step's checks scan four vertices at a time (stain_solver.cpp,
// scanFields): a bad value is found in any field, in any of the four lanes
// and in the few vertices past the last group of four. Written from outside,
// it is found by the validation of the whole state before the step runs;
// put in by a stage (the injected fault), by the scan of the band after that
// stage or, outside the band, by the validation of the vertices the step
// changed.
TEST(StageFault, EveryFieldLaneAndTailOfTheScansIsChecked) {
  const Scene scene;
  const int n = static_cast<int>(scene.mesh.vertexPositions.rows());
  ASSERT_NE(n % 4, 0) << "the mesh must leave vertices past the last group of four";
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<int> vertices = {0, 1, 2, 3, n / 2, n / 2 + 1, n - 4, n - 3, n - 2, n - 1};
  // Written from outside into a dry cloth: the validation of the whole state
  // at the step's start finds each field's bad value in each lane and in the
  // tail, before any stage runs (a positive infinite free density would
  // otherwise make its vertex wet and reach the stages).
  {
    auto solver = std::make_unique<StainSolver>(
        scene.topology, scene.mesh.vertexPositions,
        isotropicFabricField(static_cast<int>(scene.mesh.faces.rows()), 1e-3, 1e-3), StainSolverDef{});
    ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, kH)).status, StepStatus::Ok);
    int cases = 0;
    for (int field = 0; field < 7; ++field)
      for (const double bad : {std::nan(""), inf, -inf, -1.0}) {
        if (field >= 5 && bad == -1.0) continue;  // a velocity may be negative
        for (const int v : vertices) {
          SCOPED_TRACE("field " + std::to_string(field) + ", value " + std::to_string(bad) + ", vertex " +
                       std::to_string(v));
          const auto slot = [&](StainState& state) -> double& {
            Vector* densities[] = {&state.solvent, &state.solute, &state.absorbedSolvent, &state.absorbedSolute,
                                   &state.adsorbedSolute};
            return field < 5 ? (*densities[field])[v] : reinterpret_cast<double*>(&state.velocities[v])[field - 5];
          };
          slot(solver->mutableState()) = bad;
          const StainState poisoned = solver->state();
          const StepReport r = solver->step(kH, wavingPositions(scene.mesh, 2 * kH));
          EXPECT_TRUE(r.status == StepStatus::NonFinite || r.status == StepStatus::NegativeMass) << r.message;
          EXPECT_EQ(r.vertex, v) << r.message;
          EXPECT_EQ(r.stage, Stage::Guard) << r.message;
          EXPECT_NE(r.message.find("written outside a step"), std::string::npos) << r.message;
          EXPECT_TRUE(sameState(solver->state(), poisoned));
          ++cases;
          slot(solver->mutableState()) = 0.0;  // the dry cloth's value
          solver->restartMotion(wavingPositions(scene.mesh, kH), RowVectors3::Zero(n, 3));
        }
      }
    EXPECT_EQ(solver->step(kH, wavingPositions(scene.mesh, 2 * kH)).status, StepStatus::Ok);
    EXPECT_EQ(cases, (5 * 4 + 2 * 3) * static_cast<int>(vertices.size()));
  }
  // Put in by a stage, at vertices in and outside the band: the scan of the
  // band after the stage, or the validation of what the step changed.
  auto solver = scene.solver();
  const int steps = 3;
  for (int k = 1; k <= steps; ++k)
    ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
  int inBand = 0, outside = 0;
  for (const int v : vertices) {
    SCOPED_TRACE("injected at vertex " + std::to_string(v));
    const bool banded = solver->band().levels[static_cast<size_t>(v)] >= 0;
    InjectedFault fault;
    fault.stage = Stage::Interact;
    fault.step = steps + 1;
    fault.vertex = v;
    solver->injectFaultForTesting(fault);
    const StainState before = solver->state();
    const StepReport r = solver->step(kH, wavingPositions(scene.mesh, (steps + 1) * kH));
    EXPECT_EQ(r.status, StepStatus::NonFinite);
    EXPECT_EQ(r.vertex, v) << r.message;
    EXPECT_TRUE(sameState(solver->state(), before));
    (banded ? inBand : outside) += 1;
    solver->restartMotion(wavingPositions(scene.mesh, steps * kH), RowVectors3::Zero(n, 3));
  }
  EXPECT_GT(inBand, 0);
  EXPECT_GT(outside, 0);
  EXPECT_EQ(solver->step(kH, wavingPositions(scene.mesh, (steps + 1) * kH)).status, StepStatus::Ok);
  std::printf("[ scans    ] %d vertices: injected faults %d in the band, %d outside it\n", n, inBand, outside);
}

// A NaN or an infinity put in from outside where the diffusion solves (a
// nonzero density is a row of its CG), or a bad value at a held region's
// vertex, which Sources would top up before any later check saw it (−1 or
// −inf of solvent counted as added mass, a NaN velocity scaled by the top-up),
// is refused before the step runs: the report names the vertex, the field
// and its value, or the total; nothing changes, and the step runs once the
// value is mended.
TEST(StageFault, AValueWrittenFromOutsideIsRefusedBeforeTheStepRuns) {
  const Scene scene;
  const int n = static_cast<int>(scene.mesh.vertexPositions.rows());
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  struct Case {
    int vertex;
    const char* expected;
    StepStatus status;
    std::function<void(StainState&)> write;
  };
  const int c = scene.centre;  // wet and held
  const std::vector<Case> cases = {
      {0, "vertex 0 holds solvent = nan", StepStatus::NonFinite, [](StainState& s) { s.solvent[0] = std::nan(""); }},
      {n - 1, "holds solvent = inf", StepStatus::NonFinite, [&](StainState& s) { s.solvent[n - 1] = inf; }},
      {c, "holds solvent = -1", StepStatus::NegativeMass, [&](StainState& s) { s.solvent[c] = -1; }},
      {c, "holds solvent = -inf", StepStatus::NonFinite, [&](StainState& s) { s.solvent[c] = -inf; }},
      {c, "holds solute = -inf", StepStatus::NonFinite, [&](StainState& s) { s.solute[c] = -inf; }},
      {c, "holds velocity (imaginary part) = nan", StepStatus::NonFinite,
       [&](StainState& s) { s.velocities[c] = Complex(0, nan); }},
      {-1, "addedSolvent = nan", StepStatus::NonFinite, [&](StainState& s) { s.addedSolvent = nan; }},
      {-1, "evaporatedSolvent = -0.5", StepStatus::NegativeMass, [&](StainState& s) { s.evaporatedSolvent = -0.5; }},
  };
  for (const Case& k : cases) {
    SCOPED_TRACE(k.expected);
    auto solver = scene.solver();
    for (int step = 1; step <= 2; ++step)
      ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, step * kH)).status, StepStatus::Ok);
    const StainState good = solver->state();
    k.write(solver->mutableState());
    const StainState poisoned = solver->state();
    for (int attempt = 0; attempt < 2; ++attempt) {  // refused again while the value is there
      const StepReport r = solver->step(kH, wavingPositions(scene.mesh, 3 * kH));
      ASSERT_EQ(r.status, k.status) << r.stageName() << ": " << r.message;
      EXPECT_EQ(r.stage, Stage::Guard);
      EXPECT_EQ(r.vertex, k.vertex) << r.message;
      EXPECT_NE(r.message.find(k.expected), std::string::npos) << r.message;
      EXPECT_NE(r.message.find("step 3 not taken"), std::string::npos) << r.message;
      EXPECT_TRUE(sameState(solver->state(), poisoned));
      EXPECT_EQ(solver->stepCount(), 2);
    }
    solver->mutableState() = good;
    const StepReport r = solver->step(kH, wavingPositions(scene.mesh, 3 * kH));
    EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
    EXPECT_EQ(solver->stepCount(), 3);
  }
  std::printf("[ report   ] e.g. %s\n", [&] {
    auto solver = scene.solver();
    solver->step(kH, wavingPositions(scene.mesh, kH));
    solver->mutableState().solvent[scene.centre] = -1;
    return solver->step(kH, wavingPositions(scene.mesh, 2 * kH)).message;
  }().c_str());
}

bool sameTier(const IntrinsicGeometry& a, const IntrinsicGeometry& b) {
  return a.rebuildCount == b.rebuildCount && sameBits(a.edgeLengths, b.edgeLengths) &&
         sameBits(a.vertexDualAreas, b.vertexDualAreas) && sameBits(a.edgeTransportAngles, b.edgeTransportAngles) &&
         a.densityStiffness.nonZeros() == b.densityStiffness.nonZeros() &&
         std::memcmp(a.densityStiffness.valuePtr(), b.densityStiffness.valuePtr(),
                     sizeof(double) * static_cast<size_t>(a.densityStiffness.nonZeros())) == 0 &&
         a.velocityStiffness.nonZeros() == b.velocityStiffness.nonZeros() &&
         std::memcmp(a.velocityStiffness.valuePtr(), b.velocityStiffness.valuePtr(),
                     sizeof(Complex) * static_cast<size_t>(a.velocityStiffness.nonZeros())) == 0;
}

// Strain tolerance 1e-4: the waving flag rebuilds its metric every step, so
// the failing step has already rebuilt the tier and rescaled the densities to
// it. The failure gives back the densities and the tier they were per (to the
// bit, as any failed step: SurfaceGeometry kept the old tier), and the solver
// then goes on bitwise as one that never took the failed step (the tables
// stamped with the abandoned tier's rebuild count forgotten, M + hL
// reassembled). Keeping the new tier and rescaling the densities to it
// would not do: the mass stayed, the bits did not, and a collapsed face
// made every density NaN (docs/reliability.md, finding 10). Both with the
// automatic choice and with direct solves (whose factors are of M + hL as
// assembled, not of the tier).
TEST(StageFault, AFaultAfterAMetricRebuildPutsTheOldMetricBack) {
  for (const DiffusionSolverChoice diffusion : {DiffusionSolverChoice::Auto, DiffusionSolverChoice::Direct}) {
    SCOPED_TRACE(diffusion == DiffusionSolverChoice::Auto ? "auto" : "direct");
    const Scene scene;
    auto solver = scene.solver(1e-4, diffusion);
    auto twin = scene.solver(1e-4, diffusion);
    for (int k = 1; k <= 3; ++k) {
      ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
      ASSERT_EQ(twin->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
    }
    const StainState before = solver->state();
    const IntrinsicGeometry tierBefore = solver->geometry().intrinsic();
    const MassBudget budgetBefore = solver->massBudget();
    InjectedFault fault;
    fault.stage = Stage::Diffuse;
    fault.step = 4;
    fault.vertex = scene.centre;
    solver->injectFaultForTesting(fault);
    const StepReport r = solver->step(kH, wavingPositions(scene.mesh, 4 * kH));
    ASSERT_EQ(r.stage, Stage::Diffuse);
    ASSERT_EQ(solver->profile().intrinsicRefreshes, 1) << "the failed step must have rebuilt the metric";
    EXPECT_TRUE(sameState(solver->state(), before));
    EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), tierBefore));
    EXPECT_EQ(solver->massBudget().freeSolvent, budgetBefore.freeSolvent);
    EXPECT_EQ(solver->massBudget().freeSolute, budgetBefore.freeSolute);

    // Both restart at t = 3h and go on along another motion: first a step on
    // the surface of t (no rebuild: M + hL must be the old tier's), then a
    // bumped waving whose rebuild repeats the abandoned one's count with
    // another metric (tables stamped with that count must not be reused).
    const RowVectors3 still = RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3);
    solver->abandonStep(wavingPositions(scene.mesh, 3 * kH), still);
    twin->restartMotion(wavingPositions(scene.mesh, 3 * kH), still);
    const auto next = [&](int k) {
      RowVectors3 p = wavingPositions(scene.mesh, (k == 4 ? 3 : k) * kH);
      if (k > 4)
        for (Eigen::Index i = 0; i < p.rows(); ++i)
          p(i, 2) += 4e-3 * std::sin(9.0 * scene.mesh.vertexPositions(i, 0)) *
                     std::sin(7.0 * scene.mesh.vertexPositions(i, 1));
      return p;
    };
    for (int k = 4; k <= 6; ++k) {
      ASSERT_EQ(solver->step(kH, next(k)).status, StepStatus::Ok);
      ASSERT_EQ(twin->step(kH, next(k)).status, StepStatus::Ok);
      EXPECT_EQ(solver->profile().intrinsicRefreshes, k == 4 ? 0 : 1);
      EXPECT_TRUE(sameState(solver->state(), twin->state())) << "step " << k;
      EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), twin->geometry().intrinsic())) << "step " << k;
    }
  }
}

// A rebuild on a surface where a face has collapsed (two of its vertices at
// one point, which a Bullet cloth under an absurd load reaches: fuzz_capi,
// finding 10) fails the step at stage Geometry naming the face, before any
// density is divided by its zero area; the state and the tier are kept.
TEST(StageFault, ARebuildOnACollapsedFaceFailsAtGeometryAndKeepsTheTier) {
  const Scene scene;
  auto solver = scene.solver(1e-4);
  for (int k = 1; k <= 3; ++k) ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
  const StainState before = solver->state();
  const IntrinsicGeometry tierBefore = solver->geometry().intrinsic();
  RowVectors3 collapsed = wavingPositions(scene.mesh, 4 * kH);
  const int a = scene.mesh.faces(7, 0), b = scene.mesh.faces(7, 1);
  collapsed.row(a) = collapsed.row(b);
  const StepReport r = solver->step(kH, collapsed);
  EXPECT_EQ(r.status, StepStatus::NonFinite);
  EXPECT_EQ(r.stage, Stage::Geometry);
  EXPECT_NE(r.message.find("intrinsic rebuild of step 4: face "), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("has area 0 m^2 at this step's positions, expected > 0 (the surface collapsed there); "
                           "state restored"),
            std::string::npos)
      << r.message;
  EXPECT_TRUE(sameState(solver->state(), before));
  EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), tierBefore));
  // The surface recovers: the step from t runs.
  solver->abandonStep(wavingPositions(scene.mesh, 3 * kH), RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3));
  const StepReport again = solver->step(kH, wavingPositions(scene.mesh, 4 * kH));
  EXPECT_EQ(again.status, StepStatus::Ok) << again.message;
  EXPECT_EQ(solver->stepCount(), 4);
}

// The same on both fabrics, whole and partial rebuilds, each of the face's
// three corners moved onto the next; then the solver goes on bitwise as a
// twin that never took the failed step, along a moving surface.
// - Anisotropic: laying the weft out in a face with a zero-length edge threw
//   std::invalid_argument out of the step, the geometry half rebuilt (the
//   regression this guards).
// - Both: the rebuild had released M + hL and restoreBackup did not assemble
//   it again, so the restarted solver took its next step for a first step
//   (u in the frames at t) and drifted from the twin (the regression this
//   guards).
TEST(StageFault, ARebuildOnACollapsedFaceGoesOnAsIfTheStepNeverRan) {
  const Scene scene;
  for (const bool anisotropic : {false, true}) {
    for (const IntrinsicRefresh refresh : {IntrinsicRefresh::Full, IntrinsicRefresh::Partial}) {
      for (int corner = 0; corner < 3; ++corner) {
        SCOPED_TRACE(std::string(anisotropic ? "anisotropic" : "isotropic") +
                     (refresh == IntrinsicRefresh::Full ? ", whole" : ", partial") + " rebuild, corner " +
                     std::to_string(corner));
        auto solver = scene.solver(1e-4, DiffusionSolverChoice::Auto, anisotropic, refresh);
        auto twin = scene.solver(1e-4, DiffusionSolverChoice::Auto, anisotropic, refresh);
        for (int k = 1; k <= 3; ++k) {
          ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
          ASSERT_EQ(twin->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
        }
        const StainState before = solver->state();
        const IntrinsicGeometry tierBefore = solver->geometry().intrinsic();
        RowVectors3 collapsed = wavingPositions(scene.mesh, 4 * kH);
        collapsed.row(scene.mesh.faces(7, corner)) = collapsed.row(scene.mesh.faces(7, (corner + 1) % 3));
        StepReport r;
        ASSERT_NO_THROW(r = solver->step(kH, collapsed));
        EXPECT_EQ(r.status, StepStatus::NonFinite);
        EXPECT_EQ(r.stage, Stage::Geometry);
        // Face 7 or a neighbour sharing the two corners: the first collapsed face.
        EXPECT_NE(r.message.find("has area 0 m^2 at this step's positions"), std::string::npos) << r.message;
        EXPECT_TRUE(sameState(solver->state(), before));
        EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), tierBefore));
        const RowVectors3 still = RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3);
        solver->abandonStep(wavingPositions(scene.mesh, 3 * kH), still);
        twin->restartMotion(wavingPositions(scene.mesh, 3 * kH), still);
        for (int k = 4; k <= 7; ++k) {
          const StepReport again = solver->step(kH, wavingPositions(scene.mesh, k * kH));
          ASSERT_EQ(again.status, StepStatus::Ok) << again.message;
          ASSERT_EQ(twin->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
          EXPECT_TRUE(sameState(solver->state(), twin->state())) << "step " << k;
          EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), twin->geometry().intrinsic())) << "step " << k;
        }
      }
    }
  }
}

TEST(StageFault, AbandonStepReturnsToTheStateBeforeTheLastStep) {
  const Scene scene;
  auto solver = scene.solver();
  ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, kH)).status, StepStatus::Ok);
  const StainState before = solver->state();
  const double timeBefore = solver->time();
  ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, 2 * kH)).status, StepStatus::Ok);
  ASSERT_EQ(solver->profile().intrinsicRefreshes, 0);
  ASSERT_FALSE(sameState(solver->state(), before));
  const RowVectors3 still = RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3);
  solver->abandonStep(wavingPositions(scene.mesh, kH), still);
  EXPECT_TRUE(sameState(solver->state(), before));
  EXPECT_EQ(solver->time(), timeBefore);
  EXPECT_EQ(solver->stepCount(), 1);
  solver->abandonStep(wavingPositions(scene.mesh, kH), still);
  EXPECT_TRUE(sameState(solver->state(), before)) << "only the last step is undone, once";
  EXPECT_EQ(solver->stepCount(), 1);
}

// A restore leaves no step to undo: abandonStep right after it changes
// nothing, even when the step before the restore had rebuilt the metric
// (whose kept tier the restore forgot) and succeeded.
TEST(StageFault, AbandonStepRightAfterARestoreChangesNothing) {
  const Scene scene;
  auto solver = scene.solver(1e-4);
  for (int k = 1; k <= 3; ++k) ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, k * kH)).status, StepStatus::Ok);
  const StainSolverSnapshot at3 = solver->snapshot();
  ASSERT_EQ(solver->step(kH, wavingPositions(scene.mesh, 4 * kH)).status, StepStatus::Ok);
  ASSERT_EQ(solver->profile().intrinsicRefreshes, 1);
  solver->restore(at3);
  solver->abandonStep(wavingPositions(scene.mesh, 3 * kH), RowVectors3::Zero(scene.mesh.vertexPositions.rows(), 3));
  EXPECT_TRUE(sameState(solver->state(), at3.state));
  EXPECT_TRUE(sameTier(solver->geometry().intrinsic(), at3.geometry.intrinsic));
  EXPECT_EQ(solver->time(), at3.time);
  EXPECT_EQ(solver->stepCount(), 3);
}

// A small stain on a large, turning cloth: the step changes a small part of
// the state (the band, the CG diffusion's rows beyond it, an absorbed trace
// far away that the interaction dries), its rollback point and validation
// cover only those vertices; a fault after the last stage, or an abandoned
// step, must still give back the whole state to the bit.
struct SmallStain {
  TriangleMesh mesh = gridMesh(60, 60, 1.0, 1.0);
  SurfaceTopology topology{mesh.faces, static_cast<int>(mesh.vertexPositions.rows())};
  int centre = -1;
  int trace = 0;  // a corner, far from the drop: absorbed solvent below the wet threshold

  static Matrix3 rotation(double t) {
    return Eigen::AngleAxisd(1.0 * t, Vector3(0.4, 0.2, 1.0).normalized()).toRotationMatrix();
  }
  RowVectors3 positions(int step) const { return mesh.vertexPositions * rotation(step * kH).transpose(); }

  std::unique_ptr<StainSolver> solver() const {
    StainSolverDef def;
    def.liquid.evaporationRate = 1e-4;
    def.liquid.wetThreshold = 1e-4;
    const int n = static_cast<int>(mesh.vertexPositions.rows());
    auto s = std::make_unique<StainSolver>(
        topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 5e-3, 1e-4), def);
    RowVectors3 velocities(n, 3);
    const Vector3 omega = Vector3(0.4, 0.2, 1.0).normalized();
    for (int i = 0; i < n; ++i) velocities.row(i) = omega.cross(Vector3(mesh.vertexPositions.row(i))).transpose();
    s->setInitialMotion(mesh.vertexPositions, velocities);
    DropDef drop;
    drop.centerVertex = centre;
    drop.radius = 0.05;
    drop.solventMass = 2e-3;
    drop.soluteMass = 2e-4;
    s->addDrop(drop);
    s->mutableState().absorbedSolvent[trace] = 5e-5;
    return s;
  }

  SmallStain() {
    Eigen::Index best = 0;
    (mesh.vertexPositions.rowwise() - Eigen::RowVector3d(0.3, 0.6, 0)).rowwise().squaredNorm().minCoeff(&best);
    centre = static_cast<int>(best);
  }
};

TEST(StageFault, ABandRestrictedStepIsRolledBackToTheBit) {
  const SmallStain scene;
  const int n = static_cast<int>(scene.mesh.vertexPositions.rows());
  for (const char* stage : {"interact", "diffuse", "forces"}) {
    SCOPED_TRACE(stage);
    auto solver = scene.solver();
    for (int k = 1; k <= 4; ++k) ASSERT_EQ(solver->stepRigid(kH, scene.positions(k), SmallStain::rotation(k * kH)).status, StepStatus::Ok);
    // The path under test: a band of a few percent of the mesh, CG rows
    // beyond it, and the trace dried by the interaction.
    const StepProfile& p = solver->profile();
    ASSERT_LT(4 * p.bandVertices, n);
    ASSERT_GT(p.densityDiffusionVertices, p.bandVertices);
    ASSERT_GT(solver->state().absorbedSolvent[scene.trace], 0.0);
    ASSERT_EQ(solver->band().levels[static_cast<size_t>(scene.trace)], -1) << "the trace must lie outside the band";
    const StainState before = solver->state();
    const double traceBefore = before.absorbedSolvent[scene.trace];
    InjectedFault fault;
    ASSERT_TRUE(parseStage(stage, fault.stage));
    fault.step = 5;
    fault.vertex = scene.centre;
    solver->injectFaultForTesting(fault);
    const StepReport r = solver->stepRigid(kH, scene.positions(5), SmallStain::rotation(5 * kH));
    EXPECT_EQ(r.status, StepStatus::NonFinite);
    EXPECT_STREQ(r.stageName(), stage);
    EXPECT_TRUE(sameState(solver->state(), before)) << "the state before the failed step must be kept, every vertex";
    EXPECT_EQ(solver->stepCount(), 4);

    // The step again, then abandoned after it succeeded (a later coupled
    // stage failing): back to the same bits.
    solver->restartMotion(scene.positions(4), RowVectors3::Zero(n, 3));
    ASSERT_EQ(solver->stepRigid(kH, scene.positions(5), SmallStain::rotation(5 * kH)).status, StepStatus::Ok);
    ASSERT_LT(solver->state().absorbedSolvent[scene.trace], traceBefore) << "the interaction did not dry the trace";
    // Densities the CG diffusion carried beyond the band, and the interaction
    // then absorbed there (the free trace may be gone again: absorbed whole).
    int outside = 0;
    const StainState& after = solver->state();
    for (int i = 0; i < n; ++i)
      outside += solver->band().levels[static_cast<size_t>(i)] < 0 &&
                 (after.solvent[i] != before.solvent[i] || after.solute[i] != before.solute[i] ||
                  after.absorbedSolvent[i] != before.absorbedSolvent[i] ||
                  after.absorbedSolute[i] != before.absorbedSolute[i] || after.adsorbedSolute[i] != before.adsorbedSolute[i]);
    ASSERT_GT(outside, 0) << "the diffusion should write beyond the band";
    ASSERT_FALSE(sameState(solver->state(), before));
    solver->abandonStep(scene.positions(4), RowVectors3::Zero(n, 3));
    EXPECT_TRUE(sameState(solver->state(), before)) << "abandonStep after a band-restricted step";
    // And a NaN written from outside (mutableState) far from the liquid is
    // still found by the validation after a step that did not touch it.
    solver->mutableState().adsorbedSolute[n - 1] = std::nan("");
    const StainState poisoned = solver->state();
    const StepReport bad = solver->stepRigid(kH, scene.positions(5), SmallStain::rotation(5 * kH));
    EXPECT_EQ(bad.status, StepStatus::NonFinite);
    EXPECT_EQ(bad.vertex, n - 1);
    EXPECT_TRUE(sameState(solver->state(), poisoned));
  }
}

// The rollback point lists the vertices a step changes until they pass a
// quarter of the mesh, counted once each: the stages list the same band again
// and again, and a band of 15 % of the mesh noted eight times is still a list
// (counting each noting, the second time would make it a full copy). Restore gives back
// exactly the listed vertices.
TEST(StageFault, TheRollbackListCountsEachVertexOnce) {
  const int n = 100;
  StainState state;
  state.resize(n);
  StateBackup backup;
  backup.resize(n);
  backup.commit(state);
  std::vector<int> band(15);
  for (int k = 0; k < 15; ++k) band[static_cast<size_t>(k)] = 3 * k;
  for (int stage = 0; stage < 8; ++stage) backup.note(band.data(), static_cast<int>(band.size()));
  EXPECT_FALSE(backup.all());
  EXPECT_EQ(backup.vertices(), band);
  for (const int i : band) state.solvent[i] = 1.0 + i;
  backup.restore(state);
  EXPECT_EQ(state.solvent.cwiseAbs().maxCoeff(), 0.0) << "the listed vertices are given back";
  // 25 distinct vertices are a list; the 26th makes it a full copy.
  for (int i = 0; i < 25; ++i) backup.note(i);
  EXPECT_FALSE(backup.all());
  backup.note(std::vector<int>{24, 25}.data(), 2);
  EXPECT_TRUE(backup.all());
  state.solute.setConstant(2.0);
  backup.restore(state);
  EXPECT_EQ(state.solute.cwiseAbs().maxCoeff(), 0.0) << "a full restore gives back every vertex";
}

TEST(StageFault, UnknownStagesAndVerticesAreRefused) {
  const Scene scene;
  auto solver = scene.solver();
  Stage stage = Stage::Guard;
  EXPECT_FALSE(parseStage("difuse", stage));
  InjectedFault fault;
  fault.stage = Stage::Cloth;  // not one of the stain's stages
  EXPECT_THROW(solver->injectFaultForTesting(fault), std::invalid_argument);
  fault.stage = Stage::Diffuse;
  fault.vertex = static_cast<int>(scene.mesh.vertexPositions.rows());
  EXPECT_THROW(solver->injectFaultForTesting(fault), std::invalid_argument);
}

}  // namespace
}  // namespace blot::stain
