#pragma once
// Shared by the geometry, transport and operator tests: the whole geometry
// pipeline on one mesh, perturbed test meshes, angle helpers and the smallest
// eigenvalues of a generalized problem L x = λ M x (M diagonal).
#include <blot/stain/geometry/extrinsic_geometry.h>
#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/transport.h>

#include "mesh_fixture.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

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
    cotanWeights = edgeCotanWeights(topology, angles);
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

/// The `count` smallest eigenvalues of L x = λ M x (L Hermitian PSD, M
/// diagonal positive), ascending. Dense (M^{-1/2} L M^{-1/2}) for small
/// problems, shift-invert subspace iteration with Rayleigh–Ritz otherwise
/// (converged to 1e-13; throws if it does not converge).
template <typename Scalar>
Vector smallestEigenvalues(const Eigen::SparseMatrix<Scalar>& L, const SparseMatrix& M, int count) {
  using Dense = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::Index n = L.rows();
  using ScalarVector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  const Vector diagonal = M.diagonal();
  const ScalarVector d = diagonal.cast<Scalar>();
  const ScalarVector invSqrt = diagonal.cwiseSqrt().cwiseInverse().cast<Scalar>();
  if (n <= 200) {
    Dense A = invSqrt.asDiagonal() * Dense(L) * invSqrt.asDiagonal();
    A = (0.5 * (A + A.adjoint())).eval();
    Eigen::SelfAdjointEigenSolver<Dense> solver(A, Eigen::EigenvaluesOnly);
    return solver.eigenvalues().head(count);
  }
  const int block = count + 10;
  const double shift = 1.0;  // any positive shift makes L + shift M SPD
  Eigen::SparseMatrix<Scalar> shifted = L + shift * M.cast<Scalar>();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<Scalar>> factor(shifted);
  if (factor.info() != Eigen::Success) throw std::runtime_error("smallestEigenvalues: factor failed");
  std::mt19937 rng(7);
  Dense X(n, block);
  for (Eigen::Index j = 0; j < block; ++j)
    for (Eigen::Index i = 0; i < n; ++i) X(i, j) = Scalar(uniform(rng, -1.0, 1.0));
  Vector previous = Vector::Constant(count, -1.0);
  Vector values(count);
  for (int iteration = 0; iteration < 200; ++iteration) {
    Dense Y = factor.solve(d.asDiagonal() * X);
    // M-orthonormalise, then Rayleigh–Ritz on the subspace.
    Dense gram = Y.adjoint() * d.asDiagonal() * Y;
    Eigen::LLT<Dense> llt(0.5 * (gram + gram.adjoint()));
    Dense Q = llt.matrixU().template solve<Eigen::OnTheRight>(Y);
    Dense small = Q.adjoint() * (L * Q);
    Eigen::SelfAdjointEigenSolver<Dense> solver(0.5 * (small + small.adjoint()));
    X = Q * solver.eigenvectors();
    values = solver.eigenvalues().head(count);
    // Ritz values converge monotonically from above; 1e-13 is far below any
    // discretization error measured with this helper and above rounding noise.
    if ((values - previous).cwiseAbs().maxCoeff() <= 1e-13 * std::max(1.0, values.cwiseAbs().maxCoeff()))
      break;
    previous = values;
    if (iteration == 199) throw std::runtime_error("smallestEigenvalues: no convergence");
  }
  return values;
}

}  // namespace blot::stain::testing
