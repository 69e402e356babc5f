#pragma once
// Shared by the accuracy and stability studies (tests/studies, label "study"):
// CSV output into one directory, wall-clock timing, and the naive schemes the
// studies compare ours against. The naive schemes live here, in the tests, on
// purpose: they are what the solver rejects, kept only to show where they fail.
//
//  - explicit diffusion  σ ← σ − h M⁻¹ L σ  (forward Euler; stable only for
//    h < 2 / λ_max(M⁻¹L), which shrinks like dx² and like 1/θ on slivers);
//  - un-limited upwind advection: the barycentric dual-edge fluxes of
//    density_advection.h, σ_i ← σ_i − h/A_i Σ_j F_ij in one step, with no
//    sub-steps and no cap on what a vertex gives (goes negative for Courant > 1).
//
// Output directory: $BLOT_STUDY_OUT, or ./study_out when unset (created).
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/triangle_mesh.h>
#include <blot/stain/types.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::test {

/// The directory the studies write their CSV files into (created if missing).
inline std::string studyOutputDir() {
  const char* env = std::getenv("BLOT_STUDY_OUT");
  const std::string dir = (env != nullptr && *env != '\0') ? env : "study_out";
  std::filesystem::create_directories(dir);
  return dir;
}

/// 1-minute load average (from /proc/loadavg), or −1 when unavailable.
inline double loadAverage() {
  std::ifstream in("/proc/loadavg");
  double load = -1;
  if (in) in >> load;
  return load;
}

/// A CSV file in studyOutputDir(): header first, then rows of numbers/strings.
/// A comment line records the load average when the file was opened.
class CsvWriter {
 public:
  CsvWriter(const std::string& name, const std::string& header) : path_(studyOutputDir() + "/" + name) {
    file_.open(path_);
    if (!file_) throw std::runtime_error("study: cannot write " + path_);
    file_ << "# load average at start: " << loadAverage() << "\n" << header << "\n";
  }
  ~CsvWriter() { std::printf("  wrote %s\n", path_.c_str()); }
  /// Appends one field (comma-separated; numbers with 6 significant digits).
  CsvWriter& operator<<(double value) {
    separate();
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.6g", value);
    file_ << buffer;
    return *this;
  }
  CsvWriter& operator<<(int value) { return *this << static_cast<double>(value); }
  /// Text field; commas become semicolons so the row keeps its columns.
  CsvWriter& operator<<(const std::string& text) {
    separate();
    std::string clean = text;
    std::replace(clean.begin(), clean.end(), ',', ';');
    file_ << clean;
    return *this;
  }
  CsvWriter& operator<<(const char* text) { return *this << std::string(text); }
  void endRow() {
    file_ << "\n";
    file_.flush();
    first_ = true;
  }

 private:
  void separate() {
    if (!first_) file_ << ",";
    first_ = false;
  }
  std::string path_;
  std::ofstream file_;
  bool first_ = true;
};

/// Wall-clock stopwatch in milliseconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double milliseconds() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

/// Largest eigenvalue of M⁻¹ L (1/s) for the lumped mass `areas` (#V) and the
/// PSD stiffness L (#V by #V), by power iteration on the symmetric form
/// M^{-1/2} L M^{-1/2} (200 iterations from a fixed start: deterministic).
inline double largestDiffusionEigenvalue(const stain::SparseMatrix& stiffness, const stain::Vector& areas) {
  const stain::Vector invSqrt = areas.cwiseSqrt().cwiseInverse();
  stain::Vector x(areas.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = 1.0 + 0.5 * std::sin(1.7 * static_cast<double>(i));
  double lambda = 0;
  for (int k = 0; k < 200; ++k) {
    x.normalize();
    const stain::Vector y = invSqrt.cwiseProduct(stiffness * invSqrt.cwiseProduct(x));
    lambda = x.dot(y);
    x = y;
  }
  return lambda;
}

/// One forward-Euler diffusion step σ ← σ − h M⁻¹ L σ (the naive alternative).
inline void explicitDiffusionStep(const stain::SparseMatrix& stiffness, const stain::Vector& areas, double h,
                                  stain::Vector& density) {
  density -= h * (stiffness * density).cwiseQuotient(areas);
}

/// Barycentric dual-edge normals of a flat mesh (z ignored): per edge (i < j of
/// SurfaceTopology::edgeVertices), N_ij = Σ over its faces of the segment from
/// the edge midpoint to the face centroid, turned 90° to point from i to j (m).
inline Eigen::MatrixX2d barycentricDualNormals(const stain::SurfaceTopology& topology,
                                               const stain::RowVectors3& positions) {
  Eigen::MatrixX2d normals = Eigen::MatrixX2d::Zero(topology.edgeCount(), 2);
  for (int f = 0; f < topology.faceCount(); ++f) {
    const Eigen::Vector2d centroid =
        (positions.row(topology.faces()(f, 0)) + positions.row(topology.faces()(f, 1)) +
         positions.row(topology.faces()(f, 2)))
            .head<2>()
            .transpose() /
        3.0;
    for (int k = 0; k < 3; ++k) {
      const int e = topology.faceEdges()(f, k);
      const int i = topology.edgeVertices()(e, 0), j = topology.edgeVertices()(e, 1);
      const Eigen::Vector2d xi = positions.row(i).head<2>().transpose(), xj = positions.row(j).head<2>().transpose();
      const Eigen::Vector2d d = centroid - 0.5 * (xi + xj);
      Eigen::Vector2d n(d.y(), -d.x());
      if (n.dot(xj - xi) < 0) n = -n;
      normals.row(e) += n.transpose();
    }
  }
  return normals;
}

/// One un-sub-stepped, un-limited upwind step on a flat mesh with the world
/// velocity `velocity` (#V by 2, m/s): F_ij = σ↑ (u_ij · N_ij), σ_i −= h F_ij / A_i,
/// σ_j += h F_ij / A_j. Conserves Σ A σ exactly; positivity only for Courant ≤ 1.
inline void naiveUpwindStep(const stain::SurfaceTopology& topology, const Eigen::MatrixX2d& dualNormals,
                            const stain::Vector& areas, const Eigen::MatrixX2d& velocity, double h,
                            stain::Vector& density) {
  const stain::Vector old = density;
  for (int e = 0; e < topology.edgeCount(); ++e) {
    const int i = topology.edgeVertices()(e, 0), j = topology.edgeVertices()(e, 1);
    const double rate = 0.5 * (velocity.row(i) + velocity.row(j)).dot(dualNormals.row(e));
    const double flux = rate * (rate > 0 ? old[i] : old[j]);
    density[i] -= h * flux / areas[i];
    density[j] += h * flux / areas[j];
  }
}

/// A flat unit square with controlled slivers: `pairs` bands of height 1/pairs,
/// each starting with a row of nx + 1 vertices at x = k/nx and, ε above it, a
/// row shifted by half a cell (x = 0, (k + ½)/nx, 1), ε = (1/2nx) tan θ. The thin
/// band between the two rows is made of caps whose smallest angles are θ
/// (`minAngleDegrees`) and whose largest are 180° − 2θ (negative cotan
/// weights); the rest of each band is ordinary triangles. θ must be in (0, 45°)
/// and ε below the band height.
inline stain::TriangleMesh sliverSquareMesh(int nx, int pairs, double minAngleDegrees) {
  const double dx = 1.0 / nx, dy = 1.0 / pairs;
  const double eps = 0.5 * dx * std::tan(minAngleDegrees * 3.14159265358979323846 / 180.0);
  if (!(minAngleDegrees > 0 && eps < 0.5 * dy)) throw std::invalid_argument("sliverSquareMesh: minAngleDegrees");
  std::vector<std::vector<int>> rows;
  std::vector<Eigen::RowVector3d> points;
  const auto addRow = [&](double y, bool shifted) {
    std::vector<int> row;
    if (!shifted) {
      for (int i = 0; i <= nx; ++i) {
        row.push_back(static_cast<int>(points.size()));
        points.emplace_back(i * dx, y, 0.0);
      }
    } else {
      row.push_back(static_cast<int>(points.size()));
      points.emplace_back(0.0, y, 0.0);
      for (int i = 0; i < nx; ++i) {
        row.push_back(static_cast<int>(points.size()));
        points.emplace_back((i + 0.5) * dx, y, 0.0);
      }
      row.push_back(static_cast<int>(points.size()));
      points.emplace_back(1.0, y, 0.0);
    }
    rows.push_back(row);
  };
  for (int k = 0; k < pairs; ++k) {
    addRow(k * dy, false);
    addRow(k * dy + eps, true);
  }
  addRow(1.0, false);
  std::vector<Eigen::RowVector3i> faces;
  // Zip each pair of consecutive rows (both sorted by x) into a strip,
  // advancing on the side whose next vertex is further left (the bottom on a
  // tie, so the corner triangles at x = 1 keep the smallest angle θ, not θ/2).
  for (size_t r = 0; r + 1 < rows.size(); ++r) {
    const std::vector<int>& bottom = rows[r];
    const std::vector<int>& top = rows[r + 1];
    size_t i = 0, j = 0;
    while (i + 1 < bottom.size() || j + 1 < top.size()) {
      const bool advanceBottom =
          j + 1 == top.size() || (i + 1 < bottom.size() && points[bottom[i + 1]].x() <= points[top[j + 1]].x());
      if (advanceBottom) {
        faces.emplace_back(bottom[i], bottom[i + 1], top[j]);
        ++i;
      } else {
        faces.emplace_back(bottom[i], top[j + 1], top[j]);
        ++j;
      }
    }
  }
  stain::TriangleMesh mesh;
  mesh.vertexPositions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t v = 0; v < points.size(); ++v) mesh.vertexPositions.row(static_cast<Eigen::Index>(v)) = points[v];
  mesh.faces.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) mesh.faces.row(static_cast<Eigen::Index>(f)) = faces[f];
  return mesh;
}

/// Smallest corner angle of a mesh (degrees).
inline double smallestAngleDegrees(const stain::TriangleMesh& mesh) {
  double smallest = 180;
  for (int f = 0; f < mesh.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = mesh.vertexPositions.row(mesh.faces(f, k));
      const Eigen::Vector3d b = mesh.vertexPositions.row(mesh.faces(f, (k + 1) % 3));
      const Eigen::Vector3d c = mesh.vertexPositions.row(mesh.faces(f, (k + 2) % 3));
      const double angle = std::atan2((b - a).cross(c - a).norm(), (b - a).dot(c - a));
      smallest = std::min(smallest, angle * 180.0 / 3.14159265358979323846);
    }
  }
  return smallest;
}

/// Health of a density field against its start: finite, growth of max |σ|, and
/// the most negative value relative to the largest.
struct FieldHealth {
  bool finite = true;
  double growth = 1;       ///< max |σ| / max |σ0|
  double minOverMax = 0;   ///< min σ / max σ (negative: negative mass)
  bool blewUp() const { return !finite || growth > 1e3; }
};

inline FieldHealth fieldHealth(const stain::Vector& density, double initialMax) {
  FieldHealth h;
  h.finite = density.allFinite();
  if (!h.finite) {
    h.growth = std::numeric_limits<double>::infinity();
    h.minOverMax = -std::numeric_limits<double>::infinity();
    return h;
  }
  h.growth = density.cwiseAbs().maxCoeff() / initialMax;
  h.minOverMax = std::min(0.0, density.minCoeff() / density.maxCoeff());
  return h;
}

}  // namespace blot::test
