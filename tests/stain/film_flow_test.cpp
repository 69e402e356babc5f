// The liquid as a thin viscous film (stages/film_flow.h, docs/transport.md
// "The liquid film"): the Nusselt velocity of a uniform film under a body
// force, a lake at rest in a bowl that stays at rest, and liquid in a basin
// that settles instead of accelerating without bound (the paper's form,
// without friction or pressure, shown failing in the same basin).
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stages/film_flow.h>
#include <blot/stain/stain_solver.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.8;

/// No interaction, the film terms on, the rest as the paper has them.
StainSolverDef filmDef() {
  StainSolverDef def;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  applyPhysicsModel(PhysicsModel::Film, def.switches, def.liquid);
  def.geometryVertices = VertexRefresh::AllVertices;
  return def;
}

/// A grid of `cells` x `cells` over [-half, half]², lifted onto the
/// paraboloid z = r²/(2R): a bowl, normals up (into the liquid's side).
TriangleMesh bowlMesh(int cells, double half, double radius) {
  TriangleMesh mesh = gridMesh(cells, cells, 2 * half, 2 * half);
  for (int i = 0; i < mesh.vertexPositions.rows(); ++i) {
    const double x = mesh.vertexPositions(i, 0) - half, y = mesh.vertexPositions(i, 1) - half;
    mesh.vertexPositions.row(i) = Vector3(x, y, (x * x + y * y) / (2 * radius)).transpose();
  }
  return mesh;
}

// ------------------------------------------------ the Nusselt film

/// Steady depth-averaged velocity of a film of thickness H on a slope α with
/// slip length λ: a H (H + 3λ)/(3ν), a = g sin α (Nusselt 1916 for λ = 0).
double nusselt(double alpha, double H, double nu, double lambda) {
  return kG * std::sin(alpha) * H * (H + 3 * lambda) / (3 * nu);
}

struct UniformFilm {
  double speed = 0;  ///< |u| at the centre after the run (m/s)
  std::vector<double> history;  ///< |u| at the centre after each step
};

/// A uniform film of thickness H on a 10 x 10 sheet tilted by α, alone with
/// its body force and friction (no advection, diffusion or wall: every
/// vertex is the same ODE), for `steps` steps of h.
UniformFilm uniformFilm(double alpha, double H, double nu, double lambda, double h, int steps) {
  TriangleMesh mesh = gridMesh(10, 10, 1.0, 1.0);
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-alpha, Vector3::UnitX()).toRotationMatrix();
  mesh.vertexPositions = mesh.vertexPositions * tilt.transpose();
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def = filmDef();
  def.switches.velocityAdvection = def.switches.densityAdvection = false;
  def.switches.densityDiffusion = def.switches.velocityDiffusion = false;
  def.switches.boundaryWall = false;
  def.liquid.kinematicViscosity = nu;
  def.liquid.slipLength = lambda;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 0.0),
                     def);
  StainState& state = solver.mutableState();
  state.solvent.setConstant(def.liquid.liquidDensity * H);
  const int centre = 5 * 11 + 5;
  UniformFilm film;
  for (int k = 0; k < steps; ++k) {
    const StepReport r = solver.step(h, mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
    film.history.push_back(solver.relativeVelocity(centre).norm());
  }
  film.speed = film.history.back();
  return film;
}

TEST(FilmFlow, UniformFilmReachesTheNusseltVelocity) {
  // Slopes, thicknesses (0.05-2 mm), viscosities (water to 20x water), with
  // and without slip: after 60 relaxation times H(H+3λ)/(3ν) the velocity is
  // the steady value to rounding, whatever h k is.
  for (const double alpha : {kPi / 12, kPi / 4, kPi / 2})
    for (const double H : {5e-5, 3e-4, 2e-3})
      for (const double nu : {1e-6, 2e-5})
        for (const double lambda : {0.0, 1e-5}) {
          const double h = 0.01;
          const double k = 3 * nu / (H * (H + 3 * lambda));
          const int steps = std::max(50, static_cast<int>(std::ceil(60.0 / (k * h) * (1 + k * h))));
          if (steps > 3000) continue;  // 60 relaxation times of a 2 mm water film (1.3 s) is 8000 steps
          const UniformFilm film = uniformFilm(alpha, H, nu, lambda, h, steps);
          const double expected = nusselt(alpha, H, nu, lambda);
          EXPECT_NEAR(film.speed, expected, 1e-11 * expected)
              << "alpha " << alpha << " H " << H << " nu " << nu << " lambda " << lambda;
        }
}

TEST(FilmFlow, TransientFollowsTheClosureAndConvergesInTheStep) {
  // The start-up of a 1 mm water film on a 30° slope. Backward Euler on
  // du/dt = a − k u gives u_n = (a/k)(1 − (1 + hk)^−n) exactly; against the
  // closure's own exponential (a/k)(1 − e^{−kt}) the error at t = 1/k is
  // first order in h. (The closure's decay rate 3ν/H² stands for the exact
  // Stokes start-up's slowest mode, π²ν/(4H²): 18 % slower, docs/accuracy.md.)
  const double alpha = kPi / 6, H = 1e-3, nu = 1e-6, lambda = 0.0;
  const double k = 3 * nu / (H * H), a = kG * std::sin(alpha);
  double previousError = 0;
  for (const int perTau : {8, 16, 32, 64}) {
    const double h = 1.0 / (k * perTau);
    const UniformFilm film = uniformFilm(alpha, H, nu, lambda, h, perTau);
    const double closedForm = (a / k) * (1 - std::pow(1 + h * k, -perTau));
    EXPECT_NEAR(film.speed, closedForm, 1e-12 * closedForm);
    const double error = std::abs(film.speed - (a / k) * (1 - std::exp(-1.0)));
    std::printf("h = tau/%d: u(tau) %.6f m/s, closure %.6f, error %.3e\n", perTau, film.speed,
                (a / k) * (1 - std::exp(-1.0)), error);
    if (previousError > 0) {
      EXPECT_NEAR(previousError / error, 2.0, 0.15);
    }
    previousError = error;
  }
}

// ------------------------------------------------ a lake at rest

TEST(FilmFlow, LakeAtRestInABowlStaysAtRest) {
  // A level pool in a paraboloid bowl (R = 10 m, 1 m across, 5 mm deep at
  // the centre, its shore between vertices): φ = −g·x + g_n H is the same at
  // every wet vertex, so the one discrete gradient of gravity and pressure
  // vanishes and the shoreline's reconstruction holds the dry bank still.
  // Friction, both diffusions and the interaction off: nothing else could
  // stop a slosh. 1000 steps of 0.01 s.
  const TriangleMesh mesh = bowlMesh(24, 0.5, 10.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def = filmDef();
  def.switches.filmFriction = false;
  def.switches.densityDiffusion = def.switches.velocityDiffusion = false;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4),
                     def);
  solver.completeGeometry();
  const ExtrinsicGeometry& geometry = solver.geometry().extrinsic();
  const double level = kG * 0.005;  // φ of the lake: its surface at z = 5 mm
  StainState& state = solver.mutableState();
  int wet = 0;
  for (int i = 0; i < topology.vertexCount(); ++i) {
    const double gn = kG * geometry.frames[static_cast<size_t>(i)].col(2).z();  // −g·n, n up
    const double H = (level - kG * mesh.vertexPositions(i, 2)) / gn;
    state.solvent[i] = H > 0 ? def.liquid.liquidDensity * H : 0.0;
    wet += H > 0 ? 1 : 0;
  }
  double worst = 0;
  for (int k = 0; k < 1000; ++k) {
    const StepReport r = solver.step(0.01, mesh.vertexPositions);
    ASSERT_TRUE(r.ok()) << r.message;
    for (int i = 0; i < topology.vertexCount(); ++i)
      if (solver.state().solvent[i] > 0) worst = std::max(worst, std::abs(solver.state().velocities[i]));
  }
  std::printf("lake at rest, %d wet vertices, 1000 steps: max |u| %.3e m/s\n", wet, worst);
  EXPECT_GT(wet, 100);
  EXPECT_LE(worst, 1e-12);
}

// ------------------------------------------------ a basin

struct BasinRun {
  double startEnergy = 0, worstEnergy = 0, finalEnergy = 0;  ///< film energy (J)
  double finalSpeed = 0;  ///< max |u| over the liquid at the end (m/s)
  double worstSpeed = 0;  ///< max over the run
  double centroidShift = 0;  ///< largest distance of the liquid's centroid from where it started (m)
  int filmSubsteps = 0;  ///< most film sub-steps a step took
};

/// The basins: a paraboloid bowl z = r²/(2R), a trough z = x²/(2R) (R = 1 m,
/// 1 m across, 16 x 16 cells), and the inside of a sphere of radius 0.5 m
/// (its faces turned so that the normals point inwards, to the liquid).
enum class Basin { Bowl, Trough, SphereInside };

TriangleMesh basinMesh(Basin shape) {
  if (shape == Basin::SphereInside) {
    TriangleMesh mesh = icosphereMesh(3, 0.5);
    mesh.faces.col(1).swap(mesh.faces.col(2));
    mesh.vertexPositions.col(2).array() += 0.5;  // resting on the origin
    return mesh;
  }
  TriangleMesh mesh = bowlMesh(16, 0.5, 1.0);
  if (shape == Basin::Trough)
    for (int i = 0; i < mesh.vertexPositions.rows(); ++i)
      mesh.vertexPositions(i, 2) = mesh.vertexPositions(i, 0) * mesh.vertexPositions(i, 0) / 2;
  return mesh;
}

/// Where a drop released `x` from the bottom lands: (x, 0) on the bowl's and
/// the trough's parabola, x of arc up the sphere's wall.
Vector3 basinPoint(Basin shape, double x) {
  if (shape == Basin::SphereInside) return Vector3(0.5 * std::sin(x / 0.5), 0.0, 0.5 - 0.5 * std::cos(x / 0.5));
  return Vector3(x, 0.0, x * x / 2);
}

/// A 0.2 kg drop of water released at rest `x` from the bottom of a basin,
/// interaction off, for `seconds`; the energy is the film's own (filmEnergy:
/// kinetic, gravitational, pressure).
BasinRun basin(PhysicsModel model, bool densityDiffusion, double x, double seconds, Basin shape = Basin::Bowl) {
  const TriangleMesh mesh = basinMesh(shape);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const int n = topology.vertexCount();
  StainSolverDef def;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  applyPhysicsModel(model, def.switches, def.liquid);
  def.switches.densityDiffusion = densityDiffusion;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 1e-4),
                     def);
  DropDef drop;
  drop.centerPoint = basinPoint(shape, x);
  drop.radius = 0.1;
  drop.solventMass = 0.2;
  solver.addDrop(drop);
  StepContext ctx = makeStepContext(0.01, def.gravity, def.switches, def.liquid);
  ctx.switches.filmPressure = true;  // the same energy for both models
  std::vector<char> wet(static_cast<size_t>(n));
  const auto measure = [&](double& e, Vector3& centroid) {
    const Vector& areas = solver.geometry().intrinsic().vertexDualAreas;
    double mass = 0;
    centroid.setZero();
    for (int i = 0; i < n; ++i) {
      wet[static_cast<size_t>(i)] = solver.state().solvent[i] > def.liquid.wetThreshold ? 2 : 0;
      mass += areas[i] * solver.state().solvent[i];
      centroid += areas[i] * solver.state().solvent[i] * mesh.vertexPositions.row(i).transpose();
    }
    centroid /= mass;
    e = filmEnergy(ctx, solver.geometry().extrinsic(), areas, solver.state(), wet).total();
  };
  BasinRun run;
  Vector3 start, centroid;
  measure(run.startEnergy, start);
  run.worstEnergy = run.startEnergy;
  const int steps = static_cast<int>(std::lround(seconds / 0.01));
  for (int k = 0; k < steps; ++k) {
    const StepReport r = solver.step(0.01, mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
    if (!r.ok()) break;
    double e = 0;
    measure(e, centroid);
    run.worstEnergy = std::max(run.worstEnergy, e);
    run.filmSubsteps = std::max(run.filmSubsteps, solver.profile().filmSubsteps);
    run.centroidShift = std::max(run.centroidShift, (centroid - start).norm());
    double speed = 0;
    for (int i = 0; i < n; ++i)
      if (wet[static_cast<size_t>(i)] != 0) speed = std::max(speed, std::abs(solver.state().velocities[i]));
    run.worstSpeed = std::max(run.worstSpeed, speed);
    run.finalSpeed = speed;
    run.finalEnergy = e;
  }
  return run;
}

TEST(FilmFlow, LiquidInABowlSettlesAndGainsNoEnergy) {
  // Released on the bowl's wall: it runs down, sloshes and settles. Without
  // the density diffusion nothing but gravity can give the film energy, so it
  // never grows; with it (wicking) the film spreads up the walls against
  // gravity and its flow balances the wicking (u H = D ∇H) instead of
  // stopping. The paper's form keeps accelerating at the bottom.
  const BasinRun film = basin(PhysicsModel::Film, false, 0.25, 20.0);
  const BasinRun wicking = basin(PhysicsModel::Film, true, 0.25, 20.0);
  const BasinRun paper = basin(PhysicsModel::Paper, false, 0.25, 5.0);
  std::printf("bowl, from the wall: film (20 s): E %.4e -> max %.4e -> %.4e J, max |u| %.3e m/s (end %.3e)\n"
              "                     film + wicking (20 s): E %.4e -> max %.4e -> %.4e J, max |u| %.3e (end %.3e)\n"
              "                     paper (5 s): E %.4e -> max %.4e J, max |u| %.3e m/s (end %.3e)\n",
              film.startEnergy, film.worstEnergy, film.finalEnergy, film.worstSpeed, film.finalSpeed,
              wicking.startEnergy, wicking.worstEnergy, wicking.finalEnergy, wicking.worstSpeed, wicking.finalSpeed,
              paper.startEnergy, paper.worstEnergy, paper.worstSpeed, paper.finalSpeed);
  EXPECT_LE(film.worstEnergy, film.startEnergy + 1e-9 * std::abs(film.startEnergy));
  EXPECT_LT(film.finalEnergy, 0.25 * film.startEnergy);
  EXPECT_LT(film.finalSpeed, 0.05 * film.worstSpeed);
  EXPECT_LT(wicking.worstSpeed, 1.2 * film.worstSpeed);
  EXPECT_LT(wicking.finalSpeed, 0.1 * wicking.worstSpeed);
  EXPECT_GT(paper.worstSpeed, 10 * film.worstSpeed);
  EXPECT_GT(paper.worstEnergy, 10 * paper.startEnergy);
}

TEST(FilmFlow, InATroughAndInsideASphereTooTheLiquidSettlesAndGainsNoEnergy) {
  for (const Basin shape : {Basin::Trough, Basin::SphereInside}) {
    const char* name = shape == Basin::Trough ? "trough" : "inside a sphere";
    const BasinRun film = basin(PhysicsModel::Film, false, 0.25, 20.0, shape);
    const BasinRun bottom = basin(PhysicsModel::Film, true, 0.0, 20.0, shape);
    const BasinRun paper = basin(PhysicsModel::Paper, false, 0.25, 5.0, shape);
    std::printf("%s, from the wall: film (20 s): E %.4e -> max %.4e -> %.4e J, max |u| %.3e m/s (end %.3e); "
                "at the bottom with wicking: centroid moved %.3e m, max |u| %.3e m/s; paper (5 s): E %.4e -> max "
                "%.4e J, max |u| %.3e m/s\n",
                name, film.startEnergy, film.worstEnergy, film.finalEnergy, film.worstSpeed, film.finalSpeed,
                bottom.centroidShift, bottom.worstSpeed, paper.startEnergy, paper.worstEnergy, paper.worstSpeed);
    EXPECT_LE(film.worstEnergy, film.startEnergy + 1e-9 * std::abs(film.startEnergy)) << name;
    EXPECT_LT(film.finalSpeed, 0.05 * film.worstSpeed) << name;
    EXPECT_LT(bottom.centroidShift, 5e-3) << name;
    EXPECT_GT(paper.worstEnergy, 5 * paper.startEnergy) << name;  // energy out of nothing
  }
}

TEST(FilmFlow, DropAtTheBottomOfABowlStaysThere) {
  // Placed at the lowest point: pressure spreads it a little, friction
  // stops it, and it stays (the paper's form sends it sloshing ever faster).
  const BasinRun film = basin(PhysicsModel::Film, true, 0.0, 20.0);
  const BasinRun paper = basin(PhysicsModel::Paper, true, 0.0, 5.0);
  std::printf("bowl, at the bottom: film (20 s): centroid moved %.3e m, max |u| %.3e m/s (end %.3e), %d film sub-steps\n"
              "                     paper (5 s): centroid moved %.3e m, max |u| %.3e m/s (end %.3e)\n",
              film.centroidShift, film.worstSpeed, film.finalSpeed, film.filmSubsteps, paper.centroidShift, paper.worstSpeed,
              paper.finalSpeed);
  EXPECT_LT(film.centroidShift, 5e-3);
  EXPECT_LT(film.worstSpeed, 0.5);
  EXPECT_GT(paper.worstSpeed, 10 * film.worstSpeed);
}

}  // namespace
}  // namespace blot::stain

namespace blot::stain {
namespace {

// ------------------------------------------------ switches that mean what they say

/// The 20 x 20 sheet on [0, 1]² folded along its grid line x = 0.5 by
/// θ(t) = 0.6 sin(3t): the half x > 0.5 turns about the line, every triangle
/// moves rigidly (a discrete isometry) and the metric is the flat sheet's.
RowVectors3 folded(const TriangleMesh& rest, double t) {
  RowVectors3 p = rest.vertexPositions;
  const double theta = 0.6 * std::sin(3.0 * t);
  for (int i = 0; i < p.rows(); ++i) {
    const double x = rest.vertexPositions(i, 0) - 0.5;
    if (x <= 0) continue;
    p(i, 0) = 0.5 + x * std::cos(theta);
    p(i, 2) = x * std::sin(theta);
  }
  return p;
}

/// Densities after 1 s of a drop across the fold line, with inertia,
/// Coriolis, gravity and the film's pressure off: nothing may tell the folded
/// sheet from the flat one (the stages that read the cloth's velocity are the
/// inertial ones).
StainState afterOneSecond(PhysicsModel model, bool fold) {
  const TriangleMesh mesh = gridMesh(20, 20, 1.0, 1.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  applyPhysicsModel(model, def.switches, def.liquid);
  def.switches.linearInertia = def.switches.coriolis = def.switches.gravity = def.switches.filmPressure = false;
  StainSolver solver(topology, fold ? folded(mesh, 0.0) : mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-3), def);
  DropDef drop;
  drop.centerVertex = 10 * 21 + 12;  // (0.6, 0.5)
  drop.radius = 0.2;
  drop.solventMass = 0.05;
  drop.soluteMass = 0.01;
  solver.addDrop(drop);
  for (int k = 1; k <= 100; ++k) {
    const StepReport r = solver.step(0.01, fold ? folded(mesh, 0.01 * k) : mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
  }
  return solver.state();
}

TEST(FilmFlow, AnIsometricFoldWithTheInertialTermsOffChangesNothing) {
  for (const PhysicsModel model : {PhysicsModel::Film, PhysicsModel::Paper}) {
    const StainState flat = afterOneSecond(model, false);
    const StainState fold = afterOneSecond(model, true);
    const double peak = flat.solvent.maxCoeff();
    const double solvent = (flat.solvent - fold.solvent).cwiseAbs().maxCoeff();
    const double solute = (flat.solute - fold.solute).cwiseAbs().maxCoeff();
    double speed = 0;
    for (int i = 0; i < fold.vertexCount(); ++i) speed = std::max(speed, std::abs(fold.velocities[i]));
    std::printf("%s model, folded against flat after 1 s: |d solvent| %.3e, |d solute| %.3e of peak %.3e; "
                "max |u| %.3e m/s\n",
                model == PhysicsModel::Film ? "film" : "paper", solvent, solute, peak, speed);
    EXPECT_LE(solvent, 1e-12 * peak);
    EXPECT_LE(solute, 1e-12 * peak);
    EXPECT_LE(speed, 1e-12);
  }
}

// ------------------------------------------------ solute carried by the solvent

/// The largest |σ_s − c₀ ρ| over the largest σ_s: how far the solute has
/// left the concentration c₀ it started with (ρ = σ_f + σ_s).
double concentrationSpread(const StainState& s, double c0) {
  return (s.solute - c0 * (s.solvent + s.solute)).cwiseAbs().maxCoeff() / s.solute.maxCoeff();
}

TEST(SoluteWithSolvent, AUniformConcentrationStaysUniformAndNoSoluteIsLost) {
  // A drop running down a 30° slope: advection, wicking, pressure and
  // friction all move it; nothing may unmix it.
  TriangleMesh mesh = gridMesh(20, 20, 1.0, 1.0);
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-kPi / 6, Vector3::UnitX()).toRotationMatrix();
  mesh.vertexPositions = mesh.vertexPositions * tilt.transpose();
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const StainSolverDef def = filmDef();
  ASSERT_TRUE(def.switches.soluteWithSolvent);
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-3),
                     def);
  DropDef drop;
  drop.centerVertex = 15 * 21 + 10;
  drop.radius = 0.2;
  drop.solventMass = 0.5;
  drop.soluteMass = 0.02;
  solver.addDrop(drop);
  const double c0 = drop.soluteMass / (drop.solventMass + drop.soluteMass);
  for (int k = 0; k < 200; ++k) {
    const StepReport r = solver.step(0.01, mesh.vertexPositions);
    ASSERT_TRUE(r.ok()) << r.message;
  }
  const double spread = concentrationSpread(solver.state(), c0);
  const MassBudget budget = solver.massBudget();
  std::printf("a drop on a 30° slope after 2 s: concentration spread %.2e, solute error %.2e, solvent error %.2e\n",
              spread, budget.soluteError(), budget.solventError());
  EXPECT_GT(solver.profile().terms & static_cast<unsigned>(StepTerm::SoluteWithSolvent), 0u);
  EXPECT_LE(spread, 1e-12);
  EXPECT_LE(budget.soluteError(), 1e-13);
  EXPECT_LE(budget.solventError(), 1e-13);
}

/// A film of uniform thickness on a flat strip, its solute in the half x < 0
/// (c₀ there, 0 beyond, c₀/2 on the line x = 0), after `seconds`: the
/// concentration c = σ_s/ρ at each vertex of the strip's middle row, by x.
struct Mixing {
  std::vector<double> x, concentration;
};
constexpr double kStripWicking = 4e-3;  // the fabric's diffusivity (m²/s)
Mixing mixStrip(PhysicsModel model, double molecularDiffusivity, int cells, double h, double seconds) {
  const double length = 1.0, c0 = 0.1;
  TriangleMesh mesh = gridMesh(cells, cells / 8, length, length / 8);
  mesh.vertexPositions.col(0).array() -= length / 2;
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def;
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  applyPhysicsModel(model, def.switches, def.liquid);
  def.gravity = Vector3::Zero();
  def.liquid.molecularDiffusivity = molecularDiffusivity;
  StainSolver solver(topology, mesh.vertexPositions,
                     isotropicFabricField(static_cast<int>(mesh.faces.rows()), kStripWicking, 1e-3), def);
  StainState& state = solver.mutableState();
  const double dx = length / cells;
  for (int i = 0; i < state.vertexCount(); ++i) {
    const double x = mesh.vertexPositions(i, 0);
    const double c = x < -dx / 2 ? c0 : (x < dx / 2 ? c0 / 2 : 0.0);
    state.solute[i] = c;  // ρ = 1 kg/m²
    state.solvent[i] = 1.0 - c;
  }
  const int steps = static_cast<int>(std::lround(seconds / h));
  for (int k = 0; k < steps; ++k) {
    const StepReport r = solver.step(h, mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
  }
  Mixing m;
  const int row = cells / 16;  // the middle row of the strip's cells / 8 + 1 rows
  for (int i = 0; i <= cells; ++i) {
    const int v = row * (cells + 1) + i;
    m.x.push_back(mesh.vertexPositions(v, 0));
    const StainState& s = solver.state();
    m.concentration.push_back(s.solute[v] / (s.solvent[v] + s.solute[v]) / c0);
  }
  return m;
}

/// The largest difference from c₀/2 erfc(x / (2 √(D t))), in units of c₀.
double errorAgainstErfc(const Mixing& m, double diffusivity, double seconds) {
  double error = 0.0;
  for (size_t k = 0; k < m.x.size(); ++k)
    error = std::max(error, std::abs(m.concentration[k] - 0.5 * std::erfc(m.x[k] / (2 * std::sqrt(diffusivity * seconds)))));
  return error;
}

TEST(SoluteWithSolvent, ConcentrationsEvenOutByMolecularDiffusionAlone) {
  // A uniform film does not flow, so only D_m may mix its solute: the
  // concentration follows the heat kernel's erfc with D_m and converges
  // under refinement; with D_m = 0 nothing moves at all. The paper's form
  // mixes it with the fabric's wicking tensor instead (4× D_m here).
  const double seconds = 2.0, dm = 1e-3;
  const Mixing coarse = mixStrip(PhysicsModel::Film, dm, 32, 0.02, seconds);
  const Mixing fine = mixStrip(PhysicsModel::Film, dm, 64, 0.005, seconds);
  const double coarseError = errorAgainstErfc(coarse, dm, seconds), fineError = errorAgainstErfc(fine, dm, seconds);
  const Mixing still = mixStrip(PhysicsModel::Film, 0.0, 32, 0.02, seconds);
  double moved = 0.0;
  for (size_t k = 0; k < still.x.size(); ++k) {
    const double x = still.x[k], dx = 1.0 / 32;
    moved = std::max(moved, std::abs(still.concentration[k] - (x < -dx / 2 ? 1.0 : (x < dx / 2 ? 0.5 : 0.0))));
  }
  const Mixing paper = mixStrip(PhysicsModel::Paper, 0.0, 32, 0.02, seconds);
  const double paperError = errorAgainstErfc(paper, kStripWicking, seconds);
  std::printf("a concentration step, D_m = %.0e m²/s, %.0f s: max error against erfc %.2e (32 cells, h 0.02), "
              "%.2e (64 cells, h 0.005); D_m = 0: largest change %.2e; paper's form against erfc with the fabric's "
              "D %.2e\n",
              dm, seconds, coarseError, fineError, moved, paperError);
  EXPECT_LE(coarseError, 0.01);
  EXPECT_LT(fineError, 0.5 * coarseError);
  EXPECT_LE(moved, 1e-12);
  EXPECT_LE(paperError, 0.02);  // the paper mixes at the fabric's rate
  EXPECT_GT(errorAgainstErfc(paper, dm, seconds), 0.1);
}

// ------------------------------------------------ the in-plane viscosity, weighted by mass

struct ShearRun {
  double startEnergy = 0, finalEnergy = 0;
  double worstGrowth = 0;       ///< largest E_k / E_{k−1} − 1 over the steps
  double momentumDrift = 0;     ///< largest |P_k − P_0| / Σ A ρ |v|, P = Σ A ρ v (world)
  double dissipationError = 0;  ///< largest |E_{k−1} − E_k − D_k| / E_0, D the profile's viscous dissipation
  double poolSpeed = 0;         ///< the thick pool's largest speed at the end (m/s)
  double flowChange = 0;        ///< with a uniform flow: the largest change of any velocity (m/s)
};

/// A film on a flat 1 m square, 2 kg/m² for x < 0.5 (a still pool) and
/// 0.02 kg/m² beyond (moving at 1 m/s along y; or, with `uniform`, the whole
/// film moving at 1 m/s along x), with only the in-plane viscosity acting
/// (fabric ν = 0.01 m²/s), for 1 s.
ShearRun shearLayer(bool massWeighted, bool uniform) {
  const TriangleMesh mesh = gridMesh(20, 20, 1.0, 1.0);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  StainSolverDef def = filmDef();
  def.gravity = Vector3::Zero();
  def.switches.velocityAdvection = def.switches.densityAdvection = def.switches.densityDiffusion = false;
  def.switches.filmFriction = def.switches.boundaryWall = false;
  def.switches.massWeightedViscosity = massWeighted;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 0.01),
                     def);
  const int n = topology.vertexCount();
  const std::vector<Matrix3>& frames = solver.geometry().extrinsic().nextFrames;
  StainState& state = solver.mutableState();
  std::vector<Vector3> start(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const bool pool = mesh.vertexPositions(i, 0) < 0.5 - 1e-9;
    state.solvent[i] = pool ? 2.0 : 0.02;
    const Vector3 v = uniform ? Vector3(1, 0, 0) : (pool ? Vector3::Zero() : Vector3(0, 1, 0));
    const Matrix3& f = frames[static_cast<size_t>(i)];
    state.velocities[i] = Complex(f.col(0).dot(v), f.col(1).dot(v));
    start[static_cast<size_t>(i)] = v;
  }
  const Vector& areas = solver.geometry().intrinsic().vertexDualAreas;
  const auto measure = [&](Vector3& momentum, double& scale) {
    double energy = 0;
    momentum.setZero();
    scale = 0;
    for (int i = 0; i < n; ++i) {
      const Vector3 v = solver.relativeVelocity(i);
      const double m = areas[i] * solver.state().solvent[i];
      energy += 0.5 * m * v.squaredNorm();
      momentum += m * v;
      scale += m * v.norm();
    }
    return energy;
  };
  ShearRun run;
  Vector3 p0, p;
  double scale0 = 0, scale = 0;
  run.startEnergy = measure(p0, scale0);
  double previous = run.startEnergy;
  for (int k = 0; k < 100; ++k) {
    const StepReport r = solver.step(0.01, mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
    const double e = measure(p, scale);
    run.worstGrowth = std::max(run.worstGrowth, e / previous - 1);
    run.momentumDrift = std::max(run.momentumDrift, (p - p0).norm() / scale0);
    if (massWeighted)
      run.dissipationError =
          std::max(run.dissipationError, std::abs(previous - e - solver.profile().viscousDissipation) / run.startEnergy);
    previous = e;
  }
  run.finalEnergy = previous;
  for (int i = 0; i < n; ++i) {
    if (mesh.vertexPositions(i, 0) < 0.5 - 1e-9) run.poolSpeed = std::max(run.poolSpeed, solver.relativeVelocity(i).norm());
    run.flowChange = std::max(run.flowChange, (solver.relativeVelocity(i) - start[static_cast<size_t>(i)]).norm());
  }
  return run;
}

TEST(FilmViscosity, WeightedByMassItOnlyDissipatesAndConservesMomentum) {
  const ShearRun mass = shearLayer(true, false);
  const ShearRun area = shearLayer(false, false);
  std::printf("thin film at 1 m/s beside a still pool 100x thicker, 1 s of viscosity: by mass, energy %.3e -> %.3e J "
              "(largest step growth %.1e), momentum drift %.1e, dissipation reported vs measured %.1e of E0, pool "
              "speed %.3f m/s; by area (the paper's), energy %.3e -> %.3e J, pool speed %.3f m/s\n",
              mass.startEnergy, mass.finalEnergy, mass.worstGrowth, mass.momentumDrift, mass.dissipationError,
              mass.poolSpeed, area.startEnergy, area.finalEnergy, area.poolSpeed);
  EXPECT_LE(mass.worstGrowth, 1e-13);
  EXPECT_LT(mass.finalEnergy, mass.startEnergy);
  // 100 solves, each to 1e-11 of its right-hand side.
  EXPECT_LE(mass.momentumDrift, 1e-10);
  EXPECT_LE(mass.dissipationError, 1e-11);
  // Weighted by area, the pool takes speed from the trace: energy out of nothing.
  EXPECT_GT(area.finalEnergy, 2 * area.startEnergy);
  EXPECT_GT(area.poolSpeed, 10 * mass.poolSpeed);
}

TEST(FilmViscosity, AUniformFlowOverAnUnevenFilmIsLeftAlone) {
  const ShearRun flow = shearLayer(true, true);
  std::printf("a uniform 1 m/s flow over a film 2 and 0.02 kg/m² thick, 1 s: largest velocity change %.1e m/s\n",
              flow.flowChange);
  EXPECT_LE(flow.flowChange, 1e-13);
}

}  // namespace
}  // namespace blot::stain
