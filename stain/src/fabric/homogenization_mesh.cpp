// Cell-problem meshes of a periodic weave tile: uniform and corner-graded.
//
// Design note (the derivation and the measured rates are in docs/patterns.md).
//  - Where cells meet at a lattice corner, the cell-problem solution behaves
//    like r^α Φ(θ) with α → 0 as the contrast grows (α ≈ 0.13 for a 1:100
//    chessboard, 0.04 at 1:1000): each decade of distance to the corner holds
//    about the same share of the energy, so a mesh must reach radius ~10⁻³⁰ to
//    miss less than 1% of it. Near the corner the solution is smooth in
//    (ln r, θ), so a geometric mesh with a fixed number of elements per ring
//    resolves it with the same relative accuracy at every scale.
//  - Rejected: tensor-product grading of each cell's K intervals toward both
//    ends. Its elements along the cell edges have aspect ratio h_max/h_min
//    (10³⁰ here), and the stiffness entries with it, which the Cholesky
//    factorization cannot absorb.
//  - Construction: each cell is split into four quarters, one per corner. In a
//    quarter (corner at the origin, [0, ½]²) rays run from the corner to 2m + 1
//    points evenly spaced on the two far sides; square rings at L∞ radius
//    s_ℓ = ½σ^ℓ, σ = e^(−1/m), cut them into trapezoids (each split into two
//    triangles along its shorter diagonal); a fan closes the innermost ring.
//    Successive rings are similar, so the element matrices are the same at
//    every scale (2-D stiffness is scale-invariant) and the conditioning does
//    not grow with the depth. Cell edges and midlines are mesh lines; quarters
//    on either side of one are mirror images, so nodes match (conforming).
//  - Vertex identity: a quarter point is named by (lattice corner, direction
//    signs, ray k, ring ℓ); points on a cell edge or midline are renamed to one
//    canonical name (see canonicalSlot), so a flat array maps names to ids.
#include <blot/stain/fabric/homogenization_mesh.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace blot::stain {

namespace {

/// Square corners 0 = (0,0), 1 = (1,0), 2 = (0,1), 3 = (1,1); counter-clockwise
/// triangles. Diagonal 0 ("/") joins corners 0 and 3, diagonal 1 ("\") 1 and 2.
constexpr int kTriangleCorners[2][2][3] = {{{0, 1, 3}, {0, 3, 2}}, {{0, 1, 2}, {1, 3, 2}}};

void checkTile(int rows, int cols) {
  if (rows < 1 || cols < 1)
    throw std::invalid_argument("cell mesh: the tile needs at least one cell, got " + std::to_string(rows) + "x" +
                                std::to_string(cols));
}

/// Names quarter points on the torus; see the design note.
class GradedVertexNames {
 public:
  GradedVertexNames(int rows, int cols, int raysPerSide, int layers)
      : rows_(rows), cols_(cols), rays_(2 * raysPerSide + 1), rings_(layers + 1), m_(raysPerSide) {
    const long slots = static_cast<long>(rows) * cols * 4 * rays_ * rings_ + static_cast<long>(rows) * cols;
    ids_.assign(static_cast<size_t>(slots), -1);
  }

  /// Id of point (ray k, ring ℓ) of the quarter at lattice corner (i, j) that
  /// extends toward signs (sx, sy) ∈ {±1}²; ring = layers + 1 names the corner itself.
  int id(int i, int j, int sx, int sy, int k, int ring) {
    const long slot = canonicalSlot(i, j, sx, sy, k, ring);
    int& id = ids_[static_cast<size_t>(slot)];
    if (id < 0) id = count_++;
    return id;
  }
  int count() const { return count_; }

 private:
  long canonicalSlot(int i, int j, int sx, int sy, int k, int ring) const {
    if (ring == rings_) return static_cast<long>(rows_) * cols_ * 4 * rays_ * rings_ + corner(i, j);
    const int twoM = 2 * m_;
    if (k == 0) sy = 1;      // on the horizontal cell edge: both sides name it alike
    if (k == twoM) sx = 1;   // on the vertical cell edge
    if (ring == 0) {         // on the cell midlines: name it from the corner to the left / below
      const bool onVerticalMidline = k <= m_ && k != twoM;  // x = corner ± ½ (k = 0: edge midpoint)
      const bool onHorizontalMidline = k >= m_ && k != 0;   // y = corner ± ½
      if (onVerticalMidline && sx == 1) ++i, sx = -1;
      if (onHorizontalMidline && sy == 1) ++j, sy = -1;
    }
    const int signs = (sx > 0 ? 1 : 0) + (sy > 0 ? 2 : 0);
    return ((static_cast<long>(corner(i, j)) * 4 + signs) * rays_ + k) * rings_ + ring;
  }
  int corner(int i, int j) const { return ((j % rows_ + rows_) % rows_) * cols_ + (i % cols_ + cols_) % cols_; }

  int rows_, cols_, rays_, rings_, m_;
  std::vector<int> ids_;
  int count_ = 0;
};

}  // namespace

CellMesh uniformCellMesh(int rows, int cols, int subdivisions) {
  checkTile(rows, cols);
  if (subdivisions < 1)
    throw std::invalid_argument("uniform cell mesh: subdivisions must be >= 1, got " + std::to_string(subdivisions));
  const int K = subdivisions, nx = cols * K, ny = rows * K;
  const double h = 1.0 / K;
  auto vertex = [nx, ny](int i, int j) { return (j % ny) * nx + i % nx; };
  CellMesh mesh;
  mesh.vertexCount = nx * ny;
  const size_t triangles = static_cast<size_t>(2) * static_cast<size_t>(nx) * static_cast<size_t>(ny);
  mesh.triangleVertices.reserve(triangles);
  mesh.triangleCorners.reserve(triangles);
  mesh.triangleCells.reserve(triangles);
  for (int j = 0; j < ny; ++j) {
    const int row = rows - 1 - j / K;  // file row 0 is the top of the tile
    for (int i = 0; i < nx; ++i) {
      const int diagonal = (i + j) % 2;
      const int squareVertices[4] = {vertex(i, j), vertex(i + 1, j), vertex(i, j + 1), vertex(i + 1, j + 1)};
      for (int t = 0; t < 2; ++t) {
        const int* corners = kTriangleCorners[diagonal][t];
        std::array<int, 3> ids;
        Eigen::Matrix<double, 3, 2> local;
        for (int k = 0; k < 3; ++k) {
          ids[static_cast<size_t>(k)] = squareVertices[corners[k]];
          local.row(k) << (corners[k] & 1) * h, (corners[k] >> 1) * h;
        }
        mesh.triangleVertices.push_back(ids);
        mesh.triangleCorners.push_back(local);
        mesh.triangleCells.push_back(row * cols + i / K);
      }
    }
  }
  return mesh;
}

double gradedRingRatio(int raysPerSide) { return std::exp(-1.0 / raysPerSide); }

int gradedLayersFor(int raysPerSide, double innerRadius) {
  if (!(innerRadius > 0)) throw std::invalid_argument("graded cell mesh: inner radius must be > 0");
  if (innerRadius >= 0.5) return 1;
  // ½σ^L ≤ r  ⇔  L ≥ m·ln(1/(2r)); the small slack absorbs round-off at exact powers.
  return std::max(1, static_cast<int>(std::ceil(raysPerSide * std::log(0.5 / innerRadius) - 1e-9)));
}

double gradedInnerRadius(const GradedMeshLevel& level) {
  return 0.5 * std::exp(-static_cast<double>(level.layers) / level.raysPerSide);
}

long gradedVertexCount(int rows, int cols, const GradedMeshLevel& level) {
  // Per quarter: (2m − 1)·L interior points, L on each of its two edge rays
  // (shared by 2 quarters), m − 1 on each midline side (shared by 2), the cell
  // centre (4), two edge midpoints (4 each) and the corner (4): 2mL + m.
  return 4L * rows * cols * level.raysPerSide * (2L * level.layers + 1);
}

CellMesh gradedCellMesh(int rows, int cols, const GradedMeshLevel& level) {
  checkTile(rows, cols);
  const int m = level.raysPerSide, L = level.layers;
  if (m < 1 || L < 1)
    throw std::invalid_argument("graded cell mesh: rays per side and layers must be >= 1, got " + std::to_string(m) +
                                " and " + std::to_string(L));
  std::vector<double> radii(static_cast<size_t>(L) + 1);
  for (int l = 0; l <= L; ++l) radii[static_cast<size_t>(l)] = 0.5 * std::exp(-static_cast<double>(l) / m);

  GradedVertexNames names(rows, cols, m, L);
  CellMesh mesh;
  const size_t triangles = static_cast<size_t>(rows) * static_cast<size_t>(cols) * 4 * static_cast<size_t>(4 * m * L + 2 * m);
  mesh.triangleVertices.reserve(triangles);
  mesh.triangleCorners.reserve(triangles);
  mesh.triangleCells.reserve(triangles);
  mesh.triangleLatticeCorners.reserve(triangles);
  mesh.triangleRings.reserve(triangles);
  mesh.ringCount = L + 1;
  mesh.latticeCornerCount = rows * cols;
  mesh.raysPerSide = m;

  for (int cy = 0; cy < rows; ++cy) {      // cell [cx, cx+1] x [cy, cy+1], y up
    for (int cx = 0; cx < cols; ++cx) {
      const int cell = (rows - 1 - cy) * cols + cx;
      for (int quarter = 0; quarter < 4; ++quarter) {
        const int i = cx + (quarter & 1), j = cy + (quarter >> 1);  // the quarter's lattice corner
        const int sx = (quarter & 1) ? -1 : 1, sy = (quarter >> 1) ? -1 : 1;  // into the cell
        const int latticeCorner = (j % rows) * cols + i % cols;
        // Ray k in [0, 2m] at L∞ radius s: (s, s·k/m) for k ≤ m, (s·(2m−k)/m, s) beyond.
        auto point = [&](int k, double s) {
          const double a = k <= m ? s : s * (2 * m - k) / m, b = k <= m ? s * k / m : s;
          return Vector2(sx * a, sy * b);
        };
        // Orientation is irrelevant: the stiffness and ∫∇x_i use |area| and
        // products of two gradients, whose signs cancel.
        auto addTriangle = [&](int a, int b, int c, const Vector2& pa, const Vector2& pb, const Vector2& pc,
                               int ring) {
          Eigen::Matrix<double, 3, 2> local;
          local.row(0) = pa.transpose();
          local.row(1) = pb.transpose();
          local.row(2) = pc.transpose();
          mesh.triangleVertices.push_back({a, b, c});
          mesh.triangleCorners.push_back(local);
          mesh.triangleCells.push_back(cell);
          mesh.triangleLatticeCorners.push_back(latticeCorner);
          mesh.triangleRings.push_back(ring);
        };
        for (int l = 0; l < L; ++l) {
          const double outer = radii[static_cast<size_t>(l)], inner = radii[static_cast<size_t>(l) + 1];
          for (int k = 0; k < 2 * m; ++k) {
            const int a = names.id(i, j, sx, sy, k, l), b = names.id(i, j, sx, sy, k + 1, l);
            const int c = names.id(i, j, sx, sy, k + 1, l + 1), d = names.id(i, j, sx, sy, k, l + 1);
            const Vector2 pa = point(k, outer), pb = point(k + 1, outer);
            const Vector2 pc = point(k + 1, inner), pd = point(k, inner);
            // Quad a (outer k), b (outer k+1), c (inner k+1), d (inner k), split
            // along its shorter diagonal.
            if ((pa - pc).squaredNorm() <= (pb - pd).squaredNorm()) {
              addTriangle(a, d, c, pa, pd, pc, l);
              addTriangle(a, c, b, pa, pc, pb, l);
            } else {
              addTriangle(a, d, b, pa, pd, pb, l);
              addTriangle(d, c, b, pd, pc, pb, l);
            }
          }
        }
        const int centre = names.id(i, j, sx, sy, 0, L + 1);
        for (int k = 0; k < 2 * m; ++k) {
          const int a = names.id(i, j, sx, sy, k, L), b = names.id(i, j, sx, sy, k + 1, L);
          addTriangle(centre, a, b, Vector2::Zero(), point(k, radii[static_cast<size_t>(L)]),
                      point(k + 1, radii[static_cast<size_t>(L)]), L);
        }
      }
    }
  }
  mesh.vertexCount = names.count();
  if (mesh.vertexCount != gradedVertexCount(rows, cols, level))
    throw std::logic_error("graded cell mesh: vertex count " + std::to_string(mesh.vertexCount) + ", expected " +
                           std::to_string(gradedVertexCount(rows, cols, level)));
  return mesh;
}

}  // namespace blot::stain
