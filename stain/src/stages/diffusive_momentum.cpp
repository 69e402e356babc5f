// Stage "diffuse", last part: the density diffusion's mass fluxes carry the
// liquid's velocity (stages/diffusive_momentum.h).
#include <blot/stain/stages/diffusive_momentum.h>

#include <blot/stain/geometry/transport.h>

#include <algorithm>

#include "stages/ring_stiffness.h"

namespace blot::stain {

void DiffusiveMomentumScratch::resize(int vertexCount, int ringEntries) {
  values.setZero(vertexCount);
  order.clear();
  order.reserve(static_cast<size_t>(vertexCount));
  done.assign(static_cast<size_t>(vertexCount), 0);
  stiffnessEntries.assign(static_cast<size_t>(ringEntries), -1);
}

int carryMomentumWithDiffusion(const StepContext& ctx, const SurfaceTopology& topology,
                               const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry* moving, LiquidBand& band,
                               DiffusiveMomentumScratch& scratch, StainState& state, const std::vector<int>* beyondBand) {
  const int n = topology.vertexCount();
  const SparseMatrix& L = intrinsic.densityStiffness;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  if (!ctx.switches.diffusiveMomentum || band.vertices.empty() || L.rows() != n || L.cols() != n ||
      scratch.values.size() != n || scratch.done.size() != static_cast<size_t>(n) ||
      scratch.stiffnessEntries.size() != neighbors.size() ||
      intrinsic.vertexDualAreas.size() != n || state.velocities.size() != n ||
      band.levels.size() != static_cast<size_t>(n) || band.ringRebuildCounts.size() != static_cast<size_t>(n))
    return 0;
  if (moving != nullptr && (moving->positions.rows() != n || moving->nextPositions.rows() != n ||
                            moving->nextFrames.size() != static_cast<size_t>(n)))
    moving = nullptr;
  const int* inner = L.innerIndexPtr();
  const double* values = L.valuePtr();
  const double* solvent = state.solvent.data();
  const double* solute = state.solute.data();
  const double* areas = intrinsic.vertexDualAreas.data();
  Complex* u = state.velocities.data();
  std::vector<int>& entries = scratch.stiffnessEntries;
  std::vector<char>& done = scratch.done;
  const auto liquid = [&](int k) { return std::max(solvent[k], 0.0) + std::max(solute[k], 0.0); };
  const double wet = ctx.liquid.wetThreshold;
  const auto inBand = [&](int j) { return band.levels[static_cast<size_t>(j)] >= 0; };

  // Vertex i's mix: what it held before the diffusion (A ρ = A ρ⁺ − in +
  // out, at its own u; on the band at least the wet threshold's worth, so
  // that u moves continuously from the band's extended value as liquid first
  // arrives: a trace's u decides what the next advection brings it; none
  // past the band, where u meant nothing) with what came in, each sender's
  // liquid at the u it held. Senders are band vertices or vertices past it
  // already done. Returns false where nothing came in.
  const double h = ctx.h;
  const auto mix = [&](int i, bool ownLiquid, Complex& mixed) {
    const size_t ii = static_cast<size_t>(i);
    // The band fills its vertices' transports once per rebuild; a vertex
    // beyond it is filled here (so is a band vertex, should one be stale).
    if (band.ringRebuildCounts[ii] != intrinsic.rebuildCount)
      fillRingTransports(topology, intrinsic.edgeTransportAngles, i, band.ringTransports.data());
    const int begin = offsets[ii], end = offsets[ii + 1];
    if (begin == end) return false;  // an isolated vertex
    const int first = entries[static_cast<size_t>(begin)];
    if (first < 0 || inner[first] != neighbors[static_cast<size_t>(begin)]) fillStiffnessEntries(topology, L, i, entries);
    // On a moving cloth u is relative to it: a sender's liquid arrives with
    // the difference of the two vertices' surface velocities added (the
    // chord over the step, in i's frame at t + h), as the band's extension
    // and the advection's frame change carry it. (Past the band the frames
    // are not this step's: no difference added to those traces.)
    const Matrix3* frame = moving != nullptr && ownLiquid ? &moving->nextFrames[ii] : nullptr;
    Vector3 vi = Vector3::Zero();
    if (frame != nullptr) vi = (moving->nextPositions.row(i) - moving->positions.row(i)).transpose() / h;
    const double here = liquid(i);
    double in = 0.0, out = 0.0;
    Complex carried(0.0, 0.0);
    for (int m = begin; m < end; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      const double difference = liquid(j) - here;
      const int k = entries[static_cast<size_t>(m)];
      if (difference == 0.0 || k < 0) continue;  // no flux, or no entry
      const double flux = h * -values[k] * difference;
      if (flux < 0.0) {
        out -= flux;
        continue;
      }
      if (!(flux > 0.0) || !(inBand(j) || done[static_cast<size_t>(j)])) continue;  // no u to carry
      // e^{iθ} u_j written out: no libgcc call (__muldc3's NaN path) in the loop.
      const Complex t = band.ringTransports(m), v = u[j];
      Complex sent(t.real() * v.real() - t.imag() * v.imag(), t.real() * v.imag() + t.imag() * v.real());
      if (frame != nullptr) {
        const Vector3 change = (moving->nextPositions.row(j) - moving->positions.row(j)).transpose() / h - vi;
        sent += Complex(frame->col(0).dot(change), frame->col(1).dot(change));
      }
      in += flux;
      carried += flux * sent;
    }
    if (!(in > 0.0)) return false;
    const double before = ownLiquid ? std::max(areas[i] * here - in + out, areas[i] * wet) : 0.0;
    mixed = (before * u[i] + carried) / (before + in);
    return true;
  };

  // The band: every vertex from the velocities before the pass (into
  // scratch, written back after it), so the result depends neither on the
  // numbering nor on the order, and the pass runs in memory order.
  int changed = 0;
  Complex* next = scratch.values.data();
  for (const int i : band.vertices) {
    next[i] = u[i];
    if (liquid(i) > 0.0) mix(i, true, next[i]);
  }
  for (const int i : band.vertices) {
    changed += next[i] != u[i];
    u[i] = next[i];
  }
  // Past the band, the wettest first (liquid flows down the density, so a
  // vertex's senders there are done before it whatever the numbering), each
  // written at once: a trace two vertices past the band reads the one
  // between as it now is. These lists are short.
  if (beyondBand == nullptr) return changed;
  std::vector<int>& order = scratch.order;
  order.clear();
  for (const int i : *beyondBand)
    if (!inBand(i) && liquid(i) > 0.0) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const double la = liquid(a), lb = liquid(b);
    return la > lb || (la == lb && a < b);
  });
  for (const int i : order) {
    Complex mixed;
    if (!mix(i, false, mixed)) continue;  // nothing came in: its u stays undefined
    changed += mixed != u[i];
    u[i] = mixed;
    done[static_cast<size_t>(i)] = 1;
  }
  for (const int i : order) done[static_cast<size_t>(i)] = 0;
  return changed;
}

}  // namespace blot::stain
