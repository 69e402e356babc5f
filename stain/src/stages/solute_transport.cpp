// Stage "diffuse", the solute's part in the film model: the solution's
// wicking flux carries its solute (stages/solute_transport.h).
#include <blot/stain/stages/solute_transport.h>

#include <algorithm>
#include <cmath>

#include "numerics/compensated_sum.h"
#include "stages/ring_stiffness.h"

namespace blot::stain {
using diffusion_internal::CompensatedSum;

namespace {

constexpr int kMaxSoluteSweeps = 200;
constexpr double kSoluteSweepTolerance = 1e-13;  // relative to the largest concentration

}  // namespace

void SoluteTransportScratch::resize(int vertexCount, int ringEntries) {
  heldLiquid.setZero(vertexCount);
  concentrations.setZero(vertexCount);
  passed.setZero(vertexCount);
  sentShare.setZero(vertexCount);
  diagonals.setZero(vertexCount);
  couplings.setZero(ringEntries);
  vertices.clear();
  vertices.reserve(static_cast<size_t>(vertexCount));
  listed.assign(static_cast<size_t>(vertexCount), 0);
  stiffnessEntries.assign(static_cast<size_t>(ringEntries), -1);
}

void holdLiquidForSoluteTransport(const std::vector<int>& band, StainState& state, SoluteTransportScratch& scratch) {
  for (const int i : band) {
    const double liquid = state.solvent[i] + state.solute[i];
    scratch.heldLiquid[i] = liquid;
    state.solvent[i] = liquid;
  }
}

SoluteTransportReport carrySoluteWithSolvent(const StepContext& ctx, const SurfaceTopology& topology,
                                             const IntrinsicGeometry& intrinsic, const std::vector<int>& band,
                                             const std::vector<int>& beyondBand, SoluteTransportScratch& scratch,
                                             StainState& state) {
  SoluteTransportReport report;
  const SparseMatrix& L = intrinsic.densityStiffness;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringEdges = topology.ringEdges();
  const double* values = L.valuePtr();
  const double* areas = intrinsic.vertexDualAreas.data();
  const double* weights = intrinsic.edgeCotanWeights.data();
  double* liquid = state.solvent.data();  // ρ⁺ until the split at the end
  double* solute = state.solute.data();
  double* held = scratch.heldLiquid.data();
  double* c = scratch.concentrations.data();
  double* passed = scratch.passed.data();
  double* share = scratch.sentShare.data();
  double* diagonals = scratch.diagonals.data();
  double* couplings = scratch.couplings.data();
  std::vector<int>& vertices = scratch.vertices;
  std::vector<char>& listed = scratch.listed;
  const double h = ctx.h;
  const double molecular = h * ctx.liquid.molecularDiffusivity;

  // The vertices: the band (held before the diffusion) and those the
  // diffusion reached past it (which held no liquid: 0).
  vertices.clear();
  for (const std::vector<int>* list : {&band, &beyondBand})
    for (const int i : *list) {
      if (listed[static_cast<size_t>(i)] != 0) continue;
      if (list == &beyondBand) held[i] = 0.0;
      listed[static_cast<size_t>(i)] = 1;
      vertices.push_back(i);
    }
  // Memory order: the sweeps below read neighbours' data, in index order
  // mostly from cache (ordered by ρ⁺ a sweep would be nearly a forward
  // substitution, but its reads jump across the mesh: slower on large meshes).
  std::sort(vertices.begin(), vertices.end());
  report.vertices = static_cast<int>(vertices.size());

  // The concentrations held. One concentration everywhere is the solution
  // (every row of the system is then a sum of its masses), whatever the
  // fluxes: liquid that reached a vertex holding none brings it too.
  double largest = 0.0, least = 1.0;
  for (const int i : vertices) {
    const double before = std::max(held[i], 0.0);
    c[i] = before > 0.0 ? std::clamp(solute[i] / before, 0.0, 1.0) : 0.0;
    largest = std::max(largest, c[i]);
    if (before > 0.0) least = std::min(least, c[i]);
  }
  report.converged = !(largest > least);
  if (report.converged)
    for (const int i : vertices) c[i] = largest;

  if (!report.converged) {
    // Each edge's flux from ρ⁺: what passed through each tank, its outflow,
    // and the share of that outflow that can carry solute.
    const auto flux = [&](int i, int m) {  // F_ji for ring entry m of i (j its neighbour)
      const int k = scratch.stiffnessEntries[static_cast<size_t>(m)];
      if (k < 0) return 0.0;
      const int j = neighbors[static_cast<size_t>(m)];
      return h * -values[k] * (liquid[j] - liquid[i]);
    };
    for (const int i : vertices) {
      const size_t ii = static_cast<size_t>(i);
      const int begin = offsets[ii], end = offsets[ii + 1];
      ensureStiffnessEntries(topology, L, i, scratch.stiffnessEntries);
      double in = 0.0, out = 0.0;
      for (int m = begin; m < end; ++m) {
        const double f = flux(i, m);
        if (f > 0.0) in += f;
        else out -= f;
      }
      passed[i] = areas[i] * std::max(held[i], 0.0) + in;
      share[i] = out > passed[i] ? passed[i] / out : 1.0;
    }
    // The couplings: θ_j max(F_ji, 0) + d_ij for each ring entry of a listed
    // vertex (0 towards a vertex that is not listed: it holds no liquid), and
    // the diagonals S_i + Σ_j d_ij.
    for (const int i : vertices) {
      const size_t ii = static_cast<size_t>(i);
      double diagonal = passed[i];
      for (int m = offsets[ii]; m < offsets[ii + 1]; ++m) {
        const int j = neighbors[static_cast<size_t>(m)];
        double coupling = 0.0;
        if (listed[static_cast<size_t>(j)] != 0) {
          const double f = flux(i, m);
          if (f > 0.0) coupling += share[j] * f;
          const double w = weights[ringEdges[static_cast<size_t>(m)]];
          if (molecular > 0.0 && w > 0.0) {
            const double exchange = molecular * w * std::min(std::max(liquid[i], 0.0), std::max(liquid[j], 0.0));
            coupling += exchange;
            diagonal += exchange;
          }
        }
        couplings[m] = coupling;
      }
      diagonals[i] = diagonal;
    }

    // Symmetric Gauss–Seidel from the concentrations held: a forward and a
    // backward sweep in turn, so a chain of fluxes in either index direction
    // is followed within two sweeps; the error falls geometrically at the
    // rate of the largest share of a vertex's solute that came from others.
    const auto relax = [&](int i, double& change) {
      const size_t ii = static_cast<size_t>(i);
      double source = areas[i] * std::max(solute[i], 0.0);
      for (int m = offsets[ii]; m < offsets[ii + 1]; ++m)
        if (couplings[m] != 0.0) source += couplings[m] * c[neighbors[static_cast<size_t>(m)]];
      const double next = diagonals[i] > 0.0 ? source / diagonals[i] : 0.0;
      change = std::max(change, std::abs(next - c[i]));
      c[i] = next;
    };
    while (!report.converged && report.sweeps < kMaxSoluteSweeps) {
      double change = 0.0;
      if (report.sweeps++ % 2 == 0) {
        for (const int i : vertices) relax(i, change);
      } else {
        for (auto k = vertices.rbegin(); k != vertices.rend(); ++k) relax(*k, change);
      }
      if (change <= kSoluteSweepTolerance * largest) {
        report.converged = true;
        break;
      }
    }
  }

  // The split: σ_s⁺ = c ρ⁺, rescaled to the solute the vertices held. (No
  // liquid carried any solute, e.g. solute without liquid: it stays put.)
  CompensatedSum target, result;
  for (const int i : vertices) {
    if (solute[i] != 0.0) target.add(areas[i] * solute[i]);
    const double s = c[i] * std::max(liquid[i], 0.0);
    if (s != 0.0) result.add(areas[i] * s);
  }
  const bool carried = result.value() > 0.0;
  if (carried && target.value() > 0.0) report.massFactor = target.value() / result.value();
  for (const int i : vertices) {
    const double rho = liquid[i];
    const double s = carried ? std::min(c[i] * std::max(rho, 0.0) * report.massFactor, std::max(rho, 0.0)) : solute[i];
    solute[i] = s;
    liquid[i] = rho - s;
    c[i] = 0.0;
    listed[static_cast<size_t>(i)] = 0;
  }
  return report;
}

}  // namespace blot::stain
