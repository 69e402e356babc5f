// The stain step, written once as the stage list of DESIGN.md: each stage is
// one line of advanceStages (docs/architecture.md). Which terms run is decided
// once per step (activeTerms); a failed stage leaves the state as the step
// found it (StateBackup: a preallocated mirror, from which the vertices the
// step listed as changed are copied back).
#include <blot/stain/stages/external_forces.h>
#include <blot/stain/stages/film_flow.h>
#include <blot/stain/stages/interaction.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/thread_limit.h>

#include "numerics/lanes.h"
#include "numerics/machine_load.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include <omp.h>

namespace blot::stain {
namespace {

// A density below −1e-12 of the largest magnitude is negative mass, not
// rounding (the limiter and the solves keep densities ≥ 0 to rounding).
constexpr double kNegativeDensityTolerance = 1e-12;

// At most this many film sub-steps a step (filmSubsteps): a 3 mm puddle of
// water on 2.5 cm edges takes about 4 at h = 0.01 s.
constexpr int kMaxFilmSubsteps = 64;

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// The solver's thread count for the parallel regions started in this scope
/// (OpenMP's nthreads-var of the calling thread; restored on exit). It sets
/// the count even when it is already the one asked for: libgomp allocates a
/// thread's own ICV block at that thread's first omp_set_num_threads, so
/// setting it on every step puts that allocation in the first step on a thread
/// and not in the first step that changes the count (adaptive threads change
/// it in steady state).
class ThreadScope {
 public:
  explicit ThreadScope(int threads) : saved_(omp_get_max_threads()) { omp_set_num_threads(threads); }
  ~ThreadScope() {
    if (omp_get_max_threads() != saved_) omp_set_num_threads(saved_);
  }
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;

 private:
  int saved_;
};

int resolvedThreads(int threads) { return threads > 0 ? threads : std::max(1, omp_get_max_threads()); }

/// Adds the elapsed wall-clock milliseconds to `out` when it goes out of scope.
class ScopedTimer {
 public:
  explicit ScopedTimer(double& out) : out_(out), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    out_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  double& out_;
  std::chrono::steady_clock::time_point start_;
};

/// The five density fields of a state, named as the reports name them.
constexpr size_t kDensityFields = 5;
std::array<std::pair<const char*, const Vector*>, kDensityFields> densityFields(const StainState& s) {
  return {{{"solvent", &s.solvent},
           {"solute", &s.solute},
           {"absorbed solvent", &s.absorbedSolvent},
           {"absorbed solute", &s.absorbedSolute},
           {"adsorbed solute", &s.adsorbedSolute}}};
}

/// The extremes of the five density fields (from 0, as a reduction by
/// std::max and std::min takes them: a NaN is passed over) and whether those
/// fields and u are all finite, over vertices list[0, count), or 0 .. count−1
/// when kListed is false. The common case of the step's checks (all finite,
/// none below the floor) needs nothing else; the search for the vertex runs
/// only when it fails.
struct FieldScan {
  double largest = 0, smallest = 0;
  bool finite = true;
  void merge(const FieldScan& other) {
    largest = std::max(largest, other.largest);
    smallest = std::min(smallest, other.smallest);
    finite = finite && other.finite;
  }
  /// The floor −tol × the largest magnitude seen.
  double floor(double relativeTolerance) const { return -relativeTolerance * std::max(largest, -smallest); }
  /// Every value finite and no density below the floor: no vertex to search for.
  bool passes(double floor) const { return finite && smallest >= floor; }
};

/// Four vertices at a time (numerics/lanes.h): each lane keeps the extremes
/// of its own vertices, and the extremes of those are the fields' (a maximum
/// does not depend on the order its values come in, and lanes::max passes
/// over a NaN as std::max does), so the result is the scalar pass's. A lane's
/// sum of v·0 is ±0 while every v is finite and NaN from the first ±inf or
/// NaN on, which stays.
template <bool kListed>
FieldScan scanFields(const StainState& s, const int* list, int count) {
  using lanes::Lanes;
  const auto named = densityFields(s);
  std::array<const double*, kDensityFields> fields{};
  for (size_t f = 0; f < fields.size(); ++f) fields[f] = named[f].second->data();
  const double* u = reinterpret_cast<const double*>(s.velocities.data());  // re, im of each vertex
  const auto vertex = [&](int k) {
    if constexpr (kListed) return list[k];
    return k;
  };
  Lanes largest = lanes::splat(0.0), smallest = largest, poison = largest;
  int k = 0;
  for (; k + lanes::kLanes <= count; k += lanes::kLanes) {
    const int i0 = vertex(k), i1 = vertex(k + 1), i2 = vertex(k + 2), i3 = vertex(k + 3);
    for (const double* f : fields) {
      const Lanes v = kListed ? lanes::gather(f[i0], f[i1], f[i2], f[i3]) : lanes::load(f + k);
      largest = lanes::max(largest, v);
      smallest = lanes::min(smallest, v);
      poison = poison + v * 0.0;
    }
    // The four vertices' eight parts of u, in either order (only their finiteness counts).
    const Lanes u0 = kListed ? lanes::gather(u[2 * i0], u[2 * i1], u[2 * i2], u[2 * i3]) : lanes::load(u + 2 * k);
    const Lanes u1 = kListed ? lanes::gather(u[2 * i0 + 1], u[2 * i1 + 1], u[2 * i2 + 1], u[2 * i3 + 1])
                             : lanes::load(u + 2 * k + lanes::kLanes);
    poison = poison + u0 * 0.0 + u1 * 0.0;
  }
  FieldScan scan;
  double lanesLargest[lanes::kLanes], lanesSmallest[lanes::kLanes], lanesPoison[lanes::kLanes];
  lanes::store(largest, lanesLargest);
  lanes::store(smallest, lanesSmallest);
  lanes::store(poison, lanesPoison);
  for (int l = 0; l < lanes::kLanes; ++l) {
    scan.largest = std::max(scan.largest, lanesLargest[l]);
    scan.smallest = std::min(scan.smallest, lanesSmallest[l]);
    scan.finite = scan.finite && lanesPoison[l] == 0.0;
  }
  constexpr double kLargest = std::numeric_limits<double>::max();
  for (; k < count; ++k) {
    const int i = vertex(k);
    for (const double* f : fields) {
      scan.largest = std::max(scan.largest, f[i]);
      scan.smallest = std::min(scan.smallest, f[i]);
      scan.finite = scan.finite && std::abs(f[i]) <= kLargest;  // false for NaN and ±inf
    }
    scan.finite = scan.finite && std::abs(u[2 * i]) <= kLargest && std::abs(u[2 * i + 1]) <= kLargest;
  }
  return scan;
}

/// Whether vertex i holds a non-finite value or a density below `floor`.
bool badVertex(const StainState& s, int i, double floor) {
  for (const auto& [name, field] : densityFields(s))
    if (!std::isfinite((*field)[i]) || (*field)[i] < floor) return true;
  return !std::isfinite(s.velocities[i].real()) || !std::isfinite(s.velocities[i].imag());
}

/// First vertex with a non-finite or negative (below −tol·max) density, or -1.
int firstBadVertex(const StainState& s, double relativeTolerance) {
  const FieldScan scan = scanFields<false>(s, nullptr, s.vertexCount());
  const double floor = scan.floor(relativeTolerance);
  if (scan.passes(floor)) return -1;
  for (int i = 0; i < s.vertexCount(); ++i)
    if (badVertex(s, i, floor)) return i;
  return -1;
}

/// The first field of vertex i that is non-finite or below `floor`, as
/// "solvent = -1" (empty when none is).
std::string badValueAt(const StainState& s, int i, double floor) {
  std::ostringstream text;
  for (const auto& [name, field] : densityFields(s))
    if (!std::isfinite((*field)[i]) || (*field)[i] < floor) {
      text << name << " = " << (*field)[i];
      return text.str();
    }
  const Complex u = s.velocities[i];
  if (!std::isfinite(u.real())) text << "velocity (real part) = " << u.real();
  else if (!std::isfinite(u.imag())) text << "velocity (imaginary part) = " << u.imag();
  return text.str();
}

/// firstBadVertex over `vertices` only (the ones a step changed): the
/// smallest listed vertex with a non-finite value or a density below
/// −tol × the largest listed magnitude, or -1.
int firstBadVertexAmong(const StainState& s, const std::vector<int>& vertices, double relativeTolerance) {
  const FieldScan scan = scanFields<true>(s, vertices.data(), static_cast<int>(vertices.size()));
  const double floor = scan.floor(relativeTolerance);
  if (scan.passes(floor)) return -1;
  int first = -1;
  for (const int i : vertices)
    if (badVertex(s, i, floor) && (first < 0 || i < first)) first = i;
  return first;
}

double weightedSum(const Vector& density, const Vector& areas) { return density.dot(areas); }

/// `def` when every parameter is usable, checked before anything is built from
/// it: a negative rate would create mass and a NaN would only surface steps
/// later as a non-finite density far from its cause. Rates, capacities and
/// a_evap and the slip length finite and >= 0; σ_sat, ρ and ν finite and > 0
/// (they divide); gravity
/// finite; strain tolerance finite and > 0. Throws std::invalid_argument naming
/// the field, the value and what was expected.
const StainSolverDef& checkedDefinition(const StainSolverDef& def) {
  const auto require = [](bool ok, const char* field, double value, const char* expected) {
    if (ok) return;
    std::ostringstream message;
    message << "StainSolverDef::" << field << " must be " << expected << ", got " << value;
    throw std::invalid_argument(message.str());
  };
  const auto nonNegative = [&](const char* field, double value) {
    require(std::isfinite(value) && value >= 0, field, value, "finite and >= 0");
  };
  const auto positive = [&](const char* field, double value) {
    require(std::isfinite(value) && value > 0, field, value, "finite and > 0");
  };
  const LiquidParameters& liquid = def.liquid;
  nonNegative("liquid.absorptionRate", liquid.absorptionRate);
  positive("liquid.saturationDensity", liquid.saturationDensity);
  nonNegative("liquid.desorptionRate", liquid.desorptionRate);
  nonNegative("liquid.adsorptionCapacity", liquid.adsorptionCapacity);
  nonNegative("liquid.evaporationRate", liquid.evaporationRate);
  nonNegative("liquid.boundaryEvaporationFactor", liquid.boundaryEvaporationFactor);
  nonNegative("liquid.wetThreshold", liquid.wetThreshold);
  positive("liquid.liquidDensity", liquid.liquidDensity);
  positive("liquid.kinematicViscosity", liquid.kinematicViscosity);
  nonNegative("liquid.slipLength", liquid.slipLength);
  nonNegative("liquid.molecularDiffusivity", liquid.molecularDiffusivity);
  const std::string threadRange = "a count in [0, " + std::to_string(kMaxThreads) + "] (0: the OpenMP default)";
  require(def.threads >= 0 && def.threads <= kMaxThreads, "threads", def.threads, threadRange.c_str());
  for (int k = 0; k < 3; ++k)
    require(std::isfinite(def.gravity[k]), "gravity", def.gravity[k], "finite in every component");
  positive("strainTolerance", def.strainTolerance);
  // A Region refresh re-measures around the vertices the test measured: with
  // the whole-mesh test, a strain outside them would trip every step.
  if (def.intrinsicRefresh == IntrinsicRefresh::Region && def.strainTest != StrainTest::AroundLiquid)
    throw std::invalid_argument(
        "StainSolverDef::intrinsicRefresh Region needs strainTest AroundLiquid, got WholeMesh");
  return def;
}

}  // namespace

double MassBudget::solventError() const {
  const double total = freeSolvent + absorbedSolvent + evaporatedSolvent;
  return addedSolvent > 0 ? std::abs(total - addedSolvent) / addedSolvent : std::abs(total);
}

double MassBudget::soluteError() const {
  const double total = freeSolute + absorbedSolute + adsorbedSolute;
  return addedSolute > 0 ? std::abs(total - addedSolute) / addedSolute : std::abs(total);
}

StainSolver::StainSolver(const SurfaceTopology& topology, const RowVectors3& restPositions,
                         const FabricField& fabric, const StainSolverDef& def)
    : def_(checkedDefinition(def)), geometry_(topology, restPositions, fabric, def.strainTolerance) {
  geometry_.setIntrinsicRefresh(def.intrinsicRefresh);
  const int n = topology.vertexCount();
  state_.resize(n);
  backup_.resize(n);
  validateAll_ = true;
  diffusionScratch_.resize(n, topology.edgeCount());
  systems_.setSolverChoice(def_.diffusionSolver);
  velocityScratch_.prepare(topology);
  densityScratch_.resize(n, topology.edgeCount(), topology.faceCount());
  band_.resize(n, static_cast<int>(topology.ringNeighbors().size()));
  filmScratch_.resize(n);
  interactionScratch_.reserve(static_cast<size_t>(n));
  diffusedPastReach_.reserve(static_cast<size_t>(n));
  momentumScratch_.resize(n, static_cast<int>(topology.ringNeighbors().size()));
  soluteScratch_.resize(n, static_cast<int>(topology.ringNeighbors().size()));
  filmViscosityScratch_.resize(n, static_cast<int>(topology.ringNeighbors().size()));
  strainTestVertices_.reserve(static_cast<size_t>(n));
  strainTestMarks_.assign(static_cast<size_t>(n), 0);
  surfaceVelocityScratch_ = RowVectors3::Zero(n, 3);
  initialVelocities_ = RowVectors3::Zero(n, 3);
  evaporatedMass_ = Vector::Zero(n);
  threads_ = resolvedThreads(def_.threads);
  threadChoice_.reset(threads_);
  geometry_.setVertexRefresh(def_.geometryVertices);
  systems_.preparePatterns(geometry_.intrinsic());  // the first step then assembles in place
}

StainSolver::~StainSolver() = default;

void StainSolver::prepareForDeformation() { geometry_.prepareWholeRebuilds(); }

void StainSolver::completeGeometry() {
  const ThreadScope threads(threads_);
  geometry_.prepareAllVertices();
}

void StainSolver::completeGeometryAfterOutsideWrite() {
  if (!writtenSinceRefresh_ && def_.framesOnDampVertices) return;
  completeGeometry();
  writtenSinceRefresh_ = false;
}

void StainSolver::setThreadCount(int threads) {
  if (threads < 0 || threads > kMaxThreads)
    throw std::invalid_argument("StainSolver::setThreadCount: expected a count in [0, " + std::to_string(kMaxThreads) +
                                "], got " + std::to_string(threads));
  threads_ = resolvedThreads(threads);
  threadChoice_.reset(threads_);
}

void StainSolver::setAdaptiveThreads(bool adaptive) {
  def_.adaptiveThreads = adaptive;
  threadChoice_.reset(threads_);
}

void StainSolver::setInitialMotion(const RowVectors3& positions, const RowVectors3& velocities) {
  if (positions.rows() != state_.vertexCount() || velocities.rows() != state_.vertexCount())
    throw std::invalid_argument("StainSolver::setInitialMotion: expected " +
                                std::to_string(state_.vertexCount()) + " rows");
  const ThreadScope threads(threads_);
  // Twice: the first refresh puts p(0) in the t + h slot, the second shifts it
  // to t with frames fitted to it. The first step then sets t − h from v(0).
  geometry_.refreshExtrinsic(positions, 1.0);
  geometry_.refreshExtrinsic(positions, 1.0);
  geometry_.prepareAllVertices();  // the coupling and the views read p(0)'s frames before a step
  initialVelocities_ = velocities;
}

void StainSolver::setPositionsBeforeFirstStep(const RowVectors3& positions) {
  if (positions.rows() != state_.vertexCount() || !positions.allFinite())
    throw std::invalid_argument("StainSolver::setPositionsBeforeFirstStep: expected " +
                                std::to_string(state_.vertexCount()) + " finite rows");
  if (started_) return;
  positionsBeforeFirstStep_ = positions;  // sized once: the same rows each time
  havePositionsBeforeFirstStep_ = true;
}

Complex StainSolver::velocityInCurrentFrame(int i) const {
  const Complex u = state_.velocities[i];
  const PhysicsSwitches& on = def_.switches;
  // Only a step that ran the frame change leaves u at the midpoint; any other
  // moving step had ω = 0 or no liquid (where u plays no part).
  if (!started_ || !on.coriolis || !on.velocityAdvection || on.coriolisScheme != CoriolisScheme::ExactRotation)
    return u;
  const RowVectors3& omega = geometry_.extrinsic().vertexAngularVelocities;
  if (omega.rows() != state_.vertexCount() || omega(i, 2) == 0.0) return u;
  return u * std::polar(1.0, -0.5 * omega(i, 2) * systems_.assembledStep());
}

Vector3 StainSolver::surfaceVelocity(int i) const {
  const ExtrinsicGeometry& e = geometry_.extrinsic();
  const double h = systems_.assembledStep();
  if (!started_ || !(h > 0)) return initialVelocities_.row(i).transpose();
  return (e.nextPositions.row(i) - e.positions.row(i)).transpose() / h;
}

Vector3 StainSolver::relativeVelocity(int i) const {
  const Matrix3& frame = geometry_.extrinsic().nextFrames[static_cast<size_t>(i)];
  const Complex u = velocityInCurrentFrame(i);
  return frame.col(0) * u.real() + frame.col(1) * u.imag();
}

Vector3 StainSolver::worldVelocity(int i) const { return surfaceVelocity(i) + relativeVelocity(i); }

void StainSolver::restartMotion(const RowVectors3& positions, const RowVectors3& velocities) {
  // The state is kept to the bit (u stays in the frame convention the steps
  // use); only the geometry restarts: p(t) with frames fitted to it, and
  // p(t − h) = p − h v as the first step sets it.
  setInitialMotion(positions, velocities);
  const double h = systems_.assembledStep();
  if (h > 0) {
    geometry_.setPreviousPositions(geometry_.extrinsic().nextPositions - h * initialVelocities_);
  } else {
    started_ = false;  // no step yet: the first step does it
  }
  undoable_ = false;
}

void StainSolver::abandonStep(const RowVectors3& positions, const RowVectors3& velocities) {
  if (undoable_) {  // the stain step succeeded; a later stage of the coupled step failed
    restoreBackup();
    time_ = backupTime_;
    --steps_;
  } else if (inStep_ && backup_.any()) {
    restoreBackup();
  }
  inStep_ = false;
  restartMotion(positions, velocities);
}

StainState& StainSolver::mutableState() {
  stateWrittenOutside();
  writtenOutside_ = true;  // liquid may have been put on without a drop
  return state_;
}

bool StainSolver::everHeldLiquid() const {
  return state_.addedSolvent > 0 || state_.addedSolute > 0 || writtenOutside_;
}

bool StainSolver::strainExceededAroundLiquid() {
  // The vertices holding free liquid (holdsFreeLiquid): the candidates of the
  // incremental wet set hold every one of them when the set is not stale, so
  // the list is the same whichever way it was found.
  const double threshold = def_.liquid.wetThreshold;
  const auto add = [&](int i) {
    if (strainTestMarks_[static_cast<size_t>(i)]) return;
    strainTestMarks_[static_cast<size_t>(i)] = 1;
    strainTestVertices_.push_back(i);
  };
  strainTestVertices_.clear();
  if (band_.scanAll) {
    for (int i = 0; i < state_.vertexCount(); ++i)
      if (holdsFreeLiquid(state_, i, threshold)) add(i);
  } else {
    for (const int i : band_.candidates)
      if (holdsFreeLiquid(state_, i, threshold)) add(i);
  }
  // Sources add liquid on their regions this step.
  if (def_.switches.sources)
    for (const HeldRegion& region : heldRegions_)
      for (const int v : region.vertices) add(v);
  for (const int i : strainTestVertices_) strainTestMarks_[static_cast<size_t>(i)] = 0;
  return geometry_.strainExceededAround(strainTestVertices_.data(), static_cast<int>(strainTestVertices_.size()));
}

void StainSolver::stateWrittenOutside() {
  writtenSinceRefresh_ = true;
  backup_.markStale();
  band_.scanAll = true;
  validateAll_ = true;
}

void StainSolver::noteChanged(const int* vertices, int count) {
  backup_.note(vertices, count);
  band_.noteChanged(vertices, count);
}

void StainSolver::noteAllChanged() {
  backup_.noteAll();
  band_.scanAll = true;
}

void StainSolver::restoreBackup() {
  if (backup_.any()) backup_.restore(state_);  // else the step changed nothing yet
  if (rebuiltInStep_) {
    // The restored densities are per the old dual areas: the old tier comes
    // back with them (SurfaceGeometry keeps it; no copy), and M + hL is
    // assembled from it again, the values the step found (factors follow
    // lazily). So a failed rebuilding step leaves the stain to the bit as it
    // was; rejected: keeping the new tier and rescaling the densities to it,
    // which broke when the rebuilt surface had collapsed (a zero area) and
    // left a metric from positions the step abandoned.
    geometry_.undoIntrinsicRefresh();
    // Tables filled from the abandoned tier carry its rebuild count, which
    // the next rebuild repeats with another metric (as after restore()).
    velocityScratch_.invalidate();
    band_.invalidateIntrinsic();
    // At the step size of the moment, or, where the rebuild released the
    // systems before they were assembled again (a failure at stage
    // geometry), at the one the step found: left unassembled, the next
    // restartMotion would take the solver for one that never stepped, and
    // its next step for a first step (u in the frames at t).
    const double h = systems_.assembledStep() > 0 ? systems_.assembledStep() : backupAssembledStep_;
    systemsOfTier_ = h > 0 && systems_.assemble(geometry_.intrinsic(), h) == SolverStatus::Ok;
    rebuiltInStep_ = false;
    band_.scanAll = true;
  }
}

void StainSolver::injectFaultForTesting(const InjectedFault& fault) {
  const bool checked = fault.stage == Stage::Sources || (fault.stage >= Stage::BodyForces && fault.stage <= Stage::Interact);
  if (!checked)
    throw std::invalid_argument(std::string("injected fault: '") + stageName(fault.stage) + "' is not a stain stage");
  if (fault.vertex < 0 || fault.vertex >= state_.vertexCount())
    throw std::invalid_argument("injected fault: vertex " + std::to_string(fault.vertex) + " out of range [0, " +
                                std::to_string(state_.vertexCount()) + ")");
  fault_ = fault;
  fault_.armed = true;
}

template <class Work>
bool StainSolver::runStage(Stage stage, bool active, StepReport& report, Work&& work) {
  if (!active) return true;
  const Clock::time_point start = Clock::now();
  if constexpr (std::is_same_v<decltype(work()), SolverStatus>) {
    const SolverStatus status = work();
    profile_.milliseconds[static_cast<size_t>(stage)] += millisecondsSince(start);
    profile_.markRan(stage);
    if (status != SolverStatus::Ok) {
      restoreBackup();
      report.status = StepStatus::SolverFailure;
      report.stage = stage;
      // The state the step started from was valid (validated whole after a
      // write from outside, by the step's checks otherwise): the solve met
      // something this step made, and the restored state holds nothing to name.
      report.message = "stage '" + std::string(stageName(stage)) + "' of step " + std::to_string(steps_ + 1) + ": " +
                       toString(status) + "; state restored";
      return false;
    }
  } else {
    work();
    profile_.milliseconds[static_cast<size_t>(stage)] += millisecondsSince(start);
    profile_.markRan(stage);
  }
  return checkStage(stage, report);
}

bool StainSolver::checkStage(Stage stage, StepReport& report) {
  if (fault_.armed && fault_.step == steps_ + 1 && fault_.stage == stage) {
    noteChanged(&fault_.vertex, 1);
    state_.solvent[fault_.vertex] = std::numeric_limits<double>::quiet_NaN();
    fault_.armed = false;  // fires once
  }
  // One pass over the vertices the stages touched (wet + halo, held ones
  // after "sources"): the extremes of every field and whether all are
  // finite. The search for the vertex runs only on a failure.
  const bool held = stage == Stage::Sources;
  FieldScan scan = scanFields<true>(state_, band_.vertices.data(), band_.size());
  if (held)
    for (const HeldRegion& region : heldRegions_)
      scan.merge(scanFields<true>(state_, region.vertices.data(), static_cast<int>(region.vertices.size())));
  const double floor = scan.floor(kNegativeDensityTolerance);
  if (scan.passes(floor)) return true;

  int vertex = -1;
  for (int i : band_.vertices)
    if (badVertex(state_, i, floor)) {
      vertex = i;
      break;
    }
  if (vertex < 0 && held)
    for (const HeldRegion& region : heldRegions_)
      for (int v : region.vertices)
        if (vertex < 0 && badVertex(state_, v, floor)) vertex = v;
  const bool finite = scan.finite;
  report.status = finite ? StepStatus::NegativeMass : StepStatus::NonFinite;
  report.stage = stage;
  report.vertex = vertex;
  report.message = std::string(finite ? "negative density" : "non-finite value") + " at vertex " +
                   std::to_string(vertex) + " after stage '" + stageName(stage) + "' of step " +
                   std::to_string(steps_ + 1) + "; state restored";
  restoreBackup();
  return false;
}

void StainSolver::addDrop(const DropDef& drop) {
  undoable_ = false;
  stateWrittenOutside();
  // Every vertex's frame and ω: u is turned below wherever it is stored, and
  // the drop lands on vertices that may be outside the last band.
  {
    const ThreadScope threads(threads_);
    geometry_.prepareAllVertices();
  }
  // The drop's world velocity is made relative to the surface here; u is
  // blended in the current frames (nextFrames), so a state kept in the last
  // step's midpoint frames is turned there and back (exact rotations).
  const int n = state_.vertexCount();
  surfaceVelocityScratch_.resize(n, 3);
  for (int i = 0; i < n; ++i) surfaceVelocityScratch_.row(i) = surfaceVelocity(i).transpose();
  ComplexVector& u = state_.velocities;
  for (int i = 0; i < n; ++i) {
    const Complex turned = velocityInCurrentFrame(i);
    u[i] = turned;
  }
  const RowVectors3& omega = geometry_.extrinsic().vertexAngularVelocities;
  const bool midpoint = started_ && def_.switches.coriolis && def_.switches.velocityAdvection &&
                        def_.switches.coriolisScheme == CoriolisScheme::ExactRotation && omega.rows() == n;
  const auto turnBack = [&] {
    if (!midpoint) return;
    for (int i = 0; i < n; ++i)
      if (omega(i, 2) != 0.0) u[i] *= std::polar(1.0, 0.5 * omega(i, 2) * systems_.assembledStep());
  };
  try {
    stain::addDrop(drop, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), state_,
                   &surfaceVelocityScratch_);
  } catch (...) {
    turnBack();
    throw;
  }
  turnBack();
}

void StainSolver::addHeldRegion(const HeldRegion& region) {
  for (int v : region.vertices)
    if (v < 0 || v >= state_.vertexCount())
      throw std::invalid_argument("held region: vertex " + std::to_string(v) + " out of range [0, " +
                                  std::to_string(state_.vertexCount() - 1) + "]");
  if (!(region.solventDensity >= 0) || !(region.soluteDensity >= 0))
    throw std::invalid_argument("held region: densities must be finite and >= 0");
  heldRegions_.push_back(region);
}

void StainSolver::prepareBand() {
  // The wet set, then the band around it with u extended onto it
  // (liquid_band.h). A whole-mesh direct velocity solve reads u everywhere,
  // so then the band (and the extension) covers the mesh.
  // Where u lives on the free liquid only, soaked vertices (liquid the
  // fibres hold, u = 0) are filed apart: the band grows from the free liquid.
  updateWetVertices(def_.liquid.wetThreshold, state_, band_, def_.soakedApart && ctx_.switches.velocityOnFreeLiquid);
  // (The film's mass-weighted viscosity has its own solve on the liquid.)
  const bool areaWeightedViscosity = ctx_.switches.velocityDiffusion && !ctx_.switches.massWeightedViscosity;
  velocityByFactor_ = areaWeightedViscosity && !systems_.vectorIterative();
  // The per-vertex geometry where this step reads it (the wet set now, each
  // ring as the band grows), and on the traces of liquid where a reader
  // between steps asks for them (the coupling's free relative momentum).
  if (def_.framesOnDampVertices) geometry_.prepareVertices(band_.dampVertices);
  const auto settleSoaked = [&] {
    settleSoakedVelocities(band_, state_, [&](int i) { noteChanged(&i, 1); });
  };
  if (band_.wetCount() == 0) {
    settleSoaked();
    profile_.wetVertices = profile_.haloVertices = profile_.bandVertices = 0;
    profile_.soakedVertices = static_cast<int>(band_.soakedVertices.size());
    return;
  }
  geometry_.prepareVertices(band_.vertices);
  const PhysicsSwitches& on = ctx_.switches;
  // u of the wet vertices into F^t first (the discrete frame change), so the
  // extension reads and writes one frame convention.
  const bool frameChange = on.coriolis && on.velocityAdvection && on.coriolisScheme == CoriolisScheme::ExactRotation;
  if (frameChange && !firstStep_)
    applyHalfFrameRotation(ctx_, geometry_.extrinsic(), band_.wetMask, state_, &band_.vertices);  // the wet set, so far
  LiquidBandInputs inputs;
  inputs.h = ctx_.h;
  inputs.gravity = on.gravity ? ctx_.gravity : Vector3::Zero();
  inputs.useAccelerations = on.linearInertia;
  // The extension carries the surface's velocity only where the liquid feels
  // the frame's motion: with linear inertia and Coriolis off, u is carried as
  // a velocity relative to the cloth and no stage reads the cloth's velocity.
  inputs.surfaceMoved = surfaceMoved_ && (on.linearInertia || on.coriolis);
  // A direct velocity solve reads u everywhere: the band then covers the
  // mesh. Under Auto the factor is also taken when the band's own solve is
  // predicted dearer than it plus that wider band.
  inputs.coverComponent = velocityByFactor_;
  // The film's potential gradient acts on the wet set only; its largest kick
  // joins the speed bound (on top of the tangential g − p̈ already there).
  if (on.filmPressure)
    inputs.filmAcceleration = filmAccelerations(ctx_, geometry_.topology(), geometry_.extrinsic(), state_,
                                                band_.wetMask, band_.vertices, filmScratch_);
  growLiquidBand(inputs, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), band_, state_, &geometry_);
  if (areaWeightedViscosity && !velocityByFactor_ && systems_.solverChoice() == DiffusionSolverChoice::Auto &&
      velocityCostOnBand(systems_, band_.interiorCount) >
          velocityCostByFactor(systems_, state_.vertexCount() - band_.size())) {
    velocityByFactor_ = true;
    inputs.coverComponent = true;
    shrinkBandToWetSet(band_);
    growLiquidBand(inputs, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), band_, state_,
                   &geometry_);
  }
  settleSoaked();
  // The half rotation wrote the wet u, the extension the rest of the band;
  // every later stage but the diffusion and the interaction writes inside it.
  noteChanged(band_.vertices.data(), band_.size());
  profile_.wetVertices = band_.wetCount();
  profile_.soakedVertices = static_cast<int>(band_.soakedVertices.size());
  profile_.haloVertices = band_.haloCount;
  profile_.bandVertices = band_.size();
  profile_.bandRings = band_.rings;
  profile_.reachRings = band_.reachRings;
  profile_.markRan(Stage::LiquidBand);
}

StepReport StainSolver::step(double h, const RowVectors3& nextPositions) {
  StepReport report = refreshGeometry(h, nextPositions, nullptr);
  return report.ok() ? advanceStages() : report;
}

StepReport StainSolver::stepRigid(double h, const RowVectors3& nextPositions, const Matrix3& rotation) {
  StepReport report = refreshGeometry(h, nextPositions, &rotation);
  return report.ok() ? advanceStages() : report;
}

PhysicsSwitches StainSolver::activeTerms(bool surfaceMoved, bool anyLiquid) const {
  const PhysicsSwitches& on = def_.switches;
  const LiquidParameters& liquid = def_.liquid;
  const bool any = anyLiquid;
  PhysicsSwitches active = on;
  // A zero coefficient is a term switched off: zero gravity adds nothing (and
  // drives no film pressure), a zero rate transfers nothing.
  active.gravity = any && on.gravity && !def_.gravity.isZero(0.0);
  active.linearInertia = any && on.linearInertia && surfaceMoved;
  active.coriolis = any && on.coriolis && surfaceMoved;
  active.filmPressure = any && on.filmPressure && active.gravity;
  active.filmFriction = any && on.filmFriction && liquid.kinematicViscosity > 0;
  active.velocityAdvection = any && on.velocityAdvection;
  active.densityAdvection = any && on.densityAdvection;
  active.densityDiffusion = any && on.densityDiffusion;
  active.soluteWithSolvent = any && on.soluteWithSolvent;
  active.massWeightedViscosity = any && on.massWeightedViscosity;
  active.velocityDiffusion = any && on.velocityDiffusion;
  active.absorption = any && on.absorption && liquid.absorptionRate > 0;
  active.adsorption = any && on.adsorption && liquid.desorptionRate > 0;
  active.evaporation = any && on.evaporation && liquid.evaporationRate > 0;
  active.sources = on.sources && !heldRegions_.empty();
  return active;
}

bool StainSolver::validStateWrittenOutside(StepReport& report) {
  const auto refuse = [&](StepStatus status, int vertex, const std::string& what) {
    report.status = status;
    report.vertex = vertex;
    report.message = what + ", written outside a step (mutableState or restore); expected finite densities >= 0, "
                     "finite velocities and finite totals >= 0: step " + std::to_string(steps_ + 1) +
                     " not taken, nothing changed";
    return false;
  };
  const std::pair<const char*, double> totals[] = {{"evaporatedSolvent", state_.evaporatedSolvent},
                                                   {"addedSolvent", state_.addedSolvent},
                                                   {"addedSolute", state_.addedSolute}};
  for (const auto& [name, value] : totals)
    if (!(std::isfinite(value) && value >= 0)) {
      std::ostringstream text;
      text << name << " = " << value;
      return refuse(std::isfinite(value) ? StepStatus::NegativeMass : StepStatus::NonFinite, -1, text.str());
    }
  const FieldScan scan = scanFields<false>(state_, nullptr, state_.vertexCount());
  const double floor = scan.floor(kNegativeDensityTolerance);
  if (scan.passes(floor)) {
    // Every vertex passed: from here on the step's own checks (the band
    // after each stage, the vertices it changed at the end) cover the state.
    validateAll_ = false;
    return true;
  }
  int bad = 0;
  while (!badVertex(state_, bad, floor)) ++bad;  // one exists: the scan did not pass
  const bool finite = !badVertex(state_, bad, -std::numeric_limits<double>::infinity());
  return refuse(finite ? StepStatus::NegativeMass : StepStatus::NonFinite, bad,
                "vertex " + std::to_string(bad) + " holds " + badValueAt(state_, bad, floor));
}

StepReport StainSolver::refreshGeometry(double h, const RowVectors3& nextPositions, const Matrix3* rigidRotation) {
  inStep_ = false;
  StepReport report = checkTimeStep(h);
  if (!report.ok()) return report;
  if (nextPositions.rows() != state_.vertexCount() || !nextPositions.allFinite()) {
    report.status = StepStatus::InvalidArgument;
    report.message = "next positions must be " + std::to_string(state_.vertexCount()) + " finite rows";
    return report;
  }
  if (rigidRotation != nullptr &&
      (!rigidRotation->allFinite() ||
       (rigidRotation->transpose() * *rigidRotation - Matrix3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
       !(rigidRotation->determinant() > 0))) {
    report.status = StepStatus::InvalidArgument;
    report.message = "stepRigid: rotation must be a rotation matrix";
    return report;
  }
  if (validateAll_ && !validStateWrittenOutside(report)) return report;
  // A probe of the threads needs idle cores to measure anything but waiting
  // (ThreadChoice, "skipProbe").
  if (def_.adaptiveThreads && threadChoice_.laterProbeStarting() &&
      !roomForThreads(threadChoice_.most(), omp_get_num_procs()))
    threadChoice_.skipProbe();
  const ThreadScope threads(stepThreads());
  profile_ = StepProfile{};
  profile_.vertexCount = state_.vertexCount();
  profile_.threads = stepThreads();
  // The rollback point: the mirror takes the last step's changes (O(changed
  // vertices)); this step then lists the vertices it may change. A dry step
  // without sources lists none and copies nothing.
  ScopedTimer total(profile_.total);  // the commit is the step's own pass ("other")
  backup_.commit(state_);
  undoable_ = false;
  rebuiltInStep_ = false;
  backupTime_ = time_;
  backupAssembledStep_ = systems_.assembledStep();
  ScopedTimer t(profile_.milliseconds[static_cast<size_t>(Stage::Geometry)]);
  report.stage = Stage::Geometry;

  // On the first step u is in the frames at t, not in a last step's midpoint frame.
  firstStep_ = !started_;
  if (!started_) {
    // p(−h) from the motion where it knows it; else p(−h) ≈ p(0) − h v(0):
    // the first centred acceleration then sees the motion's initial velocity
    // instead of a jump from rest (but only half its acceleration).
    if (havePositionsBeforeFirstStep_) {
      geometry_.setPreviousPositions(positionsBeforeFirstStep_);
    } else {
      geometry_.setPreviousPositions(geometry_.extrinsic().nextPositions - h * initialVelocities_);
    }
    started_ = true;
  }
  havePositionsBeforeFirstStep_ = false;
  const bool aroundLiquid = def_.strainTest == StrainTest::AroundLiquid;
  bool rebuild = rigidRotation != nullptr
                     ? geometry_.refreshExtrinsicRigid(nextPositions, *rigidRotation, h)
                     : geometry_.refreshExtrinsic(nextPositions, h, everHeldLiquid() && !aroundLiquid);
  if (rigidRotation == nullptr && aroundLiquid && everHeldLiquid()) rebuild = strainExceededAroundLiquid();
  writtenSinceRefresh_ = false;  // new frames: a vertex without them is one no stage reads
  profile_.maxEdgeStrain = geometry_.maxEdgeStrain();
  // A partial rebuild changes M + h L in the columns of the vertices it
  // re-measured: those are refilled when the systems hold the old tier's values.
  bool assembleColumns = false;
  if (rebuild) {
    // Densities are per area: when the dual areas change, rescale them so
    // each vertex keeps its mass (A_old σ_old = A_new σ_new).
    areaScratch_ = geometry_.intrinsic().vertexDualAreas;
    const bool systemsOfOldTier = systemsOfTier_ && systems_.assembledStep() == h;
    systems_.releaseFactors();  // the stale factors are not kept while new operators are assembled
    systemsOfTier_ = false;
    if (def_.intrinsicRefresh == IntrinsicRefresh::Region)
      geometry_.setRefreshRegion(strainTestVertices_.data(), static_cast<int>(strainTestVertices_.size()));
    rebuiltInStep_ = true;  // from here on, a failure gives the old tier back (restoreBackup)
    try {
      geometry_.refreshIntrinsic();
    } catch (const std::invalid_argument& error) {
      // An anisotropic face whose weft cannot be laid out in the rebuilt
      // metric: a face with a zero-length edge (a collapsed face) has no
      // plane to lay it out in. The areas are computed before the operators,
      // so the report names the collapsed face as for an isotropic fabric.
      StepReport failed = checkRebuiltAreas();
      restoreBackup();
      if (failed.ok()) {
        failed.status = StepStatus::NonFinite;
        failed.stage = Stage::Geometry;
        failed.message = "intrinsic rebuild of step " + std::to_string(steps_ + 1) + ": " + error.what() +
                         "; state restored";
      }
      return failed;
    }
    if (const StepReport collapsed = checkRebuiltAreas(); !collapsed.ok()) {
      restoreBackup();  // the old tier back, before any density is rescaled by a zero area
      return collapsed;
    }
    const Vector& areas = geometry_.intrinsic().vertexDualAreas;
    Vector* const densities[] = {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                                 &state_.adsorbedSolute};
    if (geometry_.lastRefreshPartial()) {
      // Only the re-measured vertices' dual areas changed: every other
      // ratio is x / x = 1 and would leave its densities' bits as they are.
      const std::vector<int>& changed = geometry_.refreshedVertices();
      noteChanged(changed.data(), static_cast<int>(changed.size()));
      for (const int i : changed) {
        const double ratio = areaScratch_[i] / areas[i];
        for (Vector* f : densities) (*f)[i] *= ratio;
      }
      assembleColumns = systemsOfOldTier;
    } else {
      noteAllChanged();  // every density is rescaled
      areaScratch_.array() /= areas.array();
      for (Vector* f : densities) f->array() *= areaScratch_.array();
    }
    profile_.intrinsicRefreshes = 1;
    profile_.markRan(StepTerm::IntrinsicRebuild);
  }
  // New values for M + h L; the factors are computed lazily, by the first
  // direct solve that needs one (a CG-only step factorizes nothing).
  if (rebuild || systems_.assembledStep() != h) {
    profile_.markRan(StepTerm::SystemAssembly);
    const std::vector<int>& v1 = geometry_.refreshedVertices();
    const std::vector<int>& v2 = geometry_.reassembledConnectionVertices();
    const SolverStatus status =
        assembleColumns ? systems_.assembleColumns(geometry_.intrinsic(), h, v1.data(), static_cast<int>(v1.size()),
                                                   v2.data(), static_cast<int>(v2.size()))
                        : systems_.assemble(geometry_.intrinsic(), h);
    if (status != SolverStatus::Ok) {
      restoreBackup();  // the densities, and the old tier when this step rebuilt it
      report.status = StepStatus::SolverFailure;
      report.message = std::string("diffusion system assembly failed: ") + toString(status);
      return report;
    }
    systemsOfTier_ = true;
  }
  const bool surfaceMoved = geometry_.surfaceMoved();
  if (geometry_.fittedRefresh()) {
    profile_.markRan(StepTerm::RotationFits);
  } else if (rigidRotation != nullptr && surfaceMoved) {
    profile_.markRan(StepTerm::RigidFrames);
  }
  profile_.markRan(Stage::Geometry);
  surfaceMoved_ = surfaceMoved;
  // The terms as if liquid is there; the band (advanceStages) switches the
  // liquid's terms off when there is none.
  ctx_ = makeStepContext(h, def_.gravity, activeTerms(surfaceMoved, true), def_.liquid);
  inStep_ = true;
  return report;
}

StepReport StainSolver::advanceStages() {
  StepReport report;
  if (!inStep_) {
    report.status = StepStatus::InvalidArgument;
    report.message = "advanceStages: no refreshGeometry that returned Ok before it";
    return report;
  }
  report = runStages();
  // The whole step's time (refreshGeometry's part and this), at the count it ran with.
  if (report.ok() && def_.adaptiveThreads) threadChoice_.record(profile_.total);
  return report;
}

StepReport StainSolver::runStages() {
  StepReport report;
  const ThreadScope threads(stepThreads());
  ScopedTimer total(profile_.total);
  if (evaporationWritten_) {  // the coupling reads it after every step
    // The last interaction wrote it on its band and absorbing vertices
    // (band_ still holds them until prepareBand).
    for (const int i : band_.vertices) evaporatedMass_[i] = 0.0;
    for (const int i : band_.absorbingVertices) evaporatedMass_[i] = 0.0;
    for (const int i : diffusedPastReach_) evaporatedMass_[i] = 0.0;  // and past its reach set
    evaporationWritten_ = false;
  }
  // Held regions are topped up first, so liquid they add this step is in the
  // band and gets this step's forces.
  if (!runStage(Stage::Sources, ctx_.switches.sources, report, [&] {
        for (const HeldRegion& region : heldRegions_)
          noteChanged(region.vertices.data(), static_cast<int>(region.vertices.size()));
        applySources(ctx_, heldRegions_, geometry_.intrinsic(), state_);
        profile_.markRan(StepTerm::Sources);
      }))
    return report;
  {
    ScopedTimer t(profile_.milliseconds[static_cast<size_t>(Stage::LiquidBand)]);
    prepareBand();
  }
  profile_.geometryVertices = surfaceMoved_ ? geometry_.preparedVertexCount() : 0;
  if (band_.wetCount() == 0) {  // no free liquid: nothing to move
    const PhysicsSwitches withLiquid = ctx_.switches;
    ctx_.switches = activeTerms(surfaceMoved_, false);
    if (!band_.soakedVertices.empty()) {  // liquid the fibres hold still dries and absorbs
      ctx_.switches.absorption = withLiquid.absorption;
      ctx_.switches.adsorption = withLiquid.adsorption;
      ctx_.switches.evaporation = withLiquid.evaporation;
    }
  }
  const StepContext& ctx = ctx_;
  const PhysicsSwitches& on = ctx.switches;  // the terms this step runs (activeTerms)
  const SurfaceTopology& topology = geometry_.topology();
  const IntrinsicGeometry& intrinsic = geometry_.intrinsic();
  const ExtrinsicGeometry& extrinsic = geometry_.extrinsic();
  // The Coriolis term is the discrete frame change (docs/transport.md): half
  // the frame increment in prepareBand, the frame velocity along the
  // backtrack and the other half after the velocity advection.
  const bool frameChange = on.coriolis && on.velocityAdvection && on.coriolisScheme == CoriolisScheme::ExactRotation;

  diffusedPastReach_.clear();  // filled by this step's density diffusion, if it runs
  // clang-format off
  const std::vector<char>& band = band_.bandMask;    // forces act here, u is defined here
  const std::vector<char>& reach = band_.reachMask;  // where the advection can move liquid this step
  const std::vector<int>* among = smallBand() ? &band_.vertices : nullptr;  // the masked loops visit the band, not #V
  if (!runStage(Stage::BodyForces, on.gravity || on.linearInertia, report, [&] { clearVelocityWithoutFreeLiquid(ctx, band, state_, among); applyBodyForces(ctx, extrinsic, band, state_, among); markTerms({{StepTerm::Gravity, on.gravity}, {StepTerm::LinearInertia, on.linearInertia}}); }) ||
      !runStage(Stage::AdvectVelocity, on.velocityAdvection, report, [&] { advectVelocity(ctx, topology, intrinsic, reach, velocityScratch_, state_, among); profile_.markRan(StepTerm::VelocityAdvection); }) ||
      !runStage(Stage::Coriolis, on.coriolis, report, [&] { profile_.markRan(StepTerm::Coriolis);
                                                            frameChange ? applyFrameVelocityChange(ctx, extrinsic, velocityScratch_.footVertices, velocityScratch_.footWeights, reach, state_, among)
                                                                        : applyCoriolis(ctx, extrinsic, band, state_, among); }))
    return report;
  // The wall acts on the liquid's u once this step's terms are all in it:
  // between them u is a split step's intermediate (on a rotating disc the
  // inertia's outward push is undone by the frame change). Extended values
  // are left alone: a wall far from the liquid must not reach it through a
  // whole-mesh velocity solve.
  applyBoundaryWall(ctx, topology, intrinsic, band_.wetMask, state_, among);
  // The film (film_flow.h): its potential gradient and friction, then the
  // densities it moves, in as many sub-steps as the film needs to stay
  // stable (one without the film terms: the paper's order).
  const bool film = on.filmPressure || on.filmFriction;
  const int filmSteps = film ? filmSubsteps(ctx, extrinsic, state_, band_, kMaxFilmSubsteps) : 1;
  profile_.filmSubsteps = filmSteps;
  StepContext filmContext = ctx;
  filmContext.h = ctx.h / filmSteps;
  filmContext.invH = 1.0 / filmContext.h;
  const StepContext& sub = filmSteps > 1 ? filmContext : ctx;
  for (int s = 0; s < filmSteps; ++s) {
    if (!runStage(Stage::FilmPressure, on.filmPressure, report, [&] { if (s > 0) filmAccelerations(sub, topology, extrinsic, state_, band_.wetMask, band_.vertices, filmScratch_);
                                                                       applyFilmPotential(sub, filmScratch_, band_.wetMask, band_.vertices, state_);
                                                                       profile_.markRan(StepTerm::FilmPressure); }) ||
        !runStage(Stage::FilmFriction, on.filmFriction, report, [&] { profile_.frictionDissipation += applyFilmFriction(sub, intrinsic.vertexDualAreas, band_.wetMask, band_.vertices, state_);
                                                                       profile_.markRan(StepTerm::FilmFriction); }))
      return report;
    if (film) applyBoundaryWall(sub, topology, intrinsic, band_.wetMask, state_, among);  // the film's kick points off the mesh too
    if (!runStage(Stage::AdvectDensity, on.densityAdvection, report, [&] { recordAdvection(advectDensities(sub, topology, intrinsic, extrinsic, band_.wetMask, densityScratch_, state_, &geometry_.restEdgeFrameNormals(), &reach, among)); }))
      return report;
  }
  if (!runStage(Stage::Diffuse, on.densityDiffusion || on.velocityDiffusion, report, [&] { return diffuseLiquid(ctx, among); }) ||
      !runStage(Stage::Interact, on.absorption || on.adsorption || on.evaporation, report, [&] { noteChanged(band_.absorbingVertices.data(), static_cast<int>(band_.absorbingVertices.size()));
                                                                                                   withDiffusedLiquidInReach([&] { interact(ctx, topology, intrinsic, reach, state_, &evaporatedMass_, interactionVertices(), &band_.soakedMask); });
                                                                                                   evaporationWritten_ = on.evaporation;
                                                                                                   markTerms({{StepTerm::Absorption, on.absorption}, {StepTerm::Adsorption, on.adsorption}, {StepTerm::Evaporation, on.evaporation}}); }))
    return report;
  // clang-format on
  return finishStep();
}

SolverStatus StainSolver::diffuseLiquid(const StepContext& ctx, const std::vector<int>* among) {
  const PhysicsSwitches& on = ctx.switches;
  const SurfaceTopology& topology = geometry_.topology();
  const IntrinsicGeometry& intrinsic = geometry_.intrinsic();
  // In the film model the diffusion moves the solution and its flux carries
  // the solute (solute_transport.h); with no solute there is nothing to carry.
  const bool carrySolute = on.densityDiffusion && on.soluteWithSolvent &&
                           std::any_of(band_.vertices.begin(), band_.vertices.end(),
                                       [&](int i) { return state_.solute[i] != 0.0; });
  if (carrySolute) holdLiquidForSoluteTransport(band_.vertices, state_, soluteScratch_);
  const SolverStatus status =
      recordDiffusion(diffuse(ctx, intrinsic, systems_, diffusionScratch_, state_, &band_.diffusionMask, velocityByFactor_));
  if (status != SolverStatus::Ok) return status;  // the step is undone: the held liquid with it
  if (carrySolute) {
    carrySoluteWithSolvent(ctx, topology, intrinsic, band_.vertices, diffusedPastReach_, soluteScratch_, state_);
    profile_.markRan(StepTerm::SoluteWithSolvent);
  }
  // The liquid the density diffusion moved carries its u (band vertices: noted above).
  if (on.densityDiffusion)
    carryMomentumWithDiffusion(ctx, topology, intrinsic,
                               surfaceMoved_ && (on.linearInertia || on.coriolis) ? &geometry_.extrinsic() : nullptr,
                               band_, momentumScratch_, state_, &diffusedPastReach_);
  // The film's viscosity, weighted by mass, on the liquid the step hands on.
  if (on.velocityDiffusion && on.massWeightedViscosity) {
    const FilmViscosityReport viscosity =
        diffuseFilmVelocity(ctx, topology, intrinsic, band_.vertices, filmViscosityScratch_, state_);
    profile_.viscousDissipation += viscosity.dissipation;
    profile_.diffusionIterations += viscosity.iterations;
    profile_.velocityDiffusionVertices = viscosity.vertices;
    profile_.markRan(StepTerm::VelocityDiffusionByMass);
  }
  // The viscosity and the carried momentum are velocity terms too: the wall
  // again, on every band vertex (liquid that reached the wall this step
  // included), so no u the step hands on points off the mesh.
  applyBoundaryWall(ctx, topology, intrinsic, band_.bandMask, state_, among);
  return status;
}

FilmEnergy StainSolver::liquidEnergy() const {
  const ExtrinsicGeometry& extrinsic = geometry_.extrinsic();
  const bool after = extrinsic.nextPositions.rows() == state_.vertexCount();  // the state's time is t + h
  return stain::liquidEnergy(def_.switches.gravity ? def_.gravity : Vector3::Zero(), def_.liquid.liquidDensity,
                             geometry_.topology(), after ? extrinsic.nextPositions : extrinsic.positions,
                             geometry_.intrinsic().vertexDualAreas, state_);
}

bool StainSolver::smallBand() const {
  // A list in band order reads the fields out of order and the interaction's
  // needs a sort: worth it below a quarter of the mesh (the same results).
  return 4 * static_cast<long long>(band_.size()) < state_.vertexCount();
}

const std::vector<int>* StainSolver::interactionVertices() {
  // The reach set and the absorbing traces outside it (each once), in index
  // order: a superset of what the interaction processes (interaction.h).
  if (!smallBand() || 4 * band_.absorbingVertices.size() >= static_cast<size_t>(state_.vertexCount())) return nullptr;
  std::vector<int>& list = interactionScratch_;
  list.clear();
  for (const int i : band_.vertices)
    if (band_.reachMask[static_cast<size_t>(i)]) list.push_back(i);
  for (const int i : band_.absorbingVertices)
    if (!band_.reachMask[static_cast<size_t>(i)]) list.push_back(i);
  // Diffused liquid outside the band (inside it, the loop above took it: it
  // is marked in the reach mask while the interaction runs).
  for (const int i : diffusedPastReach_)
    if (band_.levels[static_cast<size_t>(i)] < 0) list.push_back(i);
  std::sort(list.begin(), list.end());
  return &list;
}

template <class F>
void StainSolver::withDiffusedLiquidInReach(const F& f) {
  struct Unmark {
    StainSolver& solver;
    ~Unmark() {
      for (const int i : solver.diffusedPastReach_) solver.band_.reachMask[static_cast<size_t>(i)] = 0;
    }
  } unmark{*this};
  for (const int i : diffusedPastReach_) band_.reachMask[static_cast<size_t>(i)] = 1;
  f();
}

void StainSolver::markTerms(std::initializer_list<std::pair<StepTerm, bool>> terms) {
  for (const auto& [term, ran] : terms)
    if (ran) profile_.markRan(term);
}

void StainSolver::recordAdvection(const DensityAdvectionReport& r) {
  profile_.advectionSubsteps += r.substeps;
  profile_.advectionVertices = r.activeVertices;
  profile_.markRan(StepTerm::DensityAdvection);
}

SolverStatus StainSolver::recordDiffusion(const DiffusionReport& r) {
  profile_.diffusionIterations = r.densityIterations + r.velocityIterations;
  profile_.limiterCorrectedVertices = r.limiterCorrectedVertices;
  profile_.limiterMovedMass = r.limiterMovedMass;
  profile_.factorizations = r.factorizations;
  if (r.factorizations > 0) profile_.markRan(StepTerm::Factorization);
  // What the solves wrote. CG or RKL2 densities: the active rows only (RKL2
  // grows them one ring per stage; the limiter moves mass only to vertices
  // with σ > 0, all of them in the active set, which starts from every
  // nonzero density); CG or RKL2 velocities: the rows of
  // band_.diffusionMask, inside the band (noted). The direct solve writes
  // whole fields, and lists the vertices whose densities it changed or left
  // nonzero (the limiter's only), mostly where the liquid is.
  const auto onRows = [](DiffusionMethod m) {
    return m == DiffusionMethod::ConjugateGradient || m == DiffusionMethod::SuperTimeStepping;
  };
  // The densities' written set is noted, and the liquid it holds past the
  // reach set listed: the interaction processes it this step, as it does
  // the reach set (list == nullptr: every vertex; runStages emptied the
  // list before the stages).
  const auto densitiesWritten = [&](const int* list, int count) {
    if (list != nullptr) {
      noteChanged(list, count);
    } else {
      noteAllChanged();
      count = state_.vertexCount();
    }
    for (int k = 0; k < count; ++k) {
      const int i = list != nullptr ? list[k] : k;
      if (band_.reachMask[static_cast<size_t>(i)] == 0 && state_.solvent[i] + state_.solute[i] > 0.0)
        diffusedPastReach_.push_back(i);
    }
  };
  if (onRows(r.densityMethod)) {
    densitiesWritten(diffusionScratch_.densityActive.data(), r.densityActiveVertices);
  } else if (r.densityMethod == DiffusionMethod::Direct && r.directSupportVertices >= 0) {
    densitiesWritten(diffusionScratch_.directSupport.data(), r.directSupportVertices);
  } else if (r.densityMethod != DiffusionMethod::None) {
    densitiesWritten(nullptr, 0);
  }
  if (onRows(r.velocityMethod)) {
    noteChanged(diffusionScratch_.velocityActive.data(), r.velocityActiveVertices);
  } else if (r.velocityMethod != DiffusionMethod::None) {
    noteAllChanged();
  }
  const int n = state_.vertexCount();
  if (r.densityMethod != DiffusionMethod::None) {
    const bool krylov = r.densityMethod != DiffusionMethod::Direct;  // CG or RKL2: on the liquid
    profile_.markRan(krylov ? StepTerm::DensityDiffusionKrylov : StepTerm::DensityDiffusionDirect);
    profile_.densityDiffusionVertices = krylov ? r.densityActiveVertices : n;
  }
  if (r.velocityMethod != DiffusionMethod::None) {
    const bool krylov = r.velocityMethod != DiffusionMethod::Direct;  // CG or RKL2: on the band
    profile_.markRan(krylov ? StepTerm::VelocityDiffusionKrylov : StepTerm::VelocityDiffusionDirect);
    profile_.velocityDiffusionVertices = krylov ? r.velocityActiveVertices : n;
  }
  return r.status;
}

StepReport StainSolver::checkRebuiltAreas() const {
  StepReport report;
  const Vector& areas = geometry_.intrinsic().faceAreas;
  for (Eigen::Index f = 0; f < areas.size(); ++f) {
    if (areas[f] > 0 && std::isfinite(areas[f])) continue;
    const Triangles& faces = geometry_.topology().faces();
    char value[32];
    std::snprintf(value, sizeof value, "%.17g", areas[f]);
    report.status = StepStatus::NonFinite;
    report.stage = Stage::Geometry;
    report.vertex = faces(f, 0);
    report.message = "intrinsic rebuild of step " + std::to_string(steps_ + 1) + ": face " + std::to_string(f) +
                     " (vertices " + std::to_string(faces(f, 0)) + ", " + std::to_string(faces(f, 1)) + ", " +
                     std::to_string(faces(f, 2)) + ") has area " + value +
                     " m^2 at this step's positions, expected > 0 (the surface collapsed there); state restored";
    return report;
  }
  return report;
}

StepReport StainSolver::finishStep() {
  StepReport report;
  inStep_ = false;
  // The vertices this step changed: the others hold values that passed an
  // earlier validation (a write from outside is validated whole before the
  // step runs: validStateWrittenOutside). Restored only if changed.
  const bool everyVertex = backup_.all();  // validateAll_ is false here: refreshGeometry cleared it
  const int bad = everyVertex ? firstBadVertex(state_, kNegativeDensityTolerance)
                              : firstBadVertexAmong(state_, backup_.vertices(), kNegativeDensityTolerance);
  if (bad >= 0) {
    restoreBackup();
    report.status = StepStatus::NonFinite;
    report.stage = Stage::Validate;
    report.vertex = bad;
    report.message = "non-finite or negative value at vertex " + std::to_string(bad) + " after step " +
                     std::to_string(steps_ + 1) + "; state restored";
    return report;
  }
  time_ += ctx_.h;
  ++steps_;
  undoable_ = true;
  return report;
}

MassBudget StainSolver::massBudget() const {
  const Vector& a = geometry_.intrinsic().vertexDualAreas;
  MassBudget b;
  b.freeSolvent = weightedSum(state_.solvent, a);
  b.absorbedSolvent = weightedSum(state_.absorbedSolvent, a);
  b.evaporatedSolvent = state_.evaporatedSolvent;
  b.addedSolvent = state_.addedSolvent;
  b.freeSolute = weightedSum(state_.solute, a);
  b.absorbedSolute = weightedSum(state_.absorbedSolute, a);
  b.adsorbedSolute = weightedSum(state_.adsorbedSolute, a);
  b.addedSolute = state_.addedSolute;
  return b;
}

// Snapshots: the whole dynamic state by value. The backup, wet mask and
// scratch buffers are rewritten at the start of every step, so they are not
// part of it; the systems are reassembled from the restored intrinsic tier
// (same pattern, same values: the same factor as the original's, when a
// direct solve needs it).
StainSolverSnapshot StainSolver::snapshot() const {
  StainSolverSnapshot s;
  s.state = state_;
  s.geometry = geometry_.dynamicState();
  s.heldRegions = heldRegions_;
  s.initialVelocities = initialVelocities_;
  s.factorizedStep = systems_.assembledStep();
  s.time = time_;
  s.steps = steps_;
  s.started = started_;
  s.writtenOutside = writtenOutside_;
  return s;
}

void StainSolver::restore(const StainSolverSnapshot& s) {
  const int n = state_.vertexCount();
  const auto requireRows = [n](Eigen::Index rows, const char* field) {
    if (rows != n)
      throw std::invalid_argument(std::string("StainSolver::restore: ") + field + " has " + std::to_string(rows) +
                                  " rows, the solver has " + std::to_string(n) + " vertices");
  };
  requireRows(s.state.vertexCount(), "state");
  requireRows(s.state.velocities.size(), "state.velocities");
  requireRows(s.geometry.extrinsic.positions.rows(), "geometry.extrinsic.positions");
  requireRows(s.geometry.intrinsic.vertexDualAreas.size(), "geometry.intrinsic.vertexDualAreas");
  requireRows(static_cast<Eigen::Index>(s.geometry.rotations.size()), "geometry.rotations");
  requireRows(s.initialVelocities.rows(), "initialVelocities");
  if (s.geometry.intrinsic.edgeLengths.size() != geometry_.intrinsic().edgeLengths.size())
    throw std::invalid_argument("StainSolver::restore: geometry.intrinsic.edgeLengths has " +
                                std::to_string(s.geometry.intrinsic.edgeLengths.size()) + " entries, the solver has " +
                                std::to_string(geometry_.intrinsic().edgeLengths.size()) + " edges");
  for (const HeldRegion& region : s.heldRegions)
    for (int v : region.vertices)
      if (v < 0 || v >= n)
        throw std::invalid_argument("StainSolver::restore: held region vertex " + std::to_string(v) +
                                    " out of range [0, " + std::to_string(n) + ")");
  const ThreadScope threads(threads_);
  geometry_.restoreDynamicState(s.geometry);
  systemsOfTier_ = false;  // until assembled from the restored tier
  // Tables filled from the replaced intrinsic tier are stamped with its
  // rebuild count, which the restored tier may repeat with other values.
  velocityScratch_.invalidate();
  band_.invalidateIntrinsic();
  if (s.factorizedStep > 0) {  // the factors follow lazily, as after any assembly
    const SolverStatus status = systems_.assemble(geometry_.intrinsic(), s.factorizedStep);
    if (status != SolverStatus::Ok)
      throw std::runtime_error(std::string("StainSolver::restore: diffusion system assembly failed: ") +
                               toString(status));
    systemsOfTier_ = true;
  }
  state_ = s.state;
  stateWrittenOutside();
  // As saved, so that a restored solver tests strain exactly where the one
  // that saved it did (everHeldLiquid), also after a write from outside that
  // was cleared again; and set by any liquid in a state that records none
  // added, which a state put together elsewhere may hold without either
  // flag (a saving solver with liquid always had a drop, a source or a write
  // from outside). Where liquid was added, everHeldLiquid holds already and
  // the flag stays as saved, so a resumed run saves what the uninterrupted
  // one does, to the byte.
  writtenOutside_ = s.writtenOutside;
  if (!(state_.addedSolvent > 0 || state_.addedSolute > 0))
    for (const Vector* f : {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                            &state_.adsorbedSolute})
      writtenOutside_ = writtenOutside_ || (f->array() != 0.0).any();
  backup_.commit(state_);  // the rollback point is the restored state (as a full backup of it was)
  backupAssembledStep_ = systems_.assembledStep();
  heldRegions_ = s.heldRegions;
  initialVelocities_ = s.initialVelocities;
  time_ = s.time;
  steps_ = s.steps;
  started_ = s.started;
  // No step of the restored state to undo: an abandonStep before the next
  // step changes nothing (it would otherwise undo the step before the
  // restore, whose kept tier restoreDynamicState forgot).
  undoable_ = inStep_ = rebuiltInStep_ = false;
}

}  // namespace blot::stain
