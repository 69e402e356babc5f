// Stage "diffuse", last part: the density diffusion's mass fluxes carry the
// liquid's velocity (stages/diffusive_momentum.h).
#include <blot/stain/stages/diffusive_momentum.h>

#include <blot/stain/geometry/transport.h>

#include <algorithm>

namespace blot::stain {

void DiffusiveMomentumScratch::resize(int vertexCount, int ringEntries) {
  order.clear();
  order.reserve(static_cast<size_t>(vertexCount));
  done.assign(static_cast<size_t>(vertexCount), 0);
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
                               const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry* moving, LiquidBand& band,
                               DiffusiveMomentumScratch& scratch, StainState& state, const std::vector<int>* beyondBand) {
  const int n = topology.vertexCount();
  const SparseMatrix& L = intrinsic.densityStiffness;
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  if (!ctx.switches.diffusiveMomentum || band.vertices.empty() || L.rows() != n || L.cols() != n ||
      scratch.done.size() != static_cast<size_t>(n) || scratch.stiffnessEntries.size() != neighbors.size() ||
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

  // Every vertex the diffusion left liquid at whose u means something: the
  // band's, and those past it (their u is what came in), wettest first.
  // Liquid flows down the density, so whatever the numbering each vertex's
  // senders come before it (equal densities exchange nothing).
  std::vector<int>& order = scratch.order;
  order.clear();
  for (const int i : band.vertices)
    if (liquid(i) > 0.0) order.push_back(i);
  if (beyondBand != nullptr)
    for (const int i : *beyondBand)
      if (!inBand(i) && liquid(i) > 0.0) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const double la = liquid(a), lb = liquid(b);
    return la > lb || (la == lb && a < b);
  });

  // Each vertex mixes what it held before the diffusion (A ρ = A ρ⁺ − in +
  // out, at its u; none past the band, where u meant nothing) with what came
  // in, each sender's liquid at the u it sent: the mix it then holds and
  // passes on. Senders are band vertices or vertices already done.
  const double h = ctx.h;
  int changed = 0;
  for (const int i : order) {
    const size_t ii = static_cast<size_t>(i);
    // The band fills its vertices' transports once per rebuild; a vertex
    // beyond it is filled here (so is a band vertex, should one be stale).
    if (band.ringRebuildCounts[ii] != intrinsic.rebuildCount)
      fillRingTransports(topology, intrinsic.edgeTransportAngles, i, band.ringTransports.data());
    const int begin = offsets[ii], end = offsets[ii + 1];
    done[ii] = 1;
    if (begin == end) continue;  // an isolated vertex
    const int first = entries[static_cast<size_t>(begin)];
    if (first < 0 || inner[first] != neighbors[static_cast<size_t>(begin)]) fillStiffnessEntries(topology, L, i, entries);
    // On a moving cloth u is relative to it: a sender's liquid arrives with
    // the difference of the two vertices' surface velocities added (the
    // chord over the step, in i's frame at t + h), as the band's extension
    // and the advection's frame change carry it. (Past the band the frames
    // are not this step's: no difference added to those traces.)
    const Matrix3* frame = moving != nullptr && inBand(i) ? &moving->nextFrames[ii] : nullptr;
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
    if (!(in > 0.0)) continue;
    // A ρ, held before the diffusion; on the band at least the wet
    // threshold's worth, so that u moves continuously from the band's
    // extended value as liquid first arrives (a trace's u decides what the
    // next advection brings it: a jump there turned rounding into a visible
    // asymmetry).
    const double before = inBand(i) ? std::max(areas[i] * here - in + out, areas[i] * wet) : 0.0;
    const Complex mixed = (before * u[i] + carried) / (before + in);
    changed += mixed != u[i];
    u[i] = mixed;
  }
  for (const int i : order) done[static_cast<size_t>(i)] = 0;
  return changed;
}

}  // namespace blot::stain
