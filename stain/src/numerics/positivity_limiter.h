// The mass-conserving positivity limiter (paper sec. 3.2; design note in
// stages/diffusion.cpp): ring-by-ring redistribution of negative densities.
#pragma once

#include <blot/stain/stages/diffusion.h>

#include <algorithm>
#include <utility>

namespace blot::stain::diffusion_internal {

// Most vertices the limiter's ring-by-ring search around one negative vertex
// may visit (about 8 rings on a regular mesh) before the global fallback.
constexpr int kLimiterSearchBudget = 256;

// Neighbours of vertex i as a half-open range of vertex indices (may contain i
// itself, which the limiter skips).
struct NeighborRange {
  const int* begin;
  const int* end;
};

// One-ring from the topology's CSR rings.
struct TopologyRings {
  const SurfaceTopology& topology;
  NeighborRange operator()(int i) const {
    const int* data = topology.ringNeighbors().data();
    return {data + topology.ringOffsets()[static_cast<size_t>(i)],
            data + topology.ringOffsets()[static_cast<size_t>(i) + 1]};
  }
};

// Operator neighbours: the column pattern of the (symmetric) stiffness matrix.
struct MatrixRings {
  const SparseMatrix& matrix;
  NeighborRange operator()(int i) const {
    const int* inner = matrix.innerIndexPtr();
    const int begin = matrix.outerIndexPtr()[i];
    const int end =
        matrix.isCompressed() ? matrix.outerIndexPtr()[i + 1] : begin + matrix.innerNonZeroPtr()[i];
    return {inner + begin, inner + end};
  }
};

// The set of vertices one limiter search has visited: open addressing on the
// stack, with a stamp per search so it is never cleared (no allocation, O(1)
// membership, which a linear scan of the visited list is not once the search
// passes the first ring).
class SearchSet {
 public:
  SearchSet() {
    for (Slot& slot : slots_) slot = {-1, -1};
  }
  void restart() { ++stamp_; }
  /// Inserts v; false if it was already in this search.
  bool insert(int v) {
    unsigned h = (static_cast<unsigned>(v) * 2654435761u) >> (32 - kBits);
    while (slots_[h].stamp == stamp_) {
      if (slots_[h].vertex == v) return false;
      h = (h + 1) & (kCapacity - 1);
    }
    slots_[h] = {v, stamp_};
    return true;
  }

 private:
  static constexpr int kBits = 9;
  static constexpr int kCapacity = 1 << kBits;  // 2 × kLimiterSearchBudget: load ≤ ½
  static_assert(kCapacity >= 2 * kLimiterSearchBudget, "search set too small");
  struct Slot {
    int vertex, stamp;
  };
  Slot slots_[kCapacity];
  int stamp_ = 0;
};

// `candidates` (optional, `candidateCount` vertices): the only vertices that
// can be negative (a CG solve's active set), visited in that order instead of
// scanning all of them in index order.
template <typename Rings>
std::pair<int, double> limit(const Rings& rings, const Vector& dualAreas, Vector& densities,
                             const int* candidates = nullptr, int candidateCount = 0) {
  const int n = static_cast<int>(densities.size());
  double* sigma = densities.data();
  const double* area = dualAreas.data();
  const int visits = candidates != nullptr ? candidateCount : n;
  int corrected = 0;
  for (int v = 0; v < visits; ++v) corrected += sigma[candidates != nullptr ? candidates[v] : v] < 0.0 ? 1 : 0;
  if (corrected == 0) return {0, 0.0};

  double moved = 0.0;
  bool remaining = false;
  int visited[kLimiterSearchBudget];  // the search region, ring by ring (no allocation)
  SearchSet seen;
  for (int v = 0; v < visits; ++v) {
    const int i = candidates != nullptr ? candidates[v] : v;
    if (!(sigma[i] < 0.0)) continue;       // the common case: one comparison
    double deficit = -area[i] * sigma[i];  // kg
    sigma[i] = 0.0;
    {
      // Fast path, bit for bit the first ring of the search below: the ring's
      // entries other than i are distinct (a matrix column), so no visited set
      // is needed when the first ring covers the deficit, as it does for
      // almost every fix (7K per step on the 35K grid of stain_step_bench).
      const NeighborRange ring = rings(i);
      double available = 0.0;
      for (const int* j = ring.begin; j != ring.end; ++j) {
        if (*j != i && sigma[*j] > 0.0) available += area[*j] * sigma[*j];
      }
      if (ring.end - ring.begin < kLimiterSearchBudget && available > 0.0 && available >= deficit) {
        const double keep = 1.0 - deficit / available;
        for (const int* j = ring.begin; j != ring.end; ++j) {
          if (*j != i && sigma[*j] > 0.0) sigma[*j] *= keep;
        }
        moved += deficit;
        continue;
      }
    }
    seen.restart();
    seen.insert(i);
    visited[0] = i;
    int size = 1, levelBegin = 0;
    bool full = false;
    while (deficit > 0.0 && !full) {
      // The next ring: unvisited neighbours of the current one.
      const int levelEnd = size;
      for (int k = levelBegin; k < levelEnd && !full; ++k) {
        const NeighborRange ring = rings(visited[k]);
        for (const int* j = ring.begin; j != ring.end; ++j) {
          if (size == kLimiterSearchBudget) {
            full = true;
            break;
          }
          if (seen.insert(*j)) visited[size++] = *j;
        }
      }
      if (size == levelEnd) break;  // nothing further: the component is exhausted
      double available = 0.0;       // kg held by positive vertices of this ring
      for (int k = levelEnd; k < size; ++k) {
        if (sigma[visited[k]] > 0.0) available += area[visited[k]] * sigma[visited[k]];
      }
      if (available > 0.0) {
        const double taken = std::min(deficit, available);
        const double keep = 1.0 - taken / available;  // exactly 0 when all of it is taken
        for (int k = levelEnd; k < size; ++k) {
          if (sigma[visited[k]] > 0.0) sigma[visited[k]] *= keep;
        }
        deficit -= taken;
        moved += taken;
      }
      levelBegin = levelEnd;
    }
    if (deficit > 0.0) {
      sigma[i] = -deficit / area[i];
      remaining = true;
    }
  }
  if (!remaining) return {corrected, moved};

  // Global fallback, proportional to the mass each positive vertex holds.
  double deficit = 0.0, available = 0.0;
  for (int i = 0; i < n; ++i) {
    if (sigma[i] < 0.0) deficit -= area[i] * sigma[i];
    if (sigma[i] > 0.0) available += area[i] * sigma[i];
  }
  if (deficit == 0.0) return {corrected, moved};
  if (available >= deficit) {
    const double keep = 1.0 - deficit / available;
    for (int i = 0; i < n; ++i) sigma[i] = sigma[i] < 0.0 ? 0.0 : sigma[i] * keep;
    moved += deficit;
  } else {
    // The field's total is negative: no positive solution has this mass.
    // Conserve it anyway (spread the net negative mass over the negatives).
    const double keep = 1.0 - available / deficit;
    for (int i = 0; i < n; ++i) sigma[i] = sigma[i] > 0.0 ? 0.0 : sigma[i] * keep;
    moved += available;
  }
  return {corrected, moved};
}

}  // namespace blot::stain::diffusion_internal
