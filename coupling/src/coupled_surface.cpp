// One moving surface with its stain: cloth → stain → coupling. The momentum
// bookkeeping, the exchange impulses and the rejected alternatives are in
// docs/coupling.md; the exchange itself is coupling::exchangeMomentum.
#include <blot/coupling/coupled_surface.h>
#include <blot/coupling/liquid_exchange.h>

#include <blot/stain/geometry/intrinsic_geometry.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace blot::coupling {
namespace {

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Bending pairs: for each interior edge the two vertices opposite it, sorted
// (a < b), without duplicates and without pairs that are already mesh edges.
Eigen::MatrixX2i bendingPairs(const stain::SurfaceTopology& topology) {
  const auto& faces = topology.faces();
  const auto& twins = topology.halfedgeTwins();
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(static_cast<size_t>(topology.edgeCount()));
  for (int h = 0; h < topology.halfedgeCount(); ++h) {
    const int t = twins[static_cast<size_t>(h)];
    if (t < h) continue;  // boundary (−1) or seen from the twin
    const int a = faces(h / 3, (h % 3 + 2) % 3), b = faces(t / 3, (t % 3 + 2) % 3);
    if (a != b) pairs.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<std::pair<int, int>> edges;
  edges.reserve(static_cast<size_t>(topology.edgeCount()));
  const auto& ev = topology.edgeVertices();
  for (int e = 0; e < topology.edgeCount(); ++e) edges.emplace_back(ev(e, 0), ev(e, 1));
  std::sort(edges.begin(), edges.end());
  pairs.erase(std::remove_if(pairs.begin(), pairs.end(),
                             [&](const std::pair<int, int>& p) { return std::binary_search(edges.begin(), edges.end(), p); }),
              pairs.end());
  Eigen::MatrixX2i out(static_cast<Eigen::Index>(pairs.size()), 2);
  for (size_t k = 0; k < pairs.size(); ++k) out.row(static_cast<Eigen::Index>(k)) << pairs[k].first, pairs[k].second;
  return out;
}

}  // namespace

void describeClothMesh(const stain::TriangleMesh& mesh, const stain::SurfaceTopology& topology, cloth::ClothDef& def) {
  if (topology.vertexCount() != mesh.vertexPositions.rows() || topology.faceCount() != mesh.faces.rows())
    throw std::invalid_argument("describeClothMesh: topology has " + std::to_string(topology.vertexCount()) +
                                " vertices and " + std::to_string(topology.faceCount()) + " faces, mesh " +
                                std::to_string(mesh.vertexPositions.rows()) + " and " +
                                std::to_string(mesh.faces.rows()));
  def.restPositions = mesh.vertexPositions;
  def.faces = mesh.faces;
  def.uvs = mesh.vertexUVs;
  def.edges = topology.edgeVertices();
  def.bendingPairs = bendingPairs(topology);
  def.nodeAreas =
      stain::vertexDualAreas(topology, stain::faceAreas(topology, stain::edgeLengths(topology, mesh.vertexPositions)));
}

CoupledSurface::CoupledSurface(std::unique_ptr<cloth::SurfaceMotion> motion, const stain::SurfaceTopology& topology,
                               const stain::FabricField& fabric, const stain::StainSolverDef& stainDef,
                               CouplingMode mode, RelativeMomentum relative)
    : motion_(std::move(motion)), mode_(mode), relative_(relative) {
  if (!motion_) throw std::invalid_argument("CoupledSurface: no motion given");
  if (motion_->vertexCount() != topology.vertexCount())
    throw std::invalid_argument("CoupledSurface: motion has " + std::to_string(motion_->vertexCount()) +
                                " vertices, topology " + std::to_string(topology.vertexCount()));
  if (mode_ == CouplingMode::TwoWay && !motion_->acceptsLiquidLoads())
    throw std::invalid_argument("coupling mode two-way needs a Bullet cloth source");
  topology_ = std::make_unique<stain::SurfaceTopology>(topology);
  // A free film's momentum reads the frame of every vertex holding free
  // liquid, traces too, between steps: the steps prepare them.
  stain::StainSolverDef def = stainDef;
  def.framesOnDampVertices = def.framesOnDampVertices || relative_ == RelativeMomentum::Free;
  stain_ = std::make_unique<stain::StainSolver>(*topology_, motion_->positions(), fabric, def);
  stain_->setInitialMotion(motion_->positions(), motion_->velocities());
  // A surface that deforms rebuilds its metric: what the first rebuild
  // would allocate is sized now, at load, rather than in a step.
  if (motion_->deforms()) stain_->prepareForDeformation();

  const int n = topology.vertexCount();
  liquidMasses_ = Eigen::VectorXd::Zero(n);
  startMasses_ = Eigen::VectorXd::Zero(n);
  startRelative_ = Eigen::MatrixX3d::Zero(n, 3);
  endRelative_ = Eigen::MatrixX3d::Zero(n, 3);
  impulses_ = Eigen::MatrixX3d::Zero(n, 3);
  previousImpulses_ = Eigen::MatrixX3d::Zero(n, 3);
  positionsBefore_ = Eigen::MatrixX3d::Zero(n, 3);
  wallPrevious_.assign(static_cast<size_t>(n), -1);
  wallNext_.assign(static_cast<size_t>(n), -1);
  for (const std::vector<int>& loop : topology_->boundaryLoops()) {
    const size_t k = loop.size();
    for (size_t j = 0; j < k; ++j) {
      wallPrevious_[static_cast<size_t>(loop[j])] = loop[(j + k - 1) % k];
      wallNext_[static_cast<size_t>(loop[j])] = loop[(j + 1) % k];
    }
  }
  gatherLiquid(liquidMasses_, nullptr);
}

CoupledSurface::~CoupledSurface() = default;

Eigen::Vector3d CoupledSurface::relativeVelocity(int i) const {
  const stain::ExtrinsicGeometry& e = stain_->geometry().extrinsic();
  const stain::Matrix3& f = e.nextFrames[static_cast<size_t>(i)];
  const stain::Complex u = stain_->velocityInCurrentFrame(i);
  Eigen::Vector3d r = f.col(0) * u.real() + f.col(1) * u.imag();
  const int previous = wallPrevious_[static_cast<size_t>(i)];
  if (previous < 0) return r;
  // Boundary vertex: the loop runs with the surface on its left, so the
  // outward in-plane direction is (along the loop) × normal.
  const Eigen::Vector3d along = e.nextPositions.row(wallNext_[static_cast<size_t>(i)]) - e.nextPositions.row(previous);
  const Eigen::Vector3d outward = along.cross(f.col(2));
  const double norm = outward.norm();
  if (!(norm > 0)) return r;
  const double out = r.dot(outward) / norm;
  if (out > 0) r -= (out / norm) * outward;
  return r;
}

// masses (#V, kg) = Aᵢ Σ_c σ_c; relativeMomenta (#V by 3, kg m/s) = mᶠᵢ Rᵢ
// (relativeVelocity) in the frame the state belongs to (nextFrames: the
// newest positions).
void CoupledSurface::gatherLiquid(Eigen::VectorXd& masses, Eigen::MatrixX3d* relativeMomenta) const {
  const stain::StainState& s = stain_->state();
  const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
  const int n = s.vertexCount();
  for (int i = 0; i < n; ++i) {
    const double free = s.freeDensity(i);
    // The stages leave rounding-sized negative densities (down to −1e-12 of
    // the largest, StainSolver's check): the cloth carries no negative mass.
    masses[i] = std::max(0.0, areas[i] * s.liquidDensity(i));
    if (relativeMomenta == nullptr) continue;
    if (free > 0 && relative_ == RelativeMomentum::Free) {
      relativeMomenta->row(i) = ((areas[i] * free) * relativeVelocity(i)).transpose();
    } else {
      relativeMomenta->row(i).setZero();
    }
  }
}

stain::StepReport CoupledSurface::step(double h) {
  // h before anything moves: the cloth would otherwise step with it first.
  if (const stain::StepReport guard = stain::checkTimeStep(h); !guard.ok()) return guard;
  const Clock::time_point start = Clock::now();
  Clock::time_point mark = start;
  if (mode_ == CouplingMode::TwoWay) {
    const stain::StepReport taken = takeLiquidAtStart();
    if (!taken.ok()) return taken;  // nothing has changed yet
  }
  const double exchange = millisecondsSince(mark);

  // The first step's p(t − h) from the motion, where it knows it exactly (a
  // rotating or accelerating rigid motion): p − h v would halve its
  // acceleration on that step.
  if (!stain_->started() && motion_->positionsBefore(h, positionsBefore_))
    stain_->setPositionsBeforeFirstStep(positionsBefore_);
  mark = Clock::now();
  stain::StepReport report = advanceCloth(h);  // Stage::Cloth
  times_.cloth = millisecondsSince(mark);
  if (!report.ok()) return abandonStep(report);

  mark = Clock::now();
  Eigen::Matrix3d rotation;
  const bool rigid = motion_->knownRotation(rotation);
  report = stain_->refreshGeometry(h, motion_->positions(), rigid ? &rotation : nullptr);  // Stage::Geometry
  if (report.ok()) report = stain_->advanceStages();  // Stage::BodyForces … Stage::Sources, Stage::Validate
  times_.stain = millisecondsSince(mark);
  if (!report.ok()) return abandonStep(report);

  mark = Clock::now();
  report = exchangeWithCloth();  // Stage::Coupling
  times_.coupling = exchange + millisecondsSince(mark);
  if (!report.ok()) return abandonStep(report);
  times_.total = millisecondsSince(start);
  return report;
}

stain::StepReport CoupledSurface::takeLiquidAtStart() {
  stain::StepReport report;
  report.stage = stain::Stage::Coupling;
  // Free: the momentum reads each wet vertex's frame, which a write from
  // outside may have put where no step prepared it.
  if (relative_ == RelativeMomentum::Free) stain_->completeGeometryAfterOutsideWrite();
  gatherLiquid(startMasses_, &startRelative_);
  if (startMasses_ == liquidMasses_) return report;
  // Only a state given from outside (a drop, a write to the stain's state, a
  // load) can put more on a vertex than its node takes; the stages cannot.
  for (Eigen::Index i = 0; i < startMasses_.size(); ++i)
    if (!(startMasses_[i] <= cloth::kMaxLiquidLoad)) {
      report.status = stain::StepStatus::NonFinite;
      report.vertex = static_cast<int>(i);
      report.message = "the liquid at vertex " + std::to_string(i) + " (" + std::to_string(startMasses_[i]) +
                       " kg) is more than a cloth node takes (1e30 kg); nothing changed";
      return report;
    }
  liquidMasses_ = startMasses_;
  motion_->setLiquidLoads(liquidMasses_, impulses_);
  return report;
}

stain::StepReport CoupledSurface::advanceCloth(double h) {
  // The cloth's state now is the last good one: kept, so that a failure in
  // any later stage puts cloth and stain back at t together.
  motion_->keepRollbackPoint();
  if (fault_.armed && fault_.stage == stain::Stage::Cloth && fault_.step == stain_->stepCount() + 1) {
    Eigen::MatrixX3d kick = impulses_;
    kick.row(fault_.vertex).setConstant(1e30);
    motion_->setLiquidLoads(liquidMasses_, kick);
    fault_.armed = false;  // fires once
  }
  motion_->advance(h);
  return checkMotion();
}

stain::StepReport CoupledSurface::exchangeWithCloth() {
  stain::StepReport report;
  report.stage = stain::Stage::Coupling;
  if (mode_ != CouplingMode::TwoWay) {
    gatherLiquid(liquidMasses_, nullptr);
    return report;
  }
  impulses_.swap(previousImpulses_);  // kept until the impulses below are known to be finite
  gatherLiquid(liquidMasses_, &endRelative_);
  // Vapour leaves each vertex as the interaction stage evaporated it there.
  Eigen::Vector3d vapourMomentum = evaporatedMomentum_;
  int bad = exchangeMomentum(startMasses_, liquidMasses_, startRelative_, endRelative_, motion_->velocities(),
                             stain_->evaporatedMass(), impulses_, vapourMomentum);
  if (fault_.armed && fault_.stage == stain::Stage::Coupling && fault_.step == stain_->stepCount()) {
    impulses_(fault_.vertex, 0) = std::numeric_limits<double>::quiet_NaN();
    if (bad < 0 || fault_.vertex < bad) bad = fault_.vertex;
    fault_.armed = false;  // fires once
  }
  if (bad >= 0) {
    impulses_.swap(previousImpulses_);
    liquidMasses_ = startMasses_;
    report.status = stain::StepStatus::NonFinite;
    report.vertex = bad;
    report.message = "non-finite liquid mass or momentum exchange at vertex " + std::to_string(bad);
    return report;
  }
  evaporatedMomentum_ = vapourMomentum;
  motion_->setLiquidLoads(liquidMasses_, impulses_);
  return report;
}

stain::StepReport CoupledSurface::abandonStep(stain::StepReport report) {
  motion_->rollBack();
  // The stain has not begun this step when the cloth failed: its state is t's.
  if (report.stage != stain::Stage::Cloth) stain_->abandonStep(motion_->positions(), motion_->velocities());
  if (report.stage == stain::Stage::Cloth || report.stage == stain::Stage::Coupling)
    report.message += "; cloth and stain restored to the state before the step";
  return report;
}

stain::StepReport CoupledSurface::checkMotion() const {
  stain::StepReport report;
  const Eigen::MatrixX3d& x = motion_->positions();
  const Eigen::MatrixX3d& v = motion_->velocities();
  // One pass that is finite only if every value is; the search runs on failure.
  double sum = 0;
  for (Eigen::Index k = 0; k < x.size(); ++k) sum += 0 * x.data()[k] + 0 * v.data()[k];
  report.stage = stain::Stage::Cloth;
  if (std::isfinite(sum) && motion_->isHealthy()) return report;
  report.status = stain::StepStatus::NonFinite;
  for (Eigen::Index i = 0; i < x.rows() && report.vertex < 0; ++i)
    if (!x.row(i).allFinite() || !v.row(i).allFinite()) report.vertex = static_cast<int>(i);
  if (report.vertex >= 0) {
    report.message = "non-finite position or velocity at vertex " + std::to_string(report.vertex);
  } else {
    // Finite but exploded: name the fastest node, where it started.
    Eigen::Index fastest = 0;
    v.rowwise().squaredNorm().maxCoeff(&fastest);
    report.vertex = static_cast<int>(fastest);
    report.message = "the Bullet cloth exploded (bounding box past 10x its rest diagonal, an edge stretched past "
                     "10x, or Bullet disabled the body); fastest node " + std::to_string(report.vertex) + " at " +
                     std::to_string(v.row(fastest).norm()) + " m/s";
  }
  return report;
}

void CoupledSurface::injectFaultForTesting(const stain::InjectedFault& fault) {
  if (fault.stage != stain::Stage::Cloth && fault.stage != stain::Stage::Coupling) {
    stain_->injectFaultForTesting(fault);
    return;
  }
  if (fault.vertex < 0 || fault.vertex >= motion_->vertexCount())
    throw std::invalid_argument("injected fault: vertex " + std::to_string(fault.vertex) + " out of range [0, " +
                                std::to_string(motion_->vertexCount()) + ")");
  if (fault.stage == stain::Stage::Cloth && !motion_->acceptsLiquidLoads())
    throw std::invalid_argument("injected fault: stage 'cloth' needs a Bullet cloth source");
  if (fault.stage == stain::Stage::Coupling && mode_ != CouplingMode::TwoWay)
    throw std::invalid_argument("injected fault: stage 'coupling' needs two-way coupling");
  fault_ = fault;
  fault_.armed = true;
}

Eigen::Vector3d CoupledSurface::totalMomentum() const {
  const stain::StainState& s = stain_->state();
  const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
  const Eigen::MatrixX3d& v = motion_->velocities();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  const Eigen::VectorXd* cloth = motion_->clothNodeMasses();
  for (int i = 0; i < s.vertexCount(); ++i) {
    const double free = s.freeDensity(i);
    const double liquid = areas[i] * s.liquidDensity(i);
    const double mass = liquid + (cloth != nullptr ? (*cloth)[i] : 0.0);
    p += mass * v.row(i).transpose();
    if (free > 0 && relative_ == RelativeMomentum::Free) p += (areas[i] * free) * relativeVelocity(i);
    if (mode_ == CouplingMode::TwoWay) p += impulses_.row(i).transpose();
  }
  return p;
}

double CoupledSurface::totalMass() const {
  const stain::StainState& s = stain_->state();
  const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
  const Eigen::VectorXd* cloth = motion_->clothNodeMasses();
  double total = 0;
  for (int i = 0; i < s.vertexCount(); ++i) {
    total += areas[i] * s.liquidDensity(i);
    if (cloth != nullptr) total += (*cloth)[i];
  }
  return total;
}

}  // namespace blot::coupling
