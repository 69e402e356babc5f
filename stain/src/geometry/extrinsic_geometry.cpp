// Extrinsic geometry: normals and per-vertex tangent frames (paper sec. 3.1).
//
// Design note. Vertex normals are the normalised sum of the unnormalised face
// cross products (area weighting, as the paper's "area-weighted average unit
// normal of the one-ring"). Rejected: angle weighting, which is slightly more
// faithful on irregular meshes but is not what the paper uses and would need
// the corner angles (intrinsic tier) inside the every-step extrinsic refresh.
// Frames follow the paper: z_i the normal, y_i = z_i × e / |z_i × e| with e the
// edge to the first one-ring neighbour, x_i = y_i × z_i, so x_i is that edge
// projected to the tangent plane and the polar-map angle of the reference edge
// is exactly 0 (transport.h relies on it).
#include <blot/stain/geometry/extrinsic_geometry.h>

#include <cmath>

namespace blot::stain {
namespace {

// Below this relative length a cross product is treated as zero (a degenerate
// face, or a reference edge parallel to the normal).
constexpr double kDegenerate = 1e-14;

Vector3 faceCross(const Triangles& faces, const RowVectors3& positions, int f) {
  const Vector3 p0 = positions.row(faces(f, 0)).transpose();
  const Vector3 p1 = positions.row(faces(f, 1)).transpose();
  const Vector3 p2 = positions.row(faces(f, 2)).transpose();
  return (p1 - p0).cross(p2 - p0);
}

// Any unit vector orthogonal to unit n (used only for degenerate input).
Vector3 anyOrthogonal(const Vector3& n) {
  const Vector3 axis = std::abs(n.x()) < 0.9 ? Vector3::UnitX() : Vector3::UnitY();
  return n.cross(axis).normalized();
}

}  // namespace

RowVectors3 faceNormals(const SurfaceTopology& topology, const RowVectors3& vertexPositions) {
  RowVectors3 normals(topology.faceCount(), 3);
  for (int f = 0; f < topology.faceCount(); ++f) {
    normals.row(f) = faceCross(topology.faces(), vertexPositions, f).normalized().transpose();
  }
  return normals;
}

RowVectors3 vertexNormals(const SurfaceTopology& topology, const RowVectors3& vertexPositions) {
  const Triangles& faces = topology.faces();
  RowVectors3 sums = RowVectors3::Zero(topology.vertexCount(), 3);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Eigen::RowVector3d c = faceCross(faces, vertexPositions, f).transpose();
    for (int k = 0; k < 3; ++k) sums.row(faces(f, k)) += c;
  }
  for (int v = 0; v < topology.vertexCount(); ++v) {
    const double length = sums.row(v).norm();
    // A fan whose cross products cancel (a fully folded one-ring) has no
    // meaningful normal; fall back to the first ring face's normal so the
    // frame stays orthonormal instead of becoming NaN.
    if (length > 0.0) {
      sums.row(v) /= length;
    } else {
      const int f = topology.ringFaces()[static_cast<size_t>(topology.ringOffsets()[static_cast<size_t>(v)])];
      sums.row(v) = faceCross(faces, vertexPositions, f).normalized().transpose();
    }
  }
  return sums;
}

Matrix3 VertexFrames::frame(int i) const {
  Matrix3 f;
  f.col(0) = xAxes.row(i).transpose();
  f.col(1) = yAxes.row(i).transpose();
  f.col(2) = zAxes.row(i).transpose();
  return f;
}

VertexFrames vertexTangentFrames(const SurfaceTopology& topology,
                                 const RowVectors3& vertexPositions,
                                 const RowVectors3& vertexNormals) {
  const int n = topology.vertexCount();
  VertexFrames frames;
  frames.xAxes.resize(n, 3);
  frames.yAxes.resize(n, 3);
  frames.zAxes = vertexNormals;
  for (int i = 0; i < n; ++i) {
    const Vector3 z = vertexNormals.row(i).transpose();
    const int ref = topology.ringNeighbors()[static_cast<size_t>(topology.ringOffsets()[static_cast<size_t>(i)])];
    const Vector3 e = (vertexPositions.row(ref) - vertexPositions.row(i)).transpose();
    Vector3 y = z.cross(e);
    const double length = y.norm();
    // The reference edge parallel to the normal can only happen on a folded
    // mesh; any orthonormal completion is then as good as another, and the
    // polar-map convention α_ref = 0 no longer matches the 3D frame there.
    y = length > kDegenerate * e.norm() ? Vector3(y / length) : anyOrthogonal(z);
    frames.yAxes.row(i) = y.transpose();
    frames.xAxes.row(i) = y.cross(z).transpose();
  }
  return frames;
}

}  // namespace blot::stain
