// Paper Fig. 4 experiment (see tiled_spot_diffusion.h).
#include "tiled_spot_diffusion.h"

#include <blot/stain/geometry/intrinsic_geometry.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/operators.h>
#include <blot/stain/numerics/sparse_solver.h>
#include <blot/stain/geometry/surface_topology.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace blot::test {
namespace {

using stain::Matrix2;
using stain::SparseMatrix;
using stain::Vector;

Eigen::MatrixX3d uniformTensors(int faceCount, const Matrix2& s) {
  Eigen::MatrixX3d rows(faceCount, 3);
  for (int f = 0; f < faceCount; ++f) rows.row(f) << s(0, 0), s(0, 1), s(1, 1);
  return rows;
}

Vector diffuse(const stain::SurfaceTopology& topology, const stain::RowVectors3& positions, const SparseMatrix& mass,
               const Eigen::MatrixX3d& faceTensors, const Vector& initial, const TiledSpotSetup& setup) {
  stain::RowVectors3 weft = stain::RowVectors3::Zero(topology.faceCount(), 3);
  weft.col(0).setOnes();  // weft along x everywhere
  const double h = setup.duration / setup.steps;
  const SparseMatrix system = mass + h * stain::anisotropicStiffness(topology, positions, faceTensors, weft);
  stain::RealCholeskySolver solver;
  if (solver.compute(system) != stain::SolverStatus::Ok) throw std::runtime_error("tiledSpotDiffusion: factorization failed");
  Vector sigma = initial, rhs, next;
  for (int step = 0; step < setup.steps; ++step) {
    rhs = mass * sigma;
    if (solver.solve(rhs, next) != stain::SolverStatus::Ok) throw std::runtime_error("tiledSpotDiffusion: solve failed");
    sigma.swap(next);
  }
  return sigma;
}

}  // namespace

TiledSpotResult tiledSpotDiffusion(const stain::WeavePattern& pattern, const TiledSpotSetup& setup) {
  TiledSpotResult result;
  result.cellsX = pattern.cols() * setup.tilesX;
  result.cellsY = pattern.rows() * setup.tilesY;
  const int m = setup.squaresPerCell;
  result.verticesX = result.cellsX * m + 1;
  result.verticesY = result.cellsY * m + 1;
  const stain::TriangleMesh mesh = stain::gridMesh(result.cellsX * m, result.cellsY * m, result.cellsX, result.cellsY);
  const int vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  const stain::SurfaceTopology topology(mesh.faces, vertexCount, "tiled rectangle");
  const SparseMatrix mass = stain::lumpedMassMatrix(
      stain::vertexDualAreas(topology, stain::faceAreas(topology, stain::edgeLengths(topology, mesh.vertexPositions))));

  // (1) each face takes the tensor of the cell containing its centroid; cell
  // row 0 of the file is the top of each tile.
  Eigen::MatrixX3d fine(topology.faceCount(), 3);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const stain::Vector3 centroid = (mesh.vertexPositions.row(mesh.faces(f, 0)) + mesh.vertexPositions.row(mesh.faces(f, 1)) +
                                     mesh.vertexPositions.row(mesh.faces(f, 2))).transpose() / 3.0;
    const int cx = static_cast<int>(centroid.x()), cy = static_cast<int>(centroid.y());
    const Matrix2& s = pattern.cellTensor(pattern.rows() - 1 - cy % pattern.rows(), cx % pattern.cols());
    fine.row(f) << s(0, 0), s(0, 1), s(1, 1);
  }
  result.homogenized = stain::homogenize(pattern);

  Vector initial(vertexCount);
  const Eigen::RowVector3d centre(0.5 * result.cellsX, 0.5 * result.cellsY, 0.0);
  for (int v = 0; v < vertexCount; ++v)
    initial(v) = std::exp(-(mesh.vertexPositions.row(v) - centre).squaredNorm() / (2 * setup.spotRadius * setup.spotRadius));

  const int faceCount = topology.faceCount();
  result.original = diffuse(topology, mesh.vertexPositions, mass, fine, initial, setup);
  result.effective = diffuse(topology, mesh.vertexPositions, mass, uniformTensors(faceCount, result.homogenized.effective), initial, setup);
  result.average = diffuse(topology, mesh.vertexPositions, mass, uniformTensors(faceCount, result.homogenized.average), initial, setup);

  const auto norm = [&mass](const Vector& x) { return std::sqrt(x.dot(mass * x)); };
  result.effectiveError = norm(result.effective - result.original) / norm(result.original);
  result.averageError = norm(result.average - result.original) / norm(result.original);
  const double initialMass = (mass * initial).sum();
  for (const Vector* field : {&result.original, &result.effective, &result.average})
    result.massDrift = std::max(result.massDrift, std::abs((mass * *field).sum() - initialMass) / initialMass);
  return result;
}

}  // namespace blot::test
