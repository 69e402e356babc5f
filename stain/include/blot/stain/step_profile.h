#pragma once
/// The step's vocabulary: one Stage per line of the coupled step (DESIGN.md,
/// docs/architecture.md), and what a step reports: its status, the time and
/// work of each stage (StepProfile), and the terms each stage ran (StepTerm).
#include <blot/stain/output_fields.h>

#include <array>
#include <string>

namespace blot::stain {

/// One line of the coupled step, in step order. It indexes the profile's
/// times and "ran" bits, StepReport::stage and InjectedFault::stage.
/// Guard and Validate are the checks before and after the work; Drops, Cloth
/// and Coupling belong to the coupled step (coupling/, engine/), the others to
/// the stain step (StainSolver), which checks its output after each of Sources,
/// BodyForces … Interact (those can carry an InjectedFault).
enum class Stage : int {
  Guard,           ///< arguments checked before anything changes
  Drops,           ///< drops queued since the last step are added
  Cloth,           ///< the cloth (any SurfaceMotion) advances to t + h
  Geometry,        ///< extrinsic refresh; intrinsic rebuild and refactorization when the metric changed
  Sources,         ///< held regions, topped up first so new liquid gets this step's forces
  LiquidBand,      ///< the wet set, the band around it and u extended onto it
  BodyForces,      ///< tangential gravity and linear inertia −Fᵀp̈
  FilmPressure,    ///< gravity and the film's hydrostatic pressure, one potential gradient
  FilmFriction,    ///< the film's drag on the fabric, −3νu/(H(H + 3λ)), implicit
  AdvectVelocity,  ///< semi-Lagrangian u
  Coriolis,        ///< −2ω × u (discrete frame change, or a rotation after advection)
  AdvectDensity,   ///< upwind σ fluxes
  Diffuse,         ///< implicit diffusion of σ_f, σ_s and u
  Interact,        ///< absorption, adsorption, evaporation
  Validate,        ///< every value finite and no negative density after the stain step
  Coupling,        ///< liquid mass and momentum exchanged with the cloth
};
/// The last stage: a stage added after Coupling moves this line.
inline constexpr Stage kLastStage = Stage::Coupling;
inline constexpr int kStageCount = static_cast<int>(kLastStage) + 1;
/// The stain step's stages (StainSolver), Geometry through Interact.
inline constexpr Stage kFirstStainStage = Stage::Geometry;
inline constexpr Stage kLastStainStage = Stage::Interact;

/// The stage's name in reports, fault injection and profile JSON ("guard",
/// "cloth", "forces", "film-pressure", "advect-velocity", ...).
const char* stageName(Stage stage);
/// The stage named `name` (as stageName writes it); false when there is none.
bool parseStage(const std::string& name, Stage& stage);

/// What a stage did, one bit per term (StepProfile::terms): the finer record
/// behind StepProfile::ran(Stage) (which forces, which solver, fits or rigid
/// frames). A bit is set when the term did work this step; a term switched off
/// (PhysicsSwitches), with a zero coefficient (rate, gravity), or with nothing
/// to act on (no wet vertex, a surface that did not move) stays clear.
/// stageOf(term) is the stage it belongs to.
enum class StepTerm : unsigned {
  RotationFits = 1u << 0,        ///< Geometry: a rotation fit per vertex (on the geometryVertices)
  RigidFrames = 1u << 1,         ///< Geometry: a known rigid motion, no fits (all #V)
  IntrinsicRebuild = 1u << 2,    ///< Geometry: metric rebuilt, the strain passed the tolerance (all #V)
  Factorization = 1u << 3,       ///< Diffuse: a numeric factorization, at the first direct solve after new values
  Gravity = 1u << 4,             ///< BodyForces: tangential gravity (band)
  LinearInertia = 1u << 5,       ///< BodyForces: −Fᵀ p̈ (band)
  Coriolis = 1u << 6,            ///< Coriolis: −2 ω × u (band; the frame change on the reach set)
  FilmPressure = 1u << 7,        ///< FilmPressure: −∇(−g·x + g_n H) on the free liquid
  VelocityAdvection = 1u << 8,   ///< AdvectVelocity: semi-Lagrangian u (the band's reach set)
  DensityAdvection = 1u << 9,    ///< AdvectDensity: upwind σ fluxes (wet + sub-step rings, inside the reach set)
  DensityDiffusionKrylov = 1u << 10,   ///< Diffuse: σ_f, σ_s by CG on the liquid's Krylov support
  DensityDiffusionDirect = 1u << 11,   ///< Diffuse: σ_f, σ_s by the factorization (all #V)
  VelocityDiffusionKrylov = 1u << 12,  ///< Diffuse: u by CG on the band (its vertices next to the outside as boundary data)
  VelocityDiffusionDirect = 1u << 13,  ///< Diffuse: u by the factorization (all #V)
  Absorption = 1u << 14,         ///< Interact: K_p > 0 (reach set)
  Adsorption = 1u << 15,         ///< Interact: K_d > 0 (reach set)
  Evaporation = 1u << 16,        ///< Interact: K_evap > 0 (reach set)
  Sources = 1u << 17,            ///< Sources: held regions
  SystemAssembly = 1u << 18,     ///< Geometry: M + h L refilled (new metric or new h; factors now stale)
  FilmFriction = 1u << 19,       ///< FilmFriction: the film's drag on the fabric (free liquid)
  SoluteWithSolvent = 1u << 20,  ///< Diffuse: the solution's flux carries its solute, plus D_m (band)
  VelocityDiffusionByMass = 1u << 21,  ///< Diffuse: u by CG with mass weights on the free liquid
};
/// Number of StepTerm bits (bit k = 1u << k for k in [0, kStepTermCount)).
/// VelocityDiffusionByMass is the last bit: a term added after it moves this line.
inline constexpr int kStepTermCount = 22;
static_assert(1u << (kStepTermCount - 1) == static_cast<unsigned>(StepTerm::VelocityDiffusionByMass),
              "kStepTermCount counts the StepTerm bits up to the last one");

/// Short name of one term ("gravity", "density-diffusion-krylov", ...).
const char* stepTermName(StepTerm term);
/// The stage's name with '_' for '-' ("advect_velocity"): its key in JSON and
/// Python dicts.
std::string stageKey(Stage stage);
/// The stage a term belongs to.
Stage stageOf(StepTerm term);

struct StepProfile;
std::string describeTerms(const StepProfile& profile);  // below; StepProfile::fields lists it

/// Wall-clock milliseconds per stage of the last step, what ran, and counters.
struct StepProfile {
  std::array<double, kStageCount> milliseconds{};  ///< per Stage (ms)
  double total = 0;                ///< the whole step (ms)
  unsigned stagesRan = 0;          ///< bit k: Stage k did work this step
  unsigned terms = 0;              ///< StepTerm bits of the terms that ran (see describeTerms)
  int advectionSubsteps = 0;       ///< density-advection sub-steps taken
  /// Film sub-steps (potential, friction, density advection) the step took
  /// to keep the friction-dominated film stable (1 without the film terms).
  int filmSubsteps = 0;
  /// Kinetic energy the film's friction with the fabric took this step (J).
  double frictionDissipation = 0;
  /// Kinetic energy the mass-weighted in-plane viscosity took this step (J).
  double viscousDissipation = 0;
  int intrinsicRefreshes = 0;      ///< 1 if the metric changed enough to rebuild the operators this step
  int factorizations = 0;          ///< numeric Cholesky factorizations this step (direct solves only; 0–2)
  double maxEdgeStrain = 0;        ///< largest |ℓ/ℓ_factored − 1| this step
  int wetVertices = 0;             ///< vertices holding liquid at the start of the step
  int diffusionIterations = 0;     ///< CG iterations, density + velocity (0: direct solves)
  int limiterCorrectedVertices = 0;  ///< vertices whose negative density the limiter fixed
  double limiterMovedMass = 0;     ///< kg moved by the positivity limiter
  int vertexCount = 0;             ///< #V of the surface
  int threads = 1;                 ///< OpenMP threads the step used (StainSolver::stepThreads)
  int haloVertices = 0;            ///< dry vertices next to wet ones (level 1 of the band)
  /// Soaked vertices (liquid the fibres hold, u = 0) filed apart from the
  /// wet set, which is then the free liquid (LiquidBand::soakedVertices).
  int soakedVertices = 0;
  /// Vertices of the liquid band (wet + the rings the step can reach and read,
  /// StainSolver::bandVertices; the whole mesh with a direct velocity solve).
  int bandVertices = 0;
  int bandRings = 0;               ///< deepest level of the band (rings beyond the wet set)
  int reachRings = 0;              ///< deepest level of the reach set (where the advection can move liquid this step)
  int geometryVertices = 0;        ///< vertices whose extrinsic geometry the step computed (the band and
                                   ///< traces of liquid; #V in VertexRefresh::AllVertices; 0 if the surface did not move)
  int advectionVertices = 0;       ///< vertices density advection worked on (wet + sub-step halo, or #V)
  int densityDiffusionVertices = 0;   ///< rows of the density solve (Krylov support, #V if direct)
  int velocityDiffusionVertices = 0;  ///< rows of the velocity solve (band less its outer ring, #V if direct)

  /// Every field, once (output_fields.h): Python "last_profile" (the stage
  /// times, the terms that ran and a few counters), the viewer's stage bars.
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    constexpr unsigned notPython = kPythonOutput;
    v.perStage(outputField("milliseconds", "milliseconds", "ms"), s.milliseconds, Stage::Guard, kLastStage);
    v.field(outputField("total", "total_ms", "ms"), s.total);
    v.computed(outputField("describeTerms", "terms"), [&s] { return describeTerms(s); });
    v.field(outputField("stagesRan", "stages_ran").notIn(notPython), s.stagesRan);
    v.field(outputField("terms", "term_bits").notIn(notPython), s.terms);
    v.field(outputField("advectionSubsteps", "advection_substeps"), s.advectionSubsteps);
    v.field(outputField("filmSubsteps", "film_substeps"), s.filmSubsteps);
    v.field(outputField("frictionDissipation", "friction_dissipation", "J"), s.frictionDissipation);
    v.field(outputField("viscousDissipation", "viscous_dissipation", "J"), s.viscousDissipation);
    v.field(outputField("intrinsicRefreshes", "intrinsic_refreshes"), s.intrinsicRefreshes);
    v.field(outputField("factorizations", "factorizations"), s.factorizations);
    v.field(outputField("maxEdgeStrain", "max_edge_strain"), s.maxEdgeStrain);
    v.field(outputField("wetVertices", "wet_vertices"), s.wetVertices);
    v.field(outputField("bandVertices", "band_vertices"), s.bandVertices);
    v.field(outputField("diffusionIterations", "diffusion_iterations"), s.diffusionIterations);
    v.field(outputField("limiterCorrectedVertices", "limiter_corrected_vertices").notIn(notPython),
            s.limiterCorrectedVertices);
    v.field(outputField("limiterMovedMass", "limiter_moved_mass", "kg").notIn(notPython), s.limiterMovedMass);
    v.field(outputField("vertexCount", "vertex_count").notIn(notPython), s.vertexCount);
    v.field(outputField("threads", "threads").notIn(notPython), s.threads);
    v.field(outputField("haloVertices", "halo_vertices").notIn(notPython), s.haloVertices);
    v.field(outputField("soakedVertices", "soaked_vertices").notIn(notPython), s.soakedVertices);
    v.field(outputField("bandRings", "band_rings").notIn(notPython), s.bandRings);
    v.field(outputField("reachRings", "reach_rings").notIn(notPython), s.reachRings);
    v.field(outputField("geometryVertices", "geometry_vertices").notIn(notPython), s.geometryVertices);
    v.field(outputField("advectionVertices", "advection_vertices").notIn(notPython), s.advectionVertices);
    v.field(outputField("densityDiffusionVertices", "density_diffusion_vertices").notIn(notPython),
            s.densityDiffusionVertices);
    v.field(outputField("velocityDiffusionVertices", "velocity_diffusion_vertices").notIn(notPython),
            s.velocityDiffusionVertices);
  }

  double time(Stage stage) const { return milliseconds[static_cast<size_t>(stage)]; }
  bool ran(Stage stage) const { return (stagesRan & (1u << static_cast<unsigned>(stage))) != 0; }
  bool ran(StepTerm term) const { return (terms & static_cast<unsigned>(term)) != 0; }
  void markRan(Stage stage) { stagesRan |= 1u << static_cast<unsigned>(stage); }
  void markRan(StepTerm term) { terms |= static_cast<unsigned>(term); }
  /// The stain stages' time (ms): kFirstStainStage through kLastStainStage.
  double stainTime() const;
  /// Adds another step's stage times (ms), for sums over steps.
  void addTimes(const StepProfile& other) {
    for (int k = 0; k < kStageCount; ++k) milliseconds[static_cast<size_t>(k)] += other.milliseconds[static_cast<size_t>(k)];
    total += other.total;
  }
};
static_assert(describesEveryMember<StepProfile>(), "StepProfile changed: list the new field in StepProfile::fields");

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
  Stage stage = Stage::Guard;  ///< where it failed (meaningful when status != Ok)
  int vertex = -1;             ///< offending vertex, or -1
  std::string message;
  const char* stageName() const { return blot::stain::stageName(stage); }
  bool ok() const { return status == StepStatus::Ok; }
};

/// The step size's guard, the first thing a step checks, before anything
/// moves: Ok for a finite h > 0, else InvalidArgument at Stage::Guard naming
/// the value.
StepReport checkTimeStep(double h);

/// Testing only: a NaN written on purpose inside a step, so that tests and
/// `blot run --testing-inject-fault` exercise the fault path end to end (the
/// stage check, the rollback, the report). Never set it in production.
struct InjectedFault {
  /// Stage after which the NaN is written: Cloth (an impulse that blows up a
  /// Bullet cloth) and Coupling (CoupledSurface), or a checked stain stage
  /// (Sources, BodyForces … Interact).
  Stage stage = Stage::Guard;
  int step = 1;    ///< 1-based number of the step it fires in; it fires once
  int vertex = 0;  ///< where (the solvent density there; a node impulse for Cloth)
  bool armed = false;  ///< set by injectFaultForTesting, cleared when it fires
};

}  // namespace blot::stain
