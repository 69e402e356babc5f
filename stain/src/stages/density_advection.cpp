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
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  const std::vector<int>& ringEdges = topology.ringEdges();
  const Vector& areas = intrinsic.vertexDualAreas;
  const double h = ctx.h;
  std::vector<int>& active = scratch.activeVertices;
  std::vector<char>& marks = scratch.activeMarks;
  DensityAdvectionReport report;

  // Layer 0: the wet vertices (or everything).
  int wetCount = 0;
  const int visits = visitCount(n, among);
  if (!wet.empty()) {
    for (int k = 0; k < visits; ++k) wetCount += wet[static_cast<size_t>(visited(k, among))] ? 1 : 0;
  }
  // With a reach set the rings are built even for a large wet set: liquid
  // must not leave the band (its outer rings hold no advected velocity).
  const bool everything = wet.empty() || (reach == nullptr && 2 * wetCount >= n);
  active.clear();
  if (everything) {
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
  const int wetEnd = static_cast<int>(active.size());
  if (!everything) addNextRing(topology, 0, wetEnd, active, marks, reach);
  const int firstRingEnd = static_cast<int>(active.size());

  // U_i = F_i u_i (world) and p_i, row-major, on active[from, to).
  auto worldVelocities = [&](int from, int to) {
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
  };
  // Ring speeds and outflow rates on active[from, to); edges to inactive
  // vertices are closed. Returns the largest Courant number over the wet ones.
  // Raw pointers and no data-dependent branches (see positivePart).
  const int* ringOffsets = offsets.data();
  const int* ringNeighbors = neighbors.data();
  const int* ringEdgeIds = ringEdges.data();
  const char* marked = marks.data();
  const double* velocities3 = scratch.vertexVelocities.data();
  double* speeds = scratch.ringSpeeds.data();
  // Rigid motion: the same speed from the rest frames (see the header), u
  // read as it is stored; the expression for an edge is evaluated identically
  // from both ends (a = edgeVertices(e, 0) first), so the two entries are
  // again bitwise opposite.
  const bool rigid = restEdgeFrameNormals != nullptr && extrinsic.rigid &&
                     restEdgeFrameNormals->rows() == edgeCount;
  const double* frameNormals = rigid ? restEdgeFrameNormals->data() : nullptr;
  const int* edgeFirst = topology.edgeVertices().data();
  const int* edgeSecond = edgeFirst + edgeCount;
  const Complex* u = state.velocities.data();
  auto ringSpeedsAndOutflowRigid = [&](int from, int to) {
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
          maxCourantHere = std::max(maxCourantHere, h * outflow / areas(i));
      }
#pragma omp critical(blot_threads_combine)
      {
        maxCourant = std::max(maxCourant, maxCourantHere);
      }
    });
    return maxCourant;
  };
  // Deforming surface: the dual-edge normal of every edge between two active
  // vertices of active[from, to) and its neighbours, computed once per edge
  // (not once from each end) from its faces' unit normals and centroids,
  // computed once per face (not once per dual edge at each end, six times).
  // The same terms in the same order as dualEdgeNormal: the same bits.
  std::vector<int>& edges = scratch.activeEdges;
  std::vector<int>& faces = scratch.activeFaces;
  std::vector<char>& edgeMarks = scratch.edgeMarks;
  std::vector<char>& faceMarks = scratch.faceMarks;
  const std::vector<int>& edgeHalfedges = topology.edgeHalfedges();
  const std::vector<int>& twins = topology.halfedgeTwins();
  edges.clear();
  faces.clear();
  auto cacheDualNormals = [&](int from, int to) {
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
  };
  const double* dualNormals = scratch.edgeDualNormals.data();
  auto ringSpeedsAndOutflow = [&](int from, int to) {
    if (rigid) return ringSpeedsAndOutflowRigid(from, to);
    cacheDualNormals(from, to);
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
          maxCourantHere = std::max(maxCourantHere, h * outflow / areas(i));
      }
#pragma omp critical(blot_threads_combine)
      {
        maxCourant = std::max(maxCourant, maxCourantHere);
      }
    });
    return maxCourant;
  };

  if (!rigid) worldVelocities(0, firstRingEnd);
  const double maxCourant = ringSpeedsAndOutflow(0, wetEnd);
  report.maxCourant = maxCourant;
  if (!(maxCourant > 0.0)) {  // nothing moves (or non-finite input: leave the state as is)
    for (const int i : active) marks[static_cast<size_t>(i)] = 0;
    active.clear();
    for (const int e : edges) edgeMarks[static_cast<size_t>(e)] = 0;
    for (const int f : faces) faceMarks[static_cast<size_t>(f)] = 0;
    return report;
  }
  const int substeps =
      static_cast<int>(std::min<double>(std::ceil(maxCourant), std::max(1, ctx.maxAdvectionSubsteps)));
  const double tau = h / substeps;
  report.substeps = substeps;

  // Rings 2..n of the halo, then speeds on everything but the wet set (done).
  if (!everything) {
    int ringBegin = wetEnd, ringEnd = firstRingEnd;
    for (int ring = 2; ring <= substeps && ringEnd > ringBegin; ++ring) {
      addNextRing(topology, ringBegin, ringEnd, active, marks, reach);
      ringBegin = ringEnd;
      ringEnd = static_cast<int>(active.size());
    }
    if (!rigid) worldVelocities(firstRingEnd, ringEnd);
    ringSpeedsAndOutflow(wetEnd, ringEnd);
  }
  const int count = static_cast<int>(active.size());
  report.activeVertices = count;

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
  for (const int e : edges) edgeMarks[static_cast<size_t>(e)] = 0;
  for (const int f : faces) faceMarks[static_cast<size_t>(f)] = 0;
  report.limitedVertices = limited;
  return report;
}

}  // namespace blot::stain
