// The stain state's storage (struct of arrays, one vector per field).
//
// Design note: resize allocates every field at once and zeroes it, including
// the running totals, so a state is either fully sized for a mesh or empty;
// the step never resizes (no allocation inside step).
#include <blot/stain/stain_state.h>

#include <stdexcept>

namespace blot::stain {

void StainState::resize(int vertexCount) {
  if (vertexCount < 0) throw std::invalid_argument("StainState::resize: negative vertex count");
  velocities = ComplexVector::Zero(vertexCount);
  solvent = Vector::Zero(vertexCount);
  solute = Vector::Zero(vertexCount);
  absorbedSolvent = Vector::Zero(vertexCount);
  absorbedSolute = Vector::Zero(vertexCount);
  adsorbedSolute = Vector::Zero(vertexCount);
  evaporatedSolvent = 0;
  addedSolvent = 0;
  addedSolute = 0;
}

namespace {

void copyVertex(const StainState& from, int i, StainState& to) {
  to.velocities[i] = from.velocities[i];
  to.solvent[i] = from.solvent[i];
  to.solute[i] = from.solute[i];
  to.absorbedSolvent[i] = from.absorbedSolvent[i];
  to.absorbedSolute[i] = from.absorbedSolute[i];
  to.adsorbedSolute[i] = from.adsorbedSolute[i];
}

void copyTotals(const StainState& from, StainState& to) {
  to.evaporatedSolvent = from.evaporatedSolvent;
  to.addedSolvent = from.addedSolvent;
  to.addedSolute = from.addedSolute;
}

}  // namespace

void StateBackup::resize(int vertexCount) {
  mirror_.resize(vertexCount);
  vertices_.clear();
  vertices_.reserve(static_cast<size_t>(vertexCount));
  marks_.assign(static_cast<size_t>(vertexCount), 0);
  all_ = false;
  stale_ = true;
}

void StateBackup::clearList() {
  for (const int i : vertices_) marks_[static_cast<size_t>(i)] = 0;
  vertices_.clear();
  all_ = false;
}

void StateBackup::commit(const StainState& state) {
  if (stale_ || all_) {
    mirror_ = state;  // same sizes: no allocation
  } else {
    for (const int i : vertices_) copyVertex(state, i, mirror_);
    copyTotals(state, mirror_);
  }
  stale_ = false;
  clearList();
}

void StateBackup::restore(StainState& state) {
  if (all_ || stale_) {
    state = mirror_;
  } else {
    for (const int i : vertices_) copyVertex(mirror_, i, state);
    copyTotals(mirror_, state);
  }
  clearList();
}

}  // namespace blot::stain
