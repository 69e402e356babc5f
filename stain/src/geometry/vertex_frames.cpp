// SurfaceGeometry's per-vertex extrinsic values (normals, U_i, frames at t
// and t + h, p̈_i, ω_i): every vertex at each refresh, or on demand.
//
// Design note: docs/design-notes.md, "stain/src/geometry/surface_geometry.cpp".
#include <blot/stain/geometry/surface_geometry.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "geometry/surface_geometry_internal.h"
#include "numerics/threads.h"

namespace blot::stain {

using detail::kMinParallelVertices;
using detail::kPrepareGroup;
using detail::rotationVector;

void SurfaceGeometry::setVertexRefresh(VertexRefresh mode) {
  vertexRefresh_ = mode;
  if (mode == VertexRefresh::AllVertices) prepareAllVertices();
}

void SurfaceGeometry::evaluateSlot(const SlotRule& rule, int i, Eigen::Quaterniond& rotation, Matrix3& frame,
                                   RowVectors3& normals, Matrix3& fit) const {
  const Matrix3& restFrame = dynamic_.extrinsic.restFrames[static_cast<size_t>(i)];
  if (rule.kind == SlotKind::Rest) {
    rotation = Eigen::Quaterniond::Identity();
    frame = restFrame;
    normals.row(i) = restNormals_.row(i);
    fit = Matrix3::Identity();
    return;
  }
  rotation = rule.rotation;
  fit = rule.matrix;
  frame.noalias() = rule.matrix * restFrame;
  normals.row(i) = frame.col(2).transpose();
}

void SurfaceGeometry::sampleSlot(const RowVectors3& positions, int i, RotationFitJob& job) const {
  const SurfaceTopology& topology = *topology_;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const int n = topology.vertexCount();
  const size_t k = static_cast<size_t>(i);
  const double* x = positions.data();
  const double* y = x + n;
  const double* z = y + n;
  // The fit reads the rest frame after every slot of its group is sampled:
  // asked for now, its two lines (cold after a cloth step) arrive meanwhile.
  const char* restFrame = reinterpret_cast<const char*>(&dynamic_.extrinsic.restFrames[k]);
  __builtin_prefetch(restFrame);
  __builtin_prefetch(restFrame + sizeof(Matrix3) - 1);
  const int begin = offsets[k], end = offsets[k + 1];
  const double xi = x[i], yi = y[i], zi = z[i];
  Matrix3 covariance = Matrix3::Zero();
  Vector3 normalSum = Vector3::Zero();
  Vector3 first = Vector3::Zero(), previous = Vector3::Zero();
  for (int m = begin; m < end; ++m) {
    const size_t mk = static_cast<size_t>(m);
    const int j = neighbors[mk];
    const Vector3 e(x[j] - xi, y[j] - yi, z[j] - zi);
    covariance.noalias() += e * restRingEdges_[mk].transpose();
    if (m == begin) {
      first = e;
    } else {
      normalSum += previous.cross(e);
    }
    previous = e;
  }
  if (!topology.vertexIsBoundary()[k]) normalSum += previous.cross(first);  // the ring's closing face
  job.vertex = i;
  job.covariance = covariance;
  job.normal = normalSum;
  job.normalSquared = normalSum.squaredNorm();
  job.edge = first;
}

void SurfaceGeometry::prepareGroup(DynamicState& d, const int* vertices, const bool* currentValid, int count,
                                   RotationFitStats& counts) const {
  ExtrinsicGeometry& ex = d.extrinsic;
  RotationFitJob jobs[2 * kPrepareGroup];
  Matrix3 unused[kPrepareGroup];
  int jobCount = 0;
  // A slot's values: fitted in the lanes below, or from its rule.
  const auto slot = [&](const SlotRule& rule, const RowVectors3& positions, int i, Eigen::Quaterniond& rotation,
                        Matrix3& frame, RowVectors3& normals, Matrix3& fit) {
    if (rule.kind != SlotKind::Fitted) {
      evaluateSlot(rule, i, rotation, frame, normals, fit);
      return;
    }
    RotationFitJob& job = jobs[jobCount++];
    sampleSlot(positions, i, job);
    job.rotation = &rotation;
    job.frame = &frame;
    job.normals = &normals;
    job.fit = &fit;
  };
  for (int g = 0; g < count; ++g) {
    const int i = vertices[g];
    const size_t k = static_cast<size_t>(i);
    __builtin_prefetch(&d.rotations[k]);  // read by finishVertex (ω), cold since the last step
    if (!currentValid[g])
      slot(currentRule_, ex.positions, i, d.rotations[k], ex.frames[k], ex.vertexNormals,
           rates_.still ? ex.kabschRotations[k] : unused[g]);
    if (!rates_.still)
      slot(nextRule_, ex.nextPositions, i, d.nextRotations[k], ex.nextFrames[k], d.nextNormals,
           ex.kabschRotations[k]);
  }
  fitRotations(jobs, jobCount, dynamic_.extrinsic.restFrames, rotationFitMethod_, counts);
  for (int g = 0; g < count; ++g) finishVertex(d, vertices[g]);
}

void SurfaceGeometry::finishVertex(DynamicState& d, int i) const {
  const size_t k = static_cast<size_t>(i);
  ExtrinsicGeometry& ex = d.extrinsic;
  if (rates_.still) {
    d.nextRotations[k] = d.rotations[k];
    ex.nextFrames[k] = ex.frames[k];
    d.nextNormals.row(i) = ex.vertexNormals.row(i);
    ex.vertexAngularVelocities.row(i).setZero();
  } else {
    // ω_i: (F^t)ᵀ F^{t+h} = F̄ᵀ (U^tᵀ U^{t+h}) F̄, whose rotation vector is F̄ᵀ
    // times that of U^tᵀ U^{t+h}.
    const Vector3 restAxis =
        rates_.shared ? rates_.sharedAxis : rotationVector(d.rotations[k].conjugate() * d.nextRotations[k]);
    ex.vertexAngularVelocities.row(i) = (ex.restFrames[k].transpose() * restAxis * (1.0 / rates_.h)).transpose();
  }
  // p̈_i^t by the centred second difference.
  const double h = rates_.h, previousH = rates_.previousH;
  const double invH = 1.0 / h, invHSquared = 1.0 / (h * h), invPreviousH = 1.0 / previousH;
  const double secondDifferenceScale = 2.0 / (h + previousH);
  const RowVectors3& p0 = ex.previousPositions;
  const RowVectors3& p1 = ex.positions;
  const RowVectors3& p2 = ex.nextPositions;
  for (int c = 0; c < 3; ++c) {
    ex.vertexAccelerations(i, c) =
        previousH == h
            ? (p2(i, c) - 2.0 * p1(i, c) + p0(i, c)) * invHSquared
            : secondDifferenceScale * ((p2(i, c) - p1(i, c)) * invH - (p1(i, c) - p0(i, c)) * invPreviousH);
  }
}

void SurfaceGeometry::addCounts(const RotationFitStats& counts) {
  rotationFitStats_.fittedVertices += counts.fittedVertices;
  rotationFitStats_.newtonIterations += counts.newtonIterations;
  rotationFitStats_.svdFallbacks += counts.svdFallbacks;
}

template <typename VertexAt>
int SurfaceGeometry::prepareEach(int count, const VertexAt& vertexAt, RotationFitStats& total) {
  // Groups of kPrepareGroup list positions, the stale vertices of each fitted
  // together (prepareGroup), on the calling thread's OpenMP threads from
  // kMinParallelVertices on (threads::runLoop). A vertex's values depend on
  // its own slots only: the grouping and the threads change no bit. The
  // counts are integers, the same summed in any order.
  int prepared = 0;
  const int groups = (count + kPrepareGroup - 1) / kPrepareGroup;
  threads::runLoop(count >= kMinParallelVertices, [&] {
    RotationFitStats here;
    int preparedHere = 0;
#pragma omp for schedule(static) nowait
    for (int group = 0; group < groups; ++group) {
      int ids[kPrepareGroup];
      bool currentValid[kPrepareGroup];
      int stale = 0;
      for (int k = group * kPrepareGroup; k < std::min(count, (group + 1) * kPrepareGroup); ++k) {
        const int i = vertexAt(k);
        const unsigned stamp = preparedAt_[static_cast<size_t>(i)];
        if (stamp == refreshIndex_) continue;
        ids[stale] = i;
        currentValid[stale] = stamp + 1 == refreshIndex_;
        ++stale;
      }
      if (stale == 0) continue;
      prepareGroup(dynamic_, ids, currentValid, stale, here);
      for (int g = 0; g < stale; ++g) preparedAt_[static_cast<size_t>(ids[g])] = refreshIndex_;
      preparedHere += stale;
    }
#pragma omp critical(blot_threads_combine)
    {
      total.fittedVertices += here.fittedVertices;
      total.svdFallbacks += here.svdFallbacks;
      total.newtonIterations += here.newtonIterations;
      prepared += preparedHere;
    }
  });
  return prepared;
}

void SurfaceGeometry::prepareVertices(const int* vertices, int count) {
  const int n = topology_->vertexCount();
  for (int k = 0; k < count; ++k)
    if (vertices[k] < 0 || vertices[k] >= n)
      throw std::invalid_argument("SurfaceGeometry::prepareVertices: vertex " + std::to_string(vertices[k]) +
                                  " out of range [0, " + std::to_string(n) + ")");
  // In index order, each id once: a vertex's values depend on its own slot
  // only, so the order changes no bit, but neighbouring vertices then read
  // neighbouring memory in turn (the band lists its vertices ring by ring),
  // and the parallel loop never sees a repeat (two threads would write one
  // vertex). A list longer than #V has repeats: it goes in windows of #V ids,
  // one after the other.
  RotationFitStats total;
  for (int start = 0; start < count; start += n) {
    const int window = std::min(n, count - start);
    prepareOrder_.assign(vertices + start, vertices + start + window);  // capacity #V: no allocation
    std::sort(prepareOrder_.begin(), prepareOrder_.end());
    prepareOrder_.erase(std::unique(prepareOrder_.begin(), prepareOrder_.end()), prepareOrder_.end());
    const int* order = prepareOrder_.data();
    preparedCount_ += prepareEach(static_cast<int>(prepareOrder_.size()), [&](int k) { return order[k]; }, total);
  }
  addCounts(total);
}

void SurfaceGeometry::prepareAllVertices() {
  RotationFitStats total;
  preparedCount_ += prepareEach(topology_->vertexCount(), [](int i) { return i; }, total);
  addCounts(total);
}

}  // namespace blot::stain
