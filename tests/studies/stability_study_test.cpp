// Study (label "study", skipped by CI): stability where methods fail. Five
// sweeps, each one CSV in $BLOT_STUDY_OUT with one row per (parameter, method):
//
//   time step h up to 1 s, anisotropy ratio up to 1e6, mesh quality (slivers
//   with smallest angles down to 0.1°), rotation speed up to 50 rad/s, and
//   the velocity's diffusion on the liquid band against the whole mesh over
//   the time step (VelocityTimeStepSweep, its own columns);
//
// for ours and its naive alternative: diffusion by the solver's Auto choice
// (RKL2 or backward Euler on the support, or the factor) + positivity limiter
// vs explicit diffusion σ ← σ − h M⁻¹Lσ and vs each scheme without the
// limiter, beside the three methods Auto chooses from, each forced;
// sub-stepped upwind vs one sub-step (cap 1) vs the naive un-limited upwind;
// Coriolis as the discrete frame change (ours) vs the split exact rotation
// exp(−2iωh) after advection vs explicit u += −2hω×u.
// The Coriolis runs put a thin film over the whole disc (every vertex wet,
// RotatingDiscSetup::filmEverywhere), so the energy measures the integration,
// not dry vertices' placeholder velocities.
//
// Columns: amplification = max|σ_end| / max|σ_0| for densities, or for the
// Coriolis runs the kinetic energy Σ ½ A σ |u|² (disc frame) over that of the
// exact velocity field for the same masses (1 at the start);
// negativity = −min σ / max σ at the end (0: none); blew_up = non-finite or
// amplification > 1e3; mass_error = relative change of Σ Aσ. A run that
// overflows is recorded with amplification 1e30 (the charts' ceiling).
// Assertions: ours never blows up, never goes negative, conserves mass.
#include <blot/stain/stages/diffusion.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "stain_fixture.h"
#include "study_runs.h"
#include "study_support.h"

namespace blot::stain {
namespace {

using namespace liquid_testing;
using test::CsvWriter;

constexpr double kCeiling = 1e30;
constexpr const char* kHeader = "parameter,method,amplification,negativity,blew_up,mass_error,note";

double capped(double v) { return std::isfinite(v) ? std::min(v, kCeiling) : kCeiling; }

/// One row, also printed.
void record(CsvWriter& csv, double parameter, const std::string& method, double amplification, double negativity,
            double massError, const std::string& note = "") {
  const bool blewUp = !std::isfinite(amplification) || amplification > 1e3;
  std::printf("  %10.4g  %-56s amp %10.3e  neg %10.3e  mass %9.2e  %s %s\n", parameter, method.c_str(),
              amplification, negativity, massError, blewUp ? "BLOW-UP" : "", note.c_str());
  csv << parameter << method << capped(amplification) << capped(std::max(0.0, negativity)) << (blewUp ? 1 : 0)
      << capped(massError) << note;
  csv.endRow();
}

/// A smooth bump of radius 0.2 at (0.5, 0.5) on a unit-square mesh.
Vector squareBump(const LiquidMesh& g) {
  Vector s(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) s[i] = test::bump(g.position(i).head<2>(), Vector2(0.5, 0.5), 0.2);
  return s;
}

struct DiffusionOutcome {
  test::FieldHealth health;
  double massError = 0;
  std::string methods;  ///< the density method each implicit-path step took, e.g. "RKL2 (6 stages) x50"
};

const char* methodName(DiffusionMethod method) {
  switch (method) {
    case DiffusionMethod::None: return "none";
    case DiffusionMethod::Direct: return "factor";
    case DiffusionMethod::ConjugateGradient: return "CG";
    case DiffusionMethod::SuperTimeStepping: return "RKL2";
  }
  return "?";
}

/// One step's method as the notes write it: "RKL2 (5 stages)", "CG", "factor".
std::string methodLabel(DiffusionMethod method, int stages, bool fellBack) {
  std::string label = methodName(method);
  if (method == DiffusionMethod::SuperTimeStepping) label += " (" + std::to_string(stages) + " stages)";
  if (fellBack) label += " (CG stalled: factor)";
  return label;
}

/// The methods of a run's steps as runs of equal labels, in step order:
/// "RKL2 (5 stages) x20, factor x30".
struct MethodRuns {
  std::string text, last;
  int run = 0;
  void add(const std::string& label) {
    if (label != last) {
      flush();
      last = label;
      run = 0;
    }
    ++run;
  }
  const std::string& finish() {
    flush();
    run = 0;
    return text;
  }

 private:
  void flush() {
    if (run > 0) text += (text.empty() ? "" : ", ") + last + " x" + std::to_string(run);
  }
};

/// `steps` steps of size h: through diffuse() (the solver `choice`, the
/// limiter as given: Auto is ours, Direct backward Euler by the factor,
/// Iterative backward Euler by CG on the support, SuperTimeStepping RKL2 on
/// the support) or explicit, the latter optionally split into
/// `explicitSubsteps` equal sub-steps.
DiffusionOutcome runDiffusion(const LiquidMesh& g, double h, int steps, bool implicit, bool limiter,
                              int explicitSubsteps = 1,
                              DiffusionSolverChoice choice = DiffusionSolverChoice::Auto) {
  const Vector initial = squareBump(g);
  const double mass0 = totalMass(g.areas(), initial);
  Vector sigma = initial;
  DiffusionOutcome out;
  if (implicit) {
    DiffusionSystems systems;
    systems.setSolverChoice(choice);
    if (systems.factorize(g.intrinsic, h) != SolverStatus::Ok) throw std::runtime_error("factorize failed");
    DiffusionScratch scratch;
    scratch.resize(g.vertexCount());
    StainState state = zeroState(g.vertexCount());
    state.solvent = initial;
    PhysicsSwitches switches;
    switches.velocityDiffusion = false;
    switches.positivityLimiter = limiter;
    const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
    MethodRuns methods;
    for (int k = 0; k < steps; ++k) {
      const DiffusionReport report = diffuse(ctx, g.intrinsic, systems, scratch, state);
      if (report.status != SolverStatus::Ok) throw std::runtime_error("diffuse failed");
      methods.add(methodLabel(report.densityMethod, report.densityStages, report.fallbacks > 0));
    }
    out.methods = methods.finish();
    sigma = state.solvent;
  } else {
    for (int k = 0; k < steps * explicitSubsteps && sigma.allFinite(); ++k)
      test::explicitDiffusionStep(g.intrinsic.densityStiffness, g.areas(), h / explicitSubsteps, sigma);
  }
  out.health = test::fieldHealth(sigma, initial.maxCoeff());
  out.massError = std::abs(totalMass(g.areas(), sigma) - mass0) / mass0;
  return out;
}

/// The density solves behind ours, each forced, limiter on (the methods
/// Auto chooses among), with `prefix` before each label; each is asserted
/// stable, non-negative and mass-conserving, as ours is.
void recordForcedDiffusion(CsvWriter& csv, double parameter, const LiquidMesh& g, double h, int steps,
                           const std::string& prefix);

void recordDiffusion(CsvWriter& csv, double parameter, const std::string& method, const DiffusionOutcome& o,
                     const std::string& note = "") {
  const std::string both = o.methods.empty() ? note : note.empty() ? o.methods : note + "; " + o.methods;
  record(csv, parameter, method, o.health.growth, -o.health.minOverMax, o.massError, both);
}

/// Both schemes ours chooses from without the limiter: backward Euler (the
/// factor) and RKL2, labelled prefix + scheme + " without " + limiterName.
void recordWithoutLimiter(CsvWriter& csv, double parameter, const LiquidMesh& g, double h, int steps,
                          const std::string& prefix, const std::string& limiterName) {
  recordDiffusion(csv, parameter, prefix + "backward Euler without " + limiterName,
                  runDiffusion(g, h, steps, true, false, 1, DiffusionSolverChoice::Direct));
  recordDiffusion(csv, parameter, prefix + "RKL2 without " + limiterName,
                  runDiffusion(g, h, steps, true, false, 1, DiffusionSolverChoice::SuperTimeStepping));
}

void recordForcedDiffusion(CsvWriter& csv, double parameter, const LiquidMesh& g, double h, int steps,
                           const std::string& prefix) {
  const std::pair<DiffusionSolverChoice, const char*> forced[] = {
      {DiffusionSolverChoice::Direct, "backward Euler by the factor + limiter"},
      {DiffusionSolverChoice::Iterative, "backward Euler by CG on the support + limiter"},
      {DiffusionSolverChoice::SuperTimeStepping, "RKL2 on the support + limiter"}};
  for (const auto& [choice, label] : forced) {
    const DiffusionOutcome o = runDiffusion(g, h, steps, true, true, 1, choice);
    recordDiffusion(csv, parameter, prefix + label, o);
    EXPECT_FALSE(o.health.blewUp()) << label << " at " << parameter;
    EXPECT_GE(o.health.minOverMax, 0.0) << label << " at " << parameter;
    EXPECT_LT(o.massError, 1e-12) << label << " at " << parameter;
  }
}

void recordAdvection(CsvWriter& csv, double parameter, test::AdvectionMethod method,
                     const test::RotationAdvectionResult& r) {
  record(csv, parameter, test::toString(method), r.health.growth, -r.health.minOverMax, r.massError,
         "substeps/step " + std::to_string(r.substepsPerStep));
}

void recordDisc(CsvWriter& csv, double parameter, const std::string& method, const test::RotatingDiscResult& r) {
  const std::string note = r.ok ? "" : "step rejected at " + std::to_string(r.stepsDone + 1) + " (" + r.failure + ")";
  record(csv, parameter, method, r.ok ? r.energyRatio : std::numeric_limits<double>::infinity(), -r.minOverMax,
         r.massError, note);
}

const std::initializer_list<CoriolisScheme> kCoriolisSchemes = {
    CoriolisScheme::ExactRotation, CoriolisScheme::SplitRotation, CoriolisScheme::Explicit};

const char* coriolisLabel(CoriolisScheme scheme) {
  switch (scheme) {
    case CoriolisScheme::ExactRotation: return "Coriolis: ours (frame change)";
    case CoriolisScheme::SplitRotation: return "Coriolis: split rotation (before)";
    case CoriolisScheme::Explicit: return "Coriolis: explicit";
  }
  return "?";
}

/// Kinetic energy ratio of liquid at rest in the inertial frame under the frame
/// change: its relative speed is the frame's chord speed ω r sinc(ωh/2).
double chordEnergyRatio(double omegaH) {
  const double x = 0.5 * omegaH;
  return x == 0 ? 1.0 : std::pow(std::sin(x) / x, 2);
}

const std::initializer_list<test::AdvectionMethod> kAdvectionMethods = {
    test::AdvectionMethod::Ours, test::AdvectionMethod::CapOne, test::AdvectionMethod::Naive};

// Diffusion on a 32x32 unit square (D = 1e-2 m²/s isotropic), advection of a
// blob by 2 rad/s on a 32-ring disc, and the Fig. 5 disc at 2 rad/s with
// liquid at rest in the inertial frame; 50 steps of each h.
TEST(StabilityStudy, TimeStepSweep) {
  CsvWriter csv("stability_timestep.csv", kHeader);
  const LiquidMesh square(gridMesh(32, 32, 1, 1),
                          uniformFabric(2 * 32 * 32, fabricTensor(1e-2, 1e-2), fabricTensor(1, 1), 0.0));
  const double lambda = test::largestDiffusionEigenvalue(square.intrinsic.densityStiffness, square.areas());
  std::printf("  explicit diffusion stability limit 2/lambda_max = %.4g s\n", 2 / lambda);
  const TriangleMesh disc = discMesh(32, 1.0);
  const LiquidMesh discGeometry(disc, isotropicFabric(static_cast<int>(disc.faces.rows())));
  const int steps = 50;
  for (const double h : {1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0}) {
    const DiffusionOutcome ours = runDiffusion(square, h, steps, true, true);
    recordDiffusion(csv, h, "diffusion: ours (Auto + limiter)", ours);
    recordForcedDiffusion(csv, h, square, h, steps, "diffusion: ");
    recordDiffusion(csv, h, "diffusion: explicit", runDiffusion(square, h, steps, false, false));
    EXPECT_FALSE(ours.health.blewUp());
    EXPECT_GE(ours.health.minOverMax, 0.0);
    EXPECT_LT(ours.massError, 1e-12);

    for (const test::AdvectionMethod method : kAdvectionMethods) {
      test::RotationAdvectionSetup setup;
      setup.omega = 2.0;
      setup.h = h;
      setup.steps = steps;
      setup.method = method;
      const test::RotationAdvectionResult r = test::runRigidRotationAdvection(discGeometry, setup);
      recordAdvection(csv, h, method, r);
      if (method == test::AdvectionMethod::Ours) {
        EXPECT_FALSE(r.health.blewUp());
        EXPECT_GE(r.health.minOverMax, 0.0);
        EXPECT_LT(r.massError, 1e-12);
      }
    }

    for (const CoriolisScheme scheme : kCoriolisSchemes) {
      test::RotatingDiscSetup setup;
      setup.rings = 32;
      setup.h = h;
      setup.duration = steps * h;
      setup.scheme = scheme;
      setup.filmEverywhere = true;
      const test::RotatingDiscResult r = test::runRotatingDisc(setup);
      recordDisc(csv, h, coriolisLabel(scheme), r);
      if (scheme == CoriolisScheme::ExactRotation) {
        // Never a blow-up and never an energy gain: the relative speed is the
        // chord speed at every ωh (docs/transport.md).
        EXPECT_TRUE(r.ok) << r.failure;
        EXPECT_NEAR(r.energyRatio, chordEnergyRatio(setup.omega * h), 1e-9);
        EXPECT_LE(r.energyRatio, 1.0 + 1e-12);
      }
    }
  }
  // Over a longer run at h = 1 s (ωh = 2 rad per step): ours, the split step,
  // and both without the film (the blob alone, dry vertices keeping the
  // initial velocity as a placeholder).
  for (const int longSteps : {50, 100, 200}) {
    for (const CoriolisScheme scheme : {CoriolisScheme::ExactRotation, CoriolisScheme::SplitRotation}) {
      for (const bool film : {true, false}) {
        test::RotatingDiscSetup setup;
        setup.rings = 32;
        setup.h = 1.0;
        setup.duration = longSteps;
        setup.scheme = scheme;
        setup.filmEverywhere = film;
        const test::RotatingDiscResult r = test::runRotatingDisc(setup);
        std::printf("  %s at h = 1 s, %d steps, %s: energy ratio %.3f %s\n", coriolisLabel(scheme), longSteps,
                    film ? "film everywhere" : "blob only", r.energyRatio, r.ok ? "" : r.failure.c_str());
        if (scheme == CoriolisScheme::ExactRotation && film) {
          EXPECT_NEAR(r.energyRatio, chordEnergyRatio(2.0), 1e-9);
        }
      }
    }
  }
}

/// How one velocity-diffusion run solves (runVelocity).
enum class VelocityMode { WholeMeshFactor, WholeMeshRkl2, BandAuto, BandCg, BandRkl2, Explicit };

struct VelocityOutcome {
  double amplification = 0;  ///< max|u_end| / max|u_0| (1e30 if non-finite)
  Eigen::VectorXcd u;        ///< u at the end
  Eigen::VectorXcd first;    ///< u after the first step
  std::string methods;       ///< the velocity method of each step, as DiffusionOutcome's
  DiffusionMethod firstMethod = DiffusionMethod::None;
};

/// `steps` steps of velocity diffusion (viscosity only) of a smooth field:
/// u = bump × the world x direction in each vertex's tangent basis, on the
/// vertices within 0.2 of the square's centre (the "liquid"). Whole mesh by
/// the factor; or on the band, the engine's liquid band with the liquid fixed:
/// rows = the liquid and its ring, their other neighbours' values held
/// (Dirichlet, here 0); or explicit, u ← u − h M⁻¹ L u on the whole mesh.
VelocityOutcome runVelocity(const LiquidMesh& g, double h, int steps, VelocityMode mode) {
  const int n = g.vertexCount();
  const std::vector<int>& offsets = g.topology.ringOffsets();
  const std::vector<int>& neighbors = g.topology.ringNeighbors();
  Eigen::VectorXcd u0 = Eigen::VectorXcd::Zero(n);
  std::vector<char> rows(static_cast<size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    const double b = test::bump(g.position(i).head<2>(), Vector2(0.5, 0.5), 0.2);
    if (b <= 0) continue;
    // The first ring edge is the tangent basis's x axis (the polar map's
    // reference; the square is flat and these vertices are interior).
    const Vector3 e = g.position(neighbors[static_cast<size_t>(offsets[i])]) - g.position(i);
    u0[i] = b * std::polar(1.0, -std::atan2(e.y(), e.x()));
    rows[static_cast<size_t>(i)] = 1;
    for (int m = offsets[i]; m < offsets[i + 1]; ++m) rows[static_cast<size_t>(neighbors[static_cast<size_t>(m)])] = 1;
  }
  VelocityOutcome out;
  Eigen::VectorXcd u = u0;
  if (mode == VelocityMode::Explicit) {
    const ComplexSparseMatrix& L = g.intrinsic.velocityStiffness;
    for (int k = 0; k < steps && u.allFinite(); ++k) {
      u -= h * (L * u).cwiseQuotient(g.areas().cast<Complex>());
      if (k == 0) out.first = u;
    }
  } else {
    DiffusionSystems systems;
    const bool rkl2 = mode == VelocityMode::BandRkl2 || mode == VelocityMode::WholeMeshRkl2;
    systems.setSolverChoice(mode == VelocityMode::WholeMeshFactor ? DiffusionSolverChoice::Direct
                            : mode == VelocityMode::BandCg        ? DiffusionSolverChoice::Iterative
                            : rkl2                                ? DiffusionSolverChoice::SuperTimeStepping
                                                                  : DiffusionSolverChoice::Auto);
    if (systems.assemble(g.intrinsic, h) != SolverStatus::Ok) throw std::runtime_error("assemble failed");
    DiffusionScratch scratch;
    scratch.resize(n);
    StainState state = zeroState(n);
    state.velocities = u0;
    PhysicsSwitches switches;
    switches.densityDiffusion = false;
    const StepContext ctx = makeStepContext(h, Vector3(0, 0, -9.8), switches, LiquidParameters{});
    const bool whole = mode == VelocityMode::WholeMeshFactor || mode == VelocityMode::WholeMeshRkl2;
    const std::vector<char>* band = whole ? nullptr : &rows;
    MethodRuns methods;
    for (int k = 0; k < steps; ++k) {
      const DiffusionReport report = diffuse(ctx, g.intrinsic, systems, scratch, state, band);
      if (report.status != SolverStatus::Ok) throw std::runtime_error("diffuse failed");
      if (k == 0) {
        out.first = state.velocities;
        out.firstMethod = report.velocityMethod;
      }
      methods.add(methodLabel(report.velocityMethod, report.velocityStages, report.fallbacks > 0));
    }
    out.methods = methods.finish();
    u = state.velocities;
  }
  const double largest = u.allFinite() ? u.cwiseAbs().maxCoeff() : std::numeric_limits<double>::infinity();
  out.amplification = largest / u0.cwiseAbs().maxCoeff();
  out.u = u;
  return out;
}

// Velocity diffusion (the connection Laplacian, viscosity 0.01 m²/s) on a
// 32x32 unit square, 50 steps of each h: the whole-mesh backward Euler by the
// factor, the liquid band's solve (Auto, CG and RKL2 forced) and explicit.
// Columns as the other sweeps', except that the fourth is not a negativity
// (velocities have signs) but the band's relative difference from the same
// scheme on the whole mesh (backward Euler by the factor for CG, whole-mesh
// RKL2 for RKL2) after the first step, on the liquid's vertices:
// √(Σ A|u − u_whole|²) / √(Σ A|u_whole|²) over the vertices that hold the
// bump (0 for the whole-mesh rows). One step, as the engine takes one on each
// band before it grows the band again from where the liquid went; over 50
// steps a band held in place with zero boundary values drains the field,
// which the amplification shows.
TEST(StabilityStudy, VelocityTimeStepSweep) {
  CsvWriter csv("stability_velocity.csv", kHeader);
  const LiquidMesh square(gridMesh(32, 32, 1, 1),
                          uniformFabric(2 * 32 * 32, fabricTensor(1e-2, 1e-2), fabricTensor(1e-2, 1e-2), 0.0));
  std::vector<char> liquid(static_cast<size_t>(square.vertexCount()), 0);
  for (int i = 0; i < square.vertexCount(); ++i)
    liquid[static_cast<size_t>(i)] = test::bump(square.position(i).head<2>(), Vector2(0.5, 0.5), 0.2) > 0;
  const auto differenceOnLiquid = [&](const Eigen::VectorXcd& u, const Eigen::VectorXcd& reference) {
    double difference = 0, norm = 0;
    for (int i = 0; i < square.vertexCount(); ++i) {
      if (!liquid[static_cast<size_t>(i)]) continue;
      difference += square.areas()[i] * std::norm(u[i] - reference[i]);
      norm += square.areas()[i] * std::norm(reference[i]);
    }
    return std::sqrt(difference / norm);
  };
  const int steps = 50;
  const std::pair<VelocityMode, const char*> modes[] = {
      {VelocityMode::WholeMeshFactor, "velocity: whole mesh: backward Euler by the factor"},
      {VelocityMode::WholeMeshRkl2, "velocity: whole mesh: RKL2 (forced)"},
      {VelocityMode::BandAuto, "velocity: ours: the band (Auto)"},
      {VelocityMode::BandCg, "velocity: the band: backward Euler by CG (forced)"},
      {VelocityMode::BandRkl2, "velocity: the band: RKL2 (forced)"},
      {VelocityMode::Explicit, "velocity: explicit on the whole mesh"}};
  for (const double h : {1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0}) {
    const VelocityOutcome whole = runVelocity(square, h, steps, VelocityMode::WholeMeshFactor);
    const VelocityOutcome wholeRkl2 = runVelocity(square, h, steps, VelocityMode::WholeMeshRkl2);
    for (const auto& [mode, label] : modes) {
      const VelocityOutcome o = mode == VelocityMode::WholeMeshFactor ? whole
                                : mode == VelocityMode::WholeMeshRkl2 ? wholeRkl2
                                                                      : runVelocity(square, h, steps, mode);
      const VelocityOutcome& reference = o.firstMethod == DiffusionMethod::SuperTimeStepping ? wholeRkl2 : whole;
      const double difference = o.first.allFinite() ? differenceOnLiquid(o.first, reference.first) : kCeiling;
      record(csv, h, label, o.amplification, difference, 0.0, o.methods);
      if (mode != VelocityMode::Explicit) {
        EXPECT_TRUE(std::isfinite(o.amplification)) << label << " at h = " << h;
        EXPECT_LE(o.amplification, 1.0 + 1e-12) << label << " at h = " << h;
      }
    }
  }
}

// Implicit diffusion on a 40x40 unit square, weft at 30°, D_weft = 1e-2 m²/s,
// D_warp = D_weft / ratio, h = 0.1 s (h D / dx² = 1.6), 20 steps. Explicit at
// the same h (above its limit ~0.016 s), and explicit split into enough
// sub-steps to be stable (the M-matrix loss then shows as negativity).
TEST(StabilityStudy, AnisotropySweep) {
  CsvWriter csv("stability_anisotropy.csv", kHeader);
  const int n = 40;
  const double h = 0.1;
  const int steps = 20;
  for (const double ratio : {1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6}) {
    const LiquidMesh g(gridMesh(n, n, 1, 1), uniformFabric(2 * n * n, fabricTensor(1e-2, 1e-2 / ratio),
                                                           fabricTensor(1, 1), kPi / 6));
    const double lambda = test::largestDiffusionEigenvalue(g.intrinsic.densityStiffness, g.areas());
    const int substeps = static_cast<int>(std::ceil(h * lambda / 1.9));
    const DiffusionOutcome ours = runDiffusion(g, h, steps, true, true);
    recordDiffusion(csv, ratio, "ours (Auto + limiter)", ours);
    recordForcedDiffusion(csv, ratio, g, h, steps, "");
    recordWithoutLimiter(csv, ratio, g, h, steps, "", "positivity limiter");
    recordDiffusion(csv, ratio, "explicit", runDiffusion(g, h, steps, false, false));
    recordDiffusion(csv, ratio, "explicit with stable sub-steps", runDiffusion(g, h, steps, false, false, substeps),
                    std::to_string(substeps) + " sub-steps per step");
    EXPECT_FALSE(ours.health.blewUp());
    EXPECT_GE(ours.health.minOverMax, 0.0);
    EXPECT_LT(ours.massError, 1e-12);
  }
}

// Flat unit squares with sliver bands (sliverSquareMesh: 32 columns, 16 bands;
// smallest angle θ, largest 180° − 2θ). Diffusion D = 1e-3 m²/s, h = 0.01 s,
// 50 steps (explicit at this h is stable on the regular 32x32 grid: limit
// ~0.25 s); advection by a rigid rotation of 2 rad/s about the centre, h =
// 0.01 s, 50 steps; and the whole StainSolver (every term on, sheet tilted 0.3
// rad, a drop with a splash) for 50 steps of 0.01 s.
TEST(StabilityStudy, MeshQualitySweep) {
  CsvWriter csv("stability_mesh_quality.csv", kHeader);
  const double h = 0.01;
  const int steps = 50;
  for (const double angle : {30.0, 10.0, 3.0, 1.0, 0.3, 0.1}) {
    const TriangleMesh mesh = test::sliverSquareMesh(32, 16, angle);
    std::printf("  smallest angle %.3f deg, %d vertices\n", test::smallestAngleDegrees(mesh),
                static_cast<int>(mesh.vertexPositions.rows()));
    const int faces = static_cast<int>(mesh.faces.rows());
    const LiquidMesh g(mesh, uniformFabric(faces, fabricTensor(1e-3, 1e-3), fabricTensor(1e-3, 1e-3), 0.0));
    const DiffusionOutcome ours = runDiffusion(g, h, steps, true, true);
    recordDiffusion(csv, angle, "diffusion: ours (Auto + limiter)", ours);
    recordForcedDiffusion(csv, angle, g, h, steps, "diffusion: ");
    recordWithoutLimiter(csv, angle, g, h, steps, "diffusion: ", "limiter");
    recordDiffusion(csv, angle, "diffusion: explicit", runDiffusion(g, h, steps, false, false));
    EXPECT_FALSE(ours.health.blewUp());
    EXPECT_GE(ours.health.minOverMax, 0.0);

    for (const test::AdvectionMethod method : kAdvectionMethods) {
      test::RotationAdvectionSetup setup;
      setup.omega = 2.0;
      setup.h = h;
      setup.steps = steps;
      setup.center = Vector2(0.5, 0.5);
      setup.blobCenter = Vector2(0.7, 0.5);
      setup.blobRadius = 0.15;
      setup.method = method;
      const test::RotationAdvectionResult r = test::runRigidRotationAdvection(g, setup);
      recordAdvection(csv, angle, method, r);
      if (method == test::AdvectionMethod::Ours) {
        EXPECT_FALSE(r.health.blewUp());
        EXPECT_GE(r.health.minOverMax, 0.0);
        EXPECT_LT(r.massError, 1e-12);
      }
    }

    // The whole step on the sliver mesh: every term on; an isotropic fabric,
    // and a 4:1 one with the weft at 30° (the anisotropic stiffness on the
    // slivers: the limiter's hardest case).
    const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()));
    for (const bool anisotropic : {false, true}) {
      StainSolverDef def;
      def.gravity = Vector3(0, -9.8 * std::sin(0.3), -9.8 * std::cos(0.3));
      const FabricField fabric =
          anisotropic ? uniformFabric(faces, fabricTensor(2e-3, 5e-4), fabricTensor(2e-3, 5e-4), kPi / 6)
                      : isotropicFabricField(faces, 1e-3, 1e-3);
      StainSolver solver(topology, mesh.vertexPositions, fabric, def);
      DropDef drop;
      drop.centerPoint = Vector3(0.5, 0.6, 0);
      drop.radius = 0.15;
      drop.solventMass = 0.01;
      drop.soluteMass = 0.001;
      drop.splashSpeed = 0.3;
      drop.splashSeed = 3;
      solver.addDrop(drop);
      // Free + absorbed solvent: absorption moves the liquid into the fibres.
      const double max0 = solver.state().solvent.maxCoeff();
      std::string note;
      for (int k = 0; k < steps; ++k) {
        const StepReport report = solver.step(h, mesh.vertexPositions);
        if (report.status != StepStatus::Ok) {
          note = "step " + std::to_string(k + 1) + " rejected: " + std::string(report.stageName()) + ": " +
                 report.message;
          break;
        }
      }
      const test::FieldHealth health =
          test::fieldHealth(solver.state().solvent + solver.state().absorbedSolvent, max0);
      const MassBudget budget = solver.massBudget();
      record(csv, angle,
             anisotropic ? "whole step: ours (StainSolver), 4:1 fabric" : "whole step: ours (StainSolver)",
             health.growth, -health.minOverMax, std::max(budget.solventError(), budget.soluteError()), note);
      EXPECT_TRUE(note.empty()) << note;
      EXPECT_GE(health.minOverMax, 0.0);
      EXPECT_LT(std::max(budget.solventError(), budget.soluteError()), 1e-12);
    }
  }
}

// The Fig. 5 disc (32 rings) with liquid at rest in the inertial frame, h =
// 0.01 s, 0.5 s; kinetic energy in the disc frame must stay constant. And the
// density advection of a blob by the same rotation on a static disc.
TEST(StabilityStudy, RotationSpeedSweep) {
  CsvWriter csv("stability_rotation.csv", kHeader);
  const double h = 0.01;
  const TriangleMesh disc = discMesh(32, 1.0);
  const LiquidMesh discGeometry(disc, isotropicFabric(static_cast<int>(disc.faces.rows())));
  for (const double omega : {0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0}) {
    for (const CoriolisScheme scheme : kCoriolisSchemes) {
      test::RotatingDiscSetup setup;
      setup.rings = 32;
      setup.omega = omega;
      setup.h = h;
      setup.duration = 0.5;
      setup.scheme = scheme;
      setup.filmEverywhere = true;
      const test::RotatingDiscResult r = test::runRotatingDisc(setup);
      recordDisc(csv, omega, coriolisLabel(scheme), r);
      if (scheme == CoriolisScheme::ExactRotation) {
        EXPECT_TRUE(r.ok) << r.failure;
        EXPECT_NEAR(r.energyRatio, chordEnergyRatio(omega * h), 1e-9);
      }
    }
    for (const test::AdvectionMethod method : kAdvectionMethods) {
      test::RotationAdvectionSetup setup;
      setup.omega = omega;
      setup.h = h;
      setup.steps = 50;
      setup.method = method;
      const test::RotationAdvectionResult r = test::runRigidRotationAdvection(discGeometry, setup);
      recordAdvection(csv, omega, method, r);
      if (method == test::AdvectionMethod::Ours) {
        EXPECT_FALSE(r.health.blewUp());
        EXPECT_GE(r.health.minOverMax, 0.0);
      }
    }
  }
}

}  // namespace
}  // namespace blot::stain
