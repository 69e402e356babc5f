#pragma once
/// Common Eigen types used across blot::stain. Shapes are written #V (vertices),
/// #F (faces), #E (edges), #H (half-edges = 3 #F) in each declaration's comment.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <complex>

namespace blot::stain {

using Vector = Eigen::VectorXd;
using Vector3 = Eigen::Vector3d;
using Vector2 = Eigen::Vector2d;
using Matrix3 = Eigen::Matrix3d;
using Matrix2 = Eigen::Matrix2d;
/// Per-vertex (or per-face) 3D quantities, one row per element.
using RowVectors3 = Eigen::MatrixX3d;
/// Triangles as three vertex indices per row, counter-clockwise seen from outside.
using Triangles = Eigen::MatrixX3i;
using Complex = std::complex<double>;
using ComplexVector = Eigen::VectorXcd;
/// Column-major compressed sparse matrices (what CHOLMOD reads without copying).
using SparseMatrix = Eigen::SparseMatrix<double>;
using ComplexSparseMatrix = Eigen::SparseMatrix<Complex>;

}  // namespace blot::stain
