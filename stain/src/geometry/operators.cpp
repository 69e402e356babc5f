// P1 finite-element operators: anisotropic stiffness, cotan Laplacian, lumped
// mass, and the connection Laplacian (paper sec. 3.2, eq. 7).
//
// Design note: docs/design-notes.md, "stain/src/geometry/operators.cpp".
#include <blot/stain/geometry/operators.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace blot::stain {
namespace {

// Relative size below which a projected weft direction is treated as zero.
constexpr double kDegenerateWeft = 1e-12;

struct FaceLayout {
  Vector2 corners[3];  // 2D corners in the face frame.
  Matrix2 tensor;      // S_T in the face frame.
};

// Lays face f out in its own frame and rotates its fabric tensor into it.
FaceLayout layoutFace(const SurfaceTopology& topology, const RowVectors3& positions,
                      const Eigen::MatrixX3d& faceTensors, const RowVectors3& faceWeftDirections,
                      int f) {
  const Triangles& faces = topology.faces();
  const Vector3 p0 = positions.row(faces(f, 0)).transpose();
  const Vector3 e1 = positions.row(faces(f, 1)).transpose() - p0;
  const Vector3 e2 = positions.row(faces(f, 2)).transpose() - p0;
  const Vector3 x = e1.normalized();
  const Vector3 n = e1.cross(e2).normalized();
  const Vector3 y = n.cross(x);

  FaceLayout layout;
  layout.corners[0] = Vector2::Zero();
  layout.corners[1] = Vector2(e1.norm(), 0.0);
  layout.corners[2] = Vector2(e2.dot(x), e2.dot(y));

  const double sww = faceTensors(f, 0), swp = faceTensors(f, 1), spp = faceTensors(f, 2);
  if (swp == 0.0 && sww == spp) {  // isotropic: orientation irrelevant
    layout.tensor = sww * Matrix2::Identity();
    return layout;
  }
  const Vector3 weft = faceWeftDirections.row(f).transpose();
  const Vector3 inPlane = weft - weft.dot(n) * n;
  const double length = inPlane.norm();
  if (!(length > kDegenerateWeft * weft.norm())) {  // also catches a zero weft
    std::ostringstream s;
    s << "anisotropicStiffness: face " << f << ": weft direction (" << weft.transpose()
      << ") has no component in the face plane (normal " << n.transpose()
      << "); the fabric orientation is undefined for an anisotropic tensor";
    throw std::invalid_argument(s.str());
  }
  const Vector2 e(inPlane.dot(x) / length, inPlane.dot(y) / length);
  Matrix2 basis;  // columns: weft e, warp e⊥ = n × e (= +90° rotation in the face)
  basis << e.x(), -e.y(), e.y(), e.x();
  Matrix2 fabric;
  fabric << sww, swp, swp, spp;
  layout.tensor = basis * fabric * basis.transpose();
  return layout;
}

// The pattern of a P1 operator on `topology`, values zero: column j holds
// row j (when j is a corner of some face) and its edge neighbours, sorted;
// compressed. The same pattern setFromTriplets makes from the per-face
// blocks, without the triplet list and Eigen's transposed temporary (9 #F
// triplets plus a copy: ~110 MB for the complex operator at 140K vertices,
// the peak of an intrinsic rebuild).
template <typename Scalar>
Eigen::SparseMatrix<Scalar> oneRingPattern(const SurfaceTopology& topology) {
  const int n = topology.vertexCount();
  const Triangles& faces = topology.faces();
  const Eigen::MatrixX2i& edges = topology.edgeVertices();
  std::vector<char> inFace(static_cast<size_t>(n), 0);
  for (int f = 0; f < topology.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) inFace[static_cast<size_t>(faces(f, k))] = 1;
  }
  Eigen::SparseMatrix<Scalar> L(n, n);
  int* starts = L.outerIndexPtr();  // n + 1, zero after construction
  for (int j = 0; j < n; ++j) starts[j + 1] = inFace[static_cast<size_t>(j)];
  for (int e = 0; e < topology.edgeCount(); ++e) {
    ++starts[edges(e, 0) + 1];
    ++starts[edges(e, 1) + 1];
  }
  for (int j = 0; j < n; ++j) starts[j + 1] += starts[j];
  L.resizeNonZeros(starts[n]);
  std::vector<int> next(starts, starts + n);
  int* rows = L.innerIndexPtr();
  for (int j = 0; j < n; ++j) {
    if (inFace[static_cast<size_t>(j)]) rows[next[static_cast<size_t>(j)]++] = j;
  }
  for (int e = 0; e < topology.edgeCount(); ++e) {
    const int i = edges(e, 0), j = edges(e, 1);
    rows[next[static_cast<size_t>(j)]++] = i;
    rows[next[static_cast<size_t>(i)]++] = j;
  }
  for (int j = 0; j < n; ++j) std::sort(rows + starts[j], rows + starts[j + 1]);
  std::fill(L.valuePtr(), L.valuePtr() + starts[n], Scalar(0));
  return L;
}

// L(row, col) += value; (row, col) must be in L's pattern. Adding face by face
// in face order sums each entry in the order setFromTriplets did (its first
// term assigned, 0 + a = a), so the values are the same to the bit.
template <typename Scalar>
inline void addEntry(Eigen::SparseMatrix<Scalar>& L, int row, int col, const Scalar& value) {
  const int* rows = L.innerIndexPtr();
  const int* at = std::lower_bound(rows + L.outerIndexPtr()[col], rows + L.outerIndexPtr()[col + 1], row);
  L.valuePtr()[at - rows] += value;
}

}  // namespace

Matrix3 triangleStiffness(const Vector2& p0, const Vector2& p1, const Vector2& p2,
                          const Matrix2& tensor) {
  const Vector2 p[3] = {p0, p1, p2};
  const double twiceSignedArea =
      (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p1.y() - p0.y()) * (p2.x() - p0.x());
  Eigen::Matrix<double, 2, 3> gradients;
  for (int k = 0; k < 3; ++k) {
    const Vector2 edge = p[(k + 2) % 3] - p[(k + 1) % 3];
    gradients.col(k) = Vector2(-edge.y(), edge.x()) / twiceSignedArea;
  }
  const double area = 0.5 * std::abs(twiceSignedArea);
  return area * gradients.transpose() * tensor * gradients;
}

Eigen::MatrixX3d identityFaceTensors(int faceCount) {
  Eigen::MatrixX3d tensors(faceCount, 3);
  tensors.col(0).setOnes();
  tensors.col(1).setZero();
  tensors.col(2).setOnes();
  return tensors;
}

SparseMatrix anisotropicStiffness(const SurfaceTopology& topology,
                                  const RowVectors3& vertexPositions,
                                  const Eigen::MatrixX3d& faceTensors,
                                  const RowVectors3& faceWeftDirections) {
  const Triangles& faces = topology.faces();
  SparseMatrix L = oneRingPattern<double>(topology);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const FaceLayout layout = layoutFace(topology, vertexPositions, faceTensors, faceWeftDirections, f);
    const Matrix3 K = triangleStiffness(layout.corners[0], layout.corners[1], layout.corners[2],
                                        layout.tensor);
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) addEntry(L, faces(f, k), faces(f, l), K(k, l));
    }
  }
  return L;
}

SparseMatrix cotanLaplacian(const SurfaceTopology& topology, const Vector& edgeCotanWeights) {
  const Eigen::MatrixX2i& ev = topology.edgeVertices();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(4 * static_cast<size_t>(topology.edgeCount()));
  for (int e = 0; e < topology.edgeCount(); ++e) {
    const int i = ev(e, 0), j = ev(e, 1);
    const double w = edgeCotanWeights(e);
    triplets.emplace_back(i, j, -w);
    triplets.emplace_back(j, i, -w);
    triplets.emplace_back(i, i, w);
    triplets.emplace_back(j, j, w);
  }
  SparseMatrix L(topology.vertexCount(), topology.vertexCount());
  L.setFromTriplets(triplets.begin(), triplets.end());
  return L;
}

SparseMatrix lumpedMassMatrix(const Vector& vertexDualAreas) {
  const auto n = vertexDualAreas.size();
  SparseMatrix M(n, n);
  M.reserve(Eigen::VectorXi::Ones(n));
  for (Eigen::Index i = 0; i < n; ++i) M.insert(i, i) = vertexDualAreas(i);
  M.makeCompressed();
  return M;
}

ComplexSparseMatrix connectionLaplacian(const SurfaceTopology& topology,
                                        const RowVectors3& vertexPositions,
                                        const Eigen::MatrixX3d& faceTransportAngles,
                                        const Eigen::MatrixX3d& faceTensors,
                                        const RowVectors3& faceWeftDirections) {
  const Triangles& faces = topology.faces();
  ComplexSparseMatrix L = oneRingPattern<Complex>(topology);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const FaceLayout layout = layoutFace(topology, vertexPositions, faceTensors, faceWeftDirections, f);
    const Matrix3 K = triangleStiffness(layout.corners[0], layout.corners[1], layout.corners[2],
                                        layout.tensor);
    Complex r[3];
    for (int k = 0; k < 3; ++k) r[k] = std::polar(1.0, faceTransportAngles(f, k));
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) {
        // Diagonal: conj(r_k) r_k = 1 exactly, keep it real.
        const Complex value = k == l ? Complex(K(k, k), 0.0) : K(k, l) * std::conj(r[k]) * r[l];
        addEntry(L, faces(f, k), faces(f, l), value);
      }
    }
  }
  return L;
}

SparseMatrix realForm(const ComplexSparseMatrix& complexMatrix) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(4 * static_cast<size_t>(complexMatrix.nonZeros()));
  for (int col = 0; col < complexMatrix.outerSize(); ++col) {
    for (ComplexSparseMatrix::InnerIterator it(complexMatrix, col); it; ++it) {
      const auto i = 2 * it.row(), j = 2 * it.col();
      const double a = it.value().real(), b = it.value().imag();
      // Explicit zeros are kept so the pattern depends on connectivity only.
      triplets.emplace_back(i, j, a);
      triplets.emplace_back(i, j + 1, -b);
      triplets.emplace_back(i + 1, j, b);
      triplets.emplace_back(i + 1, j + 1, a);
    }
  }
  SparseMatrix R(2 * complexMatrix.rows(), 2 * complexMatrix.cols());
  R.setFromTriplets(triplets.begin(), triplets.end());
  return R;
}

}  // namespace blot::stain
