// SurfaceGeometry's intrinsic tier: the whole, partial and region rebuilds
// from the current lengths, and the journal that undoes the last one.
//
// Design note: docs/design-notes.md, "stain/src/geometry/surface_geometry.cpp".
#include <blot/stain/geometry/surface_geometry.h>

#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/operators.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "geometry/surface_geometry_internal.h"

namespace blot::stain {

using detail::strainFromSquaredRatios;

namespace {

// Everything of the tier that follows from in.edgeLengths before the operators.
void lengthQuantities(const SurfaceTopology& topology, IntrinsicGeometry& in) {
  // Into the tier's arrays: no allocation once they have the mesh's sizes.
  faceAnglesAreasAndCotanWeights(topology, in.edgeLengths, in.faceCornerAngles, in.faceAreas, in.edgeCotanWeights);
  vertexDualAreas(topology, in.faceAreas, in.vertexDualAreas);
  geodesicPolarMap(topology, in.faceCornerAngles, in.polarMap);
  edgeTransportAngles(topology, in.polarMap, in.edgeTransportAngles);
  faceTransportAngles(topology, in.faceCornerAngles, in.polarMap, in.faceTransportAngles);
}

}  // namespace

void intrinsicGeometryFromLengths(const SurfaceTopology& topology, const Vector& lengths,
                                  const Eigen::MatrixX3d& densityTensors, const Eigen::MatrixX3d& velocityTensors,
                                  const Eigen::MatrixX2d& faceWeftCoefficients, IntrinsicGeometry& in) {
  in.edgeLengths = lengths;
  lengthQuantities(topology, in);
  in.densityStiffness = anisotropicStiffnessFromLengths(topology, in.edgeLengths, densityTensors, faceWeftCoefficients);
  in.velocityStiffness = connectionLaplacianFromLengths(topology, in.edgeLengths, in.faceTransportAngles,
                                                        velocityTensors, faceWeftCoefficients);
}

void SurfaceGeometry::setIntrinsicRefresh(IntrinsicRefresh mode) {
  if (mode != IntrinsicRefresh::Full && intrinsicRefresh_ == IntrinsicRefresh::Full && dynamic_.intrinsic.rebuildCount > 0) {
    IntrinsicGeometry& in = dynamic_.intrinsic;
    const Vector built = in.edgeLengths;
    intrinsicGeometryFromLengths(*topology_, built, fabric_.densityTensors, fabric_.velocityTensors,
                                 faceWeftCoefficients_, in);
    kept_.valid = false;
  }
  intrinsicRefresh_ = mode;
  if (mode != IntrinsicRefresh::Full) {
    // The table of the partial re-assemblies' entry positions.
    if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(*topology_);
    // The most a partial refresh can journal: every value forEachRefreshedValue reaches.
    const IntrinsicGeometry& in = dynamic_.intrinsic;
    const size_t edges = static_cast<size_t>(topology_->edgeCount());
    const size_t faces = static_cast<size_t>(topology_->faceCount());
    const size_t vertices = static_cast<size_t>(topology_->vertexCount());
    kept_.journal.reserve(5 * edges + 7 * faces + 2 * vertices + topology_->ringNeighbors().size() +
                          static_cast<size_t>(in.densityStiffness.nonZeros()) +
                          2 * static_cast<size_t>(in.velocityStiffness.nonZeros()));
  }
}

void SurfaceGeometry::setRefreshRegion(const int* vertices, int count) {
  if (count < 0 || count > topology_->vertexCount())
    throw std::invalid_argument("SurfaceGeometry::setRefreshRegion: " + std::to_string(count) +
                                " vertices, expected at most " + std::to_string(topology_->vertexCount()));
  for (int k = 0; k < count; ++k)
    if (vertices[k] < 0 || vertices[k] >= topology_->vertexCount())
      throw std::invalid_argument("SurfaceGeometry::setRefreshRegion: vertex " + std::to_string(vertices[k]) +
                                  " out of range");
  regionVertices_.assign(vertices, vertices + count);
}

void SurfaceGeometry::refreshIntrinsic() {
  const RowVectors3& positions = dynamic_.extrinsic.nextPositions;
  IntrinsicGeometry& in = dynamic_.intrinsic;
  kept_.maxEdgeStrain = dynamic_.maxEdgeStrain;
  kept_.strainMeasured = strainMeasured_;
  // Partial and Region choose their edges first (reading the tier, writing
  // none of it): a refresh that stays partial journals the values it is
  // about to write (refreshChosenEdges) and updates the tier in place. Full,
  // and a choice past kPartialRefreshMaxShare,
  // rebuild the whole tier from the current lengths into the kept tier's
  // arrays (swapped in, the old tier kept by the swap: no copy, no
  // allocation), the same bits as intrinsicGeometryFromLengths.
  const bool partial = intrinsicRefresh_ != IntrinsicRefresh::Full && in.rebuildCount > 0 &&
                       chooseRefreshedEdges(positions);
  const bool whole = !partial && (intrinsicRefresh_ == IntrinsicRefresh::Full || in.rebuildCount > 0);
  kept_.journaled = partial;
  kept_.rebuildCount = in.rebuildCount;
  lastRefreshPartial_ = false;  // until the partial refresh below completes
  if (whole) {
    swap(kept_.intrinsic, in);
    kept_.inverseBuiltSquaredLengths.swap(dynamic_.inverseBuiltSquaredLengths);
    in.rebuildCount = kept_.intrinsic.rebuildCount;
  } else if (!partial) {
    kept_.intrinsic = in;
    kept_.inverseBuiltSquaredLengths = dynamic_.inverseBuiltSquaredLengths;
  }
  // The undo point is set before anything below can throw (a face that
  // cannot be laid out): the caller gives the old tier back with it.
  kept_.valid = true;
  if (partial) {
    refreshChosenEdges(positions);
    lastRefreshPartial_ = true;
  } else if (whole) {
    refreshIntrinsicFromPositions(positions);
  } else {
    // The first build of a Partial geometry: every edge measured, the tier from the lengths.
    intrinsicGeometryFromLengths(*topology_, edgeLengths(*topology_, positions), fabric_.densityTensors,
                                 fabric_.velocityTensors, faceWeftCoefficients_, in);
    dynamic_.inverseBuiltSquaredLengths = in.edgeLengths.array().square().inverse().matrix();
    dynamic_.maxEdgeStrain = 0;
    strainMeasured_ = true;
    refreshedEdges_ = topology_->edgeCount();
    refreshedFaces_ = topology_->faceCount();
  }
  ++in.rebuildCount;
}

void SurfaceGeometry::prepareWholeRebuilds() {
  const SurfaceTopology& topology = *topology_;
  if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(topology);
  if (!kept_.valid && (!faceEntries_.fits(topology, kept_.intrinsic.densityStiffness) ||
                       !faceEntries_.fits(topology, kept_.intrinsic.velocityStiffness))) {
    // Every array of the tier at its size, and operators of the one-ring
    // pattern the refill writes into (the first build's own).
    kept_.intrinsic = dynamic_.intrinsic;
    kept_.inverseBuiltSquaredLengths = dynamic_.inverseBuiltSquaredLengths;
  }
}

void SurfaceGeometry::undoIntrinsicRefresh() {
  if (!kept_.valid) throw std::logic_error("SurfaceGeometry::undoIntrinsicRefresh: no refresh to undo");
  if (kept_.journaled) {
    // The journal holds every value the refresh wrote (all of them saved
    // before the first write, so also after a refresh that threw).
    size_t k = 0;
    const auto restore = [&](double& value) { value = kept_.journal[k++]; };
    forEachRefreshedValue(0, restore);
    forEachRefreshedValue(1, restore);
    dynamic_.intrinsic.rebuildCount = kept_.rebuildCount;
    kept_.journaled = false;
  } else {
    swap(kept_.intrinsic, dynamic_.intrinsic);
    kept_.inverseBuiltSquaredLengths.swap(dynamic_.inverseBuiltSquaredLengths);
  }
  dynamic_.maxEdgeStrain = kept_.maxEdgeStrain;
  strainMeasured_ = kept_.strainMeasured;
  kept_.valid = false;
  lastRefreshPartial_ = false;  // the lists describe a refresh that no longer is
}

void SurfaceGeometry::refreshIntrinsicFromPositions(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  IntrinsicGeometry& in = dynamic_.intrinsic;
  edgeLengths(topology, positions, in.edgeLengths);
  lengthQuantities(topology, in);
  if (in.rebuildCount == 0) {
    // The first build is on the rest shape, where the given wefts apply as they are.
    in.densityStiffness = anisotropicStiffness(topology, positions, fabric_.densityTensors, fabric_.weftDirections);
    in.velocityStiffness = connectionLaplacian(topology, positions, in.faceTransportAngles, fabric_.velocityTensors,
                                               fabric_.weftDirections);
  } else {
    // A rebuild lays each face out from the lengths it has just measured,
    // as every other tier path does (design note): no frames from positions.
    if (faceEntries_.index.empty()) faceEntries_ = oneRingFaceEntries(topology);
    if (!faceEntries_.fits(topology, in.densityStiffness) || !faceEntries_.fits(topology, in.velocityStiffness)) {
      in.densityStiffness =
          anisotropicStiffnessFromLengths(topology, in.edgeLengths, fabric_.densityTensors, faceWeftCoefficients_);
      in.velocityStiffness = connectionLaplacianFromLengths(topology, in.edgeLengths, in.faceTransportAngles,
                                                            fabric_.velocityTensors, faceWeftCoefficients_);
    } else {
      // The same values, into the existing patterns: no pattern build, no
      // search for each entry, no new matrices, each face laid out once.
      refillStiffnessAndConnectionFromLengths(topology, in.edgeLengths, in.faceAreas, fabric_.densityTensors,
                                              in.faceTransportAngles, fabric_.velocityTensors,
                                              faceWeftCoefficients_, faceEntries_, in.densityStiffness,
                                              in.velocityStiffness);
    }
  }
  dynamic_.inverseBuiltSquaredLengths = in.edgeLengths.array().square().inverse().matrix();
  dynamic_.maxEdgeStrain = 0;
  strainMeasured_ = true;
  refreshedEdges_ = topology.edgeCount();
  refreshedFaces_ = topology.faceCount();
}

void SurfaceGeometry::markRegionEdges() {
  const SurfaceTopology& topology = *topology_;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  // The region's vertices, then kRegionRefreshRings rings around them, ring
  // by ring (vertices1_ as the list, vertexMarks_ as its marks).
  vertices1_.clear();
  const auto add = [&](int v) {
    if (vertexMarks_[static_cast<size_t>(v)]) return;
    vertexMarks_[static_cast<size_t>(v)] = 1;
    vertices1_.push_back(v);
  };
  for (const int v : regionVertices_) add(v);
  size_t ringBegin = 0;
  for (int ring = 0; ring < kRegionRefreshRings; ++ring) {
    const size_t ringEnd = vertices1_.size();
    for (size_t k = ringBegin; k < ringEnd; ++k) {
      const size_t v = static_cast<size_t>(vertices1_[k]);
      for (int m = offsets[v]; m < offsets[v + 1]; ++m) add(neighbors[static_cast<size_t>(m)]);
    }
    ringBegin = ringEnd;
  }
  // Their faces' edges; the vertex marks cleared.
  for (const int v : vertices1_) {
    vertexMarks_[static_cast<size_t>(v)] = 0;
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f < 0) continue;
      for (int c = 0; c < 3; ++c) edgeMarks_[static_cast<size_t>(faceEdges(f, c))] = 1;
    }
  }
}

bool SurfaceGeometry::chooseRefreshedEdges(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  const int edgeCount = topology.edgeCount();
  const Eigen::MatrixX2i& edges = topology.edgeVertices();
  const double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();

  // Chosen edges: r_e = ℓ_e² / ℓ̂_e² outside [(1 − t)², (1 + t)²], t the
  // fraction of the tolerance (the strain test's ratio, so no root per edge).
  const double t = kPartialRefreshFraction * strainTolerance_;
  const double high = (1 + t) * (1 + t), low = t < 1 ? (1 - t) * (1 - t) : 0.0;
  chosenEdges_.clear();
  const bool region = intrinsicRefresh_ == IntrinsicRefresh::Region;
  if (region) markRegionEdges();
  double maxRatio = 1.0, minRatio = 1.0;
  for (int e = 0; e < edgeCount; ++e) {
    const Vector3 d = (positions.row(edges(e, 1)) - positions.row(edges(e, 0))).transpose();
    const double ratio = d.squaredNorm() * inverseBuilt[e];
    if (region ? edgeMarks_[static_cast<size_t>(e)] != 0 : (ratio > high || ratio < low)) {
      chosenEdges_.push_back(e);
    } else {
      maxRatio = std::max(maxRatio, ratio);
      minRatio = std::min(minRatio, ratio);
    }
  }
  if (static_cast<double>(chosenEdges_.size()) > kPartialRefreshMaxShare * edgeCount) {
    for (const int e : chosenEdges_) edgeMarks_[static_cast<size_t>(e)] = 0;
    return false;
  }
  unchosenStrain_ = strainFromSquaredRatios(maxRatio, minRatio);
  return true;
}

template <class At>
void SurfaceGeometry::forEachRefreshedValue(int part, const At& at) {
  IntrinsicGeometry& in = dynamic_.intrinsic;
  if (part == 0) {
    for (const int e : chosenEdges_) {
      at(in.edgeLengths(e));
      at(dynamic_.inverseBuiltSquaredLengths(e));
    }
    return;
  }
  const std::vector<int>& offsets = topology_->ringOffsets();
  for (const int f : faces1_) {
    for (int k = 0; k < 3; ++k) at(in.faceCornerAngles(f, k));
    at(in.faceAreas(f));
  }
  for (const int e : edges1_) at(in.edgeCotanWeights(e));
  for (const int v : vertices1_) {
    at(in.vertexDualAreas(v));
    at(in.polarMap.vertexAngleScales(v));
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m)
      at(in.polarMap.ringAngles(m));
  }
  for (const int e : edges2_) at(in.edgeTransportAngles(e));
  for (const int f : faces2_)  // every face updateFaceTransportAngles writes a corner of
    for (int k = 0; k < 3; ++k) at(in.faceTransportAngles(f, k));
  // The re-assemblies write entries in the columns of V1 (L_S) and V2 (connection) only.
  const int* outer = in.densityStiffness.outerIndexPtr();
  double* density = in.densityStiffness.valuePtr();
  for (const int v : vertices1_)
    for (int q = outer[v]; q < outer[v + 1]; ++q) at(density[q]);
  const int* connectionOuter = in.velocityStiffness.outerIndexPtr();
  // std::complex<double> is two doubles (re, im) by the standard's array rule.
  double* connection = reinterpret_cast<double*>(in.velocityStiffness.valuePtr());
  for (const int v : vertices2_)
    for (int q = connectionOuter[v]; q < connectionOuter[v + 1]; ++q) {
      at(connection[2 * q]);
      at(connection[2 * q + 1]);
    }
}

void SurfaceGeometry::refreshChosenEdges(const RowVectors3& positions) {
  const SurfaceTopology& topology = *topology_;
  const int n = topology.vertexCount(), edgeCount = topology.edgeCount(), faceCount = topology.faceCount();
  const Triangles& faces = topology.faces();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  const Eigen::MatrixX2i& edges = topology.edgeVertices();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<int>& ringEdges = topology.ringEdges();
  IntrinsicGeometry& in = dynamic_.intrinsic;
  double* inverseBuilt = dynamic_.inverseBuiltSquaredLengths.data();
  kept_.journal.clear();
  const auto save = [&](double& value) { kept_.journal.push_back(value); };
  forEachRefreshedValue(0, save);
  for (const int e : chosenEdges_) {
    // What edgeLengths() computes for this edge, and 1 / ℓ̂² as the whole path does.
    in.edgeLengths(e) = (positions.row(edges(e, 1)) - positions.row(edges(e, 0))).norm();
    inverseBuilt[e] = 1.0 / (in.edgeLengths(e) * in.edgeLengths(e));
    edgeMarks_[static_cast<size_t>(e)] = 1;
  }
  // F1: faces with a chosen edge; V1 their vertices; their edges (cotan weights).
  faces1_.clear();
  for (int f = 0; f < faceCount; ++f) {
    if (!(edgeMarks_[static_cast<size_t>(faceEdges(f, 0))] | edgeMarks_[static_cast<size_t>(faceEdges(f, 1))] |
          edgeMarks_[static_cast<size_t>(faceEdges(f, 2))]))
      continue;
    faces1_.push_back(f);
    for (int k = 0; k < 3; ++k) vertexMarks_[static_cast<size_t>(faces(f, k))] = 1;
  }
  for (const int e : chosenEdges_) edgeMarks_[static_cast<size_t>(e)] = 0;
  for (const int f : faces1_)
    for (int k = 0; k < 3; ++k) edgeMarks_[static_cast<size_t>(faceEdges(f, k))] = 1;
  // The marked ids of `marks` (size `count`), ascending, into `list`; the
  // marks are cleared unless `keep`.
  const auto collect = [](std::vector<char>& marks, int count, std::vector<int>& list, bool keep) {
    list.clear();
    for (int i = 0; i < count; ++i) {
      if (!marks[static_cast<size_t>(i)]) continue;
      list.push_back(i);
      if (!keep) marks[static_cast<size_t>(i)] = 0;
    }
  };
  collect(edgeMarks_, edgeCount, edges1_, false);
  collect(vertexMarks_, n, vertices1_, true);  // kept: the L_S re-assembly reads them
  // F2: ring faces of V1; edges at V1 (transport angles).
  for (const int v : vertices1_) {
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) faceMarks_[static_cast<size_t>(f)] = 1;
      edgeMarks_[static_cast<size_t>(ringEdges[static_cast<size_t>(m)])] = 1;
    }
  }
  collect(faceMarks_, faceCount, faces2_, false);
  collect(edgeMarks_, edgeCount, edges2_, false);
  // V2: vertices of F2 (kept for the connection re-assembly); F3: their ring faces.
  for (const int f : faces2_)
    for (int k = 0; k < 3; ++k) vertexMarks2_[static_cast<size_t>(faces(f, k))] = 1;
  collect(vertexMarks2_, n, vertices2_, true);
  for (const int v : vertices2_)
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      const int f = ringFaces[static_cast<size_t>(m)];
      if (f >= 0) faceMarks_[static_cast<size_t>(f)] = 1;
    }
  collect(faceMarks_, faceCount, faces3_, false);
  forEachRefreshedValue(1, save);

  // The values, in dependency order (each update writes what the whole
  // function writes for those elements).
  const auto size = [](const std::vector<int>& list) { return static_cast<int>(list.size()); };
  updateFaceAnglesAndAreas(topology, in.edgeLengths, faces1_.data(), size(faces1_), in.faceCornerAngles, in.faceAreas);
  updateEdgeCotanWeights(topology, in.edgeLengths, in.faceAreas, edges1_.data(), size(edges1_), in.edgeCotanWeights);
  updateVertexDualAreas(topology, in.faceAreas, vertices1_.data(), size(vertices1_), in.vertexDualAreas);
  updateGeodesicPolarMap(topology, in.faceCornerAngles, vertices1_.data(), size(vertices1_), in.polarMap);
  updateEdgeTransportAngles(topology, in.polarMap, edges2_.data(), size(edges2_), in.edgeTransportAngles);
  updateFaceTransportAngles(topology, in.faceCornerAngles, in.polarMap, vertices1_.data(), size(vertices1_),
                            in.faceTransportAngles);
  const auto clearVertexMarks = [&] {
    for (const int v : vertices1_) vertexMarks_[static_cast<size_t>(v)] = 0;
    for (const int v : vertices2_) vertexMarks2_[static_cast<size_t>(v)] = 0;
  };
  try {
    // L_S: blocks of F1 changed; entries among V1, re-summed over F2 (every face at V1).
    reassembleStiffnessFromLengths(topology, in.edgeLengths, fabric_.densityTensors, faceWeftCoefficients_,
                                   vertexMarks_.data(), vertices1_.data(), size(vertices1_), faces2_.data(),
                                   size(faces2_), in.densityStiffness, &faceEntries_);
    // Connection: blocks of F2 changed (transport angles); entries among V2, over F3.
    reassembleConnectionFromLengths(topology, in.edgeLengths, in.faceTransportAngles, fabric_.velocityTensors,
                                    faceWeftCoefficients_, vertexMarks2_.data(), vertices2_.data(),
                                    size(vertices2_), faces3_.data(), size(faces3_), in.velocityStiffness,
                                    &faceEntries_);
  } catch (...) {
    // A face whose weft cannot be laid out (a collapsed anisotropic face):
    // the caller undoes the tier; the marks must not outlive this refresh,
    // or the next one would re-assemble around these vertices too.
    clearVertexMarks();
    throw;
  }
  clearVertexMarks();
  dynamic_.maxEdgeStrain = unchosenStrain_;
  strainMeasured_ = true;
  refreshedEdges_ = size(chosenEdges_);
  refreshedFaces_ = size(faces3_);
}

}  // namespace blot::stain
