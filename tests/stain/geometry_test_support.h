#pragma once
// Shared by the geometry, transport and operator tests: the whole geometry
// pipeline on one mesh, perturbed test meshes and angle helpers (the spectral
// checks of operators_test are in spectral_checks.h).
#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>

#include "mesh_fixture.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

namespace blot::stain::testing {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;

/// Angle in [−π, π].
inline double wrapAngle(double angle) { return std::remainder(angle, kTwoPi); }

/// Every geometric quantity of one mesh, computed the way the engine will.
struct Geometry {
  TriangleMesh mesh;
  SurfaceTopology topology;
  Vector lengths;
  Eigen::MatrixX3d angles;
  Vector areas;
  Vector cotanWeights;
  Vector dualAreas;
  Vector angleSums;
  PolarMap polarMap;
  Vector edgeAngles;        // θ per edge
  Eigen::MatrixX3d faceAngles;  // φ per face corner
  RowVectors3 normals;
  VertexFrames frames;

  explicit Geometry(TriangleMesh m)
      : mesh(std::move(m)),
        topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "test mesh") {
    lengths = edgeLengths(topology, mesh.vertexPositions);
    angles = faceCornerAngles(topology, lengths);
    areas = faceAreas(topology, lengths);
    cotanWeights = edgeCotanWeights(topology, lengths, areas);
    dualAreas = vertexDualAreas(topology, areas);
    angleSums = vertexAngleSums(topology, angles);
    polarMap = geodesicPolarMap(topology, angles);
    edgeAngles = edgeTransportAngles(topology, polarMap);
    faceAngles = faceTransportAngles(topology, angles, polarMap);
    normals = vertexNormals(topology, mesh.vertexPositions);
    frames = vertexTangentFrames(topology, mesh.vertexPositions, normals);
  }
  int vertexCount() const { return topology.vertexCount(); }
  int faceCount() const { return topology.faceCount(); }

  SparseMatrix mass() const { return lumpedMassMatrix(dualAreas); }
  SparseMatrix cotan() const { return cotanLaplacian(topology, cotanWeights); }
  ComplexSparseMatrix connection() const {
    return connectionLaplacian(topology, mesh.vertexPositions, faceAngles,
                               identityFaceTensors(faceCount()),
                               RowVectors3::Zero(faceCount(), 3));
  }
  /// Angle of the rotation carrying vectors in j's frame into i's (edge ij).
  double transportAngle(int i, int j) const {
    const int begin = topology.ringOffsets()[static_cast<size_t>(i)];
    const int end = topology.ringOffsets()[static_cast<size_t>(i) + 1];
    for (int m = begin; m < end; ++m) {
      if (topology.ringNeighbors()[static_cast<size_t>(m)] == j) {
        const double theta = edgeAngles(topology.ringEdges()[static_cast<size_t>(m)]);
        return i < j ? theta : -theta;
      }
    }
    throw std::logic_error("transportAngle: not an edge");
  }
};

/// Uniform in [lo, hi] from one raw std::mt19937 draw (whose sequence the
/// standard fixes, unlike std::uniform_real_distribution's algorithm), so
/// every platform builds the same test meshes.
inline double uniform(std::mt19937& rng, double lo, double hi) {
  return lo + (hi - lo) * (rng() / 4294967295.0);
}

/// A flat unit-square grid whose interior vertices are moved by up to
/// `jitter` grid spacings (shared fixture, fixed seed): irregular, with obtuse
/// triangles and negative cotan weights; checked to be unfolded.
inline TriangleMesh jitteredGrid(int n, double jitter, unsigned seed) {
  TriangleMesh mesh = blot::test::jitteredGridMesh(n, n, 1.0, 1.0, jitter, seed);
  // Too much jitter folds triangles over; a folded "flat" mesh is no test.
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Vector3 a = mesh.vertexPositions.row(mesh.faces(f, 0)).transpose();
    const Vector3 b = mesh.vertexPositions.row(mesh.faces(f, 1)).transpose();
    const Vector3 c = mesh.vertexPositions.row(mesh.faces(f, 2)).transpose();
    if (!((b - a).cross(c - a).z() > 0.0)) throw std::logic_error("jitteredGrid: jitter folds a triangle");
  }
  return mesh;
}

/// An icosphere with every vertex moved radially and tangentially (fixed
/// seed): a closed, curved, irregular mesh, never folded (throws if it would be).
inline TriangleMesh jitteredIcosphere(int level, double jitter, unsigned seed) {
  TriangleMesh mesh = icosphereMesh(level);
  std::mt19937 rng(seed);
  const double spacing = 1.0 / (1 << level);
  for (Eigen::Index v = 0; v < mesh.vertexPositions.rows(); ++v) {
    for (int c = 0; c < 3; ++c) mesh.vertexPositions(v, c) += spacing * uniform(rng, -jitter, jitter);
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Vector3 a = mesh.vertexPositions.row(mesh.faces(f, 0)).transpose();
    const Vector3 b = mesh.vertexPositions.row(mesh.faces(f, 1)).transpose();
    const Vector3 c = mesh.vertexPositions.row(mesh.faces(f, 2)).transpose();
    if (!((b - a).cross(c - a).dot(a + b + c) > 0.0))
      throw std::logic_error("jitteredIcosphere: jitter folds a triangle");
  }
  return mesh;
}

/// Random symmetric positive definite fabric tensors (s_ww, s_wp, s_pp) with
/// eigenvalue ratios up to `maxRatio`, and random 3D weft directions.
inline std::pair<Eigen::MatrixX3d, RowVectors3> randomFabric(int faceCount, double maxRatio,
                                                            unsigned seed) {
  std::mt19937 rng(seed);
  const auto unit = [&rng]() { return uniform(rng, 0.0, 1.0); };
  Eigen::MatrixX3d tensors(faceCount, 3);
  RowVectors3 wefts(faceCount, 3);
  for (int f = 0; f < faceCount; ++f) {
    const double a = 1.0, b = std::pow(maxRatio, unit()), t = kPi * unit();
    const double c = std::cos(t), s = std::sin(t);
    tensors.row(f) << a * c * c + b * s * s, (a - b) * c * s, a * s * s + b * c * c;
    wefts.row(f) << 2 * unit() - 1, 2 * unit() - 1, 2 * unit() - 1;
  }
  return {tensors, wefts};
}

}  // namespace blot::stain::testing
