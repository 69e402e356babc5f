#pragma once
/// The stain's simulation state: one contiguous array per field, indexed by
/// vertex (struct of arrays). Densities are surface densities in kg/m²; the
/// mass a vertex holds is density × its dual area (IntrinsicGeometry).
#include <blot/stain/types.h>

#include <vector>

namespace blot::stain {

struct StainState {
  /// #V tangential liquid velocity in the vertex frame F_i, as the complex
  /// number u_x + i u_y (m/s). Rotating by θ is multiplying by exp(iθ).
  ComplexVector velocities;
  Vector solvent;          ///< #V σ_f, free solvent (kg/m²).
  Vector solute;           ///< #V σ_s, free (dissolved) solute (kg/m²).
  Vector absorbedSolvent;  ///< #V σ_p, solvent held in the fibres (kg/m²).
  Vector absorbedSolute;   ///< #V σ_s,p, solute absorbed with it (kg/m²).
  Vector adsorbedSolute;   ///< #V σ_s,a, solute deposited on the fibres (kg/m²).
  double evaporatedSolvent = 0;  ///< kg evaporated so far (free + absorbed).
  double addedSolvent = 0;       ///< kg added so far by sources and drops.
  double addedSolute = 0;        ///< kg added so far by sources and drops.

  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    v.field("solvent", s.solvent);
    v.field("solute", s.solute);
    v.field("absorbedSolvent", s.absorbedSolvent);
    v.field("absorbedSolute", s.absorbedSolute);
    v.field("adsorbedSolute", s.adsorbedSolute);
    v.field("velocities", s.velocities);
    v.field("evaporatedSolvent", s.evaporatedSolvent);
    v.field("addedSolvent", s.addedSolvent);
    v.field("addedSolute", s.addedSolute);
  }

  /// Zero state for `vertexCount` vertices (allocates; call at build time).
  void resize(int vertexCount);
  int vertexCount() const { return static_cast<int>(solvent.size()); }
  /// σ_f + σ_s at vertex i (kg/m²): the film that moves.
  double freeDensity(int i) const { return solvent[i] + solute[i]; }
  /// Every pool at vertex i, free, absorbed and adsorbed (kg/m²); × the dual
  /// area it is the liquid mass the vertex holds (the one sum every caller uses).
  double liquidDensity(int i) const {
    return solvent[i] + solute[i] + absorbedSolvent[i] + absorbedSolute[i] + adsorbedSolute[i];
  }
};
// A field added to StainState without a line in fields() fails here first.
static_assert(sizeof(StainState) == 5 * sizeof(Vector) + sizeof(ComplexVector) + 3 * sizeof(double),
              "StainState changed: list the new field in StainState::fields");

/// The rollback point of a step that touches few vertices: a mirror of the
/// state (every field, #V) that equals it at every vertex the step has not
/// changed, and holds the values the step began with at those it has. A
/// step lists the vertices it may change (note, before or after it changes
/// them: the mirror keeps the old values until commit); restore() puts them
/// back, commit() (at the start of the next step) copies them over, each
/// O(listed). A change to every vertex (noteAll: a metric rebuild, a
/// whole-mesh solve) makes both a full copy. markStale() says the state was
/// written from outside (StainSolver::mutableState, addDrop, restore): the
/// next commit copies everything. No allocation after resize.
class StateBackup {
 public:
  /// Sizes the mirror, list and marks (allocates; build time), stale.
  void resize(int vertexCount);
  /// The state was written outside a step: the mirror is no longer its copy.
  void markStale() { stale_ = true; }
  bool stale() const { return stale_; }
  /// Start of a step: the mirror becomes the state (the listed vertices, or
  /// all of it when stale or after noteAll), the list empties.
  void commit(const StainState& state);
  /// Vertex i (or `count` vertices) may change in this step. Past a quarter
  /// of the mesh, listing costs more than the full copies: the list becomes
  /// noteAll when it holds more than #V/4 distinct vertices (the stages of a
  /// step list the same band again and again, so the lengths of the lists
  /// noted are no measure of it).
  void note(int i) {
    if (all_ || marks_[static_cast<size_t>(i)]) return;
    marks_[static_cast<size_t>(i)] = 1;
    vertices_.push_back(i);
    if (4 * vertices_.size() > marks_.size()) noteAll();
  }
  void note(const int* list, int count) {
    for (int k = 0; k < count && !all_; ++k) note(list[k]);
  }
  /// Every vertex may change in this step.
  void noteAll() { all_ = true; }
  /// This step changed something (a vertex listed, or all).
  bool any() const { return all_ || !vertices_.empty(); }
  bool all() const { return all_; }
  /// The listed vertices (meaningful when !all()), in the order noted.
  const std::vector<int>& vertices() const { return vertices_; }
  /// The state as the step found it: the listed vertices (or every one) and
  /// the totals copied back from the mirror; the list empties.
  void restore(StainState& state);

 private:
  void clearList();

  StainState mirror_;
  std::vector<int> vertices_;
  std::vector<char> marks_;
  bool all_ = false;
  bool stale_ = true;
};

}  // namespace blot::stain
