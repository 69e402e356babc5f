// Stage "diffuse", the velocity's part in the film model: the in-plane
// viscosity weighted by the liquid's mass (stages/film_viscosity.h).
#include <blot/stain/stages/film_viscosity.h>

#include <algorithm>
#include <cmath>

#include "numerics/threads.h"
#include "stages/ring_stiffness.h"

namespace blot::stain {

namespace {

constexpr int kMaxViscosityIterations = 500;
constexpr double kViscosityTolerance = 1e-11;  // residual / right-hand side, max norms
// The product on the calling thread's OpenMP threads from this many film rows
// (below it a region's start costs about what the rows do).
constexpr int kParallelRows = 20000;

// ā b without libgcc's complex multiply (its NaN path).
inline Complex conjugateTimes(Complex a, Complex b) {
  return Complex(a.real() * b.real() + a.imag() * b.imag(), a.real() * b.imag() - a.imag() * b.real());
}
inline Complex complexTimes(Complex a, Complex b) {
  return Complex(a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real());
}

}  // namespace

void FilmViscosityScratch::resize(int vertexCount, int ringEntries) {
  vertices.clear();
  vertices.reserve(static_cast<size_t>(vertexCount));
  position.assign(static_cast<size_t>(vertexCount), -1);
  entries.assign(static_cast<size_t>(ringEntries), -1);
  for (ComplexVector* v : {&x, &r, &z, &p, &q}) v->setZero(vertexCount);
  mass.setZero(vertexCount);
  diagonal.setZero(vertexCount);
  couplings.setZero(ringEntries);
  columns.assign(static_cast<size_t>(ringEntries), 0);
  rowStarts.assign(static_cast<size_t>(vertexCount) + 1, 0);
}

FilmViscosityReport diffuseFilmVelocity(const StepContext& ctx, const SurfaceTopology& topology,
                                        const IntrinsicGeometry& intrinsic, const std::vector<int>& candidates,
                                        FilmViscosityScratch& scratch, StainState& state) {
  FilmViscosityReport report;
  const ComplexSparseMatrix& L = intrinsic.velocityStiffness;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const Complex* values = L.valuePtr();
  const double* areas = intrinsic.vertexDualAreas.data();
  const double h = ctx.h;
  std::vector<int>& vertices = scratch.vertices;
  std::vector<int>& position = scratch.position;
  const auto liquid = [&](int i) { return state.solvent[i] + state.solute[i]; };

  // The film's vertices in index order (the solve's reads then stay near
  // each other in memory), each once.
  vertices.clear();
  for (const int i : candidates)
    if (liquid(i) > 0.0 && position[static_cast<size_t>(i)] < 0) {
      position[static_cast<size_t>(i)] = 0;
      vertices.push_back(i);
    }
  std::sort(vertices.begin(), vertices.end());
  const int n = static_cast<int>(vertices.size());
  for (int k = 0; k < n; ++k) position[static_cast<size_t>(vertices[static_cast<size_t>(k)])] = k;
  report.vertices = n;
  const auto release = [&] {
    for (const int i : vertices) position[static_cast<size_t>(i)] = -1;
  };
  if (n == 0) return report;

  // The system, as compressed rows over the film: masses, couplings
  // h ρ̄_ij L_ij (row i: L is Hermitian and stored by columns, so L_ij is the
  // conjugate of column i's entry at row j) and the diagonal with
  // Σ_j h ρ̄_ij |L_ij|.
  std::vector<int>& starts = scratch.rowStarts;
  std::vector<int>& columns = scratch.columns;
  int count = 0;
  for (int k = 0; k < n; ++k) {
    const int i = vertices[static_cast<size_t>(k)];
    const size_t ii = static_cast<size_t>(i);
    ensureStiffnessEntries(topology, L, i, scratch.entries);
    const double rho = liquid(i);
    double diagonal = areas[i] * rho;
    scratch.mass[k] = diagonal;
    starts[static_cast<size_t>(k)] = count;
    for (int m = offsets[ii]; m < offsets[ii + 1]; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      const int e = scratch.entries[static_cast<size_t>(m)];
      if (e < 0 || position[static_cast<size_t>(j)] < 0 || values[e] == Complex(0.0, 0.0)) continue;
      const double weight = h * std::min(rho, liquid(j));
      scratch.couplings[count] = weight * std::conj(values[e]);
      columns[static_cast<size_t>(count)] = position[static_cast<size_t>(j)];
      ++count;
      diagonal += weight * std::sqrt(std::norm(values[e]));  // |L_ij| (std::abs calls hypot)
    }
    scratch.diagonal[k] = diagonal;
  }
  starts[static_cast<size_t>(n)] = count;
  // y = (M_ρ + h K_ρ) v on the film (v, y indexed like `vertices`); rows
  // are independent, so threads give the same bits.
  const auto apply = [&](const ComplexVector& v, ComplexVector& y) {
    threads::runLoop(n >= kParallelRows, [&] {
#pragma omp for schedule(static)
      for (int k = 0; k < n; ++k) {
        Complex sum = scratch.diagonal[k] * v[k];
        for (int c = starts[static_cast<size_t>(k)]; c < starts[static_cast<size_t>(k) + 1]; ++c)
          sum += complexTimes(scratch.couplings[c], v[columns[static_cast<size_t>(c)]]);
        y[k] = sum;
      }
    });
  };
  const auto maxNorm = [&](const ComplexVector& v) {
    double largest = 0.0;
    for (int k = 0; k < n; ++k) largest = std::max(largest, std::norm(v[k]));
    return std::sqrt(largest);
  };

  // Preconditioned CG from u: b = M_ρ u.
  ComplexVector& x = scratch.x;
  ComplexVector& r = scratch.r;
  ComplexVector& z = scratch.z;
  ComplexVector& p = scratch.p;
  ComplexVector& q = scratch.q;
  for (int k = 0; k < n; ++k) x[k] = state.velocities[vertices[static_cast<size_t>(k)]];
  apply(x, q);
  double rhsNorm = 0.0;
  for (int k = 0; k < n; ++k) {
    const Complex b = scratch.mass[k] * x[k];
    rhsNorm = std::max(rhsNorm, std::sqrt(std::norm(b)));
    r[k] = b - q[k];
  }
  const double target = kViscosityTolerance * rhsNorm;
  double rz = 0.0;
  for (int k = 0; k < n; ++k) {
    z[k] = r[k] / scratch.diagonal[k];
    p[k] = z[k];
    rz += conjugateTimes(r[k], z[k]).real();
  }
  report.converged = !(maxNorm(r) > target);
  while (!report.converged && report.iterations < kMaxViscosityIterations) {
    ++report.iterations;
    apply(p, q);
    double pq = 0.0;
    for (int k = 0; k < n; ++k) pq += conjugateTimes(p[k], q[k]).real();
    if (!(pq > 0.0)) break;
    const double alpha = rz / pq;
    for (int k = 0; k < n; ++k) {
      x[k] += alpha * p[k];
      r[k] -= alpha * q[k];
    }
    if (!(maxNorm(r) > target)) {
      report.converged = true;
      break;
    }
    double next = 0.0;
    for (int k = 0; k < n; ++k) {
      z[k] = r[k] / scratch.diagonal[k];
      next += conjugateTimes(r[k], z[k]).real();
    }
    const double beta = next / rz;
    rz = next;
    for (int k = 0; k < n; ++k) p[k] = z[k] + beta * p[k];
  }

  // The dissipation, h u⁺ᴴ K u⁺ + ½ (u⁺ − u)ᴴ M (u⁺ − u), then u ← u⁺.
  apply(x, q);
  double dissipation = 0.0;
  for (int k = 0; k < n; ++k) {
    const int i = vertices[static_cast<size_t>(k)];
    const Complex before = state.velocities[i];
    const Complex viscous = q[k] - scratch.mass[k] * x[k];  // h K u⁺
    dissipation += conjugateTimes(x[k], viscous).real() + 0.5 * scratch.mass[k] * std::norm(x[k] - before);
    state.velocities[i] = x[k];
  }
  report.dissipation = dissipation;
  release();
  return report;
}

}  // namespace blot::stain
