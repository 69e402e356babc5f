// P1 finite-element operators: anisotropic stiffness, cotan Laplacian, lumped
// mass, and the connection Laplacian (paper sec. 3.2, eq. 7).
//
// Design note: docs/design-notes.md, "stain/src/geometry/operators.cpp".
#include <blot/stain/geometry/operators.h>

#include <blot/stain/geometry/intrinsic_geometry.h>

#include "numerics/lanes.h"
#include "numerics/vector_trig.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::stain {
namespace {

// Relative size below which a projected weft direction is treated as zero.
constexpr double kDegenerateWeft = 1e-12;

struct FaceLayout {
  Vector2 corners[3];  // 2D corners in the face frame.
  Matrix2 tensor;      // S_T in the face frame.
};

// S_T = (e, e⊥) S (e, e⊥)ᵀ for the unit weft e in face coordinates and the
// fabric tensor S = [sww swp; swp spp] (e⊥ = +90° rotation in the face).
Matrix2 tensorInFace(const Vector2& e, double sww, double swp, double spp) {
  Matrix2 basis;  // columns: weft e, warp e⊥
  basis << e.x(), -e.y(), e.y(), e.x();
  Matrix2 fabric;
  fabric << sww, swp, swp, spp;
  return basis * fabric * basis.transpose();
}

// Face f laid out in its own frame: x along its first edge, n its unit
// normal, y = n × x, and its corners in (x, y).
struct FaceFrame {
  Vector3 x, y, n;
  Vector2 corners[3];
};

FaceFrame faceFrame(const SurfaceTopology& topology, const RowVectors3& positions, int f) {
  const Triangles& faces = topology.faces();
  const Vector3 p0 = positions.row(faces(f, 0)).transpose();
  const Vector3 e1 = positions.row(faces(f, 1)).transpose() - p0;
  const Vector3 e2 = positions.row(faces(f, 2)).transpose() - p0;
  FaceFrame frame;
  frame.x = e1.normalized();
  frame.n = e1.cross(e2).normalized();
  frame.y = frame.n.cross(frame.x);
  frame.corners[0] = Vector2::Zero();
  frame.corners[1] = Vector2(e1.norm(), 0.0);
  frame.corners[2] = Vector2(e2.dot(frame.x), e2.dot(frame.y));
  return frame;
}

// Face f's fabric tensor rotated into its frame.
Matrix2 tensorInFrame(const FaceFrame& frame, const Eigen::MatrixX3d& faceTensors,
                      const RowVectors3& faceWeftDirections, int f) {
  const double sww = faceTensors(f, 0), swp = faceTensors(f, 1), spp = faceTensors(f, 2);
  if (swp == 0.0 && sww == spp) return sww * Matrix2::Identity();  // isotropic: orientation irrelevant
  const Vector3& n = frame.n;
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
  const Vector2 e(inPlane.dot(frame.x) / length, inPlane.dot(frame.y) / length);
  return tensorInFace(e, sww, swp, spp);  // e⊥ = n × e
}

// Lays face f out in its own frame and rotates its fabric tensor into it.
FaceLayout layoutFace(const SurfaceTopology& topology, const RowVectors3& positions,
                      const Eigen::MatrixX3d& faceTensors, const RowVectors3& faceWeftDirections,
                      int f) {
  const FaceFrame frame = faceFrame(topology, positions, f);
  FaceLayout layout;
  for (int k = 0; k < 3; ++k) layout.corners[k] = frame.corners[k];
  layout.tensor = tensorInFrame(frame, faceTensors, faceWeftDirections, f);
  return layout;
}

// Face f's corners laid out from its edge lengths (see
// anisotropicStiffnessFromLengths): corner 0 at the origin, 1 on +x, 2 above.
// `area` is the face's triangleArea of those lengths when the caller has it
// (faceAreas: the same bits), negative to compute it here.
void intrinsicCorners(const SurfaceTopology& topology, const Vector& edgeLengths, int f, Vector2 (&corners)[3],
                      double area = -1.0) {
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  // faceEdges(f, 0) joins corners 0 and 1, (f, 1) corners 1 and 2, (f, 2) corners 2 and 0.
  const double l0 = edgeLengths(fe(f, 0)), l1 = edgeLengths(fe(f, 1)), l2 = edgeLengths(fe(f, 2));
  const double x = (l0 * l0 + (l2 - l1) * (l2 + l1)) / (2.0 * l0);
  const double y = 2.0 * (area >= 0.0 ? area : triangleArea(l0, l1, l2)) / l0;
  corners[0] = Vector2::Zero();
  corners[1] = Vector2(l0, 0.0);
  corners[2] = Vector2(x, y);
}

// Face f's unit weft in the frame of its intrinsic corners: a c₁ + b c₂
// with the rest coefficients, normalised.
Vector2 intrinsicWeft(const Vector2 (&corners)[3], const Eigen::MatrixX2d& faceWeftCoefficients, int f) {
  const double a = faceWeftCoefficients(f, 0), b = faceWeftCoefficients(f, 1);
  const Vector2 weft = a * corners[1] + b * corners[2];
  const double length = weft.norm();
  if (!(length > 0) || !std::isfinite(length)) {  // also catches a zero or out-of-plane weft (NaN coefficients)
    std::ostringstream s;
    s << "anisotropicStiffness: face " << f << ": the weft direction has no component in the face plane; "
      << "the fabric orientation is undefined for an anisotropic tensor";
    throw std::invalid_argument(s.str());
  }
  return weft / length;
}

// Face f's fabric tensor in the frame of its intrinsic corners, the unit weft
// taken from *weft (computed there by intrinsicWeft when still unset).
Matrix2 intrinsicTensor(const Vector2 (&corners)[3], const Eigen::MatrixX3d& faceTensors,
                        const Eigen::MatrixX2d& faceWeftCoefficients, int f, std::optional<Vector2>& weft) {
  const double sww = faceTensors(f, 0), swp = faceTensors(f, 1), spp = faceTensors(f, 2);
  if (swp == 0.0 && sww == spp) return sww * Matrix2::Identity();  // isotropic: orientation irrelevant
  if (!weft) weft = intrinsicWeft(corners, faceWeftCoefficients, f);
  return tensorInFace(*weft, sww, swp, spp);
}

// Lays face f out from its edge lengths (see anisotropicStiffnessFromLengths).
FaceLayout intrinsicLayout(const SurfaceTopology& topology, const Vector& edgeLengths,
                           const Eigen::MatrixX3d& faceTensors, const Eigen::MatrixX2d& faceWeftCoefficients, int f) {
  FaceLayout layout;
  intrinsicCorners(topology, edgeLengths, f, layout.corners);
  std::optional<Vector2> weft;
  layout.tensor = intrinsicTensor(layout.corners, faceTensors, faceWeftCoefficients, f, weft);
  return layout;
}

// The 3x3 stiffness of face f from its lengths.
Matrix3 intrinsicFaceStiffness(const SurfaceTopology& topology, const Vector& edgeLengths,
                               const Eigen::MatrixX3d& faceTensors, const Eigen::MatrixX2d& faceWeftCoefficients,
                               int f) {
  const FaceLayout layout = intrinsicLayout(topology, edgeLengths, faceTensors, faceWeftCoefficients, f);
  return triangleStiffness(layout.corners[0], layout.corners[1], layout.corners[2], layout.tensor);
}

// exp(iφ(f, k)) of the faces list[0..count) (faces 0..count without a list),
// asked for in that order: a block of faces at a time, whose 3 × kBlock
// angles are one vector batch (numerics/vector_trig.h: the same bits as one
// at a time, so every connection path agrees).
class FacePhases {
 public:
  FacePhases(const Eigen::MatrixX3d& faceTransportAngles, const int* list, int count)
      : angles_(faceTransportAngles), list_(list), count_(count) {}

  /// exp(iφ) of the n-th face's corners; n ascending.
  const Complex* at(int n) {
    if (n >= end_) fill(n);
    return phases_ + 3 * (n - begin_);
  }

 private:
  static constexpr int kBlock = 32;

  void fill(int n) {
    begin_ = n;
    end_ = std::min(n + kBlock, count_);
    double phi[3 * kBlock];
    for (int b = 0; b < end_ - begin_; ++b) {
      const int f = list_ != nullptr ? list_[begin_ + b] : begin_ + b;
      for (int k = 0; k < 3; ++k) phi[3 * b + k] = angles_(f, k);
    }
    trig::unitPhases(phi, phases_, 3 * (end_ - begin_));
  }

  const Eigen::MatrixX3d& angles_;
  const int* list_;
  int count_, begin_ = 0, end_ = 0;
  Complex phases_[3 * kBlock];
};

// Face f's connection block entry (k, l): K_kl conj(r_k) r_l, the diagonal real.
inline Complex connectionEntry(double Kkl, const Complex* r, int k, int l) {
  return k == l ? Complex(Kkl, 0.0) : Kkl * std::conj(r[k]) * r[l];
}
inline Complex connectionEntry(const Matrix3& K, const Complex* r, int k, int l) {
  return connectionEntry(K(k, l), r, k, l);
}

// Zeroes the entries (i, j) of L with j in vertices and i marked.
template <typename Scalar>
void zeroMarkedEntries(const char* marks, const int* vertices, int vertexCount, Eigen::SparseMatrix<Scalar>& L) {
  const int* outer = L.outerIndexPtr();
  const int* rows = L.innerIndexPtr();
  Scalar* values = L.valuePtr();
  for (int n = 0; n < vertexCount; ++n) {
    const int j = vertices[n];
    for (int p = outer[j]; p < outer[j + 1]; ++p)
      if (marks[rows[p]]) values[p] = Scalar(0);
  }
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
// Position of (row, col) in the value array of a compressed pattern holding it.
inline int entryPosition(const int* outer, const int* rows, int row, int col) {
  return static_cast<int>(std::lower_bound(rows + outer[col], rows + outer[col + 1], row) - rows);
}

template <typename Scalar>
inline void addEntry(Eigen::SparseMatrix<Scalar>& L, int row, int col, const Scalar& value) {
  L.valuePtr()[entryPosition(L.outerIndexPtr(), L.innerIndexPtr(), row, col)] += value;
}

// Face f's block entry (k, l) added into L (a partial re-assembly): at the
// position the entry table gives when it fits L, else found by a search
// (addEntry). The same position either way, so the same sums.
template <typename Scalar>
class MarkedEntryAdder {
 public:
  MarkedEntryAdder(const SurfaceTopology& topology, const OneRingEntries* entries, Eigen::SparseMatrix<Scalar>& L)
      : faces_(topology.faces()),
        entry_(entries != nullptr && entries->fits(topology, L) ? entries->index.data() : nullptr),
        L_(L) {}
  void operator()(int f, int k, int l, const Scalar& value) const {
    if (entry_ != nullptr) {
      L_.valuePtr()[entry_[9 * static_cast<size_t>(f) + static_cast<size_t>(3 * k + l)]] += value;
    } else {
      addEntry(L_, faces_(f, k), faces_(f, l), value);
    }
  }

 private:
  const Triangles& faces_;
  const int* entry_;
  Eigen::SparseMatrix<Scalar>& L_;
};

// A triangle's P1 hat-function gradients (columns) and its area: what its
// stiffness needs besides the tensor, so one face's two operators share them.
struct TriangleGradients {
  Eigen::Matrix<double, 2, 3> gradients;
  double area;
};

TriangleGradients triangleGradients(const Vector2& p0, const Vector2& p1, const Vector2& p2) {
  const Vector2 p[3] = {p0, p1, p2};
  const double twiceSignedArea =
      (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p1.y() - p0.y()) * (p2.x() - p0.x());
  TriangleGradients g;
  for (int k = 0; k < 3; ++k) {
    const Vector2 edge = p[(k + 2) % 3] - p[(k + 1) % 3];
    g.gradients.col(k) = Vector2(-edge.y(), edge.x()) / twiceSignedArea;
  }
  g.area = 0.5 * std::abs(twiceSignedArea);
  return g;
}

Matrix3 stiffnessFromGradients(const TriangleGradients& g, const Matrix2& tensor) {
  return g.area * g.gradients.transpose() * tensor * g.gradients;
}

// kStiffnessLanes faces' density and velocity stiffness blocks at once, lane
// j for face first + j (a short group's spare lanes repeat its last face).
// Each lane runs the operations of intrinsicCorners, triangleGradients and
// stiffnessFromGradients in their order: Eigen evaluates a Gᵀ T G as
// ((a Gᵀ) T) G, each inner sum in index order, and the build contracts
// nothing (-ffp-contract=off). So a lane's bits are its face's alone; the
// arithmetic shared by all four runs on numerics/lanes.h (GCC left these
// loops scalar), the tensors' branches lane by lane.
constexpr int kStiffnessLanes = 4;
static_assert(kStiffnessLanes == lanes::kLanes, "a face per lane of numerics/lanes.h");

struct StiffnessLanes {
  double density[9][kStiffnessLanes];  // K(k, l) at 3k + l
  double velocity[9][kStiffnessLanes];
};

// K = ((a Gᵀ) T) G for every lane, T(r, c) at t[2r + c].
void stiffnessOfLanes(const lanes::Lanes& area, const lanes::Lanes (&g)[2][3], const double (&t)[4][kStiffnessLanes],
                      double (&K)[9][kStiffnessLanes]) {
  const lanes::Lanes t0 = lanes::load(t[0]), t1 = lanes::load(t[1]), t2 = lanes::load(t[2]), t3 = lanes::load(t[3]);
  for (int k = 0; k < 3; ++k) {
    const lanes::Lanes a0 = area * g[0][k], a1 = area * g[1][k];
    const lanes::Lanes m0 = a0 * t0 + a1 * t2;
    const lanes::Lanes m1 = a0 * t1 + a1 * t3;
    for (int l = 0; l < 3; ++l) lanes::store(m0 * g[0][l] + m1 * g[1][l], K[3 * k + l]);
  }
}

void stiffnessLanes(const SurfaceTopology& topology, const Vector& edgeLengths, const Vector& faceAreas,
                    const Eigen::MatrixX3d& densityTensors, const Eigen::MatrixX3d& velocityTensors,
                    const Eigen::MatrixX2d& faceWeftCoefficients, int first, int count, StiffnessLanes& out) {
  constexpr int L = kStiffnessLanes;
  const Eigen::MatrixX3i& fe = topology.faceEdges();
  double l0[L], l1[L], l2[L], area[L];
  for (int j = 0; j < L; ++j) {
    const int f = first + std::min(j, count - 1);
    l0[j] = edgeLengths(fe(f, 0));
    l1[j] = edgeLengths(fe(f, 1));
    l2[j] = edgeLengths(fe(f, 2));
    const double given = faceAreas(f);
    area[j] = given >= 0.0 ? given : triangleArea(l0[j], l1[j], l2[j]);  // intrinsicCorners' rule
  }
  // intrinsicCorners: (0, 0), (l0, 0), (x, y).
  const lanes::Lanes L0 = lanes::load(l0), L1 = lanes::load(l1), L2 = lanes::load(l2);
  const lanes::Lanes X = (L0 * L0 + (L2 - L1) * (L2 + L1)) / (2.0 * L0);
  const lanes::Lanes Y = 2.0 * lanes::load(area) / L0;
  double x[L], y[L];
  lanes::store(X, x);
  lanes::store(Y, y);
  // The tensors in each face's frame (its weft needs the corners):
  // intrinsicTensor's arithmetic written out, without its Matrix2 and
  // optional (it was a call per face and tensor).
  double td[4][L], tv[4][L];
  for (int j = 0; j < L; ++j) {
    const int f = first + std::min(j, count - 1);
    double ex = 0.0, ey = 0.0;
    bool haveWeft = false;  // one unit weft for both tensors
    const auto tensor = [&](const Eigen::MatrixX3d& tensors, double (&entries)[4][L]) {
      const double sww = tensors(f, 0), swp = tensors(f, 1), spp = tensors(f, 2);
      if (swp == 0.0 && sww == spp) {  // isotropic: sww · I, as intrinsicTensor
        entries[0][j] = sww * 1.0;
        entries[1][j] = entries[2][j] = sww * 0.0;
        entries[3][j] = sww * 1.0;
        return;
      }
      if (!haveWeft) {
        const Vector2 corners[3] = {Vector2::Zero(), Vector2(l0[j], 0.0), Vector2(x[j], y[j])};
        const Vector2 e = intrinsicWeft(corners, faceWeftCoefficients, f);
        ex = e.x();
        ey = e.y();
        haveWeft = true;
      }
      // tensorInFace: B S Bᵀ with B = [e e⊥] = [ex −ey; ey ex], the products
      // evaluated as Eigen does, (B S) first, each entry's terms in index order.
      const double b[2][2] = {{ex, -ey}, {ey, ex}};
      const double fabric[2][2] = {{sww, swp}, {swp, spp}};
      double bs[2][2];
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) bs[r][c] = b[r][0] * fabric[0][c] + b[r][1] * fabric[1][c];
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) entries[2 * r + c][j] = bs[r][0] * b[c][0] + bs[r][1] * b[c][1];
    };
    tensor(densityTensors, td);
    tensor(velocityTensors, tv);
  }
  // triangleGradients: column k is the edge p[k + 2] − p[k + 1] turned by
  // +90°, over twice the signed area; the area its half magnitude.
  const lanes::Lanes zero = lanes::splat(0.0);
  const lanes::Lanes twiceSignedArea = (L0 - zero) * (Y - zero) - (zero - zero) * (X - zero);
  lanes::Lanes g[2][3];
  g[0][0] = -(Y - zero) / twiceSignedArea;  // p2 − p1
  g[1][0] = (X - L0) / twiceSignedArea;
  g[0][1] = -(zero - Y) / twiceSignedArea;  // p0 − p2
  g[1][1] = (zero - X) / twiceSignedArea;
  g[0][2] = -(zero - zero) / twiceSignedArea;  // p1 − p0
  g[1][2] = (L0 - zero) / twiceSignedArea;
  const lanes::Lanes stiffnessArea = 0.5 * lanes::abs(twiceSignedArea);
  stiffnessOfLanes(stiffnessArea, g, td, out.density);
  stiffnessOfLanes(stiffnessArea, g, tv, out.velocity);
}

}  // namespace

Matrix3 triangleStiffness(const Vector2& p0, const Vector2& p1, const Vector2& p2,
                          const Matrix2& tensor) {
  return stiffnessFromGradients(triangleGradients(p0, p1, p2), tensor);
}

Eigen::MatrixX3d identityFaceTensors(int faceCount) {
  Eigen::MatrixX3d tensors(faceCount, 3);
  tensors.col(0).setOnes();
  tensors.col(1).setZero();
  tensors.col(2).setOnes();
  return tensors;
}

namespace {

// The position-based operators face by face, in face order: add(f, k, l,
// value) receives face f's block entry (k, l). Both the assembly into a new
// pattern and the refill into an existing one go through these, so they sum
// the same terms in the same order.
template <typename Add>
void forEachStiffnessEntry(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                           const Eigen::MatrixX3d& faceTensors, const RowVectors3& faceWeftDirections,
                           const Add& add) {
  for (int f = 0; f < topology.faceCount(); ++f) {
    const FaceLayout layout = layoutFace(topology, vertexPositions, faceTensors, faceWeftDirections, f);
    const Matrix3 K = triangleStiffness(layout.corners[0], layout.corners[1], layout.corners[2],
                                        layout.tensor);
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) add(f, k, l, K(k, l));
    }
  }
}

template <typename Add>
void forEachConnectionEntry(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                            const Eigen::MatrixX3d& faceTransportAngles, const Eigen::MatrixX3d& faceTensors,
                            const RowVectors3& faceWeftDirections, const Add& add) {
  FacePhases phases(faceTransportAngles, nullptr, topology.faceCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    const FaceLayout layout = layoutFace(topology, vertexPositions, faceTensors, faceWeftDirections, f);
    const Matrix3 K = triangleStiffness(layout.corners[0], layout.corners[1], layout.corners[2],
                                        layout.tensor);
    const Complex* r = phases.at(f);
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) add(f, k, l, connectionEntry(K, r, k, l));
    }
  }
}

// The refill of L (operators.h): checks that L has the one-ring pattern the
// entries index, zeroes its values and adds every term forEach passes, in
// its order, at the face entry's position.
template <typename Scalar, typename ForEach>
void refill(const SurfaceTopology& topology, const OneRingEntries& entries, Eigen::SparseMatrix<Scalar>& L,
            const char* what, const ForEach& forEach) {
  if (!entries.fits(topology, L)) {
    throw std::invalid_argument(std::string(what) + ": the matrix or the entry table is not of this topology");
  }
  Scalar* values = L.valuePtr();
  std::fill(values, values + L.nonZeros(), Scalar(0));
  const int* entry = entries.index.data();
  forEach([&](int f, int k, int l, const Scalar& value) {
    values[entry[9 * static_cast<size_t>(f) + static_cast<size_t>(3 * k + l)]] += value;
  });
}

}  // namespace

OneRingEntries oneRingFaceEntries(const SurfaceTopology& topology) {
  const SparseMatrix pattern = oneRingPattern<double>(topology);
  const Triangles& faces = topology.faces();
  const int* outer = pattern.outerIndexPtr();
  const int* rows = pattern.innerIndexPtr();
  OneRingEntries entries;
  entries.nonZeros = pattern.nonZeros();
  entries.index.resize(9 * static_cast<size_t>(topology.faceCount()));
  for (int f = 0; f < topology.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) {
        entries.index[9 * static_cast<size_t>(f) + 3 * static_cast<size_t>(k) + static_cast<size_t>(l)] =
            entryPosition(outer, rows, faces(f, k), faces(f, l));
      }
    }
  }
  return entries;
}

SparseMatrix anisotropicStiffness(const SurfaceTopology& topology,
                                  const RowVectors3& vertexPositions,
                                  const Eigen::MatrixX3d& faceTensors,
                                  const RowVectors3& faceWeftDirections) {
  const Triangles& faces = topology.faces();
  SparseMatrix L = oneRingPattern<double>(topology);
  forEachStiffnessEntry(topology, vertexPositions, faceTensors, faceWeftDirections,
                        [&](int f, int k, int l, double value) { addEntry(L, faces(f, k), faces(f, l), value); });
  return L;
}

void refillAnisotropicStiffness(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                                const Eigen::MatrixX3d& faceTensors, const RowVectors3& faceWeftDirections,
                                const OneRingEntries& entries, SparseMatrix& L) {
  refill(topology, entries, L, "refillAnisotropicStiffness", [&](const auto& add) {
    forEachStiffnessEntry(topology, vertexPositions, faceTensors, faceWeftDirections, add);
  });
}

void refillStiffnessAndConnectionFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                             const Vector& faceAreas, const Eigen::MatrixX3d& densityTensors,
                                             const Eigen::MatrixX3d& faceTransportAngles,
                                             const Eigen::MatrixX3d& velocityTensors,
                                             const Eigen::MatrixX2d& faceWeftCoefficients,
                                             const OneRingEntries& entries, SparseMatrix& stiffness,
                                             ComplexSparseMatrix& connection) {
  if (!entries.fits(topology, stiffness) || !entries.fits(topology, connection) ||
      faceAreas.size() != topology.faceCount())
    throw std::invalid_argument(
        "refillStiffnessAndConnectionFromLengths: the stiffness, the connection, the face areas or the entry table "
        "is not of this topology");
  double* stiffnessValues = stiffness.valuePtr();
  Complex* connectionValues = connection.valuePtr();
  std::fill(stiffnessValues, stiffnessValues + stiffness.nonZeros(), 0.0);
  std::fill(connectionValues, connectionValues + connection.nonZeros(), Complex(0.0, 0.0));
  const int* entry = entries.index.data();
  // The terms of anisotropicStiffnessFromLengths and
  // connectionLaplacianFromLengths (intrinsicFaceStiffness's layout and
  // kernel), each face's layout and gradients computed once for both, four
  // faces at a time (stiffnessLanes: each face's own bits), then added face
  // by face in face order: the same bits as those assemblies.
  FacePhases phases(faceTransportAngles, nullptr, topology.faceCount());
  StiffnessLanes lanes;
  for (int first = 0; first < topology.faceCount(); first += kStiffnessLanes) {
    const int count = std::min(kStiffnessLanes, topology.faceCount() - first);
    stiffnessLanes(topology, edgeLengths, faceAreas, densityTensors, velocityTensors, faceWeftCoefficients, first,
                   count, lanes);
    for (int j = 0; j < count; ++j) {
      const int f = first + j;
      const int* at = entry + 9 * static_cast<size_t>(f);
      for (int m = 0; m < 9; ++m) stiffnessValues[at[m]] += lanes.density[m][j];
      const Complex* r = phases.at(f);
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l)
          connectionValues[at[3 * k + l]] += connectionEntry(lanes.velocity[3 * k + l][j], r, k, l);
    }
  }
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
  forEachConnectionEntry(topology, vertexPositions, faceTransportAngles, faceTensors, faceWeftDirections,
                         [&](int f, int k, int l, const Complex& value) {
                           addEntry(L, faces(f, k), faces(f, l), value);
                         });
  return L;
}

void refillConnectionLaplacian(const SurfaceTopology& topology, const RowVectors3& vertexPositions,
                               const Eigen::MatrixX3d& faceTransportAngles, const Eigen::MatrixX3d& faceTensors,
                               const RowVectors3& faceWeftDirections, const OneRingEntries& entries,
                               ComplexSparseMatrix& L) {
  refill(topology, entries, L, "refillConnectionLaplacian", [&](const auto& add) {
    forEachConnectionEntry(topology, vertexPositions, faceTransportAngles, faceTensors, faceWeftDirections, add);
  });
}

SparseMatrix anisotropicStiffnessFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                             const Eigen::MatrixX3d& faceTensors,
                                             const Eigen::MatrixX2d& faceWeftCoefficients) {
  const Triangles& faces = topology.faces();
  SparseMatrix L = oneRingPattern<double>(topology);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Matrix3 K = intrinsicFaceStiffness(topology, edgeLengths, faceTensors, faceWeftCoefficients, f);
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) addEntry(L, faces(f, k), faces(f, l), K(k, l));
    }
  }
  return L;
}

void reassembleStiffnessFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                    const Eigen::MatrixX3d& faceTensors, const Eigen::MatrixX2d& faceWeftCoefficients,
                                    const char* vertexMarks, const int* vertices, int vertexCount, const int* faceList,
                                    int faceCount, SparseMatrix& L, const OneRingEntries* entries) {
  const Triangles& faces = topology.faces();
  zeroMarkedEntries(vertexMarks, vertices, vertexCount, L);
  const MarkedEntryAdder<double> add(topology, entries, L);
  for (int n = 0; n < faceCount; ++n) {
    const int f = faceList[n];
    const Matrix3 K = intrinsicFaceStiffness(topology, edgeLengths, faceTensors, faceWeftCoefficients, f);
    for (int k = 0; k < 3; ++k) {
      if (!vertexMarks[faces(f, k)]) continue;
      for (int l = 0; l < 3; ++l)
        if (vertexMarks[faces(f, l)]) add(f, k, l, K(k, l));
    }
  }
}

ComplexSparseMatrix connectionLaplacianFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                                   const Eigen::MatrixX3d& faceTransportAngles,
                                                   const Eigen::MatrixX3d& faceTensors,
                                                   const Eigen::MatrixX2d& faceWeftCoefficients) {
  const Triangles& faces = topology.faces();
  ComplexSparseMatrix L = oneRingPattern<Complex>(topology);
  FacePhases phases(faceTransportAngles, nullptr, topology.faceCount());
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Matrix3 K = intrinsicFaceStiffness(topology, edgeLengths, faceTensors, faceWeftCoefficients, f);
    const Complex* r = phases.at(f);
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) addEntry(L, faces(f, k), faces(f, l), connectionEntry(K, r, k, l));
    }
  }
  return L;
}

void reassembleConnectionFromLengths(const SurfaceTopology& topology, const Vector& edgeLengths,
                                     const Eigen::MatrixX3d& faceTransportAngles, const Eigen::MatrixX3d& faceTensors,
                                     const Eigen::MatrixX2d& faceWeftCoefficients, const char* vertexMarks,
                                     const int* vertices, int vertexCount, const int* faceList, int faceCount,
                                     ComplexSparseMatrix& L, const OneRingEntries* entries) {
  const Triangles& faces = topology.faces();
  zeroMarkedEntries(vertexMarks, vertices, vertexCount, L);
  const MarkedEntryAdder<Complex> add(topology, entries, L);
  FacePhases phases(faceTransportAngles, faceList, faceCount);
  for (int n = 0; n < faceCount; ++n) {
    const int f = faceList[n];
    const Matrix3 K = intrinsicFaceStiffness(topology, edgeLengths, faceTensors, faceWeftCoefficients, f);
    const Complex* r = phases.at(n);
    for (int k = 0; k < 3; ++k) {
      if (!vertexMarks[faces(f, k)]) continue;
      for (int l = 0; l < 3; ++l)
        if (vertexMarks[faces(f, l)]) add(f, k, l, connectionEntry(K, r, k, l));
    }
  }
}

Eigen::MatrixX2d faceWeftCoefficients(const SurfaceTopology& topology, const RowVectors3& restPositions,
                                      const RowVectors3& faceWeftDirections) {
  const Triangles& faces = topology.faces();
  Eigen::MatrixX2d coefficients(topology.faceCount(), 2);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Vector3 r0 = restPositions.row(faces(f, 0)).transpose();
    const Vector3 r1 = restPositions.row(faces(f, 1)).transpose() - r0;
    const Vector3 r2 = restPositions.row(faces(f, 2)).transpose() - r0;
    const Vector3 w = faceWeftDirections.row(f).transpose();
    // Least squares w ≈ a r1 + b r2 (exact for an in-plane weft).
    const double g11 = r1.dot(r1), g12 = r1.dot(r2), g22 = r2.dot(r2);
    const double det = g11 * g22 - g12 * g12;
    const double b1 = r1.dot(w), b2 = r2.dot(w);
    const double a = (g22 * b1 - g12 * b2) / det, b = (g11 * b2 - g12 * b1) / det;
    const double inPlane = (a * r1 + b * r2).norm();
    if (inPlane > kDegenerateWeft * w.norm() && std::isfinite(inPlane)) {
      coefficients.row(f) << a, b;
    } else {
      coefficients.row(f).setConstant(std::numeric_limits<double>::quiet_NaN());
    }
  }
  return coefficients;
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
