#pragma once
/// The stain on one moving surface: state, geometry cache, factorized systems,
/// and the step written once as the stage list of DESIGN.md.
///
/// The cloth leads and the stain follows one step behind: step(h, p(t+h))
/// refreshes the geometry with the new positions (so accelerations and angular
/// velocities at t are centred), then advances the stain from t to t + h.
#include <blot/stain/numerics/thread_choice.h>
#include <blot/stain/output_fields.h>
#include <blot/stain/stages/density_advection.h>
#include <blot/stain/stages/diffusion.h>
#include <blot/stain/stages/diffusive_momentum.h>
#include <blot/stain/stages/liquid_band.h>
#include <blot/stain/stages/film_viscosity.h>
#include <blot/stain/stages/solute_transport.h>
#include <blot/stain/stages/sources.h>
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/stages/film_flow.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/stages/velocity_advection.h>

#include <initializer_list>
#include <memory>
#include <utility>
#include <string>
#include <vector>

namespace blot::stain {

/// Which edges the strain test of a deforming step measures (the intrinsic
/// tier is rebuilt, whole, when one of them is strained past the tolerance).
enum class StrainTest {
  /// default: every edge.
  WholeMesh,
  /// The edges of the faces at the vertices holding free liquid
  /// (σ_f + σ_s > 0) and at the held regions' vertices: the part of the
  /// metric the liquid's mass and fluxes are computed on. A dry part of the
  /// cloth may stretch past the tolerance unrebuilt; it is tested from the
  /// step after liquid reaches it. For a cloth whose liquid sits where it
  /// deforms little: no rebuild for the rest of it, and none once the free
  /// liquid has gone. Not the default: where the liquid's part deforms as
  /// much as the rest, the same tolerance lets its metric drift further
  /// between rebuilds (the whole-mesh test's other trips refresh it too), so
  /// it needs about a fifth of the tolerance for the same error
  /// (docs/accuracy.md, "Strain tolerance"). A stain left where no free
  /// liquid is keeps its densities per the areas of the last rebuild: its
  /// mass is exact, its density per area of the stretched cloth is off by
  /// the stretch since then, however large.
  AroundLiquid
};

struct StainSolverDef {
  PhysicsSwitches switches;
  LiquidParameters liquid;
  Vector3 gravity = Vector3(0, 0, -9.8);  ///< world gravity (m/s²)
  double strainTolerance = 1e-3;          ///< intrinsic rebuild threshold (relative edge strain)
  /// How a rebuild refreshes the intrinsic tier (SurfaceGeometry::setIntrinsicRefresh):
  /// Full (default), Partial (only the edges past half the tolerance; measured
  /// less accurate, docs/accuracy.md "Strain tolerance") or Region (every
  /// edge near the vertices the strain test measured; needs strainTest
  /// AroundLiquid, std::invalid_argument otherwise).
  IntrinsicRefresh intrinsicRefresh = IntrinsicRefresh::Full;
  /// Where the strain test measures (StrainTest): every edge (default) or
  /// around the liquid.
  StrainTest strainTest = StrainTest::WholeMesh;
  /// OpenMP threads this solver's steps use (≥ 0). 0: the calling thread's
  /// OpenMP default when the solver is built (OMP_NUM_THREADS, else the
  /// cores). Each step sets it for its own parallel regions and restores the
  /// caller's setting after, so solvers with different counts can coexist.
  /// Stages below their size threshold run serial whatever the count, and
  /// the results are bit-identical for any count.
  int threads = 0;
  /// With more than one thread: each step uses all of them or one, whichever
  /// recent steps measured faster (ThreadChoice: a probe alternating the two
  /// counts, then a hold), so threads that do not pay are dropped, e.g.
  /// on a machine busy with other work. false: every step uses `threads`.
  /// Only the time of a step depends on it.
  bool adaptiveThreads = true;
  /// Where the per-vertex extrinsic geometry (normals, rotation fits, frames,
  /// p̈, ω) is computed each step. OnDemand: on the liquid band and the
  /// vertices with a trace of liquid (LiquidBand::dampVertices), nothing on
  /// a dry step; addDrop, setInitialMotion and completeGeometry compute the
  /// rest. AllVertices: every vertex every step, the reference: the state
  /// after any step is bitwise the same in both modes.
  VertexRefresh geometryVertices = VertexRefresh::OnDemand;
  /// With OnDemand: whether each step also computes the per-vertex geometry
  /// of the damp vertices (a trace of free liquid outside the wet set,
  /// LiquidBand::dampVertices), which no stage reads. For a reader of every
  /// vertex holding free liquid between steps: the coupling's relative
  /// momentum with RelativeMomentum::Free sets it. false: the band only (a
  /// trace's frame is fitted when it is read: completeGeometry). Only the
  /// time of a step and which vertices are prepared depend on it.
  bool framesOnDampVertices = false;
  /// How the diffusion systems are solved (DiffusionSolverChoice): Auto, the
  /// per-solve choice by predicted cost (docs/performance.md, "The cheapest
  /// solver"), or one method forced (tests, studies, a reference run).
  DiffusionSolverChoice diffusionSolver = DiffusionSolverChoice::Auto;
  /// With switches.velocityOnFreeLiquid: soaked vertices (only fibre-held
  /// liquid above wetThreshold, u = 0) are filed apart from the wet set, so
  /// the band and its work follow the free liquid (LiquidBand::soakedVertices).
  /// false: they are wet vertices whose u is cleared each step, the rule
  /// before; the reference the approximation is measured against
  /// (docs/transport.md, "Soaked vertices").
  bool soakedApart = true;
};

/// Totals for the mass budget (kg). solute* sum to addedSolute; solvent
/// (free + absorbed) + evaporated sum to addedSolvent, to rounding.
struct MassBudget {
  double freeSolvent = 0, absorbedSolvent = 0, evaporatedSolvent = 0, addedSolvent = 0;
  double freeSolute = 0, absorbedSolute = 0, adsorbedSolute = 0, addedSolute = 0;
  double solventError() const;  ///< |free + absorbed + evaporated − added| / added
  double soluteError() const;   ///< |free + absorbed + adsorbed − added| / added

  /// Every field, once (output_fields.h): Python "mass_budget", JSON
  /// "mass_budget_kg" (grouped by solvent and solute), blotMassBudget, the
  /// viewer's mass budget bars (parts against the group's total).
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    constexpr auto kg = [](const char* name, const char* key) { return outputField(name, key, "kg"); };
    v.field(kg("freeSolvent", "free_solvent").partOf("solvent", "free"), s.freeSolvent);
    v.field(kg("absorbedSolvent", "absorbed_solvent").partOf("solvent", "absorbed"), s.absorbedSolvent);
    v.field(kg("evaporatedSolvent", "evaporated_solvent").partOf("solvent", "evaporated").labelled("evaporated"),
            s.evaporatedSolvent);
    v.field(kg("addedSolvent", "added_solvent").totalOf("solvent", "added"), s.addedSolvent);
    v.field(kg("freeSolute", "free_solute").partOf("solute", "free"), s.freeSolute);
    v.field(kg("absorbedSolute", "absorbed_solute").partOf("solute", "absorbed"), s.absorbedSolute);
    v.field(kg("adsorbedSolute", "adsorbed_solute").partOf("solute", "adsorbed"), s.adsorbedSolute);
    v.field(kg("addedSolute", "added_solute").totalOf("solute", "added"), s.addedSolute);
    v.computed(outputField("solventError", "solvent_error").errorOf("solvent"), [&s] { return s.solventError(); });
    v.computed(outputField("soluteError", "solute_error").errorOf("solute"), [&s] { return s.soluteError(); });
  }
};
static_assert(describesEveryMember<MassBudget>(), "MassBudget changed: list the new field in MassBudget::fields");

/// Everything StainSolver::step depends on beyond the constructor's inputs
/// (topology, rest shape, fabric, def): restoring it into a solver built from
/// the same inputs makes every later step bit-identical (engine save/load).
/// Drops are applied immediately by addDrop, so none are pending here.
struct StainSolverSnapshot {
  StainState state;
  SurfaceGeometry::DynamicState geometry;  ///< positions at t−h, t, t+h, frames, rotation history, intrinsic tier
  std::vector<HeldRegion> heldRegions;
  RowVectors3 initialVelocities;  ///< v(0), used by the first step's p(−h)
  double factorizedStep = 0;      ///< h the diffusion systems were assembled for (0: none yet)
  double time = 0;
  int steps = 0;
  bool started = false;
  /// The state was written through mutableState (liquid may have been on the
  /// surface without a drop): the steps test strain from then on
  /// (everHeldLiquid). Saved, not derived from the densities, which the
  /// caller may have cleared again.
  bool writtenOutside = false;

  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    s.state.visit(v);
    s.geometry.visit(v);
    v.field("heldRegions", s.heldRegions);
    v.field("initialVelocities", s.initialVelocities);
    v.field("factorizedStep", s.factorizedStep);
    v.field("time", s.time);
    v.field("steps", s.steps);
    v.field("started", s.started);
    v.field("writtenOutside", s.writtenOutside);
  }
};

class StainSolver {
 public:
  /// Builds topology-dependent caches, the geometry for the rest shape and
  /// the diffusion systems' patterns, and factorizes nothing yet (the first
  /// direct solve does, for its h).
  StainSolver(const SurfaceTopology& topology, const RowVectors3& restPositions, const FabricField& fabric,
              const StainSolverDef& def);
  ~StainSolver();

  /// For a surface that will deform (a simulated cloth, a mesh sequence):
  /// sizes now what the first metric rebuild would allocate
  /// (SurfaceGeometry::prepareWholeRebuilds), so that the first rebuild
  /// costs what later ones do and no step allocates for one. A surface that
  /// only moves rigidly never rebuilds and need not call it: it would hold
  /// one more intrinsic tier in memory. CoupledSurface calls it for every
  /// motion that deforms (cloth::SurfaceMotion::deforms).
  void prepareForDeformation();
  /// Positions and velocities at t = 0 of the moving surface (p(−h) is
  /// estimated as p(0) − h v(0) on the first step, unless
  /// setPositionsBeforeFirstStep gives it). Default: the rest shape at rest.
  void setInitialMotion(const RowVectors3& positions, const RowVectors3& velocities);
  /// p(t − h) for the next step, where it is the first (!started()): the
  /// surface's positions h before its initial ones, from a motion that knows
  /// them (cloth::SurfaceMotion::positionsBefore). That step's centred
  /// acceleration is then the motion's own; p(0) − h v(0) gives half of it
  /// (a rotating or accelerating cloth's first step kicked the liquid with
  /// half the inertia, a first-order error that never decayed). Used by the
  /// next step only; ignored once the solver has stepped.
  void setPositionsBeforeFirstStep(const RowVectors3& positions);
  /// Whether a step has run (the first step sets p(t − h)).
  bool started() const { return started_; }

  /// Advances the stain from t to t + h given the surface at t + h. On a
  /// numerical failure the state is left as it was before the step and the
  /// report names the stage and vertex.
  StepReport step(double h, const RowVectors3& nextPositions);
  /// The same step for a surface known to move rigidly: nextPositions
  /// (#V by 3, m) = R x̄ + c with x̄ the rest positions given to the
  /// constructor, R (a rotation matrix) and c the pose at t + h. The geometry
  /// refresh then sets every vertex's rotation to R instead of fitting it
  /// (SurfaceGeometry::refreshExtrinsicRigid; ~2x cheaper at 35K vertices)
  /// and skips the strain test (rigid motion keeps the metric). Results equal
  /// step's to the Kabsch fit's rounding. The caller guarantees rigidity.
  StepReport stepRigid(double h, const RowVectors3& nextPositions, const Matrix3& rotation);

  /// The two halves of step, for a caller that writes the coupled step as one
  /// list (CoupledSurface::step): stages Guard and Geometry (rigidRotation is R
  /// for a known rigid motion, or null), then the stain stages BodyForces
  /// through Sources and Validate. advanceStages runs only after a
  /// refreshGeometry that returned Ok. On a failure of either the state is as
  /// the step found it (abandonStep does the rest).
  StepReport refreshGeometry(double h, const RowVectors3& nextPositions, const Matrix3* rigidRotation);
  StepReport advanceStages();
  /// The one rollback of a failed coupled step, after any stage of it (the
  /// stain's own, or a later one such as the coupling): the state as it was
  /// before the step (densities, velocities, totals, time, step count, and
  /// the intrinsic tier with its assembled systems when the step rebuilt
  /// them), then the geometry restarted on the surface at (positions,
  /// velocities), #V by 3, m and m/s (restartMotion). A step that never began
  /// changes nothing.
  void abandonStep(const RowVectors3& positions, const RowVectors3& velocities);

  /// Adds a drop now (DropDef::velocity is its world velocity, relativeVelocity
  /// one relative to the cloth; see sources.h).
  void addDrop(const DropDef& drop);
  void addHeldRegion(const HeldRegion& region);

  const StainState& state() const { return state_; }
  /// u_i (m/s, complex) in vertex i's frame at time(), extrinsic().nextFrames.
  /// With the discrete frame change (CoriolisScheme::ExactRotation) the state
  /// keeps u in the last step's midpoint frame, half a frame increment
  /// behind: this turns it the rest of the way, exp(−iω_n h/2). Everything
  /// that reads u in world coordinates (coupling, views, outputs) uses it.
  Complex velocityInCurrentFrame(int i) const;
  /// The surface's own velocity at vertex i (m/s, world) that u is relative
  /// to: the chord (p^{t} − p^{t−h})/h of the last step, v(0) before the first.
  Vector3 surfaceVelocity(int i) const;
  /// The liquid's velocity at vertex i relative to the cloth, in world axes
  /// (m/s): F_i^{t} velocityInCurrentFrame(i), frames extrinsic().nextFrames.
  Vector3 relativeVelocity(int i) const;
  /// The liquid's world (inertial) velocity at vertex i (m/s):
  /// surfaceVelocity(i) + relativeVelocity(i).
  Vector3 worldVelocity(int i) const;
  /// The liquid band of the last step (docs/transport.md): wet vertices
  /// first, then ring by ring; the one set of vertices the step worked on.
  /// Valid until the next step.
  const std::vector<int>& bandVertices() const { return band_.vertices; }
  const LiquidBand& band() const { return band_; }
  /// The last step's velocity foot points (VelocityAdvectionScratch): rows of
  /// the reach set's vertices are that step's, other rows are stale.
  const FootVertices& velocityFootVertices() const { return velocityScratch_.footVertices; }
  const FootWeights& velocityFootWeights() const { return velocityScratch_.footWeights; }
  /// The state for writing from outside a step (tests, tools). The next
  /// step then validates and scans every vertex and copies the whole state
  /// as its rollback point: write through the reference before the next
  /// step, and call mutableState() again for writes after it.
  StainState& mutableState();
  /// The geometry: in VertexRefresh::OnDemand its per-vertex extrinsic values
  /// are this step's only where SurfaceGeometry::vertexPrepared (the band);
  /// completeGeometry() computes them on every vertex (for views and outputs).
  const SurfaceGeometry& geometry() const { return geometry_; }
  void completeGeometry();
  /// Makes every vertex holding free liquid have this step's frame. With
  /// StainSolverDef::framesOnDampVertices the last step prepared them all:
  /// completeGeometry() only if the state was written from outside since the
  /// last step's refresh (mutableState may have put liquid where no step
  /// prepared the frame), otherwise nothing. Without it, completeGeometry().
  /// For a reader of the whole state between steps that needs frames (the
  /// coupling's start-of-step momentum with RelativeMomentum::Free).
  void completeGeometryAfterOutsideWrite();
  const StepProfile& profile() const { return profile_; }
  /// The free liquid's energy now (J): kinetic ½σ|u|² relative to the cloth,
  /// gravitational −σ g·x and hydrostatic ½ρ g_n H² (film_flow.h,
  /// liquidEnergy). O(#V); for reports, not for the frame loop.
  FilmEnergy liquidEnergy() const;
  const StainSolverDef& definition() const { return def_; }
  /// Threads the steps use (≥ 1; StainSolverDef::threads resolved), and a new
  /// count (≥ 1; 0 resolves as in StainSolverDef) from the next step on.
  int threadCount() const { return threads_; }
  void setThreadCount(int threads);
  /// StainSolverDef::adaptiveThreads from the next step on (probing anew).
  bool adaptiveThreads() const { return def_.adaptiveThreads; }
  void setAdaptiveThreads(bool adaptive);
  /// Threads the next step uses: threadCount(), or 1 while adaptive threads
  /// measured one thread faster (StepProfile::threads: what a step used).
  int stepThreads() const { return def_.adaptiveThreads ? threadChoice_.threads() : threads_; }
  double time() const { return time_; }
  int stepCount() const { return steps_; }
  MassBudget massBudget() const;

  /// Copy of the dynamic state (allocates; not for use inside a frame loop).
  StainSolverSnapshot snapshot() const;
  /// Restores a snapshot taken from a solver built on the same inputs and
  /// refactorizes the diffusion systems for the snapshot's h, so the next
  /// step reuses them as the original would have. Throws
  /// std::invalid_argument naming the field whose size differs.
  void restore(const StainSolverSnapshot& snapshot);

  /// Puts the geometry on a surface at (positions, velocities), #V by 3 (m,
  /// m/s), keeping the state to the bit: as setInitialMotion, and
  /// p(t − h) = p − h v as the first step sets it. CoupledSurface calls it
  /// after a failed step has put the cloth back at t. The metric is kept (the
  /// strain test rebuilds it if the surface is stretched past the tolerance).
  void restartMotion(const RowVectors3& positions, const RowVectors3& velocities);
  /// Solvent evaporated at each vertex in the last step (#V, kg): the one
  /// per-vertex evaporation output the coupling's vapour momentum reads.
  const Vector& evaporatedMass() const { return evaporatedMass_; }
  /// Arms a testing fault for one of this solver's stages, BodyForces to
  /// Sources (InjectedFault). Throws std::invalid_argument for another stage
  /// or a vertex out of range.
  void injectFaultForTesting(const InjectedFault& fault);

 private:
  /// Stage LiquidBand: marks the wet set, takes the backup if the step has
  /// liquid, turns the wet u into F^t (the first half of the discrete frame
  /// change), then grows the liquid band and extends u onto it (liquid_band.h).
  void prepareBand();
  /// The terms this step runs: def_'s switches, less those with nothing to
  /// act on (no liquid, a surface that did not move, a zero coefficient).
  PhysicsSwitches activeTerms(bool surfaceMoved, bool anyLiquid) const;
  /// Lists vertices this step may change (the rollback point's and the
  /// incremental wet set's), before or after it changes them; noteAllChanged:
  /// every vertex (a metric rebuild, a whole-mesh solve).
  void noteChanged(const int* vertices, int count);
  void noteAllChanged();
  /// The state was written outside a step (mutableState, addDrop, restore):
  /// the next step copies, scans and validates every vertex.
  void stateWrittenOutside();
  /// The state as the step found it (backup_.restore), with the intrinsic tier and the assembled systems it
  /// had when the step being abandoned rebuilt them (SurfaceGeometry::undoIntrinsicRefresh).
  void restoreBackup();
  /// One line of the stage list: when `active`, runs `work` (void, or a
  /// SolverStatus), adds its time to the stage's, marks the stage as run and
  /// checks it (checkStage). False, with `report` filled and the state
  /// restored, when the stage failed.
  template <class Work>
  bool runStage(Stage stage, bool active, StepReport& report, Work&& work);
  /// After `stage`: writes an armed testing fault due now, then checks the
  /// band's vertices (and held ones after Sources) for non-finite values
  /// and negative densities. Fills `report` and restores the state when one
  /// is bad; returns false then.
  bool checkStage(Stage stage, StepReport& report);
  /// At the start of a step after a write from outside (validateAll_): true
  /// when every vertex and total is valid (validateAll_ then cleared); false
  /// with `report` naming the vertex or total, its value and what was
  /// expected, nothing run. A bad value at a held region's vertex would be
  /// topped up by Sources before any later check (a density of −1 counted
  /// as added mass, −inf as infinite added mass).
  bool validStateWrittenOutside(StepReport& report);
  /// The band is small enough for the stages to visit its list (vertex_visits.h).
  bool smallBand() const;
  /// The vertices the interaction visits (interaction.h's `among`), or null
  /// for all when the band is not small.
  const std::vector<int>* interactionVertices();
  /// Runs f with diffusedPastReach_ marked in the band's reach mask (the
  /// interaction's domain), and unmarks them afterwards, also when f throws.
  template <class F>
  void withDiffusedLiquidInReach(const F& f);
  // Liquid was ever on the surface (a drop, a source, a write from outside):
  // until then nothing reads the metric, and the strain test is skipped.
  bool everHeldLiquid() const;
  /// The strain test of StrainTest::AroundLiquid after refreshExtrinsic.
  bool strainExceededAroundLiquid();
  /// Marks each term whose condition is true as run this step.
  void markTerms(std::initializer_list<std::pair<StepTerm, bool>> terms);
  /// The profile's record of a density advection and of a diffusion (which
  /// also notes what the solves wrote and lists diffusedPastReach_).
  void recordAdvection(const DensityAdvectionReport& report);
  SolverStatus recordDiffusion(const DiffusionReport& report);
  /// Stage Diffuse: the density and velocity diffusion, then what the
  /// diffusion's fluxes carry (solute, momentum), the film's mass-weighted
  /// viscosity and the wall.
  SolverStatus diffuseLiquid(const StepContext& ctx, const std::vector<int>* among);
  /// Stage Validate: every value finite, no negative density; then the
  /// step counts (time, step number).
  StepReport finishStep();
  /// After a rebuild: a failure naming the first face whose area is not
  /// finite and positive (the surface collapsed there), else Ok.
  StepReport checkRebuiltAreas() const;
  /// advanceStages after its check: the stain stages and finishStep.
  StepReport runStages();

  StainSolverDef def_;
  SurfaceGeometry geometry_;
  StainState state_;
  StateBackup backup_;       // the rollback point: a mirror of the state and the vertices this step changed
  bool validateAll_ = true;  // written from outside since the last full validation passed
  // The state was written from outside since the last refresh of the
  // frames (completeGeometryAfterOutsideWrite).
  bool writtenSinceRefresh_ = false;
  // mutableState was called (or a restored state holds something): liquid
  // may be on the surface though nothing was added (everHeldLiquid).
  bool writtenOutside_ = false;
  double backupTime_ = 0;   // time_ when backup_ was taken
  // The step size M + hL was assembled for when backup_ was taken (0: none):
  // a rebuild releases the systems, and restoreBackup assembles them again.
  double backupAssembledStep_ = 0;
  InjectedFault fault_;      // testing; armed when set
  StepContext ctx_;          // this step's constants and active terms (refreshGeometry)
  bool undoable_ = false;   // the last step succeeded and no abandonStep has undone it
  bool inStep_ = false;     // refreshGeometry succeeded and the step has not finished
  bool rebuiltInStep_ = false;  // this step rebuilt the intrinsic tier (abandonStep puts the old one back)
  bool firstStep_ = false;  // this step is the solver's first (u is in the frames at t)
  DiffusionSystems systems_;
  /// This step's velocity diffusion is the whole-mesh factor (chosen when the
  /// band is built; the band then covers the mesh).
  bool velocityByFactor_ = false;
  DiffusionScratch diffusionScratch_;
  VelocityAdvectionScratch velocityScratch_;
  DensityAdvectionScratch densityScratch_;
  std::vector<HeldRegion> heldRegions_;
  LiquidBand band_;  // this step's band; its vertices are the stage checks' domain
  std::vector<int> interactionScratch_;  // interactionVertices(), reserved #V
  /// Vertices outside the reach set that hold free liquid after this step's
  /// density diffusion (recordDiffusion; reserved #V): the diffusion carries
  /// liquid past the rings the advection can reach, and the interaction
  /// processes them with the reach set (marked in it while it runs).
  std::vector<int> diffusedPastReach_;
  DiffusiveMomentumScratch momentumScratch_;  // carryMomentumWithDiffusion's
  SoluteTransportScratch soluteScratch_;      // carrySoluteWithSolvent's
  FilmViscosityScratch filmViscosityScratch_;  // diffuseFilmVelocity's
  FilmScratch filmScratch_;  // #V: −∇φ* and g_n H on the film vertices (filmAccelerations), this step's
  RowVectors3 surfaceVelocityScratch_;  // addDrop: surfaceVelocity of every vertex
  bool surfaceMoved_ = false;           // this step's surface moved (refreshGeometry)
  Vector areaScratch_;
  // The vertices the strain test measures around (StrainTest::AroundLiquid),
  // reserved #V, and their marks (#V).
  // Whether systems_ holds M + h L of the current tier (assembled since the
  // tier last changed): a partial rebuild then refills only its columns.
  bool systemsOfTier_ = false;
  std::vector<int> strainTestVertices_;
  std::vector<char> strainTestMarks_;
  Vector evaporatedMass_;  // #V kg, the last step's per-vertex evaporation
  bool evaporationWritten_ = false;  // evaporatedMass_ holds nonzero values
  RowVectors3 initialVelocities_;
  // setPositionsBeforeFirstStep's positions, for the next first step only.
  RowVectors3 positionsBeforeFirstStep_;
  bool havePositionsBeforeFirstStep_ = false;
  StepProfile profile_;
  double time_ = 0;
  int steps_ = 0;
  int threads_ = 1;
  ThreadChoice threadChoice_;  // all threads_ or one, per step (adaptiveThreads)
  bool started_ = false;
};

}  // namespace blot::stain
