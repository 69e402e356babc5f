#pragma once
// Shared by the stage tests (forces, advection): the stain fixture's tiers
// (tests/support/stain_fixture.h) of a static mesh with the whole geometry
// pipeline beside them, and frame <-> world conversions.
#include <blot/stain/stain_state.h>
#include <blot/stain/geometry/surface_geometry.h>

#include <utility>

#include "geometry_test_support.h"
#include "stain_fixture.h"

namespace blot::stain::testing {

struct StageGeometry {
  Geometry geometry;
  IntrinsicGeometry intrinsic;
  ExtrinsicGeometry extrinsic;

  explicit StageGeometry(TriangleMesh mesh) : geometry(std::move(mesh)) {
    // The stage tests use no stiffness, so any fabric will do.
    StaticTiers tiers = staticTiers(geometry.topology, geometry.mesh.vertexPositions,
                                    isotropicFabricField(geometry.topology.faceCount(), 1.0, 1.0));
    intrinsic = std::move(tiers.intrinsic);
    extrinsic = std::move(tiers.extrinsic);
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

/// Smallest edge length of a mesh (m).
inline double shortestEdge(const StageGeometry& g) { return g.intrinsic.edgeLengths.minCoeff(); }

}  // namespace blot::stain::testing
