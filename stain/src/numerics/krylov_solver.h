// The conjugate gradients on vertex pairs (design note: stages/diffusion.cpp):
// the active set, the deterministic chunked sums, the Jacobi-PCG on a growing
// support, and the band's symmetric Gauss–Seidel PCG.
#pragma once

#include <blot/stain/stages/diffusion.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <vector>

#include "numerics/compensated_sum.h"
#include "numerics/threads.h"

namespace blot::stain::diffusion_internal {

// See pairConjugateGradients: the Krylov support stops growing while the
// outermost ring's next correction is below this fraction of the flush level.
constexpr double kGrowthFraction = 0.1;

// The vertices a restricted Krylov solve works on: a breadth-first list
// (capacity #V, no allocation) with a membership mark per vertex, grown one
// ring at a time along the matrix pattern (= the one-ring for P1 operators).
class ActiveSet {
 public:
  ActiveSet(std::vector<int>& list, std::vector<char>& marks) : list_(list.data()), marks_(marks.data()) {}
  void add(int v) {
    if (!marks_[v]) {
      marks_[v] = 1;
      list_[size_++] = v;
    }
  }
  /// Adds every unmarked neighbour of the outermost layer (the whole set the
  /// first time); returns how many were added.
  int grow(const int* outer, const int* inner) {
    const int begin = layerBegin_, end = size_;
    layerBegin_ = end;
    for (int k = begin; k < end; ++k) {
      const int i = list_[k];
      for (int p = outer[i]; p < outer[i + 1]; ++p) add(inner[p]);
    }
    return size_ - end;
  }
  /// Removes the marks (the list's contents stay readable until the next add).
  void clearMarks() {
    for (int k = 0; k < size_; ++k) marks_[list_[k]] = 0;
  }
  int size() const { return size_; }
  const int* list() const { return list_; }
  /// Membership marks, #V (1: in the set).
  const char* marks() const { return marks_; }
  /// Start of the outermost layer (the last ring grow() added) in list().
  int layerBegin() const { return layerBegin_; }

 private:
  int* list_;
  char* marks_;
  int size_ = 0, layerBegin_ = 0;
};

struct KrylovOutcome {
  int iterations = 0;
  bool converged = false;
  bool finite = true;  ///< false: a non-finite right-hand side (the caller reports NonFinite)
};

// Runs body(begin, end, sums) over the active rows [0, count) in fixed chunks
// of kKrylovChunkRows, on OpenMP threads from kKrylovParallelRows rows on;
// each chunk's kSums partial sums go to partials[chunk * kSums + s] and are
// added in chunk order into total. The chunking depends on count only, so
// the sums (and the whole solve) are the same to the bit for any thread
// count, threaded or not; with one chunk it is the plain serial sum.
template <int kSums, typename Body>
void chunkedSums(int count, double* partials, double total[kSums], const Body& body) {
  const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
  threads::runLoop(count >= kKrylovParallelRows, [&] {
#pragma omp for schedule(static)
    for (int c = 0; c < chunks; ++c) {
      double sums[kSums] = {};
      body(c * kKrylovChunkRows, std::min(count, (c + 1) * kKrylovChunkRows), sums);
      for (int k = 0; k < kSums; ++k) partials[c * kSums + k] = sums[k];
    }
  });
  for (int k = 0; k < kSums; ++k) total[k] = 0.0;
  for (int c = 0; c < chunks; ++c) {
    for (int k = 0; k < kSums; ++k) total[k] += partials[c * kSums + k];
  }
}

// Jacobi-PCG on pairs: every vector holds two numbers per vertex (v[2i],
// v[2i + 1]). kComplex = false: two independent real systems A x_c = M x0_c
// (solvent and solute) sharing each pass over A, each with its own α, β and
// stopping test. kComplex = true: one Hermitian system on (Re, Im); column i
// holds A(j, i) = conj(A(i, j)), so row i of A p is Σ conj(a) p_j over column
// i, and α, β use the sums over both components (Re pᴴq = p·q on pairs).
// Runs on the active set `active` (seeded by the caller with every row whose
// residual can be non-zero); each iteration first adds the next ring (the
// support of A p) while the outermost ring's correction matters (a fixed
// domain, the velocity's band, runs bandConjugateGradients instead).
// x0 (component c of vertex j at x0[c][j * x0Stride]) is read at every
// neighbour of the active rows: zeros outside.
// x, r, p must be zero outside `active` on entry; x is written on the active
// rows only. mass[c] = compensated Σ_{active} A_i x0_c,i. `partials`: room
// for kKrylovPartialsPerChunk numbers per chunk of the largest active set
// (chunkedSums). Every row loop writes only its own rows, and reads of p at
// neighbours happen in the product loop, which writes q only.
template <bool kComplex>
KrylovOutcome pairConjugateGradients(const int* outer, const int* inner, const double* values,
                                     const double* inverseDiagonal, const double* area, const double* const x0[2],
                                     int x0Stride, double* __restrict x, double* __restrict r,
                                     double* __restrict p, double* __restrict q, ActiveSet& active,
                                     double mass[2], double* partials) {
  KrylovOutcome outcome;
  double rz[2] = {0, 0}, rr[2] = {0, 0}, bb[2] = {0, 0}, largest[2] = {0, 0};
  {
    const int* list = active.list();
    const int count = active.size();
    // Per chunk: rz, rr, bb (two each), the two compensated masses as (sum,
    // compensation) and the two largest |x0| (max: order-free).
    double sums[kKrylovPartialsPerChunk];
    chunkedSums<kKrylovPartialsPerChunk>(count, partials, sums, [&](int begin, int end, double* out) {
      CompensatedSum massSum[2];
      double top0 = 0.0, top1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        double a0 = 0.0, a1 = 0.0;  // (A x0)_i
        for (int e = outer[i]; e < outer[i + 1]; ++e) {
          const size_t j = static_cast<size_t>(inner[e]) * static_cast<size_t>(x0Stride);
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            a0 += re * x0[0][j] + im * x0[1][j];
            a1 += re * x0[1][j] - im * x0[0][j];
          } else {
            a0 += values[e] * x0[0][j];
            a1 += values[e] * x0[1][j];
          }
        }
        const size_t ii = static_cast<size_t>(i) * static_cast<size_t>(x0Stride);
        const double invD = inverseDiagonal[i];
        const double v0 = x0[0][ii], v1 = x0[1][ii];
        const double b0 = area[i] * v0, b1 = area[i] * v1;
        const double r0 = b0 - a0, r1 = b1 - a1;
        x[2 * i] = v0;
        x[2 * i + 1] = v1;
        r[2 * i] = r0;
        r[2 * i + 1] = r1;
        p[2 * i] = invD * r0;
        p[2 * i + 1] = invD * r1;
        out[0] += invD * r0 * r0;
        out[1] += invD * r1 * r1;
        out[2] += r0 * r0;
        out[3] += r1 * r1;
        out[4] += b0 * b0;
        out[5] += b1 * b1;
        massSum[0].add(b0);
        massSum[1].add(b1);
        top0 = std::max(top0, std::abs(v0));
        top1 = std::max(top1, std::abs(v1));
      }
      out[6] = massSum[0].value();
      out[7] = massSum[1].value();
      out[8] = top0;
      out[9] = top1;
    });
    rz[0] = sums[0], rz[1] = sums[1], rr[0] = sums[2], rr[1] = sums[3], bb[0] = sums[4], bb[1] = sums[5];
    // The masses and maxima are combined from the chunks' own values, not
    // the plain sums chunkedSums made of them.
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
    CompensatedSum massSum[2];
    for (int c = 0; c < chunks; ++c) {
      const double* chunk = partials + c * kKrylovPartialsPerChunk;
      massSum[0].add(chunk[6]);
      massSum[1].add(chunk[7]);
      largest[0] = std::max(largest[0], chunk[8]);
      largest[1] = std::max(largest[1], chunk[9]);
    }
    mass[0] = massSum[0].value();
    mass[1] = massSum[1].value();
  }
  if (kComplex) largest[0] = largest[1] = std::max(largest[0], largest[1]);
  // Growth stops while the next correction on the outermost ring, D⁻¹r, is
  // below kGrowthFraction × kIterativeTolerance × max |x0|: what it would add
  // further out is smaller still and would be flushed anyway (design note).
  const double growthFloor[2] = {kGrowthFraction * kIterativeTolerance * largest[0],
                                 kGrowthFraction * kIterativeTolerance * largest[1]};
  if (!std::isfinite(bb[0] + bb[1] + rr[0] + rr[1])) {
    outcome.finite = false;
    return outcome;
  }
  if (kComplex) {  // one system: combined sums in slot 0
    rz[0] += rz[1];
    rr[0] += rr[1];
    bb[0] += bb[1];
  }
  const int systems = kComplex ? 1 : 2;
  const double tolerance2 = kIterativeTolerance * kIterativeTolerance;
  bool done[2] = {rr[0] <= tolerance2 * bb[0], kComplex || rr[1] <= tolerance2 * bb[1]};
  for (int iteration = 1; iteration <= kMaxIterations; ++iteration) {
    if (done[0] && done[1]) {
      outcome.converged = true;
      return outcome;
    }
    bool reaches = false;
    for (int k = active.layerBegin(); k < active.size() && !reaches; ++k) {
      const int i = active.list()[k];
      reaches = std::abs(inverseDiagonal[i] * r[2 * i]) >= growthFloor[0] ||
                std::abs(inverseDiagonal[i] * r[2 * i + 1]) >= growthFloor[1];
    }
    if (reaches) active.grow(outer, inner);
    const int* list = active.list();
    const int count = active.size();
    // q = A p on the active rows, and pᵀq per component.
    double pq[2];
    chunkedSums<2>(count, partials, pq, [&](int begin, int end, double* out) {
      double pq0 = 0.0, pq1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        // Two partial sums per component (even and odd entries): halves the
        // chain of dependent additions that bounds this loop.
        double s0 = 0.0, s1 = 0.0, t0 = 0.0, t1 = 0.0;
        const int rowBegin = outer[i], rowEnd = outer[i + 1];
        int e = rowBegin;
        for (; e + 1 < rowEnd; e += 2) {
          const int j = inner[e], l = inner[e + 1];
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            const double re2 = values[2 * e + 2], im2 = values[2 * e + 3];
            s0 += re * p[2 * j] + im * p[2 * j + 1];
            s1 += re * p[2 * j + 1] - im * p[2 * j];
            t0 += re2 * p[2 * l] + im2 * p[2 * l + 1];
            t1 += re2 * p[2 * l + 1] - im2 * p[2 * l];
          } else {
            s0 += values[e] * p[2 * j];
            s1 += values[e] * p[2 * j + 1];
            t0 += values[e + 1] * p[2 * l];
            t1 += values[e + 1] * p[2 * l + 1];
          }
        }
        if (e < rowEnd) {
          const int j = inner[e];
          if (kComplex) {
            const double re = values[2 * e], im = values[2 * e + 1];
            s0 += re * p[2 * j] + im * p[2 * j + 1];
            s1 += re * p[2 * j + 1] - im * p[2 * j];
          } else {
            s0 += values[e] * p[2 * j];
            s1 += values[e] * p[2 * j + 1];
          }
        }
        s0 += t0;
        s1 += t1;
        q[2 * i] = s0;
        q[2 * i + 1] = s1;
        pq0 += p[2 * i] * s0;
        pq1 += p[2 * i + 1] * s1;
      }
      out[0] = pq0;
      out[1] = pq1;
    });
    if (kComplex) pq[0] += pq[1];
    double alpha[2] = {0.0, 0.0};
    for (int c = 0; c < systems; ++c) {
      if (done[c]) continue;
      alpha[c] = rz[c] / pq[c];
      if (!(pq[c] > 0.0) || !std::isfinite(alpha[c])) return outcome;  // breakdown: not converged
    }
    if (kComplex) alpha[1] = alpha[0];
    // x += α p, r −= α q, and the new rᵀD⁻¹r, rᵀr per component.
    double next[4];
    chunkedSums<4>(count, partials, next, [&](int begin, int end, double* out) {
      double z0 = 0.0, z1 = 0.0, s0 = 0.0, s1 = 0.0;
      for (int k = begin; k < end; ++k) {
        const int i = list[k];
        x[2 * i] += alpha[0] * p[2 * i];
        x[2 * i + 1] += alpha[1] * p[2 * i + 1];
        const double r0 = r[2 * i] - alpha[0] * q[2 * i];
        const double r1 = r[2 * i + 1] - alpha[1] * q[2 * i + 1];
        r[2 * i] = r0;
        r[2 * i + 1] = r1;
        z0 += inverseDiagonal[i] * r0 * r0;
        z1 += inverseDiagonal[i] * r1 * r1;
        s0 += r0 * r0;
        s1 += r1 * r1;
      }
      out[0] = z0;
      out[1] = z1;
      out[2] = s0;
      out[3] = s1;
    });
    double nextRz[2] = {next[0], next[1]}, nextRr[2] = {next[2], next[3]};
    if (kComplex) {
      nextRz[0] += nextRz[1];
      nextRr[0] += nextRr[1];
    }
    double beta[2] = {0.0, 0.0};
    for (int c = 0; c < systems; ++c) {
      if (!done[c] && rz[c] != 0.0) beta[c] = nextRz[c] / rz[c];
      if (!done[c]) {
        rz[c] = nextRz[c];
        rr[c] = nextRr[c];
      }
    }
    if (kComplex) beta[1] = beta[0];
    // p = D⁻¹ r + β p (no sums).
    const int chunks = (count + kKrylovChunkRows - 1) / kKrylovChunkRows;
    threads::runLoop(count >= kKrylovParallelRows, [&] {
#pragma omp for schedule(static)
      for (int c = 0; c < chunks; ++c) {
        const int end = std::min(count, (c + 1) * kKrylovChunkRows);
        for (int k = c * kKrylovChunkRows; k < end; ++k) {
          const int i = list[k];
          const double invD = inverseDiagonal[i];
          p[2 * i] = invD * r[2 * i] + beta[0] * p[2 * i];
          p[2 * i + 1] = invD * r[2 * i + 1] + beta[1] * p[2 * i + 1];
        }
      }
    });
    outcome.iterations = iteration;
    for (int c = 0; c < systems; ++c) {
      if (!std::isfinite(rr[c])) return outcome;
      done[c] = done[c] || rr[c] <= tolerance2 * bb[c];
    }
  }
  outcome.converged = done[0] && done[1];
  return outcome;
}

// Symmetric Gauss–Seidel–preconditioned CG on one Hermitian system (the
// connection system of the velocity) over a fixed domain `domain` (the band
// less its outer ring), the values u0 of the vertices outside it fixed
// (Dirichlet): A δ = M u0 − A u0 on the domain, x = u0 + δ written on its
// rows (pairs, vertex-indexed). The domain's rows are copied in its order
// and split at the diagonal (DomainRows), A = C + Cᴴ − D with C = D + L, and
// CG runs on C⁻¹ A C⁻ᴴ with z = D r̂ as its preconditioning: Eisenstat's form,
// whose product t + C⁻¹(p − D t), t = C⁻ᴴ p, costs one sweep over each
// triangle, about one pass over A, as the Jacobi-PCG's product does, in
// about half the iterations (design note). It stops when the true residual
// ‖r‖₂ = ‖C r̂‖₂ ≤ kIterativeTolerance ‖M u0‖₂, tested from the iteration on
// which the transformed one first says so. Serial: the sweeps have an order,
// and one order for any thread count keeps the bits. r, p, t, y: pair
// vectors of 2 × the domain's size, used by place in the domain and zero
// there on return; `rows.position` is −1 again on return.
KrylovOutcome bandConjugateGradients(const int* outer, const int* inner, const double* values,
                                     const double* inverseDiagonal, const double* area, const double* u0,
                                     const ActiveSet& domain, double* x, double* r, double* p, double* t,
                                     double* y, DomainRows& rows);

// Zeroes pair vectors (two numbers per vertex) on the active rows, their
// invariant between calls, and removes the marks.
void releaseActive(ActiveSet& active, std::initializer_list<double*> vectors);

inline double realPart(double v) { return v; }
inline double realPart(const Complex& v) { return v.real(); }

// Column j of a compressed system's Jacobi preconditioner: 1 / A_jj into
// inverse[j] (0 where it is not positive); returns A_jj / A_j − 1 = h L_jj /
// A_j, whose max over j from 0 is the system's stiffness ratio.
template <typename Scalar>
double inverseDiagonalAt(const Eigen::SparseMatrix<Scalar>& system, const Vector& areas, int j, Vector& inverse) {
  double diagonal = 0.0;
  for (int p = system.outerIndexPtr()[j]; p < system.outerIndexPtr()[j + 1]; ++p) {
    if (system.innerIndexPtr()[p] == j) diagonal = realPart(system.valuePtr()[p]);
  }
  inverse[j] = diagonal > 0.0 ? 1.0 / diagonal : 0.0;
  return diagonal / areas[j] - 1.0;
}


}  // namespace blot::stain::diffusion_internal
