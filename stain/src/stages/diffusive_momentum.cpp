// Stage "diffuse", last part: the density diffusion's mass fluxes carry the
// liquid's velocity (stages/diffusive_momentum.h).
#include <blot/stain/stages/diffusive_momentum.h>

#include <blot/stain/geometry/transport.h>

#include <algorithm>

namespace blot::stain {

void DiffusiveMomentumScratch::resize(int vertexCount, int ringEntries) {
  values.setZero(vertexCount);
  front.clear();
  front.reserve(static_cast<size_t>(vertexCount));
  frontMarks.assign(static_cast<size_t>(vertexCount), 0);
  stiffnessEntries.assign(static_cast<size_t>(ringEntries), -1);
}

namespace {

// Vertex i's ring entries' positions in the stiffness's column i (its
// pattern is the topology's and never changes; filled on first use, and
// again should a check find it stale).
void fillStiffnessEntries(const SurfaceTopology& topology, const SparseMatrix& L, int i, std::vector<int>& entries) {
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

}  // namespace

int carryMomentumWithDiffusion(const StepContext& ctx, const SurfaceTopology& topology,
                               const IntrinsicGeometry& intrinsic, LiquidBand& band, DiffusiveMomentumScratch& scratch,
                               StainState& state, std::vector<int>* beyondBand) {
  const int n = topology.vertexCount();
  const SparseMatrix& L = intrinsic.densityStiffness;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  if (!ctx.switches.diffusiveMomentum || band.vertices.empty() || L.rows() != n || L.cols() != n ||
      scratch.values.size() != n || scratch.frontMarks.size() != static_cast<size_t>(n) ||
      scratch.stiffnessEntries.size() != neighbors.size() || intrinsic.vertexDualAreas.size() != n ||
      state.velocities.size() != n || band.levels.size() != static_cast<size_t>(n) ||
      band.ringRebuildCounts.size() != static_cast<size_t>(n))
    return 0;
  const int* inner = L.innerIndexPtr();
  const double* values = L.valuePtr();
  const double* solvent = state.solvent.data();
  const double* solute = state.solute.data();
  const double* areas = intrinsic.vertexDualAreas.data();
  Complex* u = state.velocities.data();
  Complex* next = scratch.values.data();
  std::vector<int>& entries = scratch.stiffnessEntries;
  std::vector<char>& isFront = scratch.frontMarks;
  const auto liquid = [&](int k) { return std::max(solvent[k], 0.0) + std::max(solute[k], 0.0); };
  // Liquid below the wet threshold counts as none: its vertex's u is the
  // band's extension, and the liquid it sends is a trace.
  const double wet = ctx.liquid.wetThreshold;

  // Vertex i's exchange with its neighbours that `from` accepts: the mass that
  // came in, the momentum it brought (in i's frame, from u as it is) and the
  // mass that went out.
  struct Exchange {
    double in = 0, out = 0;
    Complex carried{0.0, 0.0};
  };
  const auto exchange = [&](int i, double here, auto from) {
    const size_t ii = static_cast<size_t>(i);
    // The band fills its vertices' transports once per rebuild; a vertex
    // beyond it is filled here (so is a band vertex, should one be stale).
    if (band.ringRebuildCounts[ii] != intrinsic.rebuildCount)
      fillRingTransports(topology, intrinsic.edgeTransportAngles, i, band.ringTransports.data());
    const int begin = offsets[ii], end = offsets[ii + 1];
    Exchange e;
    if (begin == end) return e;  // an isolated vertex
    const int first = entries[static_cast<size_t>(begin)];
    if (first < 0 || inner[first] != neighbors[static_cast<size_t>(begin)]) fillStiffnessEntries(topology, L, i, entries);
    for (int m = begin; m < end; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      const double difference = liquid(j) - here;
      const int k = entries[static_cast<size_t>(m)];
      if (difference == 0.0 || k < 0 || !from(j)) continue;
      const double flux = ctx.h * -values[k] * difference;
      if (flux > 0.0) {
        e.in += flux;
        const Complex t = band.ringTransports(m), v = u[j];
        e.carried += Complex(flux * (t.real() * v.real() - t.imag() * v.imag()),
                             flux * (t.real() * v.imag() + t.imag() * v.real()));
      } else if (flux < 0.0) {
        e.out -= flux;
      }
    }
    return e;
  };
  const auto inBand = [&](int j) { return band.levels[static_cast<size_t>(j)] >= 0; };

  // Which vertex sends which velocity. A band vertex that kept some of its
  // own liquid (k = A ρ⁺ − in > 0, i.e. A ρ − out with exact fluxes) sent
  // its u from before and mixes what it kept with what came in. One that
  // passed on all it held and more (the liquid reached it this step: the
  // front) sent the mix of what it held and what came in, and that mix is
  // its new u. Pass 1 takes every sender's u from before (right for all
  // but the front's receivers) and files the front.
  std::vector<int>& front = scratch.front;
  front.clear();
  for (const int i : band.vertices) {
    next[i] = u[i];
    const double here = liquid(i);
    if (!(here > wet)) continue;
    const Exchange e = exchange(i, here, inBand);
    if (!(e.in > 0.0)) continue;
    const double held = areas[i] * here, kept = held - e.in;
    if (kept > 0.0) {
      next[i] = (kept * u[i] + e.carried) / held;
    } else {
      front.push_back(i);
      isFront[static_cast<size_t>(i)] = 1;
    }
  }
  // Pass 2, the front, wettest first: liquid flows down the density, so
  // whatever the numbering a front vertex's front senders are done before
  // it. Each is written at once (what it sent, for those after it).
  const auto wettestFirst = [&](int a, int b) {
    const double la = liquid(a), lb = liquid(b);
    return la > lb || (la == lb && a < b);
  };
  std::sort(front.begin(), front.end(), wettestFirst);
  int changed = 0;
  for (const int i : front) {
    const double here = liquid(i);
    const Exchange e = exchange(i, here, inBand);
    const double before = std::max(areas[i] * here - e.in + e.out, 0.0);  // A ρ, held before the diffusion
    next[i] = (before * u[i] + e.carried) / (before + e.in);
    changed += next[i] != u[i];
    u[i] = next[i];
  }
  // Pass 3, the front's receivers that kept liquid: again, now that the
  // front holds what it sent (their own u is still the one from before).
  for (const int f : front) {
    const double fl = liquid(f);
    for (int m = offsets[static_cast<size_t>(f)]; m < offsets[static_cast<size_t>(f) + 1]; ++m) {
      const int i = neighbors[static_cast<size_t>(m)];
      const double here = liquid(i);
      if (isFront[static_cast<size_t>(i)] || !inBand(i) || !(here > wet) || !(here < fl)) continue;
      const Exchange e = exchange(i, here, inBand);
      const double held = areas[i] * here, kept = held - e.in;
      if (e.in > 0.0 && kept > 0.0) next[i] = (kept * u[i] + e.carried) / held;
    }
  }
  for (const int i : front) isFront[static_cast<size_t>(i)] = 0;
  for (const int i : band.vertices) {
    if (next[i] == u[i]) continue;
    u[i] = next[i];
    ++changed;
  }
  // Beyond the band no stage defined u: each vertex is what came in, from
  // the wettest down, so a trace two vertices past the band reads the one
  // between as it now is.
  if (beyondBand == nullptr) return changed;
  const auto last = std::partition(beyondBand->begin(), beyondBand->end(),
                                   [&](int i) { return !inBand(i) && liquid(i) > wet; });
  std::sort(beyondBand->begin(), last, wettestFirst);
  for (auto it = beyondBand->begin(); it != last; ++it) {
    const int i = *it;
    const Exchange e = exchange(i, liquid(i), [](int) { return true; });
    if (!(e.in > 0.0)) continue;
    const Complex mixed = e.carried / e.in;
    changed += mixed != u[i];
    u[i] = mixed;
  }
  return changed;
}

}  // namespace blot::stain
