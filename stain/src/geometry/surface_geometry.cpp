// The two-tier geometry cache: intrinsic operators rebuilt on strain, extrinsic
// frames refreshed every step (paper sec. 3.1 and 4; DESIGN.md step 2).
//
// Design note: docs/design-notes.md, "stain/src/geometry/surface_geometry.cpp".
#include <blot/stain/geometry/surface_geometry.h>

#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/operators.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "geometry/surface_geometry_internal.h"
#include "numerics/threads.h"

namespace blot::stain {
namespace {

void checkRows(Eigen::Index rows, Eigen::Index expected, const char* what) {
  if (rows != expected) {
    std::ostringstream s;
    s << "SurfaceGeometry: " << what << " has " << rows << " rows, expected " << expected;
    throw std::invalid_argument(s.str());
  }
}

}  // namespace

using detail::kMinParallelVertices;
using detail::kPrepareGroup;
using detail::rotationVector;
using detail::strainFromSquaredRatios;

SurfaceGeometry::SurfaceGeometry(const SurfaceTopology& topology, const RowVectors3& restPositions,
                                 const FabricField& fabric, double strainTolerance)
    : topology_(&topology), restPositions_(restPositions), fabric_(fabric),
      strainTolerance_(strainTolerance) {
  const int n = topology.vertexCount();
  const int faceCount = topology.faceCount();
  checkRows(restPositions.rows(), n, "restPositions");
  checkRows(fabric.densityTensors.rows(), faceCount, "fabric.densityTensors");
  checkRows(fabric.velocityTensors.rows(), faceCount, "fabric.velocityTensors");
  checkRows(fabric.weftDirections.rows(), faceCount, "fabric.weftDirections");
  if (!restPositions.allFinite()) throw std::invalid_argument("SurfaceGeometry: non-finite rest position");
  if (!(strainTolerance > 0) || !std::isfinite(strainTolerance))
    throw std::invalid_argument("SurfaceGeometry: strainTolerance must be finite and positive");

  ExtrinsicGeometry& ex = dynamic_.extrinsic;
  ex.previousPositions = restPositions;
  ex.positions = restPositions;
  ex.nextPositions = restPositions;
  ex.vertexNormals = vertexNormals(topology, restPositions);
  dynamic_.nextNormals = ex.vertexNormals;
  const VertexFrames restFrames = vertexTangentFrames(topology, restPositions, ex.vertexNormals);
  ex.restFrames.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) ex.restFrames[static_cast<size_t>(i)] = restFrames.frame(i);
  ex.frames = ex.restFrames;
  ex.nextFrames = ex.restFrames;
  ex.kabschRotations.assign(static_cast<size_t>(n), Matrix3::Identity());
  ex.vertexAccelerations = RowVectors3::Zero(n, 3);
  ex.vertexAngularVelocities = RowVectors3::Zero(n, 3);

  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  restRingEdges_.resize(neighbors.size());
  for (int i = 0; i < n; ++i) {
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      restRingEdges_[static_cast<size_t>(m)] = (restPositions.row(j) - restPositions.row(i)).transpose();
    }
  }
  const int edgeCount = topology.edgeCount();
  restEdgeFrameNormals_.resize(edgeCount, 4);
  for (int e = 0; e < edgeCount; ++e) {
    const Vector3 normal = dualEdgeNormal(topology, restPositions, e);
    const Matrix3& a = ex.restFrames[static_cast<size_t>(topology.edgeVertices()(e, 0))];
    const Matrix3& b = ex.restFrames[static_cast<size_t>(topology.edgeVertices()(e, 1))];
    restEdgeFrameNormals_.row(e) << a.col(0).dot(normal), a.col(1).dot(normal), b.col(0).dot(normal),
        b.col(1).dot(normal);
  }
  dynamic_.rotations.assign(static_cast<size_t>(n), Eigen::Quaterniond::Identity());
  dynamic_.nextRotations = dynamic_.rotations;
  restNormals_ = ex.vertexNormals;
  preparedAt_.assign(static_cast<size_t>(n), refreshIndex_);
  preparedCount_ = n;

  faceWeftCoefficients_ = stain::faceWeftCoefficients(topology, restPositions, fabric.weftDirections);
  edgeMarks_.assign(static_cast<size_t>(edgeCount), 0);
  faceMarks_.assign(static_cast<size_t>(faceCount), 0);
  vertexMarks_.assign(static_cast<size_t>(n), 0);
  vertexMarks2_.assign(static_cast<size_t>(n), 0);
  for (std::vector<int>* list : {&chosenEdges_, &edges1_, &edges2_}) list->reserve(static_cast<size_t>(edgeCount));
  for (std::vector<int>* list : {&faces1_, &faces2_, &faces3_}) list->reserve(static_cast<size_t>(faceCount));
  for (std::vector<int>* list : {&vertices1_, &vertices2_, &prepareOrder_, &regionVertices_})
    list->reserve(static_cast<size_t>(n));
  refreshIntrinsic();
  kept_.valid = false;  // the first build replaced no tier: nothing to undo
}

void SurfaceGeometry::setPreviousPositions(const RowVectors3& previous) {
  checkRows(previous.rows(), topology_->vertexCount(), "previous positions");
  // The next refresh shifts `positions` into `previousPositions`.
  dynamic_.extrinsic.previousPositions = previous;
  dynamic_.extrinsic.positions = previous;
  dynamic_.extrinsic.rigid = false;
  dynamic_.unchangedRefreshes = 0;
  dynamic_.lastH = 0;
  currentEqualsPrevious_ = true;
  nextEqualsCurrent_ = previous == dynamic_.extrinsic.nextPositions;
}


bool SurfaceGeometry::refreshExtrinsic(const RowVectors3& nextPositions, double h, bool strainTest) {
  return refreshExtrinsicWith(nextPositions, h, nullptr, strainTest);
}

bool SurfaceGeometry::refreshExtrinsicRigid(const RowVectors3& nextPositions, const Matrix3& rotation,
                                            double h) {
  if (!rotation.allFinite() || (rotation.transpose() * rotation - Matrix3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      !(rotation.determinant() > 0))
    throw std::invalid_argument("SurfaceGeometry::refreshExtrinsicRigid: not a rotation matrix");
#ifdef BLOT_VALIDATE
  // The caller promises p = R x̄ + c: check it against vertex 0.
  checkRows(nextPositions.rows(), topology_->vertexCount(), "nextPositions");
  const Vector3 offset = (nextPositions.row(0) - restPositions_.row(0) * rotation.transpose()).transpose();
  const double scale = 1.0 + restPositions_.cwiseAbs().maxCoeff() + offset.norm();
  for (Eigen::Index i = 0; i < nextPositions.rows(); ++i) {
    const Vector3 expected = rotation * restPositions_.row(i).transpose() + offset;
    if ((nextPositions.row(i).transpose() - expected).norm() > 1e-9 * scale)
      throw std::logic_error("SurfaceGeometry::refreshExtrinsicRigid: vertex " + std::to_string(i) +
                             " does not follow the rigid motion");
  }
#endif
  return refreshExtrinsicWith(nextPositions, h, &rotation, true);
}

bool SurfaceGeometry::refreshExtrinsicWith(const RowVectors3& nextPositions, double h,
                                           const Matrix3* rigidRotation, bool strainTest) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  checkRows(nextPositions.rows(), n, "nextPositions");
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("SurfaceGeometry: h must be finite and positive");
  ExtrinsicGeometry& ex = dynamic_.extrinsic;
  rotationFitStats_ = RotationFitStats();

  const bool unchanged = nextPositions == ex.nextPositions;
  // A still surface whose slots are rigid never measures strain (below), so
  // the shortcut does not wait for a measurement there: after a restore,
  // which clears strainMeasured_, a static surface re-shifted every step.
  if (unchanged && dynamic_.unchangedRefreshes >= 2 && (strainMeasured_ || !strainTest || ex.nextRigid)) {
    // t − h, t and t + h all hold these positions already; ω = p̈ = 0, and
    // every vertex prepared since the last shift keeps its values.
    dynamic_.lastH = h;
    return dynamic_.maxEdgeStrain > strainTolerance_;
  }
  const double previousH = dynamic_.lastH > 0 ? dynamic_.lastH : h;
  dynamic_.lastH = h;

  // Shift t + h -> t -> t − h by swapping buffers (no allocation, no copy).
  ex.previousPositions.swap(ex.positions);
  ex.positions.swap(ex.nextPositions);
  ex.nextPositions = nextPositions;  // same size: copies into the existing buffer
  ex.frames.swap(ex.nextFrames);
  ex.rigid = ex.nextRigid;
  ex.vertexNormals.swap(dynamic_.nextNormals);
  dynamic_.rotations.swap(dynamic_.nextRotations);
  currentRule_ = nextRule_;
  currentEqualsPrevious_ = nextEqualsCurrent_;
  nextEqualsCurrent_ = unchanged;
  ++refreshIndex_;
  preparedCount_ = 0;
  rates_ = RateRule();
  rates_.h = h;
  rates_.previousH = previousH;
  rates_.still = unchanged;

  if (unchanged) {
    // The surface did not move over [t, t + h]: U, frames and normals at t + h
    // are those at t (same rule, same positions); only p̈ may still be
    // non-zero (the surface just stopped).
    ex.nextRigid = ex.rigid;
    ++dynamic_.unchangedRefreshes;
    if (strainTest && !strainMeasured_ && !ex.nextRigid) measureStrain();
  } else {
    dynamic_.unchangedRefreshes = 0;
    if (rigidRotation != nullptr) {
      // Known rigid motion: U_i = R for every vertex (the Kabsch fit of a rigid
      // motion), normals R n̄ (n̄ = F̄ z), no fits, and no strain to measure.
      // When U^t was one rotation for every vertex too, the rotation vector of
      // U^tᵀ U^{t+h} is one vector: computed once.
      ex.nextRigid = true;
      nextRule_.kind = SlotKind::Rigid;
      nextRule_.matrix = *rigidRotation;
      nextRule_.rotation = Eigen::Quaterniond(*rigidRotation);
      if (currentRule_.kind != SlotKind::Fitted) {
        rates_.shared = true;
        rates_.sharedAxis = rotationVector(currentRule_.rotation.conjugate() * nextRule_.rotation);
      }
    } else {
      ex.nextRigid = false;
      nextRule_ = SlotRule();
      nextRule_.kind = SlotKind::Fitted;
      // The strain test, per edge (the fits are per vertex and may not run).
      if (strainTest) {
        measureStrain();
      } else {
        dynamic_.maxEdgeStrain = 0.0;
        strainMeasured_ = false;
      }
    }
  }
  dynamic_.nextSlotKind = static_cast<int>(nextRule_.kind);
  if (vertexRefresh_ == VertexRefresh::AllVertices) prepareAllVertices();
  return dynamic_.maxEdgeStrain > strainTolerance_;
}

bool SurfaceGeometry::strainExceededAround(const int* vertices, int count) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  // Each edge once: marked, listed, then measured and unmarked (the list
  // holds at most #E ids, its reserved capacity).
  chosenEdges_.clear();
  for (int k = 0; k < count; ++k) {
    const int v = vertices[k];
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      for (int c = 0; c < 3; ++c) {
        const int e = faceEdges(f, c);
        if (edgeMarks_[static_cast<size_t>(e)]) continue;
        edgeMarks_[static_cast<size_t>(e)] = 1;
        chosenEdges_.push_back(e);
      }
    }
  }
  const Eigen::Matrix<int, Eigen::Dynamic, 2>& edges = topology.edgeVertices();
  const double* x = dynamic_.extrinsic.nextPositions.data();
  const double* y = x + n;
  const double* z = y + n;
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  double maxRatio = 1.0, minRatio = 1.0;
  for (const int e : chosenEdges_) {
    edgeMarks_[static_cast<size_t>(e)] = 0;
    const int a = edges(e, 0), b = edges(e, 1);
    const double dx = x[b] - x[a], dy = y[b] - y[a], dz = z[b] - z[a];
    const double ratio = (dx * dx + dy * dy + dz * dz) * inverseBuilt[e];
    maxRatio = std::max(maxRatio, ratio);
    minRatio = std::min(minRatio, ratio);
  }
  dynamic_.maxEdgeStrain = strainFromSquaredRatios(maxRatio, minRatio);
  strainMeasured_ = false;  // not the whole surface's
  return dynamic_.maxEdgeStrain > strainTolerance_;
}

void SurfaceGeometry::measureStrain() {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount();
  const Eigen::Matrix<int, Eigen::Dynamic, 2>& edges = topology.edgeVertices();
  const int edgeCount = topology.edgeCount();
  const double* x = dynamic_.extrinsic.nextPositions.data();
  const double* y = x + n;
  const double* z = y + n;
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  double maxRatio = 1.0, minRatio = 1.0;
  threads::runLoop(edgeCount >= 4 * kMinParallelVertices, [&] {
    decltype(maxRatio) maxRatioHere = threads::lowest<decltype(maxRatio)>();
    decltype(minRatio) minRatioHere = threads::highest<decltype(minRatio)>();
#pragma omp for schedule(static) nowait
    for (int e = 0; e < edgeCount; ++e) {
      const int a = edges(e, 0), b = edges(e, 1);
      const double dx = x[b] - x[a], dy = y[b] - y[a], dz = z[b] - z[a];
      const double ratio = (dx * dx + dy * dy + dz * dz) * inverseBuilt[e];
      maxRatioHere = std::max(maxRatioHere, ratio);
      minRatioHere = std::min(minRatioHere, ratio);
    }
#pragma omp critical(blot_threads_combine)
    {
      maxRatio = std::max(maxRatio, maxRatioHere);
      minRatio = std::min(minRatio, minRatioHere);
    }
  });
  dynamic_.maxEdgeStrain = strainFromSquaredRatios(maxRatio, minRatio);
  strainMeasured_ = true;
}

SurfaceGeometry::DynamicState SurfaceGeometry::dynamicState() const {
  DynamicState d = dynamic_;
  const int n = topology_->vertexCount();
  RotationFitStats counts;
  int ids[kPrepareGroup];
  bool currentValid[kPrepareGroup];
  int stale = 0;
  for (int i = 0; i < n; ++i) {
    const unsigned stamp = preparedAt_[static_cast<size_t>(i)];
    if (stamp == refreshIndex_) continue;
    ids[stale] = i;
    currentValid[stale] = stamp + 1 == refreshIndex_;
    if (++stale == kPrepareGroup) {
      prepareGroup(d, ids, currentValid, stale, counts);
      stale = 0;
    }
  }
  if (stale > 0) prepareGroup(d, ids, currentValid, stale, counts);
  return d;
}

void SurfaceGeometry::restoreDynamicState(const DynamicState& s) {
  dynamic_ = s;
  kept_.valid = false;
  lastRefreshPartial_ = false;
  strainMeasured_ = false;  // measured again by the next test
  const ExtrinsicGeometry& ex = dynamic_.extrinsic;
  // A saved state has every vertex's values (dynamicState): only the t + h
  // slot's rule is needed for later refreshes.
  std::fill(preparedAt_.begin(), preparedAt_.end(), refreshIndex_);
  preparedCount_ = topology_->vertexCount();
  nextRule_ = SlotRule();
  if (s.nextSlotKind == static_cast<int>(SlotKind::Rigid) && !ex.kabschRotations.empty()) {
    nextRule_.kind = SlotKind::Rigid;
    nextRule_.rotation = dynamic_.nextRotations[0];
    nextRule_.matrix = ex.kabschRotations[0];
  } else if (s.nextSlotKind == static_cast<int>(SlotKind::Fitted)) {
    nextRule_.kind = SlotKind::Fitted;
  } else if (s.nextSlotKind != static_cast<int>(SlotKind::Rest)) {
    throw std::invalid_argument("SurfaceGeometry: nextSlotKind " + std::to_string(s.nextSlotKind) +
                                ", expected 0 (rest), 1 (rigid) or 2 (fitted)");
  }
  currentRule_ = nextRule_;  // every t slot is valid: never evaluated
  rates_ = RateRule();
  currentEqualsPrevious_ = ex.previousPositions == ex.positions;
  nextEqualsCurrent_ = ex.positions == ex.nextPositions;
}

}  // namespace blot::stain
