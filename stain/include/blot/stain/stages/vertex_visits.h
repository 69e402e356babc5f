#pragma once
/// The visit of a masked per-vertex stage loop: every vertex 0..n−1, or only
/// the vertices of a list (`among`, a superset of those the stage's mask
/// marks: the liquid band), so a stage on a small stain costs what the stain
/// does, not #V. The stages that take `among` update each vertex from values
/// no other vertex's update writes, so the visit order changes no bit.
#include <vector>

namespace blot::stain {

/// Vertices the loop visits: n, or the list's size.
inline int visitCount(int n, const std::vector<int>* among) {
  return among != nullptr ? static_cast<int>(among->size()) : n;
}
/// The k-th visited vertex (k itself without a list).
inline int visited(int k, const std::vector<int>* among) {
  return among != nullptr ? (*among)[static_cast<size_t>(k)] : k;
}

}  // namespace blot::stain
