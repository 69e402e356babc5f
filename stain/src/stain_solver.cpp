// The stain step, written once as the stage list of DESIGN.md.
//
// Design note: every stage is a free function over explicit inputs (context,
// geometry, scratch, state); this file only decides which stages run and in
// what order, times them, and guarantees that a failed step leaves the state
// as it was (the state is copied into a preallocated backup before its first
// change, which is a memcpy of a few vectors, far cheaper than any stage; a
// dry step changes nothing and skips it). Terms a scene does not need are
// skipped here, visibly: inertia on a surface that has not moved, solute
// transport when there is no solute, terms with a zero coefficient, stages on
// dry vertices; StepProfile::terms records which ran (describeTerms).
#include <blot/stain/external_forces.h>
#include <blot/stain/film_pressure.h>
#include <blot/stain/interaction.h>
#include <blot/stain/stain_solver.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace blot::stain {
namespace {

// A density below −1e-12 of the largest magnitude is negative mass, not
// rounding (the limiter and the solves keep densities ≥ 0 to rounding).
constexpr double kNegativeDensityTolerance = 1e-12;

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

/// First vertex with a non-finite or negative (below −tol·max) density, or -1.
int firstBadVertex(const StainState& s, double relativeTolerance) {
  const Vector* fields[] = {&s.solvent, &s.solute, &s.absorbedSolvent, &s.absorbedSolute, &s.adsorbedSolute};
  // One pass for the common case (all finite, none below the floor): the
  // largest and smallest value of every field and a sum that is finite only
  // if every term is; the per-vertex search below runs only when it fails.
  constexpr double kLargest = std::numeric_limits<double>::max();
  double largest = 0, smallest = 0;
  bool finite = true;
  for (const Vector* f : fields) {
    const double* v = f->data();
    for (Eigen::Index i = 0; i < f->size(); ++i) {
      largest = std::max(largest, v[i]);
      smallest = std::min(smallest, v[i]);
      finite &= std::abs(v[i]) <= kLargest;  // false for NaN and ±inf
    }
  }
  const double* u = reinterpret_cast<const double*>(s.velocities.data());
  for (Eigen::Index i = 0; i < 2 * s.velocities.size(); ++i) finite &= std::abs(u[i]) <= kLargest;
  const double scale = std::max(largest, -smallest);
  if (finite && smallest >= -relativeTolerance * scale) return -1;
  const double floor = -relativeTolerance * scale;
  for (int i = 0; i < s.vertexCount(); ++i) {
    for (const Vector* f : fields)
      if (!std::isfinite((*f)[i]) || (*f)[i] < floor) return i;
    if (!std::isfinite(s.velocities[i].real()) || !std::isfinite(s.velocities[i].imag())) return i;
  }
  return -1;
}

double weightedSum(const Vector& density, const Vector& areas) { return density.dot(areas); }

/// `def` when every parameter is usable, checked before anything is built from
/// it: a negative rate would create mass and a NaN would only surface steps
/// later as a non-finite density far from its cause. Rates, capacities and
/// a_evap finite and >= 0; σ_sat and ρ finite and > 0 (they divide); gravity
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
  for (int k = 0; k < 3; ++k)
    require(std::isfinite(def.gravity[k]), "gravity", def.gravity[k], "finite in every component");
  positive("strainTolerance", def.strainTolerance);
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
  const int n = topology.vertexCount();
  state_.resize(n);
  backup_.resize(n);
  diffusionScratch_.resize(n);
  velocityScratch_.resize(n);
  densityScratch_.resize(n, topology.edgeCount());
  band_.resize(n);
  initialVelocities_ = RowVectors3::Zero(n, 3);
  surfaceVelocityScratch_ = RowVectors3::Zero(n, 3);
}

StainSolver::~StainSolver() = default;

void StainSolver::setInitialMotion(const RowVectors3& positions, const RowVectors3& velocities) {
  if (positions.rows() != state_.vertexCount() || velocities.rows() != state_.vertexCount())
    throw std::invalid_argument("StainSolver::setInitialMotion: expected " +
                                std::to_string(state_.vertexCount()) + " rows");
  // Twice: the first refresh puts p(0) in the t + h slot, the second shifts it
  // to t with frames fitted to it. The first step then sets t − h from v(0).
  geometry_.refreshExtrinsic(positions, 1.0);
  geometry_.refreshExtrinsic(positions, 1.0);
  initialVelocities_ = velocities;
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
  return u * std::polar(1.0, -0.5 * omega(i, 2) * systems_.factorizedStep());
}

Vector3 StainSolver::surfaceVelocity(int i) const {
  const ExtrinsicGeometry& e = geometry_.extrinsic();
  const double h = systems_.factorizedStep();
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
  const double h = systems_.factorizedStep();
  if (h > 0) {
    geometry_.setPreviousPositions(geometry_.extrinsic().nextPositions - h * initialVelocities_);
  } else {
    started_ = false;  // no step yet: the first step does it
  }
  undoable_ = false;
}

void StainSolver::undoLastStep() {
  if (!undoable_) throw std::logic_error("StainSolver::undoLastStep: no successful step to undo");
  restoreBackup();
  time_ = backupTime_;
  --steps_;
  undoable_ = false;
}

void StainSolver::restoreBackup() {
  if (!backedUp_) return;  // the step changed nothing yet
  state_ = backup_;
  if (profile_.intrinsicRefreshes > 0)
    for (Vector* f : {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                      &state_.adsorbedSolute})
      f->array() *= areaScratch_.array();
}

void StainSolver::injectFaultForTesting(const InjectedFault& fault) {
  static const char* const kStages[] = {"forces",         "film-pressure", "advect-velocity", "coriolis",
                                        "advect-density", "diffuse",       "interact",        "sources"};
  if (std::find(std::begin(kStages), std::end(kStages), fault.stage) == std::end(kStages))
    throw std::invalid_argument("injected fault: unknown stain stage '" + fault.stage + "'");
  if (fault.vertex < 0 || fault.vertex >= state_.vertexCount())
    throw std::invalid_argument("injected fault: vertex " + std::to_string(fault.vertex) + " out of range [0, " +
                                std::to_string(state_.vertexCount()) + ")");
  fault_ = fault;
}

bool StainSolver::checkStage(const char* stage, StepReport& report) {
  if (!fault_.stage.empty() && fault_.step == steps_ + 1 && fault_.stage == stage) {
    state_.solvent[fault_.vertex] = std::numeric_limits<double>::quiet_NaN();
    fault_.stage.clear();  // fires once
  }
  // One pass over the vertices the stages touched (the band, held ones
  // after "sources"): the extremes of every field and a flag that is false
  // for NaN or ±inf. The search for the vertex runs only on a failure.
  const Vector* fields[] = {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                            &state_.adsorbedSolute};
  constexpr double kLargest = std::numeric_limits<double>::max();
  double largest = 0, smallest = 0;
  bool finite = true;
  const auto scan = [&](int i) {
    for (const Vector* f : fields) {
      const double v = (*f)[i];
      largest = std::max(largest, v);
      smallest = std::min(smallest, v);
      finite &= std::abs(v) <= kLargest;
    }
    finite &= std::abs(state_.velocities[i].real()) <= kLargest && std::abs(state_.velocities[i].imag()) <= kLargest;
  };
  const bool held = std::strcmp(stage, "sources") == 0;
  for (int i : band_.vertices) scan(i);
  if (held)
    for (const HeldRegion& region : heldRegions_)
      for (int v : region.vertices) scan(v);
  const double floor = -kNegativeDensityTolerance * std::max(largest, -smallest);
  if (finite && smallest >= floor) return true;

  const auto bad = [&](int i) {
    for (const Vector* f : fields)
      if (!std::isfinite((*f)[i]) || (*f)[i] < floor) return true;
    return !std::isfinite(state_.velocities[i].real()) || !std::isfinite(state_.velocities[i].imag());
  };
  int vertex = -1;
  for (int i : band_.vertices)
    if (bad(i)) {
      vertex = i;
      break;
    }
  if (vertex < 0 && held)
    for (const HeldRegion& region : heldRegions_)
      for (int v : region.vertices)
        if (vertex < 0 && bad(v)) vertex = v;
  report.status = finite ? StepStatus::NegativeMass : StepStatus::NonFinite;
  report.stage = stage;
  report.vertex = vertex;
  report.message = std::string(finite ? "negative density" : "non-finite value") + " at vertex " +
                   std::to_string(vertex) + " after stage '" + stage + "' of step " + std::to_string(steps_ + 1) +
                   "; state restored";
  restoreBackup();
  return false;
}

void StainSolver::addDrop(const DropDef& drop) {
  undoable_ = false;
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
      if (omega(i, 2) != 0.0) u[i] *= std::polar(1.0, 0.5 * omega(i, 2) * systems_.factorizedStep());
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

void StainSolver::updateWetMask(const StepContext& ctx, bool surfaceMoved, bool gravity, bool inertia,
                                bool halfFrameRotation) {
  // The wet set, then the band around it with u extended onto it
  // (liquid_band.h). A whole-mesh direct velocity solve reads u everywhere,
  // so then the band (and the extension) covers the mesh.
  markWetVertices(def_.liquid.wetThreshold, state_, band_);
  if (band_.wetCount() == 0) {
    profile_.wetVertices = profile_.haloVertices = profile_.bandVertices = 0;
    return;
  }
  if (!backedUp_) {
    backup_ = state_;  // the state as the step found it
    backedUp_ = true;
  }
  // u of the wet vertices into F^t first (the discrete frame change), so the
  // extension reads and writes one frame convention.
  if (halfFrameRotation) applyHalfFrameRotation(ctx, geometry_.extrinsic(), band_.wetMask, state_);
  LiquidBandInputs inputs;
  inputs.h = ctx.h;
  inputs.gravity = gravity ? ctx.gravity : Vector3::Zero();
  inputs.useAccelerations = inertia;
  inputs.surfaceMoved = surfaceMoved;
  const bool directVelocitySolve = ctx.switches.velocityDiffusion && !systems_.vectorIterative();
  inputs.extraRings = directVelocitySolve ? state_.vertexCount() : 0;
  growLiquidBand(inputs, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), band_, state_);
  profile_.wetVertices = band_.wetCount();
  profile_.haloVertices = band_.haloCount;
  profile_.bandVertices = band_.size();
  profile_.bandRings = band_.rings;
  profile_.reachRings = band_.reachRings;
}

StepReport StainSolver::step(double h, const RowVectors3& nextPositions) {
  return advance(h, nextPositions, nullptr);
}

StepReport StainSolver::stepRigid(double h, const RowVectors3& nextPositions, const Matrix3& rotation) {
  return advance(h, nextPositions, &rotation);
}

StepReport StainSolver::advance(double h, const RowVectors3& nextPositions, const Matrix3* rigidRotation) {
  StepReport report;
  if (!(h > 0) || !std::isfinite(h)) {
    report.status = StepStatus::InvalidArgument;
    report.stage = "guard";
    report.message = "time step must be finite and positive, got " + std::to_string(h);
    return report;
  }
  if (nextPositions.rows() != state_.vertexCount() || !nextPositions.allFinite()) {
    report.status = StepStatus::InvalidArgument;
    report.stage = "guard";
    report.message = "next positions must be " + std::to_string(state_.vertexCount()) + " finite rows";
    return report;
  }
  if (rigidRotation != nullptr &&
      (!rigidRotation->allFinite() ||
       (rigidRotation->transpose() * *rigidRotation - Matrix3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
       !(rigidRotation->determinant() > 0))) {
    report.status = StepStatus::InvalidArgument;
    report.stage = "guard";
    report.message = "stepRigid: rotation must be a rotation matrix";
    return report;
  }
  profile_ = StepProfile{};
  profile_.vertexCount = state_.vertexCount();
  // The backup (a copy of every field, O(#V)) is taken only before the first
  // change to the state: the area rescale of a rebuild, or the first stage.
  // A dry step without sources changes nothing and copies nothing.
  backedUp_ = false;  // backup_ is taken lazily, once the step changes the state
  undoable_ = false;
  backupTime_ = time_;
  const StepContext ctx = makeStepContext(h, def_.gravity, def_.switches, def_.liquid);
  ScopedTimer total(profile_.total);

  bool surfaceMoved = false;
  // On the first step u is in the frames at t, not in a last step's midpoint frame.
  const bool firstStep = !started_;
  {
    ScopedTimer t(profile_.geometry);
    if (!started_) {
      // p(−h) ≈ p(0) − h v(0): the first centred acceleration sees the motion's
      // initial velocity instead of a jump from rest.
      geometry_.setPreviousPositions(geometry_.extrinsic().nextPositions - h * initialVelocities_);
      started_ = true;
    }
    const bool rebuild = rigidRotation != nullptr ? geometry_.refreshExtrinsicRigid(nextPositions, *rigidRotation, h)
                                                  : geometry_.refreshExtrinsic(nextPositions, h);
    profile_.maxEdgeStrain = geometry_.maxEdgeStrain();
    if (rebuild) {
      backup_ = state_;  // same sizes: no allocation
      backedUp_ = true;
      // Densities are per area: when the dual areas change, rescale them so
      // each vertex keeps its mass (A_old σ_old = A_new σ_new).
      areaScratch_ = geometry_.intrinsic().vertexDualAreas;
      systems_.releaseFactors();  // the stale factors are not kept while new operators are assembled
      geometry_.refreshIntrinsic();
      areaScratch_.array() /= geometry_.intrinsic().vertexDualAreas.array();
      for (Vector* f : {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                        &state_.adsorbedSolute})
        f->array() *= areaScratch_.array();
      profile_.intrinsicRefreshes = 1;
      profile_.markRan(StepTerm::IntrinsicRebuild);
    }
    if (rebuild || systems_.factorizedStep() != h) {
      profile_.markRan(StepTerm::Factorization);
      const SolverStatus status = systems_.factorize(geometry_.intrinsic(), h);
      if (status != SolverStatus::Ok) {
        report.status = StepStatus::SolverFailure;
        report.stage = "geometry";
        report.message = std::string("factorization failed: ") + toString(status);
        return report;
      }
    }
    const ExtrinsicGeometry& e = geometry_.extrinsic();
    surfaceMoved = !(e.previousPositions == e.positions && e.positions == e.nextPositions);
    if (geometry_.rotationFitStats().fittedVertices > 0) {
      profile_.markRan(StepTerm::RotationFits);
    } else if (rigidRotation != nullptr && surfaceMoved) {
      profile_.markRan(StepTerm::RigidFrames);
    }
    profile_.geometryVertices = surfaceMoved ? state_.vertexCount() : 0;
  }

  const PhysicsSwitches& on = ctx.switches;
  // Held regions are topped up first, so liquid they add this step is in the
  // band and gets this step's forces (issue 14).
  if (on.sources && !heldRegions_.empty()) {
    if (!backedUp_) {
      backup_ = state_;  // the state as the step found it (no rebuild above)
      backedUp_ = true;
    }
    ScopedTimer t(profile_.sources);
    applySources(ctx, heldRegions_, geometry_.intrinsic(), state_);
    profile_.markRan(StepTerm::Sources);
    if (!checkStage("sources", report)) return report;
  }
  const bool gravity = on.gravity && !ctx.gravity.isZero(0.0);
  const bool inertia = on.linearInertia && surfaceMoved;
  {
    ScopedTimer t(profile_.forces);
    const bool halfFrameRotation = on.coriolis && surfaceMoved && on.velocityAdvection &&
                                   on.coriolisScheme == CoriolisScheme::ExactRotation && !firstStep;
    updateWetMask(ctx, surfaceMoved, gravity, inertia, halfFrameRotation);
  }
  const bool anyLiquid = profile_.wetVertices > 0;

  // Forces are split around the velocity advection: gravity and linear
  // inertia before it, the Coriolis rotation after it (docs/transport.md).
  // With the paper's order (all forces, then advection) liquid at rest in an
  // inertial frame on a rotating surface speeds up by 2(ωh)² per step, a
  // first-order global error (the blob of Fig. 5 ran 9 % of a radian ahead
  // over half a turn at ωh = 0.01); rotating after advection cancels it to
  // O((ωh)³) per step, at the cost of one more pass over the wet vertices.
  // The default Coriolis is the discrete frame change instead (docs/transport.md):
  // half the frame increment here (u kept in the last step's midpoint frame
  // goes into F^t), the frame velocity along the backtrack and the other half
  // after the advection; no energy is created at any ωh.
  // A zero coefficient is a term switched off: zero gravity adds nothing
  // (and drives no film pressure), a zero rate transfers nothing.
  const bool coriolis = anyLiquid && on.coriolis && surfaceMoved;
  const bool frameChange = coriolis && on.velocityAdvection && on.coriolisScheme == CoriolisScheme::ExactRotation;
  if (anyLiquid && (gravity || inertia)) {
    ScopedTimer t(profile_.forces);
    StepContext forceCtx = ctx;
    forceCtx.switches.gravity = gravity;
    forceCtx.switches.linearInertia = inertia;
    forceCtx.switches.coriolis = false;
    applyExternalForces(forceCtx, geometry_.extrinsic(), band_.bandMask, state_);
    if (gravity) profile_.markRan(StepTerm::Gravity);
    if (inertia) profile_.markRan(StepTerm::LinearInertia);
    if (!checkStage("forces", report)) return report;
  }
  if (anyLiquid && on.filmPressure && gravity) {
    ScopedTimer t(profile_.forces);
    applyFilmPressure(ctx, geometry_.topology(), geometry_.extrinsic(), band_.bandMask, state_);
    profile_.markRan(StepTerm::FilmPressure);
    if (!checkStage("film-pressure", report)) return report;
  }
  if (anyLiquid && on.velocityAdvection) {
    ScopedTimer t(profile_.advectVelocity);
    advectVelocity(ctx, geometry_.topology(), geometry_.intrinsic(), band_.reachMask, velocityScratch_, state_);
    profile_.markRan(StepTerm::VelocityAdvection);
    if (!checkStage("advect-velocity", report)) return report;
  }
  if (coriolis) {
    ScopedTimer t(profile_.forces);
    profile_.markRan(StepTerm::Coriolis);
    if (frameChange) {
      applyFrameVelocityChange(ctx, geometry_.extrinsic(), velocityScratch_.footVertices,
                               velocityScratch_.footWeights, band_.reachMask, state_);
    } else {
      StepContext coriolisCtx = ctx;
      coriolisCtx.switches.gravity = false;
      coriolisCtx.switches.linearInertia = false;
      applyExternalForces(coriolisCtx, geometry_.extrinsic(), band_.bandMask, state_);
    }
    if (!checkStage("coriolis", report)) return report;
  }
  if (anyLiquid && on.densityAdvection) {
    ScopedTimer t(profile_.advectDensity);
    const DensityAdvectionReport r =
        advectDensities(ctx, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), band_.wetMask,
                        densityScratch_, state_, &geometry_.restEdgeFrameNormals(), &band_.reachMask);
    profile_.advectionSubsteps = r.substeps;
    profile_.advectionVertices = r.activeVertices;
    profile_.markRan(StepTerm::DensityAdvection);
    if (!checkStage("advect-density", report)) return report;
  }
  if (anyLiquid && (on.densityDiffusion || on.velocityDiffusion)) {
    ScopedTimer t(profile_.diffuse);
    const DiffusionReport r = diffuse(ctx, geometry_.intrinsic(), systems_, diffusionScratch_, state_, &band_.diffusionMask);
    profile_.diffusionIterations = r.densityIterations + r.velocityIterations;
    profile_.limiterCorrectedVertices = r.limiterCorrectedVertices;
    profile_.limiterMovedMass = r.limiterMovedMass;
    const int n = state_.vertexCount();
    if (r.densityMethod != DiffusionMethod::None) {
      const bool krylov = r.densityMethod == DiffusionMethod::ConjugateGradient;
      profile_.markRan(krylov ? StepTerm::DensityDiffusionKrylov : StepTerm::DensityDiffusionDirect);
      profile_.densityDiffusionVertices = krylov ? r.densityActiveVertices : n;
    }
    if (r.velocityMethod != DiffusionMethod::None) {
      const bool krylov = r.velocityMethod == DiffusionMethod::ConjugateGradient;
      profile_.markRan(krylov ? StepTerm::VelocityDiffusionKrylov : StepTerm::VelocityDiffusionDirect);
      profile_.velocityDiffusionVertices = krylov ? r.velocityActiveVertices : n;
    }
    if (r.status != SolverStatus::Ok) {
      restoreBackup();
      report.status = StepStatus::SolverFailure;
      report.stage = "diffuse";
      report.message = toString(r.status);
      return report;
    }
    if (!checkStage("diffuse", report)) return report;
  }
  // With every rate zero the stage (and its drying deposit, which follows
  // solvent that absorption or evaporation removed) is skipped.
  StepContext interactCtx = ctx;
  interactCtx.switches.absorption = on.absorption && ctx.liquid.absorptionRate > 0;
  interactCtx.switches.adsorption = on.adsorption && ctx.liquid.desorptionRate > 0;
  interactCtx.switches.evaporation = on.evaporation && ctx.liquid.evaporationRate > 0;
  const PhysicsSwitches& transfers = interactCtx.switches;
  if (anyLiquid && (transfers.absorption || transfers.adsorption || transfers.evaporation)) {
    ScopedTimer t(profile_.interact);
    interact(interactCtx, geometry_.topology(), geometry_.intrinsic(), band_.reachMask, state_);
    if (transfers.absorption) profile_.markRan(StepTerm::Absorption);
    if (transfers.adsorption) profile_.markRan(StepTerm::Adsorption);
    if (transfers.evaporation) profile_.markRan(StepTerm::Evaporation);
    if (!checkStage("interact", report)) return report;
  }

  // Validated even when nothing ran (a bad value put in through
  // mutableState is reported the same way); restored only if changed.
  const int bad = firstBadVertex(state_, kNegativeDensityTolerance);
  if (bad >= 0) {
    if (backedUp_) restoreBackup();
    report.status = StepStatus::NonFinite;
    report.stage = "validate";
    report.vertex = bad;
    report.message = "non-finite or negative value at vertex " + std::to_string(bad) + " after step " +
                     std::to_string(steps_ + 1) + "; state restored";
    return report;
  }
  time_ += h;
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
// part of it; the factorization is redone from the restored intrinsic tier
// (same pattern, same values: the same factor as the original's).
StainSolverSnapshot StainSolver::snapshot() const {
  StainSolverSnapshot s;
  s.state = state_;
  s.geometry = geometry_.dynamicState();
  s.heldRegions = heldRegions_;
  s.initialVelocities = initialVelocities_;
  s.factorizedStep = systems_.factorizedStep();
  s.time = time_;
  s.steps = steps_;
  s.started = started_;
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
  geometry_.restoreDynamicState(s.geometry);
  if (s.factorizedStep > 0) {
    const SolverStatus status = systems_.factorize(geometry_.intrinsic(), s.factorizedStep);
    if (status != SolverStatus::Ok)
      throw std::runtime_error(std::string("StainSolver::restore: factorization failed: ") + toString(status));
  }
  state_ = s.state;
  backup_ = s.state;
  heldRegions_ = s.heldRegions;
  initialVelocities_ = s.initialVelocities;
  time_ = s.time;
  steps_ = s.steps;
  started_ = s.started;
}

}  // namespace blot::stain
