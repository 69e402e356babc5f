// One moving surface with its stain: cloth → stain → coupling (docs/coupling.md).
//
// Design note.
//  - Step order (DESIGN.md): the motion advances to t + h (Bullet applies the
//    liquid loads computed by the previous step first), the stain follows on
//    the new positions, then the coupling computes the loads for the next
//    cloth step.
//  - Liquid at vertex i: mᵢ = Aᵢ(σ_f + σ_s + σ_p + σ_s,p + σ_s,a) rides with
//    the node (added to its Bullet mass, so gravity acts on it through Bullet),
//    and its free part mᶠᵢ = Aᵢ(σ_f + σ_s) also moves relative to the cloth
//    with Rᵢ = Fᵢuᵢ (uᵢ tangential, in the vertex frame the state belongs to,
//    extrinsic().nextFrames), without its outward part at mesh-boundary
//    vertices: the stain lets no liquid leave the mesh but keeps u there, and
//    counting that u as momentum made a hanging two-way flag rise 17 mm above
//    the one-way one (the momentum the cloth paid while the liquid ran down
//    was never returned) and a waving flag blow up; the hem is a wall.
//    Momentum of cloth + liquid:
//      P = Σ (Mᵢ + mᵢ) vᵢ + Σ mᶠᵢ Rᵢ + Σ Jᵢ (J: impulses owed to the nodes).
//  - Exchange: the stain step changes m and mᶠR at fixed cloth velocities v;
//    the node impulse Jᵢ = −[(mᵢ' − mᵢ) vᵢ + mᶠᵢ'Rᵢ' − mᶠᵢRᵢ] − eᵢvᵢ returns
//    that change to the node, so P is unchanged by the stain step except for
//    the vapour eᵢvᵢ, which leaves the system with its node's velocity. The
//    Bullet step conserves Σ(M + m)v + ΣJ (links act in pairs), so P is
//    conserved across whole steps up to Bullet's float rounding.
//    Per-vertex evaporation is not reported by the stain (only the total E),
//    so eᵢ = E wᵢ/Σw with wᵢ = Aᵢ a_evap,ᵢ on vertices holding solvent before
//    or after the step — the stain's law E = a K_evap h Aᵢ wherever solvent
//    is, except where a vertex dries out within the step.
//  - Rejected: forces instead of impulses (the exchange happens at the stain
//    step's discrete mass moves, and an impulse is exact for it; a force
//    would be J/h spread over the substeps with no gain), and the liquid's
//    weight as an explicit force (Bullet already weighs the node's total mass;
//    the stain's tangential gravity on u is returned by J, so the weight is
//    counted once).
#include <blot/coupling/coupled_surface.h>

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
  bullet_ = dynamic_cast<cloth::BulletCloth*>(motion_.get());
  rigid_ = dynamic_cast<const cloth::RigidMotion*>(motion_.get());
  if (mode_ == CouplingMode::TwoWay && bullet_ == nullptr)
    throw std::invalid_argument("coupling mode two-way needs a Bullet cloth source");
  topology_ = std::make_unique<stain::SurfaceTopology>(topology);
  stain_ = std::make_unique<stain::StainSolver>(*topology_, motion_->positions(), fabric, stainDef);
  stain_->setInitialMotion(motion_->positions(), motion_->velocities());

  const int n = topology.vertexCount();
  liquidMasses_ = Eigen::VectorXd::Zero(n);
  startMasses_ = Eigen::VectorXd::Zero(n);
  startRelative_ = Eigen::MatrixX3d::Zero(n, 3);
  endRelative_ = Eigen::MatrixX3d::Zero(n, 3);
  evaporationWeights_ = Eigen::VectorXd::Zero(n);
  impulses_ = Eigen::MatrixX3d::Zero(n, 3);
  previousImpulses_ = Eigen::MatrixX3d::Zero(n, 3);
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
    const double free = s.solvent[i] + s.solute[i];
    masses[i] = areas[i] * (free + s.absorbedSolvent[i] + s.absorbedSolute[i] + s.adsorbedSolute[i]);
    if (relativeMomenta == nullptr) continue;
    if (free > 0 && relative_ == RelativeMomentum::Free) {
      relativeMomenta->row(i) = ((areas[i] * free) * relativeVelocity(i)).transpose();
    } else {
      relativeMomenta->row(i).setZero();
    }
  }
}

stain::StepReport CoupledSurface::step(double h) {
  const Clock::time_point start = Clock::now();
  const bool twoWay = mode_ == CouplingMode::TwoWay;
  const int n = motion_->vertexCount();
  const stain::StainState& s = stain_->state();
  const double wet = stain_->definition().liquid.wetThreshold;

  // Before the cloth moves: the liquid as the stain holds it now (a drop added
  // since the last step changes it; the cloth must carry that mass too).
  Clock::time_point mark = Clock::now();
  double exchange = 0;
  if (twoWay) {
    gatherLiquid(startMasses_, &startRelative_);
    for (int i = 0; i < n; ++i)
      evaporationWeights_[i] = s.solvent[i] + s.absorbedSolvent[i] > wet ? 1.0 : 0.0;
    if (startMasses_ != liquidMasses_) {
      liquidMasses_ = startMasses_;
      bullet_->setLiquidLoads(liquidMasses_, impulses_);
    }
    exchange += millisecondsSince(mark);
  }

  // Cloth. Its state now is the last good one: kept, so that a failure in any
  // stage below puts cloth and stain back at t together.
  mark = Clock::now();
  motion_->keepRollbackPoint();
  const int stepNumber = stain_->stepCount() + 1;
  if (fault_.stage == "cloth" && fault_.step == stepNumber) {
    Eigen::MatrixX3d kick = impulses_;
    kick.row(fault_.vertex).setConstant(1e30);
    bullet_->setLiquidLoads(liquidMasses_, kick);
    fault_.stage.clear();  // fires once
  }
  motion_->advance(h);
  times_.cloth = millisecondsSince(mark);
  stain::StepReport report = checkMotion();
  if (report.status != stain::StepStatus::Ok) {
    motion_->rollBack();
    return report;
  }

  mark = Clock::now();
  const double evaporatedBefore = s.evaporatedSolvent;
  report = rigid_ != nullptr ? stain_->stepRigid(h, motion_->positions(), rigid_->rotationAt(rigid_->time()))
                             : stain_->step(h, motion_->positions());
  times_.stain = millisecondsSince(mark);
  if (report.status != stain::StepStatus::Ok) {
    // The stain kept its densities; cloth and stain geometry go back to t.
    motion_->rollBack();
    stain_->restartMotion(motion_->positions(), motion_->velocities());
    return report;
  }

  mark = Clock::now();
  if (!twoWay) {
    gatherLiquid(liquidMasses_, nullptr);
  } else {
    impulses_.swap(previousImpulses_);  // kept until the impulses below are known to be finite
    gatherLiquid(liquidMasses_, &endRelative_);
    const Eigen::MatrixX3d& v = motion_->velocities();
    const double evaporated = s.evaporatedSolvent - evaporatedBefore;
    double weightSum = 0;
    if (evaporated > 0) {
      const stain::LiquidParameters& liquid = stain_->definition().liquid;
      const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
      const std::vector<char>& boundary = topology_->vertexIsBoundary();
      for (int i = 0; i < n; ++i) {
        const bool holds = evaporationWeights_[i] > 0 || s.solvent[i] + s.absorbedSolvent[i] > wet;
        evaporationWeights_[i] =
            holds ? areas[i] * (boundary[static_cast<size_t>(i)] ? liquid.boundaryEvaporationFactor : 1.0) : 0.0;
        weightSum += evaporationWeights_[i];
      }
    }
    const double vapourPerWeight = weightSum > 0 ? evaporated / weightSum : 0.0;
    Eigen::Vector3d vapourMomentum = evaporatedMomentum_;  // summed in the same order as before
    int bad = -1;
    for (int i = 0; i < n; ++i) {
      const double vapour = vapourPerWeight * evaporationWeights_[i];
      const Eigen::Vector3d vi = v.row(i).transpose();
      const Eigen::Vector3d change =
          (liquidMasses_[i] - startMasses_[i]) * vi + (endRelative_.row(i) - startRelative_.row(i)).transpose();
      impulses_.row(i) = (-change - vapour * vi).transpose();
      vapourMomentum += vapour * vi;
      if (bad < 0 && !(impulses_.row(i).allFinite() && std::isfinite(liquidMasses_[i]))) bad = i;
    }
    if (fault_.stage == "coupling" && fault_.step == stepNumber) {
      impulses_(fault_.vertex, 0) = std::numeric_limits<double>::quiet_NaN();
      if (bad < 0 || fault_.vertex < bad) bad = fault_.vertex;
      fault_.stage.clear();  // fires once
    }
    if (bad >= 0) {
      // Stage "coupling" failed: undo the stain step and the cloth step.
      impulses_.swap(previousImpulses_);
      liquidMasses_ = startMasses_;
      stain_->undoLastStep();
      motion_->rollBack();
      stain_->restartMotion(motion_->positions(), motion_->velocities());
      report.status = stain::StepStatus::NonFinite;
      report.stage = "coupling";
      report.vertex = bad;
      report.message = "non-finite liquid mass or momentum exchange at vertex " + std::to_string(bad) +
                       "; cloth and stain restored to the state before the step";
      return report;
    }
    evaporatedMomentum_ = vapourMomentum;
    bullet_->setLiquidLoads(liquidMasses_, impulses_);
  }
  times_.coupling = exchange + millisecondsSince(mark);
  times_.total = millisecondsSince(start);
  return report;
}

stain::StepReport CoupledSurface::checkMotion() const {
  stain::StepReport report;
  const Eigen::MatrixX3d& x = motion_->positions();
  const Eigen::MatrixX3d& v = motion_->velocities();
  // One pass that is finite only if every value is; the search runs on failure.
  double sum = 0;
  for (Eigen::Index k = 0; k < x.size(); ++k) sum += 0 * x.data()[k] + 0 * v.data()[k];
  if (std::isfinite(sum) && (bullet_ == nullptr || bullet_->isHealthy())) return report;
  report.status = stain::StepStatus::NonFinite;
  report.stage = "cloth";
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
  report.message += "; cloth and stain restored to the state before the step";
  return report;
}

void CoupledSurface::injectFaultForTesting(const stain::InjectedFault& fault) {
  if (fault.stage != "cloth" && fault.stage != "coupling") {
    stain_->injectFaultForTesting(fault);
    return;
  }
  if (fault.vertex < 0 || fault.vertex >= motion_->vertexCount())
    throw std::invalid_argument("injected fault: vertex " + std::to_string(fault.vertex) + " out of range [0, " +
                                std::to_string(motion_->vertexCount()) + ")");
  if (fault.stage == "cloth" && bullet_ == nullptr)
    throw std::invalid_argument("injected fault: stage 'cloth' needs a Bullet cloth source");
  if (fault.stage == "coupling" && mode_ != CouplingMode::TwoWay)
    throw std::invalid_argument("injected fault: stage 'coupling' needs two-way coupling");
  fault_ = fault;
}

Eigen::Vector3d CoupledSurface::totalMomentum() const {
  const stain::StainState& s = stain_->state();
  const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
  const Eigen::MatrixX3d& v = motion_->velocities();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int i = 0; i < s.vertexCount(); ++i) {
    const double free = s.solvent[i] + s.solute[i];
    const double liquid = areas[i] * (free + s.absorbedSolvent[i] + s.absorbedSolute[i] + s.adsorbedSolute[i]);
    const double mass = liquid + (bullet_ != nullptr ? bullet_->lumpedMasses()[i] : 0.0);
    p += mass * v.row(i).transpose();
    if (free > 0 && relative_ == RelativeMomentum::Free) p += (areas[i] * free) * relativeVelocity(i);
    if (mode_ == CouplingMode::TwoWay) p += impulses_.row(i).transpose();
  }
  return p;
}

double CoupledSurface::totalMass() const {
  const stain::StainState& s = stain_->state();
  const stain::Vector& areas = stain_->geometry().intrinsic().vertexDualAreas;
  double total = 0;
  for (int i = 0; i < s.vertexCount(); ++i) {
    total += areas[i] * (s.solvent[i] + s.solute[i] + s.absorbedSolvent[i] + s.absorbedSolute[i] + s.adsorbedSolute[i]);
    if (bullet_ != nullptr) total += bullet_->lumpedMasses()[i];
  }
  return total;
}

}  // namespace blot::coupling
