// Stage "interact": stain–fabric interaction per vertex (paper sec. 5, eqs. 9–12).
//
// Design note: docs/design-notes.md, "stain/src/stages/interaction.cpp".
#include <blot/stain/stages/interaction.h>

#include <algorithm>
#include <cassert>

#include "numerics/threads.h"

namespace blot::stain {
namespace {

// Fixed chunking of the vertex range for the deterministic reduction.
constexpr int kChunks = 64;
// Threads only above this many vertices. Measured (liquid_stages_bench, this
// 2-core machine under load from other builds): serial 12 µs at 2.5K and
// ~0.2 ms at 35K vertices (~6 ns per vertex), but 2 OpenMP threads took 2–5 ms
// at 10K–35K, the region waiting on a descheduled thread. The saving on an
// idle machine (≤ 0.1 ms at 35K) does not pay that risk at the paper's sizes.
constexpr int kParallelThreshold = 100000;
// Mask value of a vertex that holds liquid (StainSolver's mask: 2 holds, 1 halo, 0 dry).
constexpr char kHoldsLiquid = 2;

struct Rates {
  bool absorption, adsorption, evaporation;
  double absorbFraction;    // K_p h / (1 + K_p h)
  double saturation;        // σ_sat
  double adsorbFraction;    // K_d h / (1 + K_d h)
  double capacity;          // A_d
  double evaporationDepth;  // K_evap h (kg/m²)
  double boundaryFactor;    // a_evap
};

// Updates vertex i; returns the evaporated density (kg/m²).
inline double interactVertex(const Rates& r, bool onBoundary, double& free, double& solute, double& absorbed,
                             double& absorbedSolute, double& adsorbed) {
  if (r.absorption && free > 0.0) {
    double taken = r.absorbFraction * (r.saturation - absorbed);
    if (taken > 0.0) {
      double soluteTaken;
      if (taken >= free) {
        taken = free;
        soluteTaken = solute;
        free = 0.0;
      } else {
        soluteTaken = solute * (taken / free);
        free -= taken;
      }
      absorbed += taken;
      solute -= soluteTaken;
      absorbedSolute += soluteTaken;
    }
  }
  if (r.adsorption) {
    double deposited = r.adsorbFraction * (r.capacity - adsorbed);
    // Adsorption is limited by the dissolved solute; desorption needs solvent
    // to dissolve into (deposits left by drying stay put).
    if (deposited > 0.0) deposited = std::min(deposited, std::max(solute, 0.0));
    if (deposited < 0.0 && !(free > 0.0)) deposited = 0.0;
    if (deposited != 0.0) {
      solute -= deposited;
      adsorbed += deposited;
    }
  }
  double evaporated = 0.0;
  if (r.evaporation) {
    const double demand = r.evaporationDepth * (onBoundary ? r.boundaryFactor : 1.0);
    if (demand < free) {
      free -= demand;
      evaporated = demand;
    } else {
      const double fromFree = std::max(free, 0.0);
      free -= fromFree;
      const double fromAbsorbed = std::clamp(demand - fromFree, 0.0, std::max(absorbed, 0.0));
      absorbed -= fromAbsorbed;
      evaporated = fromFree + fromAbsorbed;
    }
  }
  // Solute with no free solvent left to carry it is a dry deposit.
  if (!(free > 0.0) && solute > 0.0) {
    adsorbed += solute;
    solute = 0.0;
  }
  return evaporated;
}

}  // namespace

void interact(const StepContext& ctx, const SurfaceTopology& topology, const IntrinsicGeometry& geometry,
              const std::vector<char>& wet, StainState& state, Vector* evaporatedMass,
              const std::vector<int>* among, const std::vector<char>* soaked) {
  const PhysicsSwitches& switches = ctx.switches;
  if (!switches.absorption && !switches.adsorption && !switches.evaporation) return;
  const LiquidParameters& liquid = ctx.liquid;
  const double h = ctx.h;
  const Rates rates{switches.absorption,
                    switches.adsorption,
                    switches.evaporation,
                    liquid.absorptionRate * h / (1.0 + liquid.absorptionRate * h),
                    liquid.saturationDensity,
                    liquid.desorptionRate * h / (1.0 + liquid.desorptionRate * h),
                    liquid.adsorptionCapacity,
                    liquid.evaporationRate * h,
                    liquid.boundaryEvaporationFactor};

  const int n = state.vertexCount();
  // An empty mask means every vertex; a mask of another size is a caller bug
  // (asserted) and is ignored rather than read out of bounds.
  assert(wet.empty() || wet.size() == static_cast<size_t>(n));
  const bool allWet = wet.size() != static_cast<size_t>(n);
  const std::vector<char>& boundary = topology.vertexIsBoundary();
  const bool wetFront = liquid.evaporationBoundary == EvaporationBoundary::WetFront && !allWet;
  const std::vector<int>& ringOffsets = topology.ringOffsets();
  const std::vector<int>& ringNeighbors = topology.ringNeighbors();
  // The liquid's edge: holds liquid (mask 2) with a neighbour that does not.
  // Read from the mask (the start of the step), not from the densities being
  // updated here, so the result does not depend on the vertex order.
  const bool withSoaked = soaked != nullptr && soaked->size() == static_cast<size_t>(n);
  auto holdsLiquid = [&](size_t i) { return wet[i] == kHoldsLiquid || (withSoaked && (*soaked)[i] != 0); };
  auto onWetFront = [&](int i) {
    if (!holdsLiquid(static_cast<size_t>(i))) return false;
    for (int m = ringOffsets[static_cast<size_t>(i)]; m < ringOffsets[static_cast<size_t>(i) + 1]; ++m)
      if (!holdsLiquid(static_cast<size_t>(ringNeighbors[static_cast<size_t>(m)]))) return true;
    return false;
  };
  const double* areas = geometry.vertexDualAreas.data();
  double* free = state.solvent.data();
  double* solute = state.solute.data();
  double* absorbed = state.absorbedSolvent.data();
  double* absorbedSolute = state.absorbedSolute.data();
  double* adsorbed = state.adsorbedSolute.data();
  double* vapour = evaporatedMass != nullptr && evaporatedMass->size() == n ? evaporatedMass->data() : nullptr;

  double evaporated[kChunks] = {};
  const int chunkSize = (n + kChunks - 1) / kChunks;
  auto processChunk = [&](int c) {
    const int begin = c * chunkSize, end = std::min(n, begin + chunkSize);
    double sum = 0.0;
    for (int i = begin; i < end; ++i) {
      if (!allWet && !wet[static_cast<size_t>(i)] && !(absorbed[i] > 0.0)) continue;
      const bool exposed = boundary[static_cast<size_t>(i)] != 0 || (wetFront && onWetFront(i));
      const double gone = interactVertex(rates, exposed, free[i], solute[i],
                                         absorbed[i], absorbedSolute[i], adsorbed[i]);
      const double mass = gone * areas[i];
      if (vapour != nullptr) vapour[i] = mass;
      sum += mass;
    }
    evaporated[c] = sum;
  };
  if (among != nullptr && !allWet) {
    // The listed vertices, in index order: each chunk's sum adds the same
    // terms in the same order as processChunk, so the total is the same bits.
    for (const int i : *among) {
      if (!wet[static_cast<size_t>(i)] && !(absorbed[i] > 0.0)) continue;
      const bool exposed = boundary[static_cast<size_t>(i)] != 0 || (wetFront && onWetFront(i));
      const double gone = interactVertex(rates, exposed, free[i], solute[i],
                                         absorbed[i], absorbedSolute[i], adsorbed[i]);
      const double mass = gone * areas[i];
      if (vapour != nullptr) vapour[i] = mass;
      evaporated[i / chunkSize] += mass;
    }
  } else if (threads::worthThreads(n > kParallelThreshold)) {
    // Small meshes and one-thread engines stay serial without entering an
    // OpenMP region at all (numerics/threads.h: a one-thread region allocates).
#pragma omp parallel for schedule(static)
    for (int c = 0; c < kChunks; ++c) processChunk(c);
  } else {
    for (int c = 0; c < kChunks; ++c) processChunk(c);
  }
  double total = 0.0;
  for (const double part : evaporated) total += part;
  state.evaporatedSolvent += total;
}

}  // namespace blot::stain
