// Stage "advect density": finite-volume upwind advection of free solvent and
// solute (paper sec. 3.1).
//
// Design note: docs/design-notes.md, "stain/src/stages/density_advection.cpp".
#include <blot/stain/stages/density_advection.h>

#include <algorithm>
#include <cmath>

#include "numerics/threads.h"

namespace blot::stain {
namespace {

// Below this many active vertices the passes run on one thread: the fork/join
// costs more than the few flops per vertex (tuned in tests/bench).
constexpr int kMinParallelVertices = 4096;

// max(x, 0) without a branch (std::max compiles to compare-and-jump under
// strict IEEE semantics, and the sign of a speed is a coin flip the branch
// predictor cannot learn). Exact: x + |x| = 2x or 0, and halving is exact.
inline double positivePart(double x) { return 0.5 * (x + std::abs(x)); }

// Appends to `active` every unmarked neighbour of active[from, to) inside
// `reach` (all when null), marking it.
void addNextRing(const SurfaceTopology& topology, int from, int to, std::vector<int>& active,
                 std::vector<char>& marks, const std::vector<char>* reach) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  for (int k = from; k < to; ++k) {
    const int i = active[static_cast<size_t>(k)];
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      if (!marks[static_cast<size_t>(j)] && (reach == nullptr || (*reach)[static_cast<size_t>(j)])) {
        marks[static_cast<size_t>(j)] = 1;
        active.push_back(j);
      }
    }
  }
}

}  // namespace

void DensityAdvectionScratch::resize(int vertexCount, int edgeCount, int faceCount) {
  activeVertices.clear();
  activeVertices.reserve(static_cast<size_t>(vertexCount));
  activeMarks.assign(static_cast<size_t>(vertexCount), 0);
  vertexVelocities.resize(vertexCount, 3);
  vertexPositions.resize(vertexCount, 3);
  ringSpeeds.resize(2 * static_cast<Eigen::Index>(edgeCount));
  outflowRates.resize(vertexCount);
  keptFractions.resize(vertexCount);
  givingRatios.resize(vertexCount);
  ringInflowShares.resize(2 * static_cast<Eigen::Index>(edgeCount));
  // Zero, not just sized: a vertex outside the active set is read as a ring
  // neighbour (its giving ratio and mass enter the shares of the active
  // vertices next to it), so those entries must hold 0, never stale or
  // uninitialised values. advectDensities restores the zeros after each call.
  vertexVelocities.setZero();
  vertexPositions.setZero();
  ringSpeeds.setZero();
  outflowRates.setZero();
  keptFractions.setZero();
  givingRatios.setZero();
  ringInflowShares.setZero();
  massSolvent.setZero(vertexCount);
  massSolute.setZero(vertexCount);
  nextMassSolvent.setZero(vertexCount);
  nextMassSolute.setZero(vertexCount);
  activeEdges.clear();
  activeEdges.reserve(static_cast<size_t>(edgeCount));
  edgeMarks.assign(static_cast<size_t>(edgeCount), 0);
  edgeDualNormals.setZero(edgeCount, 3);
  activeFaces.clear();
  activeFaces.reserve(static_cast<size_t>(faceCount));
  faceMarks.assign(static_cast<size_t>(faceCount), 0);
  faceUnitNormals.setZero(faceCount, 3);
  faceCentroids.setZero(faceCount, 3);
}

namespace {

// What one advectDensities call reads, gathered once.
struct AdvectionSurface {
  const SurfaceTopology& topology;
  const ExtrinsicGeometry& extrinsic;
  const Vector& areas;           ///< #V dual areas (m²)
  const std::vector<char>& wet;  ///< #V, nonzero on the wet set (empty = all)
  /// Rigid motion: the speed read from the rest edge frame normals
  /// (restFrameNormals, #E by 4, row-major) and u as it is stored.
  bool rigid;
  const double* restFrameNormals;  ///< null unless rigid
  double h;  ///< time step (s)
};

// The wet set (or every vertex) then its first ring, in scratch.activeVertices
// and marked in scratch.activeMarks.
struct ActiveRings {
  int wetEnd = 0;           ///< end of the wet set in activeVertices
  int firstRingEnd = 0;     ///< end of its first ring
  bool everything = false;  ///< every vertex is active (no rings)
};

// Layer 0: the wet vertices found among `among` (all #V when null), or every
// vertex when the wet set is empty or, without a reach set, covers half the
// mesh; then their first ring inside `reach`. With a reach set the rings are
// built even for a large wet set: liquid must not leave the band (its outer
// rings hold no advected velocity).
ActiveRings activateWetSet(const SurfaceTopology& topology, const std::vector<char>& wet,
                           const std::vector<char>* reach, const std::vector<int>* among,
                           DensityAdvectionScratch& scratch) {
  const int n = topology.vertexCount();
  std::vector<int>& active = scratch.activeVertices;
  std::vector<char>& marks = scratch.activeMarks;
  int wetCount = 0;
  const int visits = visitCount(n, among);
  if (!wet.empty()) {
    for (int k = 0; k < visits; ++k) wetCount += wet[static_cast<size_t>(visited(k, among))] ? 1 : 0;
  }
  ActiveRings rings;
  rings.everything = wet.empty() || (reach == nullptr && 2 * wetCount >= n);
  active.clear();
  if (rings.everything) {
    for (int i = 0; i < n; ++i) active.push_back(i);
    std::fill(marks.begin(), marks.end(), 1);
  } else {
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
      if (wet[static_cast<size_t>(i)]) {
        active.push_back(i);
        marks[static_cast<size_t>(i)] = 1;
      }
    }
  }
  rings.wetEnd = static_cast<int>(active.size());
  if (!rings.everything) addNextRing(topology, 0, rings.wetEnd, active, marks, reach);
  rings.firstRingEnd = static_cast<int>(active.size());
  return rings;
}

// U_i = F_i u_i (world, m/s) and p_i (m), row-major, on active[from, to) into
// scratch.vertexVelocities and scratch.vertexPositions.
void storeWorldVelocities(const ExtrinsicGeometry& extrinsic, const StainState& state, int from, int to,
                          DensityAdvectionScratch& scratch) {
  const std::vector<int>& active = scratch.activeVertices;
  threads::runLoop(to - from >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = from; k < to; ++k) {
      const int i = active[static_cast<size_t>(k)];
      const Matrix3& frame = extrinsic.frames[static_cast<size_t>(i)];
      const Complex u = state.velocities(i);
      scratch.vertexVelocities.row(i) = (frame.col(0) * u.real() + frame.col(1) * u.imag()).transpose();
      scratch.vertexPositions.row(i) = extrinsic.positions.row(i);
    }
  });
}

// Rigid motion: scratch.ringSpeeds (m²/s) and scratch.outflowRates on
// active[from, to) from the rest frame normals, u read as it is stored; the
// expression for an edge is evaluated identically from both ends (a =
// edgeVertices(e, 0) first), so the two entries are again bitwise opposite.
// Edges to inactive vertices are closed. Returns the largest Courant number
// h outflow_i / A_i over the wet ones. Raw pointers and no data-dependent
// branches (see positivePart).
double ringSpeedsAndOutflowRigid(const AdvectionSurface& surface, const StainState& state, int from, int to,
                                 DensityAdvectionScratch& scratch) {
  const std::vector<int>& active = scratch.activeVertices;
  const int* ringOffsets = surface.topology.ringOffsets().data();
  const int* ringNeighbors = surface.topology.ringNeighbors().data();
  const int* ringEdgeIds = surface.topology.ringEdges().data();
  const char* marked = scratch.activeMarks.data();
  double* speeds = scratch.ringSpeeds.data();
  const double* frameNormals = surface.restFrameNormals;
  const int* edgeFirst = surface.topology.edgeVertices().data();
  const int* edgeSecond = edgeFirst + surface.topology.edgeCount();
  const Complex* u = state.velocities.data();
  const std::vector<char>& wet = surface.wet;
  double maxCourant = 0.0;
  threads::runLoop(to - from >= kMinParallelVertices, [&] {
    decltype(maxCourant) maxCourantHere = threads::lowest<decltype(maxCourant)>();
#pragma omp for schedule(static) nowait
    for (int k = from; k < to; ++k) {
      const int i = active[static_cast<size_t>(k)];
      double outflow = 0.0;
      for (int m = ringOffsets[i]; m < ringOffsets[i + 1]; ++m) {
        const int j = ringNeighbors[m];
        const int e = ringEdgeIds[m];
        const double* c = frameNormals + 4 * static_cast<size_t>(e);
        const Complex ua = u[edgeFirst[e]], ub = u[edgeSecond[e]];
        const double along = (ua.real() * c[0] + ua.imag() * c[1]) + (ub.real() * c[2] + ub.imag() * c[3]);
        const double sign = i == edgeFirst[e] ? 1.0 : -1.0;
        const double speed = marked[j] ? 0.5 * (sign * along) : 0.0;
        speeds[m] = speed;
        outflow += positivePart(speed);
      }
      scratch.outflowRates(i) = outflow;
      if (wet.empty() || wet[static_cast<size_t>(i)])
        maxCourantHere = std::max(maxCourantHere, surface.h * outflow / surface.areas(i));
    }
#pragma omp critical(blot_threads_combine)
    {
      maxCourant = std::max(maxCourant, maxCourantHere);
    }
  });
  return maxCourant;
}

// Deforming surface: the dual-edge normal (#E by 3, m) of every edge between
// two active vertices of active[from, to) and its neighbours, computed once
// per edge (not once from each end) from its faces' unit normals and
// centroids, computed once per face (not once per dual edge at each end, six
// times), appended to scratch.activeEdges and activeFaces (marked). The same
// terms in the same order as dualEdgeNormal: the same bits.
void cacheDualNormals(const AdvectionSurface& surface, int from, int to, DensityAdvectionScratch& scratch) {
  const SurfaceTopology& topology = surface.topology;
  const std::vector<int>& active = scratch.activeVertices;
  const int* ringOffsets = topology.ringOffsets().data();
  const int* ringNeighbors = topology.ringNeighbors().data();
  const int* ringEdgeIds = topology.ringEdges().data();
  const char* marked = scratch.activeMarks.data();
  std::vector<int>& edges = scratch.activeEdges;
  std::vector<int>& faces = scratch.activeFaces;
  std::vector<char>& edgeMarks = scratch.edgeMarks;
  std::vector<char>& faceMarks = scratch.faceMarks;
  const std::vector<int>& edgeHalfedges = topology.edgeHalfedges();
  const std::vector<int>& twins = topology.halfedgeTwins();
  const int edgesBegin = static_cast<int>(edges.size()), facesBegin = static_cast<int>(faces.size());
  const auto addFace = [&](int halfedge) {
    if (halfedge < 0 || faceMarks[static_cast<size_t>(halfedge / 3)]) return;
    faceMarks[static_cast<size_t>(halfedge / 3)] = 1;
    faces.push_back(halfedge / 3);
  };
  for (int k = from; k < to; ++k) {
    const int i = active[static_cast<size_t>(k)];
    for (int m = ringOffsets[i]; m < ringOffsets[i + 1]; ++m) {
      const int e = ringEdgeIds[m];
      if (!marked[ringNeighbors[m]] || edgeMarks[static_cast<size_t>(e)]) continue;
      edgeMarks[static_cast<size_t>(e)] = 1;
      edges.push_back(e);
      const int first = edgeHalfedges[static_cast<size_t>(e)];
      addFace(first);
      addFace(twins[static_cast<size_t>(first)]);
    }
  }
  const int edgesEnd = static_cast<int>(edges.size()), facesEnd = static_cast<int>(faces.size());
  const auto cachedFace = [&](int f, Vector3& unitNormal, Vector3& centroid) {
    unitNormal = scratch.faceUnitNormals.row(f).transpose();
    centroid = scratch.faceCentroids.row(f).transpose();
  };
  const ExtrinsicGeometry& extrinsic = surface.extrinsic;
  threads::runLoop(edgesEnd - edgesBegin >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = facesBegin; k < facesEnd; ++k) {
      const int f = faces[static_cast<size_t>(k)];
      Vector3 unitNormal, centroid;
      faceNormalAndCentroid(topology, extrinsic.positions, f, unitNormal, centroid);
      scratch.faceUnitNormals.row(f) = unitNormal.transpose();
      scratch.faceCentroids.row(f) = centroid.transpose();
    }
#pragma omp for schedule(static)
    for (int k = edgesBegin; k < edgesEnd; ++k) {
      const int e = edges[static_cast<size_t>(k)];
      scratch.edgeDualNormals.row(e) = dualEdgeNormalFrom(topology, extrinsic.positions, e, cachedFace).transpose();
    }
  });
}

// Ring speeds (m²/s) and outflow rates on active[from, to), edges to inactive
// vertices closed: from the rest frame normals on a rigid surface, else from
// the world velocities (storeWorldVelocities) and the dual normals, cached
// here. Returns the largest Courant number h outflow_i / A_i over the wet
// ones. Raw pointers and no data-dependent branches (see positivePart).
double ringSpeedsAndOutflow(const AdvectionSurface& surface, const StainState& state, int from, int to,
                            DensityAdvectionScratch& scratch) {
  if (surface.rigid) return ringSpeedsAndOutflowRigid(surface, state, from, to, scratch);
  cacheDualNormals(surface, from, to, scratch);
  const std::vector<int>& active = scratch.activeVertices;
  const int* ringOffsets = surface.topology.ringOffsets().data();
  const int* ringNeighbors = surface.topology.ringNeighbors().data();
  const int* ringEdgeIds = surface.topology.ringEdges().data();
  const char* marked = scratch.activeMarks.data();
  const double* velocities3 = scratch.vertexVelocities.data();
  const double* dualNormals = scratch.edgeDualNormals.data();
  double* speeds = scratch.ringSpeeds.data();
  const std::vector<char>& wet = surface.wet;
  double maxCourant = 0.0;
  threads::runLoop(to - from >= kMinParallelVertices, [&] {
    decltype(maxCourant) maxCourantHere = threads::lowest<decltype(maxCourant)>();
#pragma omp for schedule(static) nowait
    for (int k = from; k < to; ++k) {
      const int i = active[static_cast<size_t>(k)];
      const double* ui = velocities3 + 3 * static_cast<size_t>(i);
      double outflow = 0.0;
      for (int m = ringOffsets[i]; m < ringOffsets[i + 1]; ++m) {
        const int j = ringNeighbors[m];
        const double* uj = velocities3 + 3 * static_cast<size_t>(j);
        // ½(U_i + U_j)·N_ij, written so that j's ring gets the exact negative
        // (sums commute; N_ji is N_ij negated, and negation is exact in IEEE).
        // An edge to an inactive j has no cached normal: its speed is 0.
        const double* dual = dualNormals + 3 * static_cast<size_t>(ringEdgeIds[m]);
        const double sign = i < j ? 1.0 : -1.0;
        const double along = sign * ((ui[0] + uj[0]) * dual[0] + (ui[1] + uj[1]) * dual[1] +
                                     (ui[2] + uj[2]) * dual[2]);
        const double speed = marked[j] ? 0.5 * along : 0.0;
        speeds[m] = speed;
        outflow += positivePart(speed);
      }
      scratch.outflowRates(i) = outflow;
      if (wet.empty() || wet[static_cast<size_t>(i)])
        maxCourantHere = std::max(maxCourantHere, surface.h * outflow / surface.areas(i));
    }
#pragma omp critical(blot_threads_combine)
    {
      maxCourant = std::max(maxCourant, maxCourantHere);
    }
  });
  return maxCourant;
}

// Unmarks the cached edges and faces and forgets their lists.
void clearEdgeAndFaceMarks(DensityAdvectionScratch& scratch) {
  for (const int e : scratch.activeEdges) scratch.edgeMarks[static_cast<size_t>(e)] = 0;
  for (const int f : scratch.activeFaces) scratch.faceMarks[static_cast<size_t>(f)] = 0;
}

// The upwind transport over the active set: per-step shares, `substeps`
// sub-steps of length tau (s) alternating between the two mass buffers (kg),
// densities written back (σ = m / A), the active marks cleared and every
// entry a later call may read as an inactive neighbour left at 0. Returns
// how many vertices had their outflow limited to what they hold.
int transportMasses(const AdvectionSurface& surface, int substeps, double tau, StainState& state,
                    DensityAdvectionScratch& scratch) {
  const std::vector<int>& active = scratch.activeVertices;
  std::vector<char>& marks = scratch.activeMarks;
  const Vector& areas = surface.areas;
  const int count = static_cast<int>(active.size());
  const int* ringOffsets = surface.topology.ringOffsets().data();
  const int* ringNeighbors = surface.topology.ringNeighbors().data();
  const double* speeds = scratch.ringSpeeds.data();
  Vector* solventBuffers[2] = {&scratch.massSolvent, &scratch.nextMassSolvent};
  Vector* soluteBuffers[2] = {&scratch.massSolute, &scratch.nextMassSolute};
  int limited = 0;
  // One parallel region for all the loops below (their implicit barriers order
  // them), or none for a small set (numerics/threads.h).
  threads::runLoop(count >= kMinParallelVertices, [&] {
    // Per-step shares: kept fraction 1 − f_i and giving ratio f_i / outflow_i.
    int limitedHere = 0;  // this thread's count, added below (numerics/threads.h)
#pragma omp for schedule(static)
    for (int k = 0; k < count; ++k) {
      const int i = active[static_cast<size_t>(k)];
      const double outflow = scratch.outflowRates(i);
      const double courant = tau * outflow / areas(i);
      if (courant > 1.0) ++limitedHere;
      const double fraction = std::min(courant, 1.0);
      scratch.keptFractions(i) = 1.0 - fraction;
      scratch.givingRatios(i) = outflow > 0.0 ? fraction / outflow : 0.0;
      scratch.massSolvent(i) = areas(i) * state.solvent(i);
      scratch.massSolute(i) = areas(i) * state.solute(i);
    }
#pragma omp critical(blot_threads_combine)
    limited += limitedHere;
    // Share of neighbour j's mass flowing into i: g_j · speed(j -> i), where
    // speed(j -> i) = −ringSpeeds(m) bit for bit.
    const double* giving = scratch.givingRatios.data();
    double* shares = scratch.ringInflowShares.data();
#pragma omp for schedule(static)
    for (int k = 0; k < count; ++k) {
      const int i = active[static_cast<size_t>(k)];
      for (int m = ringOffsets[i]; m < ringOffsets[i + 1]; ++m) {
        shares[m] = giving[ringNeighbors[m]] * positivePart(-speeds[m]);
      }
    }
    // Sub-steps alternate between the two mass buffers; the implicit barrier
    // after each loop orders them. Zero shares are multiplied, not skipped
    // (half of them are zero, in no pattern a branch predictor could learn).
    const double* kept = scratch.keptFractions.data();
    for (int step = 0; step < substeps; ++step) {
      const double* solvent = solventBuffers[step % 2]->data();
      const double* solute = soluteBuffers[step % 2]->data();
      double* nextSolvent = solventBuffers[(step + 1) % 2]->data();
      double* nextSolute = soluteBuffers[(step + 1) % 2]->data();
#pragma omp for schedule(static)
      for (int k = 0; k < count; ++k) {
        const int i = active[static_cast<size_t>(k)];
        double newSolvent = kept[i] * solvent[i];
        double newSolute = kept[i] * solute[i];
        for (int m = ringOffsets[i]; m < ringOffsets[i + 1]; ++m) {
          const int j = ringNeighbors[m];
          newSolvent += shares[m] * solvent[j];
          newSolute += shares[m] * solute[j];
        }
        nextSolvent[i] = newSolvent;
        nextSolute[i] = newSolute;
      }
    }
    const Vector& solvent = *solventBuffers[substeps % 2];
    const Vector& solute = *soluteBuffers[substeps % 2];
#pragma omp for schedule(static)
    for (int k = 0; k < count; ++k) {
      const int i = active[static_cast<size_t>(k)];
      state.solvent(i) = solvent(i) / areas(i);
      state.solute(i) = solute(i) / areas(i);
      marks[static_cast<size_t>(i)] = 0;
    }
    // Leave every entry a later call may read as an inactive neighbour at 0.
#pragma omp for schedule(static)
    for (int k = 0; k < count; ++k) {
      const int i = active[static_cast<size_t>(k)];
      scratch.givingRatios(i) = 0.0;
      scratch.massSolvent(i) = scratch.massSolute(i) = 0.0;
      scratch.nextMassSolvent(i) = scratch.nextMassSolute(i) = 0.0;
    }
  });
  return limited;
}

}  // namespace

DensityAdvectionReport advectDensities(const StepContext& ctx, const SurfaceTopology& topology,
                                       const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry& extrinsic,
                                       const std::vector<char>& wet, DensityAdvectionScratch& scratch,
                                       StainState& state, const EdgeFrameNormals* restEdgeFrameNormals,
                                       const std::vector<char>* reach, const std::vector<int>* among) {
  const int n = topology.vertexCount();
  const int edgeCount = topology.edgeCount();
  const int faceCount = topology.faceCount();
  if (static_cast<int>(scratch.activeMarks.size()) != n || scratch.massSolvent.size() != n ||
      scratch.ringSpeeds.size() != 2 * static_cast<Eigen::Index>(edgeCount) ||
      static_cast<int>(scratch.faceMarks.size()) != faceCount) {
    scratch.resize(n, edgeCount, faceCount);  // first call only
  }
  // Rigid motion: the same speed from the rest frames (see the header).
  const bool rigid = restEdgeFrameNormals != nullptr && extrinsic.rigid &&
                     restEdgeFrameNormals->rows() == edgeCount;
  const AdvectionSurface surface{topology,
                                 extrinsic,
                                 intrinsic.vertexDualAreas,
                                 wet,
                                 rigid,
                                 rigid ? restEdgeFrameNormals->data() : nullptr,
                                 ctx.h};
  DensityAdvectionReport report;
  const ActiveRings rings = activateWetSet(topology, wet, reach, among, scratch);
  scratch.activeEdges.clear();
  scratch.activeFaces.clear();

  if (!rigid) storeWorldVelocities(extrinsic, state, 0, rings.firstRingEnd, scratch);
  const double maxCourant = ringSpeedsAndOutflow(surface, state, 0, rings.wetEnd, scratch);
  report.maxCourant = maxCourant;
  if (!(maxCourant > 0.0)) {  // nothing moves (or non-finite input: leave the state as is)
    for (const int i : scratch.activeVertices) scratch.activeMarks[static_cast<size_t>(i)] = 0;
    scratch.activeVertices.clear();
    clearEdgeAndFaceMarks(scratch);
    return report;
  }
  const int substeps =
      static_cast<int>(std::min<double>(std::ceil(maxCourant), std::max(1, ctx.maxAdvectionSubsteps)));
  const double tau = ctx.h / substeps;
  report.substeps = substeps;

  // Rings 2..n of the halo, then speeds on everything but the wet set (done).
  if (!rings.everything) {
    int ringBegin = rings.wetEnd, ringEnd = rings.firstRingEnd;
    for (int ring = 2; ring <= substeps && ringEnd > ringBegin; ++ring) {
      addNextRing(topology, ringBegin, ringEnd, scratch.activeVertices, scratch.activeMarks, reach);
      ringBegin = ringEnd;
      ringEnd = static_cast<int>(scratch.activeVertices.size());
    }
    if (!rigid) storeWorldVelocities(extrinsic, state, rings.firstRingEnd, ringEnd, scratch);
    ringSpeedsAndOutflow(surface, state, rings.wetEnd, ringEnd, scratch);
  }
  report.activeVertices = static_cast<int>(scratch.activeVertices.size());
  report.limitedVertices = transportMasses(surface, substeps, tau, state, scratch);
  clearEdgeAndFaceMarks(scratch);
  return report;
}

}  // namespace blot::stain
