// The Krylov solver's non-template pieces (the band's preconditioned CG,
// releaseActive).
#include "numerics/krylov_solver.h"

#include <cmath>
#include <cstddef>

namespace blot::stain::diffusion_internal {

namespace {

// Adds Σ A(k, j) v_j over entries [begin, end) of a place's row in
// DomainRows (complex on pairs: entry (re, im), v_j at 2j, 2j + 1).
inline void addRow(const int* columns, const double* entry, int begin, int end, const double* v, double& s0,
                   double& s1) {
  for (int q = begin; q < end; ++q) {
    const int j = columns[q];
    const double re = entry[2 * q], im = entry[2 * q + 1];
    s0 += re * v[2 * j] - im * v[2 * j + 1];
    s1 += re * v[2 * j + 1] + im * v[2 * j];
  }
}

}  // namespace

KrylovOutcome bandConjugateGradients(const int* outer, const int* inner, const double* values,
                                     const double* inverseDiagonal, const double* area, const double* u0,
                                     const ActiveSet& domain, double* x, double* r, double* p, double* t,
                                     double* y, DomainRows& rows) {
  KrylovOutcome outcome;
  const int count = domain.size();
  const int* list = domain.list();
  int* position = rows.position.data();
  size_t entries = 0;
  for (int k = 0; k < count; ++k) entries += static_cast<size_t>(outer[list[k] + 1] - outer[list[k]]);
  if (entries > rows.columns.size()) {  // sized without the mesh's edges (DiffusionScratch::resize)
    rows.columns.resize(entries);
    rows.values.resize(2 * entries);
  }
  for (int k = 0; k < count; ++k) position[list[k]] = k;
  // The domain's rows, below the diagonal first; r = M u0 − A u0 (A u0 over
  // every neighbour, the fixed ones included), and b = M u0 into p for the
  // transformed tolerance below.
  int* starts = rows.starts.data();
  int* splits = rows.splits.data();
  int* columns = rows.columns.data();
  double* entry = rows.values.data();
  double bb = 0.0, rr = 0.0;
  int filled = 0;
  for (int k = 0; k < count; ++k) {
    const int i = list[k];
    starts[k] = filled;
    double a0 = 0.0, a1 = 0.0;
    for (int below = 1; below >= 0; --below) {
      if (!below) splits[k] = filled;
      for (int e = outer[i]; e < outer[i + 1]; ++e) {
        const int j = inner[e];
        // Row i holds A(i, j) = conj(column i's entry at row j).
        const double re = values[2 * e], im = -values[2 * e + 1];
        if (below) {
          a0 += re * u0[2 * j] - im * u0[2 * j + 1];
          a1 += re * u0[2 * j + 1] + im * u0[2 * j];
        }
        const int place = position[j];
        if (place < 0 || place == k || (place < k) != static_cast<bool>(below)) continue;
        columns[filled] = place;
        entry[2 * filled] = re;
        entry[2 * filled + 1] = im;
        ++filled;
      }
    }
    const double b0 = area[i] * u0[2 * i], b1 = area[i] * u0[2 * i + 1];
    r[2 * k] = b0 - a0;
    r[2 * k + 1] = b1 - a1;
    p[2 * k] = b0;
    p[2 * k + 1] = b1;
    x[2 * i] = u0[2 * i];
    x[2 * i + 1] = u0[2 * i + 1];
    bb += b0 * b0 + b1 * b1;
    rr += r[2 * k] * r[2 * k] + r[2 * k + 1] * r[2 * k + 1];
  }
  starts[count] = filled;
  // out = C⁻¹ f, in place allowed (a place reads only earlier places).
  const auto forward = [&](const double* f, double* out) {
    for (int k = 0; k < count; ++k) {
      double s0 = 0.0, s1 = 0.0;
      addRow(columns, entry, starts[k], splits[k], out, s0, s1);
      const double invD = inverseDiagonal[list[k]];
      out[2 * k] = invD * (f[2 * k] - s0);
      out[2 * k + 1] = invD * (f[2 * k + 1] - s1);
    }
  };
  // D (0 where the system has no positive diagonal, as its inverse is).
  const auto diagonal = [&](int k) {
    const double invD = inverseDiagonal[list[k]];
    return invD > 0.0 ? 1.0 / invD : 0.0;
  };
  const auto finish = [&] {
    for (int k = 0; k < count; ++k) {
      position[list[k]] = -1;
      for (double* v : {r, p, t, y}) v[2 * k] = v[2 * k + 1] = 0.0;
    }
  };
  if (!std::isfinite(bb + rr)) {
    outcome.finite = false;
    finish();
    return outcome;
  }
  const double tolerance2 = kIterativeTolerance * kIterativeTolerance;
  // The transformed system's right-hand side C⁻¹ r and its size against
  // C⁻¹ b's, both in D's norm (the transformed preconditioner multiplies by
  // D: C D⁻¹ Cᴴ = K Kᴴ with K = C D^-½): the cheap test that starts the
  // true one.
  forward(p, p);
  forward(r, r);
  double rz = 0.0, rzb = 0.0;
  for (int k = 0; k < count; ++k) {
    const double d = diagonal(k);
    rzb += d * (p[2 * k] * p[2 * k] + p[2 * k + 1] * p[2 * k + 1]);
    rz += d * (r[2 * k] * r[2 * k] + r[2 * k + 1] * r[2 * k + 1]);
    p[2 * k] = d * r[2 * k];
    p[2 * k + 1] = d * r[2 * k + 1];
  }
  bool done = rr <= tolerance2 * bb, testTrue = false;
  for (int iteration = 1; iteration <= kMaxIterations && !done; ++iteration) {
    // t = C⁻ᴴ p (the upper triangle, last place first).
    for (int k = count - 1; k >= 0; --k) {
      double s0 = 0.0, s1 = 0.0;
      addRow(columns, entry, splits[k], starts[k + 1], t, s0, s1);
      const double invD = inverseDiagonal[list[k]];
      t[2 * k] = invD * (p[2 * k] - s0);
      t[2 * k + 1] = invD * (p[2 * k + 1] - s1);
    }
    // y = C⁻¹ (p − D t), so the product is t + y, and pᴴ(t + y).
    double pq = 0.0;
    for (int k = 0; k < count; ++k) {
      double s0 = 0.0, s1 = 0.0;
      addRow(columns, entry, starts[k], splits[k], y, s0, s1);
      const double invD = inverseDiagonal[list[k]];
      y[2 * k] = invD * (p[2 * k] - s0) - t[2 * k];
      y[2 * k + 1] = invD * (p[2 * k + 1] - s1) - t[2 * k + 1];
      pq += p[2 * k] * (t[2 * k] + y[2 * k]) + p[2 * k + 1] * (t[2 * k + 1] + y[2 * k + 1]);
    }
    const double alpha = rz / pq;
    if (!(pq > 0.0) || !std::isfinite(alpha)) break;  // breakdown: not converged
    // x += α C⁻ᴴ p = α t; r̂ −= α (t + y); the new r̂ᴴ D r̂.
    double next = 0.0;
    for (int k = 0; k < count; ++k) {
      const int i = list[k];
      x[2 * i] += alpha * t[2 * k];
      x[2 * i + 1] += alpha * t[2 * k + 1];
      r[2 * k] -= alpha * (t[2 * k] + y[2 * k]);
      r[2 * k + 1] -= alpha * (t[2 * k + 1] + y[2 * k + 1]);
      next += diagonal(k) * (r[2 * k] * r[2 * k] + r[2 * k + 1] * r[2 * k + 1]);
    }
    const double beta = next / rz;
    rz = next;
    for (int k = 0; k < count; ++k) {
      const double d = diagonal(k);
      p[2 * k] = d * r[2 * k] + beta * p[2 * k];
      p[2 * k + 1] = d * r[2 * k + 1] + beta * p[2 * k + 1];
    }
    outcome.iterations = iteration;
    if (!std::isfinite(rz)) break;
    testTrue = testTrue || rz <= tolerance2 * rzb;
    if (!testTrue) continue;
    // The true residual C r̂ = D r̂ + L r̂.
    rr = 0.0;
    for (int k = 0; k < count; ++k) {
      const double d = diagonal(k);
      double s0 = d * r[2 * k], s1 = d * r[2 * k + 1];
      addRow(columns, entry, starts[k], splits[k], r, s0, s1);
      rr += s0 * s0 + s1 * s1;
    }
    done = rr <= tolerance2 * bb;
  }
  outcome.converged = done;
  finish();
  return outcome;
}

void releaseActive(ActiveSet& active, std::initializer_list<double*> vectors) {
  const int* list = active.list();
  for (double* v : vectors) {
    for (int k = 0; k < active.size(); ++k) {
      v[2 * list[k]] = 0.0;
      v[2 * list[k] + 1] = 0.0;
    }
  }
  active.clearMarks();
}

}  // namespace blot::stain::diffusion_internal
