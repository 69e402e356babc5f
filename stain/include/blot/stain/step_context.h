#pragma once
/// Per-step constants (a fresh, const StepContext each step), the physics
/// switches and liquid parameters a scene sets, and what a step reports.
#include <blot/stain/types.h>

#include <string>

namespace blot::stain {

/// Which vertices evaporate faster by a_evap (paper eq. (10): "the effective
/// exposed area of the boundary cells is greater").
enum class EvaporationBoundary {
  MeshBoundary,  ///< vertices on the mesh boundary (the literal reading)
  WetFront       ///< also vertices holding liquid next to one that does not (the liquid's own edge)
};

/// Liquid/fabric interaction parameters (paper sec. 5). Units: densities kg/m²,
/// rates 1/s, evaporation kg/(m² s).
struct LiquidParameters {
  double absorptionRate = 0.1;        ///< K_p (1/s).
  double saturationDensity = 4.0;     ///< σ_sat (kg/m²).
  double desorptionRate = 0.05;       ///< K_d (1/s), eq. (9).
  double adsorptionCapacity = 0.5;    ///< A_d (kg/m²), eq. (9).
  double evaporationRate = 0.01;      ///< K_evap (kg/(m² s)), eq. (10).
  double boundaryEvaporationFactor = 1.2;  ///< a_evap on boundary vertices (1 inside).
  EvaporationBoundary evaporationBoundary = EvaporationBoundary::MeshBoundary;  ///< where a_evap applies
  double wetThreshold = 1e-9;         ///< σ below which a vertex counts as dry (kg/m²).
  double liquidDensity = 1000.0;      ///< ρ (kg/m³), for the film pressure (PhysicsSwitches::filmPressure).
};

/// How the Coriolis term is integrated. ExactRotation (default): after the
/// velocity advection, the exact frame increment exp(−iω_n h) plus the frame
/// velocity's change along the backtrack (applyHalfFrameRotation and
/// applyFrameVelocityChange; no energy is
/// created at any ωh), or exp(−2iω_n h) when the velocity is not advected.
/// SplitRotation: always exp(−2iω_n h) after advection (the previous default;
/// energy grows at ωh ≳ 1). Explicit adds −2h ω × u (gains energy; kept only
/// for comparison).
enum class CoriolisScheme { ExactRotation, Explicit, SplitRotation };

/// Every physics term can be switched off. Terms a scene does not need are
/// also skipped automatically (static mesh: no inertia; no solute: no solute
/// transport); the profile says which ran.
struct PhysicsSwitches {
  bool gravity = true;
  bool linearInertia = true;     ///< −Fᵀ p̈
  bool coriolis = true;          ///< −2 ω × u
  bool velocityAdvection = true;
  bool densityAdvection = true;
  bool densityDiffusion = true;
  bool velocityDiffusion = true;
  bool absorption = true;
  bool adsorption = true;
  bool evaporation = true;
  bool sources = true;
  /// −∇p_ext/ρ of eq. (3) with the film's hydrostatic pressure (the paper
  /// ignores it; off by default). Drives liquid from thick to thin film: the
  /// outward flow that forms the ring of Fig. 11 (see film_pressure.h).
  bool filmPressure = false;
  bool positivityLimiter = true;  ///< mass-conserving fix of negative densities after diffusion
  CoriolisScheme coriolisScheme = CoriolisScheme::ExactRotation;
};

struct StepContext {
  double h = 0.01;        ///< time step (s)
  double invH = 100.0;    ///< 1 / h
  Vector3 gravity = Vector3(0, 0, -9.8);  ///< world gravity (m/s²)
  PhysicsSwitches switches;
  LiquidParameters liquid;
  int maxAdvectionSubsteps = 64;  ///< cap on density-advection sub-steps per step
};

/// Makes a context; h must be finite and positive (checked by the caller's guard).
inline StepContext makeStepContext(double h, const Vector3& gravity, const PhysicsSwitches& switches,
                                   const LiquidParameters& liquid) {
  StepContext ctx;
  ctx.h = h;
  ctx.invH = 1.0 / h;
  ctx.gravity = gravity;
  ctx.switches = switches;
  ctx.liquid = liquid;
  return ctx;
}

/// One bit per term of the stain step (StepProfile::terms). A bit is set when
/// the term did work this step; a term switched off (PhysicsSwitches), with a
/// zero coefficient (rate, gravity), or with nothing to act on (no wet vertex,
/// a surface that did not move) is skipped and its bit stays clear.
enum class StepTerm : unsigned {
  RotationFits = 1u << 0,        ///< extrinsic refresh with a rotation fit per vertex (all #V)
  RigidFrames = 1u << 1,         ///< extrinsic refresh of a known rigid motion, no fits (all #V)
  IntrinsicRebuild = 1u << 2,    ///< metric rebuilt: the strain passed the tolerance (all #V)
  Factorization = 1u << 3,       ///< diffusion systems refactorized (new metric or new h)
  Gravity = 1u << 4,             ///< tangential gravity (band)
  LinearInertia = 1u << 5,       ///< −Fᵀ p̈ (band)
  Coriolis = 1u << 6,            ///< −2 ω × u (band; the frame change on the reach set)
  FilmPressure = 1u << 7,        ///< −∇p_ext/ρ (band)
  VelocityAdvection = 1u << 8,   ///< semi-Lagrangian u (the band's reach set)
  DensityAdvection = 1u << 9,    ///< upwind σ fluxes (wet + sub-step rings, inside the reach set)
  DensityDiffusionKrylov = 1u << 10,   ///< σ_f, σ_s by CG on the liquid's Krylov support
  DensityDiffusionDirect = 1u << 11,   ///< σ_f, σ_s by the factorization (all #V)
  VelocityDiffusionKrylov = 1u << 12,  ///< u by CG on the band (its outermost ring as boundary data)
  VelocityDiffusionDirect = 1u << 13,  ///< u by the factorization (all #V)
  Absorption = 1u << 14,         ///< K_p > 0 (reach set)
  Adsorption = 1u << 15,         ///< K_d > 0 (reach set)
  Evaporation = 1u << 16,        ///< K_evap > 0 (reach set)
  Sources = 1u << 17,            ///< held regions
};
/// Number of StepTerm bits (bit k = 1u << k for k in [0, kStepTermCount)).
inline constexpr int kStepTermCount = 18;

/// Wall-clock milliseconds per stage of the last step, and counters.
struct StepProfile {
  double geometry = 0, forces = 0, advectVelocity = 0, advectDensity = 0, diffuse = 0, interact = 0,
         sources = 0, total = 0;
  int advectionSubsteps = 0;       ///< density-advection sub-steps taken
  int intrinsicRefreshes = 0;      ///< 1 if the metric changed enough to refactorize this step
  double maxEdgeStrain = 0;        ///< largest |ℓ/ℓ_factored − 1| this step
  int wetVertices = 0;             ///< vertices holding liquid at the start of the step
  int diffusionIterations = 0;     ///< CG iterations, density + velocity (0: direct solves)
  int limiterCorrectedVertices = 0;  ///< vertices whose negative density the limiter fixed
  double limiterMovedMass = 0;     ///< kg moved by the positivity limiter
  unsigned terms = 0;              ///< StepTerm bits of the terms that ran (see describeTerms)
  int vertexCount = 0;             ///< #V of the surface
  int haloVertices = 0;            ///< dry vertices next to wet ones (level 1 of the band)
  /// Vertices of the liquid band (wet + the rings the step can reach and read,
  /// StainSolver::bandVertices; the whole mesh with a direct velocity solve).
  int bandVertices = 0;
  int bandRings = 0;               ///< rings of the band beyond the wet set
  int reachRings = 0;              ///< rings liquid and foot points can move this step (R)
  int geometryVertices = 0;        ///< vertices the extrinsic refresh recomputed (#V, 0 if the surface did not move)
  int advectionVertices = 0;       ///< vertices density advection worked on (wet + sub-step halo, or #V)
  int densityDiffusionVertices = 0;   ///< rows of the density solve (Krylov support, #V if direct)
  int velocityDiffusionVertices = 0;  ///< rows of the velocity solve (band less its outer ring, #V if direct)
  bool ran(StepTerm term) const { return (terms & static_cast<unsigned>(term)) != 0; }
  /// Adds another step's stage times (ms), for sums over steps.
  void addTimes(const StepProfile& other) {
    geometry += other.geometry;
    forces += other.forces;
    advectVelocity += other.advectVelocity;
    advectDensity += other.advectDensity;
    diffuse += other.diffuse;
    interact += other.interact;
    sources += other.sources;
    total += other.total;
  }
  void markRan(StepTerm term) { terms |= static_cast<unsigned>(term); }
};

/// Short name of one term ("gravity", "density-diffusion-krylov", ...).
const char* stepTermName(StepTerm term);
/// The terms that ran in `profile`, in StepTerm order, with the vertices they
/// worked on, e.g. "rigid-frames[140625] gravity coriolis velocity-advection
/// density-advection[612] density-diffusion-krylov[890] ... (wet 420 + halo 96
/// of 140625)"; "none" when nothing ran. Allocates (a report, not for the
/// frame loop).
std::string describeTerms(const StepProfile& profile);

/// Numerical failure inside a step (tier c): the stage, the vertex, and why.
enum class StepStatus { Ok, SolverFailure, NonFinite, NegativeMass, InvalidArgument };

struct StepReport {
  StepStatus status = StepStatus::Ok;
  std::string stage;   ///< e.g. "diffuse"
  int vertex = -1;     ///< offending vertex, or -1
  std::string message;
};

}  // namespace blot::stain
