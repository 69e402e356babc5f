#pragma once
/// blot::Engine: the facade a game or a tool embeds. One moving surface with
/// its stain (coupling::CoupledSurface), driven by a fixed internal time step
/// behind an accumulator, with drops added at runtime, read-only per-vertex
/// views, statistics, and save/load of the whole state.
///
/// Why a fixed internal step: the stain solver factorizes (M + h L) for its h,
/// and the Bullet cloth's stability and the stain's CFL limits are tuned for
/// one h; a frame time that changes every frame would refactorize every frame
/// and make results depend on the frame rate. So step(frameDt) only feeds an
/// accumulator and runs whole internal steps of EngineDef::timeStep.
#include <blot/cloth/bullet_cloth.h>
#include <blot/cloth/mesh_sequence.h>
#include <blot/cloth/surface_motion.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/engine/stain_color.h>
#include <blot/stain/fabric/fabric_layout.h>
#include <blot/stain/stages/sources.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/geometry/mesh_order.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/triangle_mesh.h>

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::engine {

/// Where the moving mesh comes from (cloth/). Caller: positions the caller
/// supplies every step (Engine::setSurfaceFrame; cloth::CallerMotion), for a
/// cloth simulated by anything else; code only, not a scene choice.
enum class MotionSource { Static, Rigid, Sequence, Bullet, Caller };
const char* motionSourceName(MotionSource source);  ///< "static", "rigid", "sequence", "bullet", "caller"

/// A drop that lands at a given simulated time (s, ≥ 0): applied before the
/// first internal step that starts at or after `time`.
struct TimedDrop {
  double time = 0;
  stain::DropDef drop;
};

/// Everything an Engine is built from (Box2D-style definition struct). Every
/// field has a working default except `mesh`, which must be set (e.g.
/// stain::gridMesh for a patch).
/// A stain solver definition with the film model's terms on (the engine's
/// default; docs/scene-format.md, "physics.model").
inline stain::StainSolverDef filmModelDef() {
  stain::StainSolverDef def;
  stain::applyPhysicsModel(stain::PhysicsModel::Film, def.switches, def.liquid);
  return def;
}

struct EngineDef {
  /// Rest shape (#V by 3, m) and faces; validated (stain::validateMesh). Cloth
  /// vertex i is mesh vertex i for every source.
  stain::TriangleMesh mesh;
  MotionSource source = MotionSource::Static;
  cloth::RigidMotionDef rigid;        ///< used when source == Rigid (components at most kMaxSceneMagnitude)
  cloth::MeshSequenceDef sequence;    ///< used when source == Sequence (frames read with stain::loadMesh)
  /// Used when source == Bullet. Its mesh-derived fields are filled from
  /// `mesh` by coupling::describeClothMesh; set only the physical ones.
  /// cloth.world (and cloth.body) put the cloth into the caller's Bullet world,
  /// which the caller steps: one world step of timeStep before each internal
  /// step, so drive the engine with advanceSteps(1) (docs/embedding.md).
  cloth::ClothDef cloth;
  /// Used when source == Caller: the surface's velocities at time 0 (#V by 3,
  /// m/s), or no rows for a surface at rest. Its positions at time 0 are the
  /// mesh's; later ones come from Engine::setSurfaceFrame.
  Eigen::MatrixX3d callerInitialVelocities;

  /// Isotropic fabric (when fabricPatches is empty): density diffusivity (m²/s, > 0).
  double diffusivity = 0.01;
  /// Velocity diffusivity (kinematic viscosity of the film, m²/s, ≥ 0), isotropic
  /// on every face, also with fabric patches.
  double viscosity = 2e-3;
  /// Woven fabric: patches with patterns or tensors (stain::fabricLayout);
  /// every face in exactly one patch. Empty: isotropic `diffusivity`.
  std::vector<stain::FabricPatch> fabricPatches;
  /// Per patch with a pattern (same order as fabricPatches, or empty): scale
  /// its homogenized S_eff so that trace / 2 equals this (m²/s); 0 keeps the
  /// pattern's own units.
  std::vector<double> fabricPatchDiffusivities;
  /// Per patch (same order as fabricPatches, or empty): its pattern's S_eff as
  /// homogenized already (the scene loader does, to check convergence), before
  /// fabricPatchDiffusivities scales it. A patch with a pattern and no entry
  /// here (or a zero matrix) is homogenized when the Engine is built.
  std::vector<stain::Matrix2> fabricPatchEffectiveTensors;
  int homogenizationSubdivisions = stain::kAutoSubdivisions;  ///< K for the patterns' cell problems

  /// Switches, liquid parameters, gravity (m/s², also given to a Bullet cloth,
  /// and then each component at most kMaxSceneMagnitude) and the
  /// intrinsic-rebuild strain tolerance.
  /// Starts from the film model (stain::applyPhysicsModel; the paper's form:
  /// apply PhysicsModel::Paper).
  stain::StainSolverDef stain = filmModelDef();
  coupling::CouplingMode coupling = coupling::CouplingMode::OneWay;

  double timeStep = 1.0 / 120.0;  ///< internal step h (s, in [kMinTimeStep, 1], as a scene's time_step)
  /// Most internal steps one step(frameDt) call runs (≥ 1); frame time beyond
  /// that is dropped (counted in EngineStatistics::droppedTime), so a slow
  /// frame cannot trigger a spiral of ever longer catch-up frames.
  int maxStepsPerCall = 8;

  std::vector<TimedDrop> drops;               ///< scheduled drops (any order; applied in time order)
  std::vector<stain::HeldRegion> heldRegions; ///< regions held at fixed density
  /// Runtime drops queued between steps without allocating (addDrop beyond
  /// this many before the next step still works, but allocates).
  int dropQueueCapacity = 64;

  StainColorMapping colors;  ///< stain colour (Beer–Lambert, linear RGB) of colors()

  /// Where `mesh` came from when a scene renumbered it for memory locality
  /// (mesh.vertex_order "locality", SceneDef::meshOrder): engine vertex k is
  /// the file's vertex meshOrder.vertices[k], engine face k its face
  /// meshOrder.faces[k]. Empty: the mesh's own numbering. A record for the
  /// caller, so that an engine from Engine::fromSceneFile can map what it
  /// writes (in its numbering) back to the file's; the engine never reads it.
  stain::MeshOrder meshOrder;
};

/// Where a world point lands on the cloth (addDropAtPoint).
struct SurfaceHit {
  int face = -1;                              ///< face of the nearest surface point
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();  ///< weights of faces(face, 0..2), sum 1
  Eigen::Vector3d point = Eigen::Vector3d::Zero();        ///< nearest surface point (m)
  double distance = 0;                        ///< from the query point to it (m)
};

/// Sums over internal steps, for means: stain stage times (StepProfile) and
/// coupled parts (CoupledStepTimes), milliseconds.
struct PhaseTotals {
  std::array<double, stain::kStageCount> stageMilliseconds{};  ///< per stain::Stage (stain stages)
  double stainTotal = 0;
  double stage(stain::Stage s) const { return stageMilliseconds[static_cast<size_t>(s)]; }
  double cloth = 0, stain = 0, coupling = 0, total = 0;
  /// Per stain::StepTerm bit k: the internal steps in which that term ran
  /// (StepProfile::terms), so a run reports which terms it needed.
  std::array<std::int64_t, stain::kStepTermCount> termSteps{};

  /// Every field, once (stain/output_fields.h): Python "total_ms", JSON
  /// "mean_ms_per_step" (divided by the steps). The term counts are
  /// summary.json's "terms_ran_steps" (only the terms that ran).
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    constexpr unsigned notPythonNorJson = stain::kPythonOutput | stain::kJsonOutput;
    v.perStage(stain::outputField("stageMilliseconds", "stages", "ms").json("stain_"), s.stageMilliseconds,
               stain::kFirstStainStage, stain::kLastStainStage);
    v.field(stain::outputField("stainTotal", "stain_total", "ms").notIn(notPythonNorJson), s.stainTotal);
    v.field(stain::outputField("cloth", "cloth", "ms"), s.cloth);
    v.field(stain::outputField("stain", "stain", "ms"), s.stain);
    v.field(stain::outputField("coupling", "coupling", "ms"), s.coupling);
    v.field(stain::outputField("total", "total", "ms"), s.total);
    v.perTerm(stain::outputField("termSteps", "term_steps").notIn(notPythonNorJson), s.termSteps);
  }
};
static_assert(stain::describesEveryMember<PhaseTotals>(),
              "PhaseTotals changed: list the new field in PhaseTotals::fields");

struct EngineStatistics {
  std::int64_t steps = 0;           ///< internal steps taken
  double time = 0;                  ///< simulated time (s) = steps · h
  double droppedTime = 0;           ///< frame time discarded by maxStepsPerCall (s)
  int dropsApplied = 0;
  double wallSeconds = 0;           ///< wall-clock time inside internal steps (s)
  double stepsPerSecond = 0;        ///< steps / wallSeconds
  stain::StepProfile lastProfile;   ///< stain stages of the last internal step (ms)
  coupling::CoupledStepTimes lastTimes;  ///< cloth/stain/coupling of the last internal step (ms)
  PhaseTotals totals;               ///< sums since construction (ms); mean = total / steps
  int intrinsicRefreshes = 0;       ///< internal steps that rebuilt the metric
  stain::MassBudget massBudget;     ///< now (kg)
  /// The free liquid's energy now (J): kinetic (relative to the cloth),
  /// gravitational and hydrostatic (stain::StainSolver::liquidEnergy).
  stain::FilmEnergy liquidEnergy;

  /// Every field, once (stain/output_fields.h): Python `statistics()`,
  /// summary.json (`blot run`), blotStatistics (engine/src/c_api.cpp).
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    using stain::kCOutput;
    using stain::kJsonOutput;
    using stain::outputField;
    v.field(outputField("steps", "steps"), s.steps);
    v.field(outputField("time", "time", "s").json("simulated_time_s"), s.time);
    v.field(outputField("droppedTime", "dropped_time", "s").notIn(kJsonOutput), s.droppedTime);
    v.field(outputField("dropsApplied", "drops_applied"), s.dropsApplied);
    v.field(outputField("wallSeconds", "wall_seconds", "s").notIn(kJsonOutput), s.wallSeconds);
    v.field(outputField("stepsPerSecond", "steps_per_second"), s.stepsPerSecond);
    v.field(outputField("intrinsicRefreshes", "intrinsic_refreshes"), s.intrinsicRefreshes);
    v.record(outputField("lastProfile", "last_profile").notIn(kJsonOutput | kCOutput), s.lastProfile);
    v.record(outputField("lastTimes", "last_ms", "ms").notIn(kJsonOutput), s.lastTimes);
    v.record(outputField("totals", "total_ms", "ms").json("mean_ms_per_step").meanPerStep().notIn(kCOutput),
             s.totals);
    v.record(outputField("massBudget", "mass_budget", "kg").json("mass_budget_kg"), s.massBudget);
    v.record(outputField("liquidEnergy", "liquid_energy", "J").json("liquid_energy_j"), s.liquidEnergy);
  }
};
static_assert(stain::describesEveryMember<EngineStatistics>(),
              "EngineStatistics changed: list the new field in EngineStatistics::fields");

/// Error loading a state file (tier b): names the file and the mismatch.
class StateFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Engine {
 public:
  /// Builds the topology, fabric (homogenizing patterns once), motion source,
  /// stain solver and coupling. Throws std::invalid_argument (or
  /// stain::MeshError, stain::FabricLayoutError, cloth::SequenceError) naming
  /// the field for a bad def. Drops scheduled at time 0 are applied now.
  explicit Engine(const EngineDef& def);
  /// Reads and builds a scene file (scene.h); throws SceneError naming the key.
  static std::unique_ptr<Engine> fromSceneFile(const std::string& path);
  /// The same from JSON text; relative paths resolve against baseDirectory.
  static std::unique_ptr<Engine> fromSceneJson(const std::string& jsonText, const std::string& baseDirectory = ".",
                                               const std::string& sourceName = "<scene>");
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  /// Adds frameDt (s, finite, ≥ 0) to the accumulator and runs
  /// n = min(⌊accumulator / h⌋, maxStepsPerCall) internal steps; the remainder
  /// (< h) is carried to the next call, time beyond the cap is dropped. The
  /// accumulator counts in units of h, and ⌊·⌋ forgives 1e-9 of a step, so
  /// frame times that add up to whole steps (e.g. 0.016 + 0.004 at h = 0.01)
  /// run exactly those steps. Results depend only on the sequence of internal
  /// steps and drops, not on how frame time was split. Every stage of every
  /// internal step is checked for non-finite values and negative mass (cloth,
  /// each stain stage, coupling). On a failure the report names the stage, the
  /// vertex and the internal step; the step is undone so the engine keeps the
  /// last good state (cloth bit-identical, stain densities and velocities as
  /// at that time, time() and stepCount() unchanged, drops already applied
  /// stay; see CoupledSurface::step); the remaining steps of this call are
  /// not run and the accumulator is cleared. Allocates nothing after the first call, except
  /// that a step applying a drop allocates its footprint, the stain's
  /// intrinsic rebuild (edge strain past StainSolverDef::strainTolerance)
  /// allocates, and Bullet allocates contact lists when a cloth meets a
  /// collider (tests/engine/engine_allocation_test.cpp). Returns the last report.
  /// frameDt outside [0, kMaxFrameSeconds] (or NaN) is refused (status
  /// InvalidArgument, stage Guard) and changes nothing.
  stain::StepReport step(double frameDt);
  static constexpr double kMaxFrameSeconds = 1.0;
  /// Runs exactly `count` internal steps (≥ 0), bypassing the accumulator. A
  /// negative count is refused (status InvalidArgument, stage Guard) and
  /// changes nothing.
  stain::StepReport advanceSteps(int count);
  /// Testing only: arms a NaN for internal step fault.step (1-based) after
  /// fault.stage (CoupledSurface::injectFaultForTesting), to exercise the
  /// fault path end to end. Throws std::invalid_argument naming the problem.
  void injectFaultForTesting(const stain::InjectedFault& fault) { surface_->injectFaultForTesting(fault); }

  /// Queues a drop for the next internal step. Vertex drops (centerVertex ≥ 0)
  /// land there; otherwise centerPoint is projected onto the cloth (nearest
  /// point, see addDropAtPoint). Throws std::invalid_argument naming the field.
  void addDrop(const stain::DropDef& drop);
  /// Queues `drop` centred where the world point lands on the cloth now: the
  /// nearest point on any face (barycentric), which becomes centerPoint.
  SurfaceHit addDropAtPoint(const Eigen::Vector3d& point, stain::DropDef drop);
  /// Nearest point on the current surface to `point` (m); O(#F).
  SurfaceHit nearestSurfacePoint(const Eigen::Vector3d& point) const;

  /// Bullet cloth: moves the pin at `vertex` (one of EngineDef::cloth.pins)
  /// to `position` (m) in a straight line during the next internal step and
  /// holds it there (cloth::BulletCloth::setPinTarget). Throws
  /// std::invalid_argument naming the problem (not a Bullet cloth, not a pin,
  /// released, not finite or beyond cloth::kMaxPinTarget).
  void setPinTarget(int vertex, const Eigen::Vector3d& position);
  /// Caller source: the surface positions (#V by 3, m) at the end of the next
  /// internal step, and their velocities (m/s) or null for the finite
  /// difference (cloth::CallerMotion::setNextFrame). Give one frame before
  /// each internal step (advanceSteps(1)); a step without one holds the
  /// surface still. Throws std::invalid_argument for another source, a wrong
  /// row count or a non-finite value.
  void setSurfaceFrame(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d* velocities = nullptr);
  /// The same from row-major arrays of #V × 3 doubles (velocities may be null).
  void setSurfaceFrame(const double* positions, const double* velocities);

  // Read-only views, #V rows, valid until the next step(), advanceSteps() or load().
  // normals(), liquidVelocities(), liquidWorldVelocities() and colors() are
  // derived from the state: each is computed at its first call after the
  // state changed (normals and velocities need every vertex's fitted frame,
  // which the step itself computes only where the liquid is), so a loop that
  // never reads them never pays for them. Their buffers stay in place, and
  // calling them from several threads at once is safe.
  int vertexCount() const;
  const stain::Triangles& faces() const;
  const Eigen::MatrixX3d& positions() const;   ///< m, at time()
  const Eigen::MatrixX3d& normals() const;     ///< unit vertex normals at time()
  const Eigen::VectorXd& solvent() const;      ///< free solvent σ_f (kg/m²)
  const Eigen::VectorXd& solute() const;       ///< free solute σ_s (kg/m²)
  const Eigen::VectorXd& absorbedSolvent() const;  ///< σ_p (kg/m²)
  const Eigen::VectorXd& absorbedSolute() const;   ///< σ_s,p (kg/m²)
  const Eigen::VectorXd& adsorbedSolute() const;   ///< σ_s,a (kg/m²)
  /// Liquid velocity relative to the cloth, tangential, in world axes (m/s);
  /// 0 at vertices without free liquid (dry, or liquid held in the fibres,
  /// which moves with the cloth).
  const Eigen::MatrixX3d& liquidVelocities() const;
  /// Liquid velocity in the world (inertial) frame: the cloth's velocity plus
  /// liquidVelocities() (m/s).
  const Eigen::MatrixX3d& liquidWorldVelocities() const;
  const Eigen::MatrixX3d& colors() const;      ///< linear RGB in [0, 1] (Beer–Lambert, stain_color.h); files hold it sRGB-encoded

  double time() const;                 ///< simulated time (s)
  /// OpenMP threads of this engine's stain steps (EngineDef::stain.threads,
  /// scene key "threads"); a new count applies from the next step (≥ 0, 0:
  /// the calling thread's OpenMP default). Results do not depend on it.
  int threadCount() const { return surface_->stain().threadCount(); }
  void setThreadCount(int threads) { surface_->stain().setThreadCount(threads); }
  /// With two or more threads, each step uses all of them or one, whichever
  /// recent steps measured faster (EngineDef::stain.adaptiveThreads, scene key
  /// "adaptive_threads", on by default); false: every step uses
  /// threadCount(). Only the time of a step depends on it.
  bool adaptiveThreads() const { return surface_->stain().adaptiveThreads(); }
  void setAdaptiveThreads(bool adaptive) { surface_->stain().setAdaptiveThreads(adaptive); }
  std::int64_t stepCount() const { return steps_; }
  double timeStep() const { return def_.timeStep; }
  double accumulator() const { return accumulator_ * def_.timeStep; }  ///< carried frame time (s)
  const EngineDef& definition() const { return def_; }
  EngineStatistics statistics() const;
  const coupling::CoupledSurface& surface() const { return *surface_; }
  const stain::SurfaceTopology& topology() const { return *topology_; }
  /// Per-face fabric the stain runs on: tensors (m²/s) and unit weft directions
  /// in the rest shape (zero rows on isotropic faces, which have no weft).
  const stain::FabricField& fabric() const { return fabric_; }
  /// FNV-1a over every simulation array (positions, velocities, densities,
  /// time): equal hashes mean (to 64 bits) bit-identical state.
  std::uint64_t stateHash() const;

  /// Writes the whole simulation state (stain, cloth, accumulator, drops not
  /// yet applied) and the run's counters (steps, dropped time, drops applied,
  /// rebuilds, steps per term) to a binary file: magic, version, mesh sizes and
  /// fingerprint, then the arrays, then the 64-bit FNV-1a (stain/content_hash.h)
  /// of every byte before it. Timings are not saved.
  void save(const std::string& path) const;
  /// Restores a state written by save() from an engine built from the same
  /// def; the steps after it are bit-identical to the original's. Throws
  /// StateFileError naming the file and the mismatch (vertex/face counts, mesh
  /// fingerprint, motion source, version, checksum, truncation); the engine is unchanged then.
  /// Only those are checked: the file holds the state, not the definition, so
  /// an engine built with other parameters (diffusivity, gravity, pins, rigid
  /// motion, coupling) loads it and steps on with its own (as a game loads a
  /// save into a patched build). `blot run --resume` refuses a changed scene.
  /// A cloth in the caller's Bullet world (EngineDef::cloth.world) cannot be
  /// loaded into (the world is the caller's): StateFileError.
  void load(const std::string& path);

 private:
  /// A fresh motion + stain + coupling from def_ (construction and load).
  std::unique_ptr<coupling::CoupledSurface> buildSurface() const;
  stain::StepReport runInternalStep();
  void applyDueDrops();
  /// Marks the derived views stale (after anything that changes the state).
  void invalidateViews();
  /// Computes the derived views of the current state, if stale.
  void refreshFrameViews() const;
  void refreshColors() const;

  EngineDef def_;
  std::unique_ptr<stain::SurfaceTopology> topology_;
  stain::FabricField fabric_;
  std::unique_ptr<coupling::CoupledSurface> surface_;
  std::vector<TimedDrop> schedule_;      // def_.drops sorted by time
  std::size_t nextScheduled_ = 0;        // first schedule_ entry not applied yet
  std::vector<stain::DropDef> pending_;  // runtime drops for the next internal step
  double accumulator_ = 0;               // carried frame time in units of h
  std::int64_t steps_ = 0;
  std::uint64_t meshFingerprint_ = 0;
  // Derived views (preallocated; rewritten on first read after a change,
  // under viewsMutex_).
  mutable std::mutex viewsMutex_;
  mutable bool frameViewsCurrent_ = false, colorsCurrent_ = false;
  mutable Eigen::MatrixX3d normals_, liquidVelocities_, liquidWorldVelocities_, colors_;
  // Statistics.
  double droppedTime_ = 0, wallSeconds_ = 0;
  int dropsApplied_ = 0, intrinsicRefreshes_ = 0;
  PhaseTotals totals_;
};

}  // namespace blot::engine

namespace blot {
using engine::Engine;     // the embedding API is blot::Engine
using engine::EngineDef;
}  // namespace blot
