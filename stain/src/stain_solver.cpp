// The stain step, written once as the stage list of DESIGN.md.
//
// Design note: every stage is a free function over explicit inputs (context,
// geometry, scratch, state); this file only decides which stages run and in
// what order, times them, and guarantees that a failed step leaves the state
// as it was (the state is copied into a preallocated backup first, which is a
// memcpy of a few vectors, far cheaper than any stage). Terms a scene does not
// need are skipped here, visibly: inertia on a surface that has not moved,
// solute transport when there is no solute, stages on dry vertices.
#include <blot/stain/external_forces.h>
#include <blot/stain/film_pressure.h>
#include <blot/stain/interaction.h>
#include <blot/stain/stain_solver.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace blot::stain {
namespace {

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
  wet_.assign(static_cast<size_t>(n), 0);
  initialVelocities_ = RowVectors3::Zero(n, 3);
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

void StainSolver::addDrop(const DropDef& drop) {
  stain::addDrop(drop, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), state_);
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

void StainSolver::updateWetMask() {
  // Wet: holds any liquid; the halo (one ring around) is wet too, since
  // advection and diffusion move liquid into it this step.
  const SurfaceTopology& topo = geometry_.topology();
  const double threshold = def_.liquid.wetThreshold;
  const int n = state_.vertexCount();
  int wetCount = 0;
  for (int i = 0; i < n; ++i) {
    const bool holds = state_.solvent[i] > threshold || state_.absorbedSolvent[i] > threshold ||
                       state_.solute[i] > threshold;
    wet_[static_cast<size_t>(i)] = holds ? 2 : 0;
  }
  for (int i = 0; i < n; ++i) {
    if (wet_[static_cast<size_t>(i)] != 2) continue;
    ++wetCount;
    for (int m = topo.ringOffsets()[static_cast<size_t>(i)]; m < topo.ringOffsets()[static_cast<size_t>(i) + 1]; ++m) {
      char& w = wet_[static_cast<size_t>(topo.ringNeighbors()[static_cast<size_t>(m)])];
      if (w == 0) w = 1;
    }
  }
  profile_.wetVertices = wetCount;
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
  backup_ = state_;  // same sizes: no allocation
  const StepContext ctx = makeStepContext(h, def_.gravity, def_.switches, def_.liquid);
  ScopedTimer total(profile_.total);

  bool surfaceMoved = false;
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
      // Densities are per area: when the dual areas change, rescale them so
      // each vertex keeps its mass (A_old σ_old = A_new σ_new).
      areaScratch_ = geometry_.intrinsic().vertexDualAreas;
      geometry_.refreshIntrinsic();
      areaScratch_.array() /= geometry_.intrinsic().vertexDualAreas.array();
      for (Vector* f : {&state_.solvent, &state_.solute, &state_.absorbedSolvent, &state_.absorbedSolute,
                        &state_.adsorbedSolute})
        f->array() *= areaScratch_.array();
      profile_.intrinsicRefreshes = 1;
    }
    if (rebuild || systems_.factorizedStep() != h) {
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
  }

  updateWetMask();
  const bool anyLiquid = profile_.wetVertices > 0;
  const PhysicsSwitches& on = ctx.switches;

  // Forces are split around the velocity advection: gravity and linear
  // inertia before it, the Coriolis rotation after it (docs/transport.md).
  // With the paper's order (all forces, then advection) liquid at rest in an
  // inertial frame on a rotating surface speeds up by 2(ωh)² per step, a
  // first-order global error (the blob of Fig. 5 ran 9 % of a radian ahead
  // over half a turn at ωh = 0.01); rotating after advection cancels it to
  // O((ωh)³) per step, at the cost of one more pass over the wet vertices.
  const bool coriolis = anyLiquid && on.coriolis && surfaceMoved;
  if (anyLiquid && (on.gravity || (surfaceMoved && on.linearInertia))) {
    ScopedTimer t(profile_.forces);
    StepContext forceCtx = ctx;
    forceCtx.switches.linearInertia = on.linearInertia && surfaceMoved;
    forceCtx.switches.coriolis = false;
    applyExternalForces(forceCtx, geometry_.extrinsic(), wet_, state_);
  }
  if (anyLiquid && on.filmPressure) {
    ScopedTimer t(profile_.forces);
    applyFilmPressure(ctx, geometry_.topology(), geometry_.extrinsic(), wet_, state_);
  }
  if (anyLiquid && on.velocityAdvection) {
    ScopedTimer t(profile_.advectVelocity);
    advectVelocity(ctx, geometry_.topology(), geometry_.intrinsic(), wet_, velocityScratch_, state_);
  }
  if (coriolis) {
    ScopedTimer t(profile_.forces);
    StepContext coriolisCtx = ctx;
    coriolisCtx.switches.gravity = false;
    coriolisCtx.switches.linearInertia = false;
    applyExternalForces(coriolisCtx, geometry_.extrinsic(), wet_, state_);
  }
  if (anyLiquid && on.densityAdvection) {
    ScopedTimer t(profile_.advectDensity);
    const DensityAdvectionReport r =
        advectDensities(ctx, geometry_.topology(), geometry_.intrinsic(), geometry_.extrinsic(), wet_,
                        densityScratch_, state_, &geometry_.restEdgeFrameNormals());
    profile_.advectionSubsteps = r.substeps;
  }
  if (anyLiquid && (on.densityDiffusion || on.velocityDiffusion)) {
    ScopedTimer t(profile_.diffuse);
    const DiffusionReport r = diffuse(ctx, geometry_.intrinsic(), systems_, diffusionScratch_, state_, &wet_);
    profile_.diffusionIterations = r.densityIterations + r.velocityIterations;
    profile_.limiterCorrectedVertices = r.limiterCorrectedVertices;
    profile_.limiterMovedMass = r.limiterMovedMass;
    if (r.status != SolverStatus::Ok) {
      state_ = backup_;
      report.status = StepStatus::SolverFailure;
      report.stage = "diffuse";
      report.message = toString(r.status);
      return report;
    }
  }
  if (anyLiquid && (on.absorption || on.adsorption || on.evaporation)) {
    ScopedTimer t(profile_.interact);
    interact(ctx, geometry_.topology(), geometry_.intrinsic(), wet_, state_);
  }
  if (on.sources && !heldRegions_.empty()) {
    ScopedTimer t(profile_.sources);
    applySources(ctx, heldRegions_, geometry_.intrinsic(), state_);
  }

  const int bad = firstBadVertex(state_, 1e-12);
  if (bad >= 0) {
    state_ = backup_;
    report.status = StepStatus::NonFinite;
    report.stage = "validate";
    report.vertex = bad;
    report.message = "non-finite or negative value at vertex " + std::to_string(bad) + " after step " +
                     std::to_string(steps_ + 1) + "; state restored";
    return report;
  }
  time_ += h;
  ++steps_;
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
