// The whole stain step on moving surfaces: conservation on a deforming mesh,
// positivity under strong anisotropy, the rotating-disc experiment of paper
// Fig. 5 (Coriolis on/off), determinism, and failure handling.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "same_bits.h"
#include "waving_flag_motion.h"

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(StainSolver, ConservesMassOnADeformingMeshWithStrongAnisotropy) {
  const TriangleMesh mesh = gridMesh(24, 16, 1.2, 0.8);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  FabricField fabric = isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-3);
  // Eigenvalue ratio 1e6 with the weft at 30° to the grid: the raw implicit
  // solve is not an M-matrix and would create negative densities.
  fabric.densityTensors.col(0).setConstant(1e-2);
  fabric.densityTensors.col(2).setConstant(1e-8);
  for (int f = 0; f < mesh.faces.rows(); ++f) fabric.weftDirections.row(f) << std::cos(kPi / 6), std::sin(kPi / 6), 0;
  StainSolverDef def;
  def.liquid.evaporationRate = 0.002;
  StainSolver solver(topology, mesh.vertexPositions, fabric, def);
  DropDef drop;
  drop.centerPoint = Vector3(0.6, 0.4, 0);
  drop.radius = 0.15;
  drop.solventMass = 0.02;
  drop.soluteMass = 0.002;
  drop.splashSpeed = 0.3;
  drop.splashSeed = 7;
  solver.addDrop(drop);

  const double h = 0.01;
  int refreshes = 0;
  double worstNegative = 0;
  for (int n = 1; n <= 1000; ++n) {
    const StepReport r = solver.step(h, wavingPositions(mesh, n * h));
    ASSERT_EQ(r.status, StepStatus::Ok) << r.stageName() << ": " << r.message;
    refreshes += solver.profile().intrinsicRefreshes;
    const StainState& s = solver.state();
    const double scale = std::max(s.solvent.maxCoeff(), s.solute.maxCoeff());
    for (const Vector* f : {&s.solvent, &s.solute, &s.absorbedSolvent, &s.absorbedSolute, &s.adsorbedSolute})
      worstNegative = std::min(worstNegative, f->minCoeff() / scale);
  }
  const MassBudget b = solver.massBudget();
  std::printf("deforming flag, 1000 steps: %d intrinsic rebuilds, solute error %.3g, solvent error %.3g, "
              "evaporated %.3g of %.3g kg, worst negative %.3g x max\n",
              refreshes, b.soluteError(), b.solventError(), b.evaporatedSolvent, b.addedSolvent, worstNegative);
  EXPECT_GT(refreshes, 0) << "the waving flag must trip the strain test";
  EXPECT_LT(b.soluteError(), 1e-12);
  EXPECT_LT(b.solventError(), 1e-12);
  EXPECT_GE(worstNegative, -1e-12);
}

/// Paper Fig. 5: liquid released at rest in the inertial frame on a disc
/// rotating at 2 rad/s. In the disc's frame its relative velocity is −ω × x;
/// in the inertial frame the blob must stay where it was released.
double inertialDriftOverHalfTurn(bool coriolis) {
  const double radius = 1.0, omega = 2.0, h = 0.01;
  const TriangleMesh mesh = discMesh(64, radius);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  def.switches.densityDiffusion = false;
  def.switches.velocityDiffusion = false;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  def.switches.coriolis = coriolis;
  def.gravity = Vector3(0, 0, -9.8);  // normal to the disc: no tangential part
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4), def);

  const int n = static_cast<int>(mesh.vertexPositions.rows());
  RowVectors3 velocities(n, 3);
  const Vector3 w(0, 0, omega);
  for (int i = 0; i < n; ++i) velocities.row(i) = w.cross(Vector3(mesh.vertexPositions.row(i))).transpose();
  solver.setInitialMotion(mesh.vertexPositions, velocities);
  DropDef drop;
  drop.centerPoint = Vector3(0.5, 0, 0);
  drop.radius = 0.12;
  drop.solventMass = 0.01;
  drop.soluteMass = 0.001;
  solver.addDrop(drop);
  // Relative velocity of inertially resting liquid, in each vertex frame.
  StainState& s = solver.mutableState();
  for (int i = 0; i < n; ++i) {
    const Vector3 rel = -w.cross(Vector3(mesh.vertexPositions.row(i)));
    const Matrix3& F = solver.geometry().extrinsic().frames[static_cast<size_t>(i)];
    s.velocities[i] = Complex(F.col(0).dot(rel), F.col(1).dot(rel));
  }
  const auto centroid = [&](const RowVectors3& positions) {
    const Vector m = solver.state().solvent.cwiseProduct(solver.geometry().intrinsic().vertexDualAreas);
    return Vector3((positions.transpose() * m) / m.sum());
  };
  const Vector3 start = centroid(mesh.vertexPositions);
  const int steps = static_cast<int>(std::round(kPi / omega / h));  // half a revolution
  RowVectors3 positions;
  for (int k = 1; k <= steps; ++k) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(omega * k * h, Vector3::UnitZ()).toRotationMatrix();
    positions = mesh.vertexPositions * R.transpose();
    const StepReport r = solver.step(h, positions);
    EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
  }
  // After step(h, p(t+h)) the stain is at t + h: measure on those positions.
  const Vector3 end = centroid(solver.geometry().extrinsic().nextPositions);
  return (end - start).norm() / radius;
}

TEST(StainSolver, RotatingDiscCoriolisKeepsTheInertialPath) {
  const double withCoriolis = inertialDriftOverHalfTurn(true);
  const double withoutCoriolis = inertialDriftOverHalfTurn(false);
  std::printf("rotating disc, half a turn at 2 rad/s: inertial drift %.4f R with Coriolis, %.4f R without\n",
              withCoriolis, withoutCoriolis);
  EXPECT_LT(withCoriolis, 0.02);
  EXPECT_GT(withoutCoriolis, 0.1);
}

// The thread count is the solver's setting: two solvers with 1 and 2 threads
// stepped alternately on one thread give the same bits, and neither leaves
// its count in the caller's OpenMP setting. 12,321 vertices, half wet, so the
// geometry, force and advection regions run threaded (above their
// thresholds; the CG's 16K-row chunks: KrylovDiffusion tests). ~1-2 s.
// The thread tests' sheet: 12,321 vertices, with a moving drop over half of it.
struct ThreadTestSheet {
  TriangleMesh mesh = gridMesh(110, 110, 1.0, 1.0);
  SurfaceTopology topology{mesh.faces, static_cast<int>(mesh.vertexPositions.rows())};
  FabricField fabric = isotropicFabricField(static_cast<int>(mesh.faces.rows()), 2e-4, 2e-4);

  std::unique_ptr<StainSolver> wetSolver(const StainSolverDef& def) const {
    auto solver = std::make_unique<StainSolver>(topology, mesh.vertexPositions, fabric, def);
    DropDef drop;
    drop.centerPoint = Vector3(0.5, 0.5, 0);
    drop.radius = 0.4;
    drop.solventMass = 0.05;
    drop.soluteMass = 0.005;
    drop.velocity = Vector3(0.05, 0.02, 0);
    solver->addDrop(drop);
    return solver;
  }
};

TEST(StainSolver, ThreadCountIsPerSolverAndResultsAreBitIdenticalForOneAndTwoThreads) {
  const ThreadTestSheet sheet;
  const TriangleMesh& mesh = sheet.mesh;
  StainSolverDef one, two;
  one.threads = 1;
  two.threads = 2;
  two.adaptiveThreads = false;  // every step on two threads (the adaptive choice is tested below)
  const auto solverA = sheet.wetSolver(one), solverB = sheet.wetSolver(two);
  StainSolver &a = *solverA, &b = *solverB;
  EXPECT_EQ(a.threadCount(), 1);
  EXPECT_EQ(b.threadCount(), 2);
  const int caller = omp_get_max_threads();
  for (int n = 1; n <= 8; ++n) {
    const RowVectors3 next = wavingPositions(mesh, n * 0.01);
    ASSERT_TRUE(a.step(0.01, next).ok());
    EXPECT_EQ(omp_get_max_threads(), caller) << "a step must restore the caller's setting";
    ASSERT_TRUE(b.step(0.01, next).ok());
    EXPECT_EQ(omp_get_max_threads(), caller);
  }
  EXPECT_GT(b.profile().densityDiffusionVertices, 0);
  const StainState& s = a.state();
  const StainState& t = b.state();
  EXPECT_TRUE(testing::sameBits(s, t));
  EXPECT_THROW(a.setThreadCount(-1), std::invalid_argument);
  StainSolverDef bad;
  bad.threads = -2;
  EXPECT_THROW(StainSolver(sheet.topology, mesh.vertexPositions, sheet.fabric, bad), std::invalid_argument);
}

// Adaptive threads (the default): the first steps probe two threads and one
// alternately (the first pair always; the rest depends on this machine's
// timings), each step's profile says which it used, and the bits are those of
// a one-thread solver whatever the choice.
TEST(StainSolver, AdaptiveThreadsProbeBothCountsAndChangeNoBit) {
  const ThreadTestSheet sheet;
  const TriangleMesh& mesh = sheet.mesh;
  StainSolverDef one, adaptive;
  one.threads = 1;
  adaptive.threads = 2;
  ASSERT_TRUE(adaptive.adaptiveThreads);
  const auto solverA = sheet.wetSolver(one), solverB = sheet.wetSolver(adaptive);
  StainSolver &a = *solverA, &b = *solverB;
  const int caller = omp_get_max_threads();
  int used[2] = {0, 0};
  for (int n = 1; n <= ThreadChoice::kProbeSteps + 4; ++n) {
    const RowVectors3 next = wavingPositions(mesh, n * 0.01);
    ASSERT_TRUE(a.step(0.01, next).ok());
    EXPECT_EQ(a.profile().threads, 1);
    const int planned = b.stepThreads();
    ASSERT_TRUE(b.step(0.01, next).ok());
    EXPECT_EQ(b.profile().threads, planned);
    EXPECT_EQ(omp_get_max_threads(), caller);
    if (n <= 2) {
      EXPECT_EQ(planned, n == 1 ? 2 : 1) << "step " << n;
    }
    ASSERT_TRUE(planned == 1 || planned == 2);
    ++used[planned - 1];
  }
  EXPECT_GE(used[0], 1);
  EXPECT_GE(used[1], 1);
  EXPECT_EQ(b.threadCount(), 2);  // the most it may use, whatever it chose
  const StainState& s = a.state();
  const StainState& t = b.state();
  EXPECT_TRUE(testing::sameBits(s, t));
  // Switched off, every step uses the count.
  b.setAdaptiveThreads(false);
  for (int n = 1; n <= 3; ++n) {
    ASSERT_TRUE(b.step(0.01, wavingPositions(mesh, (ThreadChoice::kProbeSteps + 4 + n) * 0.01)).ok());
    EXPECT_EQ(b.profile().threads, 2);
  }
}

TEST(StainSolver, TwoRunsAreBitIdentical) {
  const TriangleMesh mesh = gridMesh(16, 12, 1.0, 0.75);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const auto run = [&]() {
    StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 2e-3, 1e-3), StainSolverDef{});
    DropDef drop;
    drop.centerVertex = 100;
    drop.radius = 0.2;
    drop.splashSpeed = 0.5;
    drop.splashSeed = 3;
    solver.addDrop(drop);
    for (int n = 1; n <= 100; ++n) EXPECT_EQ(solver.step(0.01, wavingPositions(mesh, n * 0.01)).status, StepStatus::Ok);
    return solver.state();
  };
  const StainState a = run(), b = run();
  const auto same = [](const auto& x, const auto& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), sizeof(x[0]) * static_cast<size_t>(x.size())) == 0;
  };
  EXPECT_TRUE(same(a.solvent, b.solvent));
  EXPECT_TRUE(same(a.solute, b.solute));
  EXPECT_TRUE(same(a.absorbedSolvent, b.absorbedSolvent));
  EXPECT_TRUE(same(a.adsorbedSolute, b.adsorbedSolute));
  EXPECT_TRUE(same(a.velocities, b.velocities));
}

TEST(StainSolver, RejectsBadStepWithoutTouchingTheState) {
  const TriangleMesh mesh = gridMesh(4, 4, 1.0, 1.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-3), StainSolverDef{});
  DropDef drop;
  drop.centerVertex = 12;
  drop.radius = 0.3;
  solver.addDrop(drop);
  const Vector before = solver.state().solvent;
  EXPECT_EQ(solver.step(0.0, mesh.vertexPositions).status, StepStatus::InvalidArgument);
  EXPECT_EQ(solver.step(std::nan(""), mesh.vertexPositions).status, StepStatus::InvalidArgument);
  // NaN, ±inf and a negative NaN in any coordinate (the guard reads the
  // exponent bits).
  for (const double bad : {std::nan(""), -std::nan(""), HUGE_VAL, -HUGE_VAL}) {
    for (const int column : {0, 2}) {
      RowVectors3 broken = mesh.vertexPositions;
      broken(3, column) = bad;
      EXPECT_EQ(solver.step(0.01, broken).status, StepStatus::InvalidArgument) << bad << " in column " << column;
    }
  }
  EXPECT_EQ(solver.stepCount(), 0);
  EXPECT_TRUE(solver.state().solvent == before);
}

}  // namespace
}  // namespace blot::stain
