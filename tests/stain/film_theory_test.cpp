// The liquid film (stages/film_flow.h, docs/transport.md "The liquid film")
// against two results of thin-film theory that involve the whole step, not
// one vertex's ODE: the thickness–flux relation of a steady film draining
// down a slope (Nusselt), and the spreading of a viscous drop under its own
// weight (the similarity solution of the lubrication equation, Huppert 1982).
// Each check states its tolerance and prints its numbers at every
// resolution it runs.
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stages/film_flow.h>
#include <blot/stain/stain_solver.h>

#include "sanitized_build.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.8;

/// The film model with only what a film on an inert fabric has: its
/// potential (gravity and pressure), friction and the advection of
/// velocity and densities. No wicking (density diffusion), no in-plane
/// viscosity, no interaction with the fibres.
StainSolverDef frictionAndPressureOnly(double nu, double slipLength) {
  StainSolverDef def;
  applyPhysicsModel(PhysicsModel::Film, def.switches, def.liquid);
  def.switches.absorption = def.switches.adsorption = def.switches.evaporation = false;
  def.switches.densityDiffusion = def.switches.velocityDiffusion = false;
  def.liquid.kinematicViscosity = nu;
  def.liquid.slipLength = slipLength;
  def.geometryVertices = VertexRefresh::AllVertices;
  return def;
}

// ------------------------------------------------ a film draining down a slope

/// Steady flux per unit width of a film of thickness H on a slope α with
/// slip length λ (m²/s): q = H ū = g sin α H² (H + 3λ)/(3ν) (Nusselt 1916
/// for λ = 0; the Navier slip adds the 3λ).
double nusseltFlux(double alpha, double H, double nu, double lambda) {
  return kG * std::sin(alpha) * H * H * (H + 3 * lambda) / (3 * nu);
}

struct DrainingFilm {
  double thickness = 0;   ///< mean H over the middle third of the slope at the end (m)
  double spread = 0;      ///< (max − min)/mean of H over the middle third
  double inflow = 0;      ///< volume flux per unit width the held row supplied over the last window (m²/s)
  double outflow = 0;     ///< volume flux per unit width the outlet took over the last window (m²/s)
  double drift = 0;       ///< largest relative change of H in the middle third over the last window
  int filmSubsteps = 0;   ///< most film sub-steps a step took
};

/// A sheet `width` x `length` (m) of `cells` x (length/width · cells) cells
/// tilted by α about its x axis, so that +y runs straight down the slope. Its
/// top row is a held region at thickness `feed` (the film is fed there); its
/// bottom row is an outlet: after each step the liquid that reached it is
/// taken off (counted) and the row left dry, so the film leaves the sheet
/// instead of piling up against the bottom wall. Run for `seconds` with
/// steps of h; the fluxes are measured over the last `window` seconds.
DrainingFilm drainingFilm(double alpha, double feed, double nu, double lambda, int cells, double h, double seconds,
                          double window) {
  const double width = 0.1, length = 0.3;
  const int rows = static_cast<int>(std::lround(cells * length / width));
  TriangleMesh mesh = gridMesh(cells, rows, width, length);
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-alpha, Vector3::UnitX()).toRotationMatrix();
  mesh.vertexPositions = mesh.vertexPositions * tilt.transpose();
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const StainSolverDef def = frictionAndPressureOnly(nu, lambda);
  const double rho = def.liquid.liquidDensity;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 0.0),
                     def);
  const int columns = cells + 1;
  const auto vertex = [&](int column, int row) { return row * columns + column; };
  HeldRegion inlet;
  for (int c = 0; c < columns; ++c) inlet.vertices.push_back(vertex(c, 0));
  inlet.solventDensity = rho * feed;
  inlet.soluteDensity = 0;
  solver.addHeldRegion(inlet);
  const Vector& areas = solver.geometry().intrinsic().vertexDualAreas;
  std::vector<int> middle;  // the middle third of the slope, every column
  for (int r = rows / 3; r <= 2 * rows / 3; ++r)
    for (int c = 0; c < columns; ++c) middle.push_back(vertex(c, r));

  DrainingFilm film;
  const int steps = static_cast<int>(std::lround(seconds / h));
  const int windowSteps = static_cast<int>(std::lround(window / h));
  double removed = 0, removedAtWindow = 0, addedAtWindow = 0;
  std::vector<double> middleAtWindow(middle.size());
  for (int k = 0; k < steps; ++k) {
    if (k == steps - windowSteps) {
      removedAtWindow = removed;
      addedAtWindow = solver.state().addedSolvent;
      for (size_t m = 0; m < middle.size(); ++m) middleAtWindow[m] = solver.state().solvent[middle[m]];
    }
    const StepReport r = solver.step(h, mesh.vertexPositions);
    EXPECT_TRUE(r.ok()) << r.message;
    if (!r.ok()) return film;
    film.filmSubsteps = std::max(film.filmSubsteps, solver.profile().filmSubsteps);
    StainState& state = solver.mutableState();
    for (int c = 0; c < columns; ++c) {
      const int i = vertex(c, rows);
      removed += areas[i] * state.solvent[i];
      state.solvent[i] = 0;
      state.velocities[i] = Complex(0, 0);
    }
  }
  const double time = windowSteps * h;
  film.inflow = (solver.state().addedSolvent - addedAtWindow) / (rho * width * time);
  film.outflow = (removed - removedAtWindow) / (rho * width * time);
  double lowest = 1e300, highest = 0, sum = 0;
  for (size_t m = 0; m < middle.size(); ++m) {
    const double H = filmThickness(solver.state(), middle[m], def.liquid);
    lowest = std::min(lowest, H);
    highest = std::max(highest, H);
    sum += H;
    film.drift = std::max(film.drift, std::abs(solver.state().solvent[middle[m]] - middleAtWindow[m]) /
                                          solver.state().solvent[middle[m]]);
  }
  film.thickness = sum / static_cast<double>(middle.size());
  film.spread = (highest - lowest) / film.thickness;
  return film;
}

TEST(FilmTheory, SteadyFilmDrainingDownASlopeCarriesTheNusseltFlux) {
  // Why this configuration: a film fed at the top of a slope and leaving at
  // the bottom reaches a steady state in which the same volume flux q
  // crosses every row, and away from the inlet and the outlet (where the
  // pressure gradient draws it up or down) the film is uniform, so the
  // whole step (potential, friction, wall, upwind density advection,
  // velocity advection, sub-steps) must carry q = g sin α H²(H + 3λ)/(3ν) at
  // the thickness H it settles to. q is measured as the volume the held row
  // supplies per second over the last quarter of the run (the fluxes the
  // advection actually moved, not u), H as the mean over the middle third of
  // the slope. Viscous films (ν = 1e-4, 1 and 2 mm, 30° and 10°, with the
  // default slip and without) and a 35 µm water film on 30°, where the slip
  // term 3λ/H is 0.86 of the thickness, all at Froude numbers ū/√(g_n H) of
  // 0.14-0.22 (friction-dominated, below the depth-averaged equations'
  // roll-wave threshold of 1/2) and u h/ℓ ≤ 0.14.
  //
  // Tolerance, at 16 x 48 cells: q within 1e-5 of Nusselt's at the measured
  // H (measured 4.5e-7, 4.2e-6, 3.9e-8); steady (H in the middle third
  // changed by ≤ 1e-6 over the window), uniform (spread ≤ 1e-3) and the
  // outlet's take within 1e-3 of the inlet's supply. In a uniform steady
  // film the relation holds to rounding (the backward-Euler drag's fixed
  // point is a/k, the potential's gradient of a uniform film on a plane is
  // the tangential gravity, a uniform u's cotan fluxes across a row of dual
  // edges sum to u·n times the width); what the refinement shows is how far
  // the outlet's boundary layer reaches. The dry edge below the last wet
  // row (hydrostatic reconstruction) disturbs the film there, and the
  // disturbance runs upstream as an odd-even (row by row alternating) wave
  // that halves about every row: the potential's gradient is the centred
  // mean of the face gradients and the edge flux uses the mean of the two
  // vertices' u, so neither sees an alternating mode and only the upwind
  // advection damps it. A fixed number of rows, so the middle third comes
  // clear exponentially in the resolution: error 2.4e-2, 4.3e-5, 4.5e-7 at
  // 4 x 12, 8 x 24 and 16 x 48 cells (the first case; each at most half the
  // one before is required). The outlet's own take still fluctuates in time
  // at the 1e-4 level in the 10° case, hence its looser tolerance.
  struct Case {
    double alpha, feed, nu, lambda, h, seconds;
  };
  const Case cases[] = {{kPi / 6, 1e-3, 1e-4, 1e-5, 0.05, 48},
                        {kPi / 18, 2e-3, 1e-4, 0.0, 0.05, 80},
                        {kPi / 6, 3.5e-5, 1e-6, 1e-5, 0.05, 215}};
  for (const Case& c : cases) {
    double previousError = 0;
    for (const int cells : {4, 8, 16}) {
      if (cells < 16 && &c != &cases[0]) continue;  // refinement on the first case only
      const DrainingFilm film = drainingFilm(c.alpha, c.feed, c.nu, c.lambda, cells, c.h, c.seconds, c.seconds / 4);
      const double expected = nusseltFlux(c.alpha, film.thickness, c.nu, c.lambda);
      const double error = std::abs(film.inflow - expected) / expected;
      const double froude = expected / film.thickness / std::sqrt(kG * std::cos(c.alpha) * film.thickness);
      std::printf("slope %4.1f deg, feed H %.1e m, nu %.0e, lambda %.0e, %2d x %2d cells, %.0f s: H %.6e m (spread "
                  "%.1e, drift %.1e), Froude %.2f, q in %.6e out %.6e, Nusselt %.6e m^2/s, error %.2e, %d film "
                  "sub-steps\n",
                  c.alpha * 180 / kPi, c.feed, c.nu, c.lambda, cells, 3 * cells, c.seconds, film.thickness, film.spread,
                  film.drift, froude, film.inflow, film.outflow, expected, error, film.filmSubsteps);
      if (previousError > 0) {
        EXPECT_LT(error, 0.5 * previousError) << "no convergence under refinement";
      }
      previousError = error;
      if (cells < 16) continue;
      EXPECT_LE(film.drift, 1e-6) << "not steady";
      EXPECT_LE(film.spread, 1e-3) << "not uniform";
      EXPECT_NEAR(film.outflow, film.inflow, 1e-3 * film.inflow) << "the outlet does not take what the inlet gives";
      EXPECT_LE(error, 1e-5);
    }
  }
}

// ------------------------------------------------ a viscous drop spreading under its own weight

/// The axisymmetric viscous gravity current of fixed volume V on a
/// horizontal plane (Huppert 1982, "The propagation of two-dimensional and
/// axisymmetric viscous gravity currents over a rigid horizontal surface",
/// J. Fluid Mech. 121, 43-58): ∂H/∂t = (G/r) ∂/∂r(r H³ ∂H/∂r),
/// G = g/(3ν), is the porous-medium equation ∂H/∂t = (G/4) ∇²(H⁴) in two dimensions, whose
/// Barenblatt solution is
///   H(r, t) = H_0(t) (1 − r²/R²)^{1/3},  R(t) = ξ_N (G V³ t)^{1/8},
///   H_0(t) = 4V/(3π R²),  ξ_N = (2^{10}/(3^4 π³))^{1/8} = 0.89391...
/// (derived: with D = G/4, m = 4, d = 2 the Barenblatt profile is
/// (Dt)^{−1/4}(C − (3/64) r² (Dt)^{−1/4})^{1/3}; its volume 16π C^{4/3}
/// fixes C and its edge R² = (64/3) C (Dt)^{1/4} gives ξ_N; Huppert's
/// 0.894). The profile's second moment is ∫r²H dA / V = (3/7) R².
double huppertConstant() { return std::pow(1024.0 / (81.0 * kPi * kPi * kPi), 1.0 / 8.0); }

double huppertRadius(double volume, double nu, double t) {
  return huppertConstant() * std::pow(kG / (3 * nu) * volume * volume * volume * t, 1.0 / 8.0);
}

struct Spreading {
  std::vector<double> times;   ///< s
  std::vector<double> radii;   ///< √(7/3 ⟨r²⟩) of the liquid (m): R for the similarity profile
  double volume = 0;           ///< m³
  double smallestDragStep = 0; ///< smallest h k over the liquid at the start (friction-dominated: ≫ 1)
  int filmSubsteps = 0;        ///< most film sub-steps a step took
};

/// A drop of a viscous liquid (ν = `nu`) placed on a horizontal
/// disc of radius `disc` (discMesh with `rings` rings) as the similarity
/// profile of radius R0 and centre thickness H0 at the time t0 that profile
/// has, sampled at the vertices and scaled so that its mass is exactly ρV,
/// V = (3π/4) R0² H0; run from t0 to t1 with steps of h, the moment radius
/// recorded at `samples` times spaced evenly in log t.
Spreading spreadingDrop(int rings, double disc, double R0, double H0, double nu, double t1OverT0, double h,
                        int samples) {
  const TriangleMesh mesh = discMesh(rings, disc);
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
  const int n = topology.vertexCount();
  const StainSolverDef def = frictionAndPressureOnly(nu, 0.0);
  const double rho = def.liquid.liquidDensity;
  StainSolver solver(topology, mesh.vertexPositions, isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-4, 0.0),
                     def);
  const Vector& areas = solver.geometry().intrinsic().vertexDualAreas;
  Spreading run;
  run.volume = 0.75 * kPi * R0 * R0 * H0;
  const double t0 = std::pow(R0 / huppertConstant(), 8) / (kG / (3 * nu) * std::pow(run.volume, 3));
  {
    StainState& state = solver.mutableState();
    double mass = 0;
    for (int i = 0; i < n; ++i) {
      const double r2 = mesh.vertexPositions.row(i).squaredNorm();
      state.solvent[i] = r2 < R0 * R0 ? rho * H0 * std::cbrt(1 - r2 / (R0 * R0)) : 0.0;
      mass += areas[i] * state.solvent[i];
    }
    state.solvent *= rho * run.volume / mass;
  }
  const auto momentRadius = [&] {
    double mass = 0, moment = 0;
    for (int i = 0; i < n; ++i) {
      const double m = areas[i] * solver.state().solvent[i];
      mass += m;
      moment += m * mesh.vertexPositions.row(i).squaredNorm();
    }
    return std::sqrt(7.0 / 3.0 * moment / mass);
  };
  run.smallestDragStep = 1e300;
  for (int i = 0; i < n; ++i)
    if (solver.state().solvent[i] > 0)
      run.smallestDragStep =
          std::min(run.smallestDragStep, h * filmDragRate(filmThickness(solver.state(), i, def.liquid), def.liquid));
  double t = t0;
  run.times.push_back(t);
  run.radii.push_back(momentRadius());
  for (int s = 1; s <= samples; ++s) {
    const double target = t0 * std::pow(t1OverT0, static_cast<double>(s) / samples);
    const int steps = std::max(1, static_cast<int>(std::lround((target - t) / h)));
    const double step = (target - t) / steps;  // land on the sample time
    for (int k = 0; k < steps; ++k) {
      const StepReport r = solver.step(step, mesh.vertexPositions);
      EXPECT_TRUE(r.ok()) << r.message;
      if (!r.ok()) return run;
      run.filmSubsteps = std::max(run.filmSubsteps, solver.profile().filmSubsteps);
    }
    t = target;
    run.times.push_back(t);
    run.radii.push_back(momentRadius());
  }
  return run;
}

/// Least-squares slope of log R against log t over the samples from index `from` on.
double growthExponent(const Spreading& run, size_t from) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double count = static_cast<double>(run.times.size() - from);
  for (size_t k = from; k < run.times.size(); ++k) {
    const double x = std::log(run.times[k]), y = std::log(run.radii[k]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (count * sxy - sx * sy) / (count * sxx - sx * sx);
}

TEST(FilmTheory, ViscousDropSpreadsLikeTheLubricationSimilaritySolution) {
  // A drop 3 cm in radius and 2 mm thick at its centre of a liquid with
  // ν = 1e-2 m²/s (a honey) on a horizontal cloth, no slip (λ = 0: the
  // lubrication equation above exactly), friction and pressure only, from
  // the similarity profile at its own time t0 (65 s) to 16 t0, steps of 2 s:
  // friction dominates (h k ≥ 1.4e4 over the drop at the start; the
  // relaxation time H²/(3ν) is 1e-4 s against t0). The radius is measured by
  // the liquid's second moment, R = √(7/3 ⟨r²⟩), which is the front radius
  // for the similarity profile and, unlike the outermost wet vertex, not
  // quantized by the mesh.
  //
  // Measured (disc of 8 cm, 20, 40, 80 rings, ring spacing R0/7.5 to
  // R0/30): R(16 t0) against ξ_N (G V³ t)^{1/8} is +2.0 %, +1.0 %, +0.54 %
  // (the front runs ahead; first order, the error ratio 1.96 and 1.87); the
  // growth exponent fitted over 4-16 t0 is 0.1247, 0.1273, 0.1261. The
  // sampled start is off by +0.6 %, −1.7 %, −0.7 % in R (where the rings
  // fall against the profile's (R − r)^{1/3} edge), which is why the
  // exponent is fitted after 4 t0, once that has relaxed. Tolerances: error
  // ≤ 1 % at 80 rings (1.2 % at 40 in the sanitized build, which stops
  // there) and at least 1.6 times smaller with each halving of
  // the spacing; exponent within 0.004 of 1/8 at every resolution.
  const double disc = 0.08, R0 = 0.03, H0 = 2e-3, nu = 1e-2, h = 2.0;
  const double span = 16.0;  // t1 / t0
  std::printf("Huppert's constant xi_N = (2^10/(3^4 pi^3))^(1/8) = %.6f\n", huppertConstant());
  double previousError = 0;
  // The sanitized build (10-20 times slower) runs the two coarser levels only:
  // the finest, with its 23 film sub-steps a step, is most of this test's time.
  const std::vector<int> levels = test::kSanitizedBuild ? std::vector<int>{20, 40} : std::vector<int>{20, 40, 80};
  for (const int rings : levels) {
    const Spreading run = spreadingDrop(rings, disc, R0, H0, nu, span, h, 8);
    const double t1 = run.times.back();
    const double expected = huppertRadius(run.volume, nu, t1);
    const double error = (run.radii.back() - expected) / expected;
    const double startError = (run.radii.front() - R0) / R0;
    const double exponent = growthExponent(run, 4);  // from 4 t0 on
    std::printf("%d rings (dr = %.4f m = R0/%.1f): h k >= %.2e, %d film sub-steps; R(t0) %.5f m (%+.2e), "
                "R(16 t0) %.5f m, Huppert %.5f m, error %+.3e; growth exponent (4-16 t0) %.5f (1/8)",
                rings, disc / rings, R0 * rings / disc, run.smallestDragStep, run.filmSubsteps, run.radii.front(),
                startError, run.radii.back(), expected, error, exponent);
    if (previousError != 0) std::printf(", error ratio %.2f (order %.2f)", previousError / error,
                                        std::log2(std::abs(previousError / error)));
    std::printf("\n");
    EXPECT_GT(run.smallestDragStep, 1e3);
    EXPECT_NEAR(exponent, 0.125, 0.004);
    if (previousError != 0) {
      EXPECT_GT(previousError / error, 1.6) << "no first-order convergence";
    }
    previousError = error;
  }
  EXPECT_LE(std::abs(previousError), test::kSanitizedBuild ? 0.012 : 0.01);
}

}  // namespace
}  // namespace blot::stain
