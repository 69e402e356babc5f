// The liquid the density diffusion moves carries its velocity
// (stages/diffusive_momentum.h, docs/transport.md "Momentum carried by the
// diffusive flux"): liquid pressed against the boundary wall stays bounded
// and never gains more kinetic energy than gravity released; a diffusion
// step conserves the liquid's momentum; a uniform flow is unchanged.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>

#include "stain_fixture.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// u_i in world axes (m/s), frames of the state's time.
Vector3 worldVelocity(const StainSolver& solver, int i) {
  const Matrix3& F = solver.geometry().extrinsic().nextFrames[static_cast<size_t>(i)];
  const Complex u = solver.velocityInCurrentFrame(i);
  return F.col(0) * u.real() + F.col(1) * u.imag();
}

/// A drop of `solvent` and `solute` kg over `radius` m at `centre`, moving at
/// `velocity` (world, m/s).
DropDef dropAt(const Vector3& centre, double radius, double solvent, double solute,
               const Vector3& velocity = Vector3::Zero()) {
  DropDef drop;
  drop.centerPoint = centre;
  drop.radius = radius;
  drop.solventMass = solvent;
  drop.soluteMass = solute;
  drop.velocity = velocity;
  return drop;
}

/// No interaction (the liquid stays free), the term as asked.
StainSolverDef freeLiquid(bool diffusiveMomentum) {
  StainSolverDef def;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  def.switches.diffusiveMomentum = diffusiveMomentum;
  return def;
}

/// The free liquid's mass at vertex i (kg).
double liquidMass(const StainSolver& solver, int i) {
  return solver.geometry().intrinsic().vertexDualAreas[i] * (solver.state().solvent[i] + solver.state().solute[i]);
}

// ------------------------------------------------------ against the wall

struct WallRun {
  double worstEnergyExcess = 0;  ///< max over steps (KE − released potential energy) / released at the end
  double finalSpeed = 0;         ///< max |u| over vertices holding liquid at the end (m/s)
  double energyAtHalf = 0, finalEnergy = 0;  ///< kinetic energy (J) at T/2 and T
  double outwardAtWall = 0;  ///< max over steps of u · (down the slope) at the wall's wet vertices (m/s)
};

/// A drop on a 20 x 20 sheet of 1 m tilted by 30° (a static mesh), its lower
/// edge the wall: the liquid runs down in about 0.6 s and lies against the
/// wall for the rest of T = 5 s. Diffusion on (D = ν = 1e-4 m²/s), no
/// interaction.
WallRun pressedAgainstTheWall(bool diffusiveMomentum) {
  const double alpha = kPi / 6, T = 5.0, h = 0.01;
  TriangleMesh mesh = gridMesh(20, 20, 1.0, 1.0);
  // Tilt about the x axis: y runs down the slope, to the wall at y = 1.
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-alpha, Vector3::UnitX()).toRotationMatrix();
  mesh.vertexPositions = mesh.vertexPositions * tilt.transpose();
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4),
                     freeLiquid(diffusiveMomentum));
  solver.addDrop(dropAt(tilt * Vector3(0.5, 0.5, 0.0), 0.15, 0.05, 0.0));
  const Vector3 down = tilt * Vector3::UnitY();
  const double gAlong = 9.8 * std::sin(alpha);
  const int n = topology.vertexCount();
  const auto measure = [&](double& kinetic, double& travelled) {
    double mass = 0.0, along = 0.0;
    kinetic = 0.0;
    for (int i = 0; i < n; ++i) {
      const double m = liquidMass(solver, i);
      if (m <= 0.0) continue;
      mass += m;
      along += m * mesh.vertexPositions.row(i).dot(down);
      kinetic += 0.5 * m * worldVelocity(solver, i).squaredNorm();
    }
    travelled = along / mass;
    return mass;
  };
  double kinetic = 0.0, start = 0.0;
  const double mass = measure(kinetic, start);
  const int steps = static_cast<int>(std::lround(T / h));
  WallRun run;
  std::vector<double> excess;
  for (int k = 1; k <= steps; ++k) {
    const StepReport r = solver.step(h, mesh.vertexPositions);
    EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
    double travelled = 0.0;
    measure(kinetic, travelled);
    excess.push_back(kinetic - mass * gAlong * (travelled - start));
    // The wall's vertices (rest y = 1) hand on no u that points off the mesh.
    for (int i = 0; i < n; ++i)
      if (std::abs(mesh.vertexPositions.row(i).dot(down) - 1.0) < 1e-9 &&
          solver.state().solvent[i] > solver.definition().liquid.wetThreshold)
        run.outwardAtWall = std::max(run.outwardAtWall, worldVelocity(solver, i).dot(down));
    if (k == steps / 2) run.energyAtHalf = kinetic;
    if (k == steps) {
      run.finalEnergy = kinetic;
      const double released = mass * gAlong * (travelled - start);
      for (const double e : excess) run.worstEnergyExcess = std::max(run.worstEnergyExcess, e / released);
    }
  }
  for (int i = 0; i < n; ++i)
    if (solver.state().solvent[i] > solver.definition().liquid.wetThreshold)
      run.finalSpeed = std::max(run.finalSpeed, worldVelocity(solver, i).norm());
  return run;
}

TEST(DiffusiveMomentum, LiquidPressedAgainstTheWallStopsAndGainsNoEnergy) {
  const double gAlong = 9.8 * std::sin(kPi / 6), T = 5.0;
  const WallRun carried = pressedAgainstTheWall(true);
  const WallRun field = pressedAgainstTheWall(false);
  std::printf("against the wall, 5 s: carried: max |u| %.3f m/s, KE %.3e -> %.3e J, worst (KE - released) / released %.3e\n"
              "                       paper's field u: max |u| %.3f m/s (g sin a t = %.2f), KE %.3e -> %.3e J\n",
              carried.finalSpeed, carried.energyAtHalf, carried.finalEnergy, carried.worstEnergyExcess,
              field.finalSpeed, gAlong * T, field.energyAtHalf, field.finalEnergy);
  // Never more kinetic energy than gravity released (the wall and the
  // diffusions only take it away).
  EXPECT_LE(carried.worstEnergyExcess, 0.0);
  // At rest against the wall: no liquid faster than a fall down the whole
  // sheet would make it, and the energy no longer grows.
  EXPECT_LT(carried.finalSpeed, std::sqrt(2.0 * gAlong * 1.0));
  EXPECT_LE(carried.finalEnergy, carried.energyAtHalf * 1.001);
  // The viscosity and the carried momentum act after the wall; it acts again
  // after them.
  EXPECT_LT(carried.outwardAtWall, 1e-12);
  EXPECT_LT(field.outwardAtWall, 1e-12);
  // Without it (the paper's u as a field of its own) the refilled row next to
  // the wall keeps accelerating: g sin α t, and the energy grows with t².
  EXPECT_GT(field.finalSpeed, 0.9 * gAlong * T);
  EXPECT_GT(field.finalEnergy, 2.0 * field.energyAtHalf);
}

// ------------------------------------------------------------- momentum

struct DiffusionStep {
  double momentumError = 0;  ///< |P⁺ − P| / |P|, the liquid's world momentum over one step
  double largestSpeedBefore = 0, largestSpeedAfter = 0;  ///< max |u| over wet vertices
  StepProfile profile;
};

/// One step of density diffusion alone (direct backward Euler, D = 1e-2 m²/s,
/// h D / ℓ² = 0.09 on a flat 30 x 30 sheet of 1 m) on a drop whose liquid
/// turns and shears: world velocity (0.5 + y, −x, 0).
DiffusionStep diffusionStep(bool diffusiveMomentum) {
  const TriangleMesh mesh = gridMesh(30, 30, 1.0, 1.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  PhysicsSwitches& on = def.switches;
  on.gravity = on.linearInertia = on.coriolis = on.velocityAdvection = on.densityAdvection = false;
  on.velocityDiffusion = on.absorption = on.adsorption = on.evaporation = false;
  on.diffusiveMomentum = diffusiveMomentum;
  def.diffusionSolver = DiffusionSolverChoice::Direct;
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-2, 1e-4), def);
  solver.addDrop(dropAt(Vector3(0.45, 0.5, 0.0), 0.2, 0.01, 0.001));
  const int n = topology.vertexCount();
  StainState& state = solver.mutableState();
  for (int i = 0; i < n; ++i) {
    const Vector3 x = mesh.vertexPositions.row(i).transpose();
    const Vector3 v(0.5 + x.y(), -x.x(), 0.0);
    const Matrix3& F = solver.geometry().extrinsic().nextFrames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(F.col(0).dot(v), F.col(1).dot(v));
  }
  const auto momentum = [&](double& largestSpeed) {
    Vector3 p = Vector3::Zero();
    largestSpeed = 0.0;
    for (int i = 0; i < n; ++i) {
      const double m = liquidMass(solver, i);
      if (m <= 0.0) continue;
      const Vector3 v = worldVelocity(solver, i);
      p += m * v;
      // Liquid below the wet threshold counts as none (its u is the band's).
      if (m > solver.definition().liquid.wetThreshold * solver.geometry().intrinsic().vertexDualAreas[i])
        largestSpeed = std::max(largestSpeed, v.norm());
    }
    return p;
  };
  DiffusionStep run;
  const Vector3 before = momentum(run.largestSpeedBefore);
  const StepReport r = solver.step(0.01, mesh.vertexPositions);
  EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
  const Vector3 after = momentum(run.largestSpeedAfter);
  run.momentumError = (after - before).norm() / before.norm();
  run.profile = solver.profile();
  return run;
}

TEST(DiffusiveMomentum, ADiffusionStepConservesTheLiquidsMomentum) {
  const DiffusionStep carried = diffusionStep(true);
  const DiffusionStep field = diffusionStep(false);
  std::printf("one direct diffusion step: |dP| / |P| carried %.3e, field u %.3e; max |u| %.4f -> %.4f m/s\n",
              carried.momentumError, field.momentumError, carried.largestSpeedBefore, carried.largestSpeedAfter);
  EXPECT_TRUE(carried.profile.ran(StepTerm::DensityDiffusionDirect)) << describeTerms(carried.profile);
  // Exact but for liquid that crossed two edges in the step (each sender's
  // u is the one it had, not the mix it passed on) and the traces' floor:
  // 7.3e-8 when written.
  EXPECT_LT(carried.momentumError, 1e-6);
  // The test can fail: with u a field of its own, the liquid that moved left
  // its momentum behind (1.6e-5, 200 times as much).
  EXPECT_GT(field.momentumError, 50.0 * carried.momentumError);
  // Convex combinations: no liquid gets faster.
  EXPECT_LE(carried.largestSpeedAfter, carried.largestSpeedBefore * (1.0 + 1e-12));
}

// ----------------------------------------------------------- uniform flow

/// A spreading drop coasting at 0.5 m/s along a flat sheet for 0.4 s (its
/// traces stay clear of the wall): max over steps and over vertices holding
/// liquid of |u − v| / |v|.
double uniformFlowSpread(bool diffusiveMomentum) {
  const TriangleMesh mesh = gridMesh(40, 20, 1.4, 0.6);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-4),
                     freeLiquid(diffusiveMomentum));
  const Vector3 v(0.5, 0.0, 0.0);
  solver.addDrop(dropAt(Vector3(0.4, 0.3, 0.0), 0.1, 0.01, 0.001, v));
  double spread = 0.0;
  for (int k = 1; k <= 40; ++k) {
    const StepReport r = solver.step(0.01, mesh.vertexPositions);
    EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
    for (int i = 0; i < topology.vertexCount(); ++i)
      if (liquidMass(solver, i) > 0.0) spread = std::max(spread, (worldVelocity(solver, i) - v).norm() / v.norm());
  }
  return spread;
}

TEST(DiffusiveMomentum, AUniformFlowIsUnchanged) {
  // The liquid the diffusion carries forward and back moves as the rest,
  // traces past the band included (the vertex frames differ from vertex to
  // vertex, so the transports must be right).
  const double carried = uniformFlowSpread(true), field = uniformFlowSpread(false);
  std::printf("uniform flow with diffusion, 40 steps: max |u - v| / |v| = %.3e (u a field of its own: %.3e)\n",
              carried, field);
  EXPECT_LT(carried, 1e-12);
  // Without it, a trace the diffusion carried past the band keeps the u it
  // had there (0): no stage defines it.
  EXPECT_GT(field, 0.5);
}

// ------------------------------------------------------------ moving cloth

/// max over a quarter turn of |P / M| / (ω r₀): the world velocity a drop at
/// rest in the inertial frame gains on a disc (16 rings, 1 m) spinning at
/// 2 rad/s, its liquid spreading fast (D = 1e-2 m²/s), no viscosity, no
/// wall (the rim only windows the film).
double discAtRestDrift(bool diffusiveMomentum) {
  const double omega = 2.0, r0 = 0.5, h = 0.01;
  const TriangleMesh mesh = discMesh(16, 1.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  PhysicsSwitches& on = def.switches;
  on.velocityDiffusion = on.boundaryWall = on.absorption = on.adsorption = on.evaporation = false;
  on.diffusiveMomentum = diffusiveMomentum;
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-2, 1e-4), def);
  const int n = topology.vertexCount();
  const Vector3 w(0, 0, omega);
  solver.setInitialMotion(mesh.vertexPositions, testing::spinVelocities(mesh.vertexPositions, w));
  solver.addDrop(dropAt(Vector3(r0, 0, 0), 0.2, 0.01, 0.0));
  StainState& state = solver.mutableState();
  for (int i = 0; i < n; ++i) {
    const Vector3 relative = -w.cross(Vector3(mesh.vertexPositions.row(i)));
    const Matrix3& F = solver.geometry().extrinsic().frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(F.col(0).dot(relative), F.col(1).dot(relative));
  }
  double drift = 0.0;
  const int steps = static_cast<int>(std::lround(0.5 * kPi / omega / h));
  for (int k = 1; k <= steps; ++k) {
    const Matrix3 R = Eigen::AngleAxisd(omega * k * h, Vector3::UnitZ()).toRotationMatrix();
    const StepReport r = solver.stepRigid(h, mesh.vertexPositions * R.transpose(), R);
    EXPECT_EQ(r.status, StepStatus::Ok) << r.message;
    const ExtrinsicGeometry& ex = solver.geometry().extrinsic();
    Vector3 p = Vector3::Zero();
    double mass = 0.0;
    for (int i = 0; i < n; ++i) {
      const double m = liquidMass(solver, i);
      if (m <= 0.0) continue;
      mass += m;
      p += m * (worldVelocity(solver, i) + (ex.nextPositions.row(i) - ex.positions.row(i)).transpose() / h);
    }
    drift = std::max(drift, (p / mass).norm() / (omega * r0));
  }
  return drift;
}

TEST(DiffusiveMomentum, LiquidAtRestOnASpinningDiscStaysAtRest) {
  // u is relative to the cloth: liquid a flux moves between two vertices
  // whose surface velocities differ takes the difference with it.
  const double carried = discAtRestDrift(true), field = discAtRestDrift(false);
  std::printf("spinning disc, quarter turn, D = 1e-2: world velocity drift %.3e (omega r0), field u %.3e\n",
              carried, field);
  EXPECT_LT(carried, 0.01);
  EXPECT_LT(carried, 1.5 * field + 1e-4);
}

}  // namespace
}  // namespace blot::stain
