// Stage "advect velocity": semi-Lagrangian advection of the tangent velocity
// in the flattened one-ring, with the triangle-strip walk (paper sec. 3.1).
//
// Design note: docs/design-notes.md, "stain/src/stages/velocity_advection.cpp".
#include <blot/stain/stages/velocity_advection.h>

#include <cmath>
#include <limits>

#include "numerics/threads.h"
#include "numerics/vector_trig.h"

namespace blot::stain {
namespace {

constexpr int kMaxStripTriangles = 1000;
// Below this many vertices the loops run on one thread (fork/join would cost
// more than the work; tuned in tests/bench).
constexpr int kMinParallelVertices = 2048;

// z-component of the 2D cross product a × b.
inline double cross(const Complex& a, const Complex& b) { return a.real() * b.imag() - a.imag() * b.real(); }

inline Complex unitFromAngle(double angle) { return {std::cos(angle), std::sin(angle)}; }

struct Tables {
  const Triangles& faces;
  const std::vector<int>& offsets;
  const std::vector<int>& neighbors;
  const std::vector<int>& ringFaces;
  const std::vector<signed char>& ringCorners;
  const std::vector<int>& twins;
  const std::vector<char>& isBoundary;
  const ComplexVector& ringPoints;
  const ComplexVector& ringTransports;
  const IntrinsicGeometry& geometry;
  const Eigen::MatrixX3i& faceEdges;

  /// Half-edge h = 3f + k from a = v_k to b = v_{k+1}: (c − a)/(b − a) for the
  /// apex c = v_{k+2} of face f laid out flat, i.e. (ℓ_ca/ℓ_ab) exp(iγ_a).
  Complex apexRatio(int h) const {
    const int f = h / 3, k = h % 3;
    const double lengthAB = geometry.edgeLengths(faceEdges(f, k));
    const double lengthCA = geometry.edgeLengths(faceEdges(f, (k + 2) % 3));
    return (lengthCA / lengthAB) * unitFromAngle(geometry.faceCornerAngles(f, k));
  }
  /// Half-edge h = 3f + k: exp(iφ(f, k)), vertex faces(f, k)'s frame -> face f's frame.
  Complex faceRotation(int h) const { return unitFromAngle(geometry.faceTransportAngles(h / 3, h % 3)); }
};

// Fills vertex v's ring entries of ringPoints and ringTransports from `geometry`.
void fillRing(const SurfaceTopology& topology, const IntrinsicGeometry& geometry, int v, ComplexVector& ringPoints,
              ComplexVector& ringTransports) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringEdges = topology.ringEdges();
  const int begin = offsets[static_cast<size_t>(v)], end = offsets[static_cast<size_t>(v) + 1];
  // The ring's polar angles as unit phases in one vector batch, then scaled.
  trig::unitPhases(geometry.polarMap.ringAngles.data() + begin, ringPoints.data() + begin, end - begin);
  for (int m = begin; m < end; ++m) ringPoints(m) *= geometry.edgeLengths(ringEdges[static_cast<size_t>(m)]);
  fillRingTransports(topology, geometry.edgeTransportAngles, v, ringTransports.data());
}

struct Walk {
  Complex value;
  // The foot point as a convex combination of (at most) three vertices, the
  // weights that produced `value` (before the transports): the frame-velocity
  // stencil of the Coriolis stage (VelocityAdvectionScratch::foot*).
  int footVertices[3] = {0, 0, 0};
  double footWeights[3] = {1.0, 0.0, 0.0};
  int stripSteps = 0;
  bool boundaryStop = false;
  bool capped = false;
};

// Sets walk's foot stencil to Σ w_k vertex_k (weights already normalised).
inline void setFoot(Walk& walk, int a, double wa, int b, double wb, int c, double wc) {
  walk.footVertices[0] = a;
  walk.footVertices[1] = b;
  walk.footVertices[2] = c;
  walk.footWeights[0] = wa;
  walk.footWeights[1] = wb;
  walk.footWeights[2] = wc;
}

// Interpolates the velocity at point x of strip face g (corner positions z in
// frame i's plane), each corner's velocity carried into frame i through the
// face frame (see design note), into walk.value with its foot stencil; false
// (walk untouched) if the face is degenerate.
bool interpolateInFace(const Tables& t, const ComplexVector& u, int g, const Complex (&z)[3], const Complex& x,
                       const Complex& anchor, Walk& walk) {
  const Complex axis = z[1] - z[0];
  const double axisLength = std::sqrt(std::norm(axis));
  double l0 = cross(z[1] - x, z[2] - x), l1 = cross(z[2] - x, z[0] - x), l2 = cross(z[0] - x, z[1] - x);
  l0 = l0 > 0.0 ? l0 : 0.0;
  l1 = l1 > 0.0 ? l1 : 0.0;
  l2 = l2 > 0.0 ? l2 : 0.0;
  const double sum = l0 + l1 + l2;
  if (!(axisLength > 0.0) || !(sum > 0.0)) return false;
  const Complex toPlane = anchor * (axis / axisLength);
  const int h0 = 3 * g;
  const Complex blend = l0 * (t.faceRotation(h0) * u(t.faces(g, 0))) +
                        l1 * (t.faceRotation(h0 + 1) * u(t.faces(g, 1))) +
                        l2 * (t.faceRotation(h0 + 2) * u(t.faces(g, 2)));
  walk.value = toPlane * blend / sum;
  setFoot(walk, t.faces(g, 0), l0 / sum, t.faces(g, 1), l1 / sum, t.faces(g, 2), l2 / sum);
  return true;
}

// Backtracks vertex i by the plane displacement d and returns the interpolated,
// transported velocity at the foot point.
Walk backtrack(const Tables& t, const ComplexVector& u, int i, const Complex& d) {
  Walk walk;
  walk.value = u(i);
  walk.footVertices[0] = i;  // foot = i until a branch below moves it
  if (d == Complex(0.0, 0.0)) return walk;
  const int begin = t.offsets[static_cast<size_t>(i)], end = t.offsets[static_cast<size_t>(i) + 1];
  const bool boundary = t.isBoundary[static_cast<size_t>(i)] != 0;

  // Ring sector containing d: P_m at or clockwise of d, P_m2 counter-clockwise
  // of it (exact for sectors below π, i.e. every sector of a sane polar map;
  // cross(a, b) = −cross(b, a) bit for bit, so a ray along a ring edge falls
  // in exactly one sector). A boundary fan's last sector also takes its
  // closing edge; a ray outside a boundary fan leaves the mesh at once.
  const int sectorEnd = boundary ? end - 1 : end;
  int m = -1;
  for (int k = begin; k < sectorEnd; ++k) {
    const int k2 = k + 1 < end ? k + 1 : begin;
    const double after = cross(d, t.ringPoints(k2));
    if (cross(t.ringPoints(k), d) >= 0.0 && (after > 0.0 || (boundary && k2 == end - 1 && after == 0.0))) {
      m = k;
      break;
    }
  }
  if (m < 0) {
    walk.boundaryStop = boundary;  // interior: a fan with a sector of π or more; keep u_i
    return walk;
  }
  const int m2 = m + 1 < end ? m + 1 : begin;

  // Ring triangle (i, j_m, j_m2): d = λ1 P1 + λ2 P2.
  const Complex p1 = t.ringPoints(m), p2 = t.ringPoints(m2);
  const double det = cross(p1, p2);
  if (!(det > 0.0)) return walk;  // sector of π or more (polar map breaks down): keep u_i
  double l1 = cross(d, p2) / det, l2 = cross(p1, d) / det;
  l1 = l1 > 0.0 ? l1 : 0.0;
  l2 = l2 > 0.0 ? l2 : 0.0;
  const double s = l1 + l2;
  const Complex u1 = t.ringTransports(m) * u(t.neighbors[static_cast<size_t>(m)]);
  const Complex u2 = t.ringTransports(m2) * u(t.neighbors[static_cast<size_t>(m2)]);
  const int j1 = t.neighbors[static_cast<size_t>(m)], j2 = t.neighbors[static_cast<size_t>(m2)];
  if (s <= 1.0) {
    walk.value = (1.0 - s) * u(i) + l1 * u1 + l2 * u2;
    setFoot(walk, i, 1.0 - s, j1, l1, j2, l2);
    return walk;
  }
  // The ray leaves the ring through the far edge j_m -> j_m2 (half-edge of
  // ring face f after i's corner) at t = 1/s.
  const int f = t.ringFaces[static_cast<size_t>(m)];
  const int farHalfedge = 3 * f + (t.ringCorners[static_cast<size_t>(m)] + 1) % 3;
  int h = t.twins[static_cast<size_t>(farHalfedge)];
  // Where the ray crosses the far edge: the fallback of a degenerate strip face.
  const Complex edgeValue = (l1 * u1 + l2 * u2) / s;
  if (h < 0) {
    walk.boundaryStop = true;
    walk.value = edgeValue;
    setFoot(walk, j1, l1 / s, j2, l2 / s, j1, 0.0);
    return walk;
  }

  // Strip walk. Invariant: the ray entered face g through half-edge h = a -> b,
  // with a on its left and b on its right.
  Complex za = p2, zb = p1;
  int g = h / 3, k = h % 3;
  Complex zc = za + (zb - za) * t.apexRatio(h);
  Complex z[3];
  z[k] = za;
  z[(k + 1) % 3] = zb;
  z[(k + 2) % 3] = zc;
  // Anchor κ: the crossed ring edge's vertices get their ring transports
  // (mean of the two estimates; they agree exactly on flat meshes).
  Complex anchor(1.0, 0.0);
  {
    const Complex axis = z[1] - z[0];
    const Complex toPlane = axis / std::sqrt(std::norm(axis));
    const Complex fromA = t.ringTransports(m2) * std::conj(toPlane * t.faceRotation(3 * g + k));
    const Complex fromB = t.ringTransports(m) * std::conj(toPlane * t.faceRotation(3 * g + (k + 1) % 3));
    const Complex mean = fromA + fromB;
    const double length = std::sqrt(std::norm(mean));
    anchor = length > 1e-12 ? mean / length : fromA;
  }
  walk.stripSteps = 1;
  const auto interpolateOrEdge = [&](const Complex& x) {
    if (!interpolateInFace(t, u, g, z, x, anchor, walk)) {
      walk.value = edgeValue;
      setFoot(walk, j1, l1 / s, j2, l2 / s, j1, 0.0);
    }
  };
  while (true) {
    // Exit through b -> c if the apex is left of the ray, else through c -> a.
    int exitHalfedge;
    Complex p, q;  // exit edge p -> q, p right of the ray, q left
    if (cross(d, zc) > 0.0) {
      exitHalfedge = SurfaceTopology::next(h);
      p = zb;
      q = zc;
    } else {
      exitHalfedge = SurfaceTopology::prev(h);
      p = zc;
      q = za;
    }
    const Complex edge = q - p;
    const double denominator = cross(d, edge);
    const double tExit =
        denominator > 0.0 ? cross(p, edge) / denominator : std::numeric_limits<double>::infinity();
    if (tExit >= 1.0) {
      interpolateOrEdge(d);
      return walk;
    }
    const Complex exitPoint = tExit * d;
    const int twin = t.twins[static_cast<size_t>(exitHalfedge)];
    if (twin < 0 || walk.stripSteps >= kMaxStripTriangles) {
      (twin < 0 ? walk.boundaryStop : walk.capped) = true;
      interpolateOrEdge(exitPoint);
      return walk;
    }
    h = twin;
    g = h / 3;
    k = h % 3;
    za = q;
    zb = p;
    zc = za + (zb - za) * t.apexRatio(h);
    z[k] = za;
    z[(k + 1) % 3] = zb;
    z[(k + 2) % 3] = zc;
    ++walk.stripSteps;
  }
}

}  // namespace

void VelocityAdvectionScratch::prepare(const SurfaceTopology& topology) {
  const auto entries = static_cast<Eigen::Index>(topology.ringNeighbors().size());
  resize(topology.vertexCount());
  // Written once, so that no step maps their pages.
  advected.setZero();
  footVertices.setZero();
  footWeights.setZero();
  ringPoints.setZero(entries);
  ringTransports.setZero(entries);
  ringRebuildCounts.assign(static_cast<size_t>(topology.vertexCount()), -1);
}

VelocityAdvectionReport advectVelocity(const StepContext& ctx, const SurfaceTopology& topology,
                                       const IntrinsicGeometry& geometry, const std::vector<char>& wet,
                                       VelocityAdvectionScratch& scratch, StainState& state,
                                       const std::vector<int>* among) {
  const int n = topology.vertexCount();
  if (scratch.advected.size() != n || scratch.footVertices.rows() != n ||
      scratch.ringPoints.size() != static_cast<Eigen::Index>(topology.ringNeighbors().size()) ||
      scratch.ringRebuildCounts.size() != static_cast<size_t>(n)) {
    scratch.prepare(topology);
  }
  const Tables tables{topology.faces(),       topology.ringOffsets(),   topology.ringNeighbors(),
                      topology.ringFaces(),   topology.ringCorners(),   topology.halfedgeTwins(),
                      topology.vertexIsBoundary(), scratch.ringPoints, scratch.ringTransports,
                      geometry,               topology.faceEdges()};
  const int rebuildCount = geometry.rebuildCount;
  const ComplexVector& u = state.velocities;
  ComplexVector& advected = scratch.advected;
  const bool allWet = wet.empty();
  const double h = ctx.h;
  int stripSteps = 0, boundaryStops = 0, cappedWalks = 0;

  // Every walk reads u as it was (advected is written, u only after).
  const int visits = visitCount(n, among);
  // Walks differ in length: a dynamic schedule on threads, a plain loop
  // otherwise (an orphaned dynamic loop would allocate; numerics/threads.h).
  const auto walkFrom = [&](int k, int& steps, int& stops, int& capped) {
    const int i = visited(k, among);
    if (!allWet && !wet[static_cast<size_t>(i)]) return;
    // i's ring entries are i's alone: filling them here is race-free.
    int& filledFrom = scratch.ringRebuildCounts[static_cast<size_t>(i)];
    if (filledFrom != rebuildCount) {
      fillRing(topology, geometry, i, scratch.ringPoints, scratch.ringTransports);
      filledFrom = rebuildCount;
    }
    const Walk walk = backtrack(tables, u, i, -h * u(i));
    advected(i) = walk.value;
    for (int c = 0; c < 3; ++c) {
      scratch.footVertices(i, c) = walk.footVertices[c];
      scratch.footWeights(i, c) = walk.footWeights[c];
    }
    steps += walk.stripSteps;
    stops += walk.boundaryStop ? 1 : 0;
    capped += walk.capped ? 1 : 0;
  };
  if (threads::worthThreads(visits >= kMinParallelVertices)) {
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : stripSteps, boundaryStops, cappedWalks)
    for (int k = 0; k < visits; ++k) walkFrom(k, stripSteps, boundaryStops, cappedWalks);
  } else {
    for (int k = 0; k < visits; ++k) walkFrom(k, stripSteps, boundaryStops, cappedWalks);
  }

  threads::runLoop(visits >= kMinParallelVertices, [&] {
#pragma omp for schedule(static)
    for (int k = 0; k < visits; ++k) {
      const int i = visited(k, among);
      if (allWet || wet[static_cast<size_t>(i)]) state.velocities(i) = advected(i);
    }
  });

  VelocityAdvectionReport report;
  report.stripSteps = stripSteps;
  report.boundaryStops = boundaryStops;
  report.cappedWalks = cappedWalks;
  return report;
}

}  // namespace blot::stain
