#pragma once
/// Per-step constants (a fresh, const StepContext each step), and the physics
/// switches and liquid parameters a scene sets.
#include <blot/stain/step_profile.h>
#include <blot/stain/types.h>

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
  double liquidDensity = 1000.0;      ///< ρ (kg/m³): the film's thickness H = (σ_f + σ_s)/ρ.
  /// ν = μ/ρ of the liquid (m²/s, > 0): the film's friction with the fabric
  /// (PhysicsSwitches::filmFriction). Water at 20 °C: 1.0e-6.
  double kinematicViscosity = 1.0e-6;
  /// The fabric's Navier slip length λ (m, ≥ 0): the liquid slips over the
  /// fibres, so the drag is 3νu/(H(H + 3λ)) and a film's front can advance
  /// (a no-slip film's cannot). 0: no slip.
  double slipLength = 1.0e-5;
  /// D_m, the dissolved solute's molecular diffusivity in the liquid (m²/s,
  /// ≥ 0), with PhysicsSwitches::soluteWithSolvent: the only thing that
  /// evens out concentrations inside the liquid. A small molecule in water at
  /// 20 °C: about 1e-9 (sucrose 5.2e-10, caffeine 6.3e-10).
  double molecularDiffusivity = 1.0e-9;
};

/// How the Coriolis term is integrated. ExactRotation (default): after the
/// velocity advection, the exact frame increment exp(−iω_n h) plus the frame
/// velocity's change along the backtrack (applyHalfFrameRotation and
/// applyFrameVelocityChange; no energy is
/// created at any ωh), or exp(−2iω_n h) when the velocity is not advected.
/// SplitRotation: always exp(−2iω_n h) after advection (kept for comparison;
/// energy grows at ωh ≳ 1). Explicit adds −2h ω × u (gains energy; kept only
/// for comparison).
enum class CoriolisScheme { ExactRotation, Explicit, SplitRotation };

/// Which liquid model a scene starts from; individual switches override it.
/// Film: the liquid as a thin viscous film on the fabric (friction with the
/// fibres, hydrostatic pressure balanced with gravity, evaporation strongest
/// at the wet front). Paper: the paper's equations as written (no friction,
/// no pressure, a_evap on the mesh boundary), for comparison.
enum class PhysicsModel { Film, Paper };

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
  /// Gravity and the film's hydrostatic pressure as one discrete gradient of
  /// the potential φ = −g·x + g_n H on the free liquid, with a hydrostatic
  /// reconstruction at the shoreline, so a lake at rest stays at rest on a
  /// curved mesh (film_flow.h). The paper has no pressure (off: tangential
  /// gravity per vertex, the paper's form).
  bool filmPressure = false;
  /// Friction between the film and the fabric, −3ν u/(H(H + 3λ)) on u
  /// relative to the cloth, integrated implicitly (film_flow.h). The paper
  /// has none (off).
  bool filmFriction = false;
  /// The density diffusion moves the free liquid as one solution and its
  /// flux carries the dissolved solute at the sender's concentration, which
  /// only the molecular diffusion D_m evens out (solute_transport.h). The
  /// paper diffuses solute with the fabric's tensor as it does solvent, 10⁷
  /// times faster than a molecule diffuses (off).
  bool soluteWithSolvent = false;
  /// The in-plane viscosity exchanges momentum in proportion to the liquid's
  /// mass, each edge limited by its thinner end, so it conserves momentum and
  /// only dissipates kinetic energy (film_viscosity.h). The paper weights it
  /// by area (off), which can move speed from a trace of fast liquid into a
  /// thick pool.
  bool massWeightedViscosity = false;
  /// u = 0 at wet vertices without free liquid (fibre-held only) before the
  /// body forces (clearVelocityWithoutFreeLiquid). Off: their u keeps
  /// accumulating the forces.
  bool velocityOnFreeLiquid = true;
  /// The mesh boundary is a wall (free slip, no penetration): once the
  /// velocity's stages have run, u at boundary vertices holding liquid loses
  /// the part that points off the mesh (applyBoundaryWall). Off: the boundary
  /// is open to u (the liquid still cannot cross it; analytic tests of an
  /// unbounded film).
  bool boundaryWall = true;
  /// The liquid the density diffusion moves carries its velocity: after the
  /// diffusion, each band vertex's u is the mass-weighted mean of its own and
  /// of what each edge's diffusive flux brought in (carryMomentumWithDiffusion;
  /// docs/transport.md). Off: the paper's u, a field of its own, which the
  /// refilled liquid next to the boundary wall keeps accelerating (g t).
  bool diffusiveMomentum = true;
  bool positivityLimiter = true;  ///< mass-conserving fix of negative densities after diffusion
  CoriolisScheme coriolisScheme = CoriolisScheme::ExactRotation;
  /// The model these switches started from (applyPhysicsModel), for the
  /// record (summary.json); the switches above are what runs. The defaults
  /// here are the paper's terms; the engine starts from the film model.
  PhysicsModel model = PhysicsModel::Paper;
};

/// Sets what `model` decides (docs/scene-format.md, "physics.model"): the
/// film terms, the solute's transport, the viscosity's weighting and the
/// evaporation boundary. Every other switch and parameter
/// is left as it is.
inline void applyPhysicsModel(PhysicsModel model, PhysicsSwitches& switches, LiquidParameters& liquid) {
  const bool film = model == PhysicsModel::Film;
  switches.model = model;
  switches.filmPressure = film;
  switches.filmFriction = film;
  switches.soluteWithSolvent = film;
  switches.massWeightedViscosity = film;
  liquid.evaporationBoundary = film ? EvaporationBoundary::WetFront : EvaporationBoundary::MeshBoundary;
}

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

}  // namespace blot::stain
