#pragma once
// Shared by the stage tests (forces, advection): the intrinsic and extrinsic
// tiers of a static mesh filled by hand from the geometry free functions (what
// SurfaceGeometry builds), a zero state, and frame <-> world conversions.
#include <blot/stain/stain_state.h>
#include <blot/stain/surface_geometry.h>

#include <utility>

#include "geometry_test_support.h"

namespace blot::stain::testing {

struct StageGeometry {
  Geometry geometry;
  IntrinsicGeometry intrinsic;
  ExtrinsicGeometry extrinsic;

  explicit StageGeometry(TriangleMesh mesh) : geometry(std::move(mesh)) {
    intrinsic.edgeLengths = geometry.lengths;
    intrinsic.faceCornerAngles = geometry.angles;
    intrinsic.faceAreas = geometry.areas;
    intrinsic.edgeCotanWeights = geometry.cotanWeights;
    intrinsic.vertexDualAreas = geometry.dualAreas;
    intrinsic.polarMap = geometry.polarMap;
    intrinsic.edgeTransportAngles = geometry.edgeAngles;
    intrinsic.faceTransportAngles = geometry.faceAngles;
    intrinsic.rebuildCount = 1;
    const int n = geometry.vertexCount();
    const RowVectors3& p = geometry.mesh.vertexPositions;
    extrinsic.previousPositions = p;
    extrinsic.positions = p;
    extrinsic.nextPositions = p;
    extrinsic.vertexNormals = geometry.normals;
    extrinsic.frames.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) extrinsic.frames[static_cast<size_t>(i)] = geometry.frames.frame(i);
    extrinsic.restFrames = extrinsic.frames;
    extrinsic.nextFrames = extrinsic.frames;
    extrinsic.kabschRotations.assign(static_cast<size_t>(n), Matrix3::Identity());
    extrinsic.vertexAccelerations = RowVectors3::Zero(n, 3);
    extrinsic.vertexAngularVelocities = RowVectors3::Zero(n, 3);
  }
  const SurfaceTopology& topology() const { return geometry.topology; }
  int vertexCount() const { return geometry.vertexCount(); }
  Vector3 position(int i) const { return geometry.mesh.vertexPositions.row(i).transpose(); }

  /// World vector v expressed in vertex i's frame (its tangential part).
  Complex toFrame(int i, const Vector3& v) const {
    const Matrix3& f = extrinsic.frames[static_cast<size_t>(i)];
    return {f.col(0).dot(v), f.col(1).dot(v)};
  }
  /// Frame-i tangent vector u as a world vector.
  Vector3 toWorld(int i, const Complex& u) const {
    const Matrix3& f = extrinsic.frames[static_cast<size_t>(i)];
    return f.col(0) * u.real() + f.col(1) * u.imag();
  }
};

/// Every field zero, for `n` vertices.
inline StainState zeroState(int n) {
  StainState state;
  state.velocities = ComplexVector::Zero(n);
  state.solvent = Vector::Zero(n);
  state.solute = Vector::Zero(n);
  state.absorbedSolvent = Vector::Zero(n);
  state.absorbedSolute = Vector::Zero(n);
  state.adsorbedSolute = Vector::Zero(n);
  return state;
}

/// Smallest edge length of a mesh (m).
inline double shortestEdge(const StageGeometry& g) { return g.intrinsic.edgeLengths.minCoeff(); }

}  // namespace blot::stain::testing
