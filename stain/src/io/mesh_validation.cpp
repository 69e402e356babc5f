// The checks every mesh goes through, loaded or built in code: counts, finite
// values, index ranges, degenerate faces, manifoldness (validateWithOrigins).
#include "mesh_text.h"

#include <blot/stain/geometry/surface_topology.h>

#include <climits>
#include <cmath>
#include <sstream>

namespace blot::stain::detail {

// ---------------------------------------------------------------------------
// Validation

void validateWithOrigins(const TriangleMesh& mesh, const std::string& source,
                         const ElementOrigins* origins) {
  const Eigen::Index vertexCount = mesh.vertexPositions.rows();
  const Eigen::Index faceCount = mesh.faces.rows();
  if (vertexCount == 0 || faceCount == 0) {
    fail(source, "mesh is empty (" + std::to_string(vertexCount) + " vertices, " +
                     std::to_string(faceCount) + " faces)");
  }
  if (vertexCount > INT_MAX) fail(source, "too many vertices for 32-bit indices");
  if (!mesh.faceLabels.empty() && static_cast<Eigen::Index>(mesh.faceLabels.size()) != faceCount) {
    fail(source, std::to_string(mesh.faceLabels.size()) + " face labels for " +
                     std::to_string(faceCount) + " faces");
  }
  if (mesh.vertexUVs.rows() != 0 && mesh.vertexUVs.rows() != vertexCount) {
    fail(source, std::to_string(mesh.vertexUVs.rows()) + " texture coordinates for " +
                     std::to_string(vertexCount) + " vertices");
  }

  for (Eigen::Index v = 0; v < vertexCount; ++v) {
    if (!mesh.vertexPositions.row(v).allFinite()) {
      std::ostringstream s;
      s << vertexName(v, origins) << " has a non-finite coordinate (" << mesh.vertexPositions(v, 0)
        << ", " << mesh.vertexPositions(v, 1) << ", " << mesh.vertexPositions(v, 2) << ")";
      fail(source, s.str());
    }
    if (mesh.vertexUVs.rows() != 0 && !mesh.vertexUVs.row(v).allFinite())
      fail(source, vertexName(v, origins) + " has a non-finite texture coordinate");
  }

  for (Eigen::Index f = 0; f < faceCount; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int index = mesh.faces(f, k);
      if (index < 0 || index >= vertexCount) {
        fail(source, faceName(f, origins) + ": vertex index " + std::to_string(index) +
                         " out of range [0, " + std::to_string(vertexCount - 1) + "]");
      }
    }
  }

  for (Eigen::Index f = 0; f < faceCount; ++f) {
    const int a = mesh.faces(f, 0), b = mesh.faces(f, 1), c = mesh.faces(f, 2);
    if (a == b || b == c || a == c) {
      fail(source, faceName(f, origins) + " repeats a vertex (" + std::to_string(a) + ", " +
                       std::to_string(b) + ", " + std::to_string(c) + ")");
    }
  }

  const Vector3 extent =
      mesh.vertexPositions.colwise().maxCoeff() - mesh.vertexPositions.colwise().minCoeff();
  // Finite coordinates can still overflow every derived quantity (lengths
  // squared, areas, cotangents): near 1e308 an area is inf or NaN, and NaN
  // passes any "<=" test.
  if (!std::isfinite(extent.squaredNorm())) {
    std::ostringstream s;
    s << "the bounding box (" << extent.transpose() << ") is too large: squared lengths overflow a double; "
      << "expected coordinates below about 1e150";
    fail(source, s.str());
  }
  const double minArea = 1e-14 * extent.squaredNorm();
  for (Eigen::Index f = 0; f < faceCount; ++f) {
    const Vector3 p0 = mesh.vertexPositions.row(mesh.faces(f, 0));
    const Vector3 p1 = mesh.vertexPositions.row(mesh.faces(f, 1));
    const Vector3 p2 = mesh.vertexPositions.row(mesh.faces(f, 2));
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    if (!(area > minArea)) {
      std::ostringstream s;
      s << faceName(f, origins) << " has zero area (" << area
        << " <= 1e-14 * bounding-box diagonal^2 = " << minArea << ")";
      fail(source, s.str());
    }
  }

  // Manifoldness, orientation, unreferenced vertices.
  const SurfaceTopology topology(mesh.faces, static_cast<int>(vertexCount), source);
  (void)topology;
}

}  // namespace blot::stain::detail
