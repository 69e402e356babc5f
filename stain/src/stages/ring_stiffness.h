#pragma once
// Where each ring entry of a vertex sits in a stiffness matrix (its pattern
// is the topology's), for the passes that read the diffusion's edge fluxes
// (diffusive momentum, solute) or the velocity stiffness (film viscosity).
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/types.h>

#include <vector>

namespace blot::stain {

// Vertex i's ring entries' positions in the stiffness's column i (its
// pattern is the topology's and never changes; filled on first use, and
// again should a check find it stale).
template <class Matrix>
void fillStiffnessEntries(const SurfaceTopology& topology, const Matrix& L, int i, std::vector<int>& entries) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
    const int j = neighbors[static_cast<size_t>(m)];
    int k = outer[i];
    while (k < outer[i + 1] && inner[k] != j) ++k;
    entries[static_cast<size_t>(m)] = k < outer[i + 1] ? k : -1;  // −1: no entry (a zero-area ring)
  }
}

// Fills vertex i's entries unless its first one is known to be current.
template <class Matrix>
void ensureStiffnessEntries(const SurfaceTopology& topology, const Matrix& L, int i, std::vector<int>& entries) {
  const int begin = topology.ringOffsets()[static_cast<size_t>(i)];
  if (begin == topology.ringOffsets()[static_cast<size_t>(i) + 1]) return;  // an isolated vertex
  const int first = entries[static_cast<size_t>(begin)];
  if (first < 0 || L.innerIndexPtr()[first] != topology.ringNeighbors()[static_cast<size_t>(begin)])
    fillStiffnessEntries(topology, L, i, entries);
}

}  // namespace blot::stain
