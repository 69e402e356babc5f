// The liquid band: the wet set, the rings the step can reach, and the
// velocity extended onto them (docs/transport.md, "The liquid band").
//
// Design note: docs/design-notes.md, "stain/src/stages/liquid_band.cpp".
#include <blot/stain/stages/liquid_band.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace blot::stain {
namespace {

// Resets every per-vertex entry of the last band to "outside".
void clearBand(LiquidBand& band) {
  for (const int v : band.vertices) {
    const size_t k = static_cast<size_t>(v);
    band.levels[k] = -1;
    band.wetMask[k] = band.haloMask[k] = band.reachMask[k] = band.bandMask[k] = band.diffusionMask[k] = 0;
  }
  band.vertices.clear();
  band.ringEnds.clear();
  band.dampVertices.clear();
  band.absorbingVertices.clear();
  for (const int v : band.soakedVertices) band.soakedMask[static_cast<size_t>(v)] = 0;
  band.soakedVertices.clear();
  band.rings = band.reachRings = band.haloCount = band.regrowths = band.interiorCount = 0;
  band.speedBound = 0;
  band.footInStar = false;
}

}  // namespace

void LiquidBand::resize(int vertexCount, int ringEntries) {
  const size_t n = static_cast<size_t>(vertexCount);
  vertices.clear();
  vertices.reserve(n);
  ringEnds.clear();
  ringEnds.reserve(n + 1);
  dampVertices.clear();
  dampVertices.reserve(n);
  absorbingVertices.clear();
  absorbingVertices.reserve(n);
  soakedVertices.clear();
  soakedVertices.reserve(n);
  soakedMask.assign(n, 0);
  candidates.clear();
  candidates.reserve(n);
  candidateMarks.assign(n, 0);
  scanAll = true;
  levels.assign(n, -1);
  wetMask.assign(n, 0);
  haloMask.assign(n, 0);
  reachMask.assign(n, 0);
  bandMask.assign(n, 0);
  diffusionMask.assign(n, 0);
  weights = Vector::Zero(vertexCount);
  distances.assign(n, Distances());
  rings = reachRings = haloCount = regrowths = interiorCount = 0;
  speedBound = 0;
  footInStar = false;
  if (ringEntries > 0) {
    ringTransports.setZero(ringEntries);
    ringRebuildCounts.assign(n, -1);  // no entry filled yet
  }
}

namespace {

// Files vertex i under the wet set, the damp, absorbing or soaked list (index
// order when called in index order); false when it is none of them.
bool classify(double wetThreshold, bool soakedApart, const StainState& state, int i, LiquidBand& band) {
  if (!(state.solvent[i] > wetThreshold || state.absorbedSolvent[i] > wetThreshold ||
        state.solute[i] > wetThreshold)) {
    const bool damp = state.solvent[i] + state.solute[i] > 0;
    const bool absorbing = state.absorbedSolvent[i] > 0;
    if (damp) band.dampVertices.push_back(i);
    if (absorbing) band.absorbingVertices.push_back(i);
    return damp || absorbing;
  }
  const size_t k = static_cast<size_t>(i);
  // The test clearVelocityWithoutFreeLiquid clears u by.
  if (soakedApart && !(state.solvent[i] + state.solute[i] > wetThreshold) &&
      state.absorbedSolvent[i] > wetThreshold) {
    band.soakedVertices.push_back(i);
    band.soakedMask[k] = 1;
    band.absorbingVertices.push_back(i);
    return true;
  }
  band.vertices.push_back(i);
  band.levels[k] = 0;
  band.wetMask[k] = band.haloMask[k] = band.reachMask[k] = band.bandMask[k] = band.diffusionMask[k] =
      LiquidBand::kHoldsLiquid;
  return true;
}

}  // namespace

void markWetVertices(double wetThreshold, const StainState& state, LiquidBand& band, bool soakedApart) {
  clearBand(band);
  for (const int v : band.candidates) band.candidateMarks[static_cast<size_t>(v)] = 0;
  band.candidates.clear();
  const int n = state.vertexCount();
  for (int i = 0; i < n; ++i)
    if (classify(wetThreshold, soakedApart, state, i, band)) band.noteChanged(i);
  band.ringEnds.push_back(static_cast<int>(band.vertices.size()));
  band.scanAll = false;
}

void updateWetVertices(double wetThreshold, const StainState& state, LiquidBand& band, bool soakedApart) {
  // Sorting more than an eighth of the mesh costs more than the scan.
  if (band.scanAll || 8 * band.candidates.size() > band.candidateMarks.size()) {
    markWetVertices(wetThreshold, state, band, soakedApart);
    return;
  }
  clearBand(band);
  // The vertices outside the candidates are none of wet, damp or absorbing
  // (LiquidBand::candidates), so visiting the candidates in index order
  // files every vertex the full scan would, in its order. The list shrinks
  // to those filed, in place.
  std::vector<int>& list = band.candidates;
  std::sort(list.begin(), list.end());
  size_t kept = 0;
  for (size_t k = 0; k < list.size(); ++k) {
    const int i = list[k];
    if (classify(wetThreshold, soakedApart, state, i, band)) {
      list[kept++] = i;
    } else {
      band.candidateMarks[static_cast<size_t>(i)] = 0;
    }
  }
  list.resize(kept);
  band.ringEnds.push_back(static_cast<int>(band.vertices.size()));
}

void shrinkBandToWetSet(LiquidBand& band) {
  const int wetCount = band.wetCount();
  for (int k = wetCount; k < band.size(); ++k) {
    const size_t ii = static_cast<size_t>(band.vertices[static_cast<size_t>(k)]);
    band.levels[ii] = -1;
    band.haloMask[ii] = band.reachMask[ii] = band.bandMask[ii] = band.diffusionMask[ii] = 0;
  }
  band.vertices.resize(static_cast<size_t>(wetCount));
  band.ringEnds.resize(band.ringEnds.empty() ? 0 : 1);
  band.rings = band.reachRings = band.haloCount = band.interiorCount = 0;
}

namespace {

// Sizes band.ringTransports (one entry per SurfaceTopology::ringNeighbors
// entry) and band.ringRebuildCounts (#V) for the topology; allocates on the
// first call only (LiquidBand::resize with ringEntries sizes them at build).
void sizeRingTables(const SurfaceTopology& topology, LiquidBand& band) {
  const int n = topology.vertexCount();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  if (band.ringTransports.size() != static_cast<Eigen::Index>(neighbors.size()) ||
      band.ringRebuildCounts.size() != static_cast<size_t>(n)) {
    band.ringTransports.resize(static_cast<Eigen::Index>(neighbors.size()));
    band.ringRebuildCounts.assign(static_cast<size_t>(n), -1);
  }
}

// Vertex v's ring entries of band.ringTransports (exp(iθ_vj), eq. 6) and its
// band.distances[v].shortestEdge and .starRadius (m, intrinsic), filled now
// (fillVertexTables: once per intrinsic rebuild). Without edge lengths the
// shortest edge is 0 (the band then covers the component: the distance to
// cover is infinite); without face areas the star radius is 0 (no foot point
// is then taken to be in its star). The velocity advection keeps its own copy
// of the transports: the band is built before it.
void fillVertexTablesNow(const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic, int v,
                         LiquidBand& band) {
  const bool haveLengths = intrinsic.edgeLengths.size() > 0;
  const bool haveAreas = haveLengths && intrinsic.faceAreas.size() == topology.faceCount();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& ringEdges = topology.ringEdges();
  const std::vector<int>& ringFaces = topology.ringFaces();
  const std::vector<signed char>& ringCorners = topology.ringCorners();
  const Eigen::MatrixX3i& faceEdges = topology.faceEdges();
  double shortest = haveLengths ? std::numeric_limits<double>::infinity() : 0.0;
  fillRingTransports(topology, intrinsic.edgeTransportAngles, v, band.ringTransports.data());
  // Each triangle's altitude from v: twice its area over the edge opposite v.
  double starRadius = haveAreas ? std::numeric_limits<double>::infinity() : 0.0;
  if (haveLengths) {
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      shortest = std::min(shortest, intrinsic.edgeLengths[ringEdges[static_cast<size_t>(m)]]);
      const int f = ringFaces[static_cast<size_t>(m)];
      if (!haveAreas || f < 0) continue;
      const int corner = ringCorners[static_cast<size_t>(m)];
      const double opposite = intrinsic.edgeLengths[faceEdges(f, (corner + 1) % 3)];
      starRadius = std::min(starRadius, opposite > 0.0 ? 2.0 * intrinsic.faceAreas[f] / opposite : 0.0);
    }
  }
  band.distances[static_cast<size_t>(v)].shortestEdge = shortest;
  band.distances[static_cast<size_t>(v)].starRadius = starRadius;
  band.ringRebuildCounts[static_cast<size_t>(v)] = intrinsic.rebuildCount;
}

// fillVertexTablesNow unless vertex v's tables are from this intrinsic
// rebuild already (band.ringRebuildCounts[v]).
inline void fillVertexTables(const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic, int v,
                             LiquidBand& band) {
  if (band.ringRebuildCounts[static_cast<size_t>(v)] == intrinsic.rebuildCount) return;
  fillVertexTablesNow(topology, intrinsic, v, band);
}

// What one growLiquidBand call reads, with the flags of what the geometry
// provides, gathered once.
struct BandSurface {
  const LiquidBandInputs& inputs;
  const SurfaceTopology& topology;
  const IntrinsicGeometry& intrinsic;
  const ExtrinsicGeometry& extrinsic;
  bool haveLengths;    ///< intrinsic edge lengths exist (else d is infinite)
  bool moving;         ///< frame velocities enter the extension (p at t − h and t, frames at t)
  bool inertia;        ///< p̈ enters the kick
  bool haveFrames;     ///< frames at t exist (else the kick is not projected)
  double invH;         ///< 1/h (1/s)
};

BandSurface bandSurface(const LiquidBandInputs& inputs, const SurfaceTopology& topology,
                        const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry& extrinsic) {
  const int n = topology.vertexCount();
  const bool haveFrames = extrinsic.frames.size() == static_cast<size_t>(n);
  return BandSurface{inputs,
                     topology,
                     intrinsic,
                     extrinsic,
                     intrinsic.edgeLengths.size() > 0,
                     inputs.surfaceMoved && extrinsic.previousPositions.rows() == n &&
                         extrinsic.positions.rows() == n && haveFrames,
                     inputs.useAccelerations && extrinsic.vertexAccelerations.rows() == n,
                     haveFrames,
                     1.0 / inputs.h};
}

// v_k = (p_k^t − p_k^{t−h}) / h: vertex k's velocity over the last step (3, m/s, world).
inline Vector3 surfaceVelocity(const BandSurface& surface, int k) {
  const ExtrinsicGeometry& extrinsic = surface.extrinsic;
  return (extrinsic.positions.row(k) - extrinsic.previousPositions.row(k)).transpose() * surface.invH;
}

// |tangential part of g − p̈_k| + filmAcceleration (m/s²): the kick the body
// forces give vertex k's u per unit time (the normal part is lost, the liquid
// stays on the surface).
inline double tangentialKick(const BandSurface& surface, int k) {
  Vector3 a = surface.inputs.gravity;
  if (surface.inertia) a -= surface.extrinsic.vertexAccelerations.row(k).transpose();
  if (!surface.haveFrames) return a.norm() + surface.inputs.filmAcceleration;
  const Vector3 z = surface.extrinsic.frames[static_cast<size_t>(k)].col(2);
  return (a - a.dot(z) * z).norm() + surface.inputs.filmAcceleration;
}

// Sub-step rings: the density advection moves liquid one ring a sub-step and
// takes n = ceil(max over the wet set of h outflow_i / A_i) of them. Its flux
// through the dual edge of ij is ½(U_i + U_j)·N_ij with |N_ij| ≤ Σ over the
// edge's faces of |c_T − m_ij| (the barycentric dual edge, surface_geometry.h),
// so h outflow_i / A_i ≤ d · P_i / A_i. The Courant factor max P_i / A_i over
// the wet set (1/m, 1e-9 over for rounding; infinite where it cannot be
// computed) bounds the levels: no liquid gets past level ceil(d · factor). It
// is computed when a level past 1 is first decided (a band without one, e.g. a
// wet set covering the mesh, never pays for it).
double courantFactor(const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
                     const ExtrinsicGeometry& extrinsic, const LiquidBand& band, int wetCount) {
  double largest = std::numeric_limits<double>::infinity();
  if (extrinsic.positions.rows() == topology.vertexCount()) {
    const std::vector<int>& offsets = topology.ringOffsets();
    const std::vector<int>& ringFaces = topology.ringFaces();
    const std::vector<signed char>& ringCorners = topology.ringCorners();
    const Triangles& faces = topology.faces();
    const RowVectors3& positions = extrinsic.positions;
    const Vector& areas = intrinsic.vertexDualAreas;
    largest = 0.0;
    for (int k = 0; k < wetCount; ++k) {
      const int i = band.vertices[static_cast<size_t>(k)];
      // P_i: Σ over i's faces of the two barycentric dual half-edges at i,
      // |c_T − m_ij| for each of the face's edges at i (positions at t).
      double perimeter = 0.0;
      for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
        const int f = ringFaces[static_cast<size_t>(m)];
        if (f < 0) continue;
        const int corner = ringCorners[static_cast<size_t>(m)];
        const Vector3 pi = positions.row(i).transpose();
        const Vector3 pj = positions.row(faces(f, (corner + 1) % 3)).transpose();
        const Vector3 pk = positions.row(faces(f, (corner + 2) % 3)).transpose();
        // c_T − m_ij = (2 p_k − p_i − p_j) / 6, and the same with j and k swapped.
        perimeter += ((2.0 * pk - pi - pj).norm() + (2.0 * pj - pi - pk).norm()) / 6.0;
      }
      const double area = areas[i];
      largest = std::max(largest, area > 0.0 ? perimeter / area : std::numeric_limits<double>::infinity());
    }
  }
  // NaN too: no limit from the sub-steps.
  return largest < std::numeric_limits<double>::infinity() ? largest * (1.0 + 1e-9)
                                                           : std::numeric_limits<double>::infinity();
}

// The Courant factor computed on first use, and the sub-step distances it gives.
class SubStepReach {
 public:
  SubStepReach(const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
               const ExtrinsicGeometry& extrinsic, const LiquidBand& band, int wetCount)
      : topology_(topology), intrinsic_(intrinsic), extrinsic_(extrinsic), band_(band), wetCount_(wetCount) {}
  // The least d (m) at which liquid can get to level ≥ 2 in the sub-steps:
  // ceil(d · factor) ≥ level, i.e. d · factor > level − 1. Level 1 is always
  // in reach (a step with u = 0 moves nothing, and takes no sub-step).
  double distanceTo(int level) {
    if (courantFactor_ < 0.0) {
      courantFactor_ = courantFactor(topology_, intrinsic_, extrinsic_, band_, wetCount_);
    }
    return static_cast<double>(level - 1) / courantFactor_;
  }

 private:
  const SurfaceTopology& topology_;
  const IntrinsicGeometry& intrinsic_;
  const ExtrinsicGeometry& extrinsic_;
  const LiquidBand& band_;  // its wet set (level 0) is fixed during the growth
  int wetCount_;
  double courantFactor_ = -1.0;  // not computed yet
};

// U = max |u| + h max kick over the vertices seen so far, kept as max |u|²
// (m²/s²) and max kick (m/s²): one root per decision instead of a hypot per
// vertex (glibc's hypot, with its rounding-mode guard, was a tenth of the
// band's time on a 10K cloth).
struct SpeedBound {
  double speedSquared = 0.0;
  double acceleration = 0.0;
  void add(const BandSurface& surface, const StainState& state, int i) {
    speedSquared = std::max(speedSquared, std::norm(state.velocities[i]));
    acceleration = std::max(acceleration, tangentialKick(surface, i));
  }
  double speed(double h) const { return std::sqrt(speedSquared) + h * acceleration; }
};

// d = h U (m), the farthest a foot point lies from its vertex; infinite
// without a metric or when not finite.
double footDistance(const BandSurface& surface, const SpeedBound& bound) {
  const double d = surface.inputs.h * bound.speed(surface.inputs.h);
  return surface.haveLengths && std::isfinite(d) ? d : std::numeric_limits<double>::infinity();
}

// Level 0: extension weights A_i (σ_f + σ_s)⁺ (m² by density), the distance
// labels at 0, the vertex tables, and the wet set's speed bound. Returns the
// wet set's least star radius (m).
double weighWetSet(const BandSurface& surface, int wetCount, SpeedBound& bound, LiquidBand& band,
                   const StainState& state) {
  const Vector& areas = surface.intrinsic.vertexDualAreas;
  double wetStarRadius = std::numeric_limits<double>::infinity();
  for (int k = 0; k < wetCount; ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    const size_t ii = static_cast<size_t>(i);
    band.weights[i] = areas[i] * (std::max(state.solvent[i], 0.0) + std::max(state.solute[i], 0.0));
    bound.add(surface, state, i);
    fillVertexTables(surface.topology, surface.intrinsic, i, band);
    LiquidBand::Distances& labels = band.distances[ii];
    labels.fromWet = labels.fromReach = labels.nearestWet = labels.nearestReach = 0.0;
    wetStarRadius = std::min(wetStarRadius, labels.starRadius);
  }
  return wetStarRadius;
}

// One attempt at the rings. Distance labels (growLiquidBand's comment in the
// header): a vertex is a reach centre if wet or nearestWet < d, in the reach
// set if wet or next to a reach centre of the level below, and it lets the
// band grow past it if in the reach set or nearestReach < d. Decisions are
// taken with the d of the moment; U only grows, so a "no" whose label is
// below the final d is wrong: the rings are then grown again from the wet set
// with the final d (`rejected`).
struct RingAttempt {
  double distance = 0.0;  ///< d (m) of the moment
  /// The least label a "no" compared against d: the answer changes only if
  /// the final d exceeds it.
  double rejected = std::numeric_limits<double>::infinity();
  double starLimit = 0.0;   ///< the reach set's least star radius so far (m)
  bool everything = false;  ///< covering the component
  bool inStars = false;     ///< foot points taken to be in their stars
};

// Whether band vertex v, in the reach set, is a reach centre: wet, or its
// nearestWet < d (a "no" is noted in attempt.rejected).
bool isReachCentre(const LiquidBand& band, int v, RingAttempt& attempt) {
  const size_t vv = static_cast<size_t>(v);
  if (band.levels[vv] == 0 || band.distances[vv].nearestWet < attempt.distance) return true;
  attempt.rejected = std::min(attempt.rejected, band.distances[vv].nearestWet);
  return false;
}

// Whether the band grows past vertex v: covering the component, v in the
// reach set, or (foot points not in their stars) its nearestReach < d (a "no"
// is noted in attempt.rejected; with the stars it holds while d < starLimit,
// checked by the caller).
bool letsGrow(const LiquidBand& band, int v, RingAttempt& attempt) {
  const size_t vv = static_cast<size_t>(v);
  if (attempt.everything || band.reachMask[vv] != 0) return true;
  if (attempt.inStars) return false;
  if (band.distances[vv].nearestReach < attempt.distance) return true;
  attempt.rejected = std::min(attempt.rejected, band.distances[vv].nearestReach);
  return false;
}

// Ring growth: appends to band.vertices, at `level`, every vertex outside the
// band next to a vertex of band.vertices[begin, end) (the level below) that
// lets the band grow, in discovery order; those it grows past are rows of the
// velocity solve (diffusionMask 1, unless wet).
void growRing(const SurfaceTopology& topology, int level, int begin, int end, RingAttempt& attempt,
              LiquidBand& band) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  for (int k = begin; k < end; ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    if (!letsGrow(band, i, attempt)) continue;
    if (band.diffusionMask[static_cast<size_t>(i)] == 0) band.diffusionMask[static_cast<size_t>(i)] = 1;
    for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
      const int j = neighbors[static_cast<size_t>(m)];
      if (band.levels[static_cast<size_t>(j)] >= 0) continue;
      band.levels[static_cast<size_t>(j)] = level;
      band.vertices.push_back(j);
    }
  }
}

// Velocity extension onto band vertex i at `level` ≥ 1 (growLiquidBand's
// comment in the header, "Extension"): u_i (m/s, i's frame at t) and its
// extension weight from its neighbours at the levels below, its distance
// labels (m) and whether it is in the reach set (reachMask; a "no" is noted in
// attempt.rejected, a reach vertex's star radius in attempt.starLimit). A
// soaked vertex gets u = 0 and weight 0.
void extendVelocity(const BandSurface& surface, int level, int i, SubStepReach& subSteps, RingAttempt& attempt,
                    LiquidBand& band, StainState& state) {
  const std::vector<int>& offsets = surface.topology.ringOffsets();
  const std::vector<int>& neighbors = surface.topology.ringNeighbors();
  const size_t ii = static_cast<size_t>(i);
  Complex weighted(0.0, 0.0), plain(0.0, 0.0);
  double weightSum = 0.0;
  int count = 0;
  bool inReach = false;
  double fromWet = std::numeric_limits<double>::infinity(), fromReach = fromWet;
  double nearestWet = fromWet, nearestReach = fromWet;
  const Vector3 vi = surface.moving ? surfaceVelocity(surface, i) : Vector3::Zero();
  const Matrix3* frame = surface.moving ? &surface.extrinsic.frames[ii] : nullptr;
  fillVertexTables(surface.topology, surface.intrinsic, i, band);
  const double shortest = band.distances[ii].shortestEdge;
  for (int m = offsets[ii]; m < offsets[ii + 1]; ++m) {
    const int j = neighbors[static_cast<size_t>(m)];
    const size_t jj = static_cast<size_t>(j);
    const int lj = band.levels[jj];
    if (lj < 0 || lj >= level) continue;
    Complex carried = band.ringTransports(m) * state.velocities[j];
    if (surface.moving) {
      const Vector3 change = surfaceVelocity(surface, j) - vi;
      carried += Complex(frame->col(0).dot(change), frame->col(1).dot(change));
    }
    const double w = band.weights[j];
    weighted += w * carried;
    plain += carried;
    weightSum += w;
    ++count;
    // Crossing from j to i covers at least the shorter of their shortest edges.
    const LiquidBand::Distances& from = band.distances[jj];
    const double step = std::min(from.shortestEdge, shortest);
    nearestWet = std::min(nearestWet, from.fromWet);
    fromWet = std::min(fromWet, from.fromWet + step);
    if (!attempt.everything) {  // covering the component, only the reach set is needed
      nearestReach = std::min(nearestReach, from.fromReach);
      fromReach = std::min(fromReach, from.fromReach + step);
      if (!inReach && band.reachMask[jj] != 0 && isReachCentre(band, j, attempt)) inReach = true;
    }
  }
  // count >= 1: i was found from a vertex of the level below. A soaked
  // vertex's liquid moves with the cloth: u = 0, and no weight.
  const bool soaked = band.soakedMask[ii] != 0;
  state.velocities[i] = soaked ? Complex(0.0, 0.0)
                        : weightSum > 0.0 ? weighted / weightSum
                                          : plain / static_cast<double>(count);
  band.weights[i] = soaked ? 0.0 : weightSum / static_cast<double>(count);
  // Past the sub-steps' rings no liquid gets there, whatever the labels say.
  if (inReach && level > 1) {
    const double needed = subSteps.distanceTo(level);
    if (!(needed < attempt.distance)) {
      inReach = false;
      attempt.rejected = std::min(attempt.rejected, needed);
    }
  }
  band.reachMask[ii] = inReach ? 1 : 0;
  LiquidBand::Distances& labels = band.distances[ii];
  if (inReach) attempt.starLimit = std::min(attempt.starLimit, labels.starRadius);
  labels.fromWet = fromWet;
  labels.fromReach = inReach ? 0.0 : fromReach;
  labels.nearestWet = nearestWet;
  labels.nearestReach = nearestReach;
}

// The new ring band.vertices[end, ringEnd) at `level`: prepared in toPrepare
// (when given), marked in the band (and the halo at level 1), its velocities
// extended vertex by vertex in discovery order, each joining the speed bound.
void extendRing(const BandSurface& surface, int level, int end, int ringEnd, SurfaceGeometry* toPrepare,
                SubStepReach& subSteps, RingAttempt& attempt, SpeedBound& bound, LiquidBand& band,
                StainState& state) {
  const std::vector<int>& offsets = surface.topology.ringOffsets();
  if (toPrepare != nullptr) toPrepare->prepareVertices(band.vertices.data() + end, ringEnd - end);
  for (int k = end; k < ringEnd; ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    const size_t ii = static_cast<size_t>(i);
    // What a vertex two ahead reads once a step, cold after the cloth's
    // step: its ring table, its distance labels and its frame at t.
    if (k + 2 < ringEnd) {
      const size_t ahead = static_cast<size_t>(band.vertices[static_cast<size_t>(k) + 2]);
      const char* table = reinterpret_cast<const char*>(band.ringTransports.data() + offsets[ahead]);
      __builtin_prefetch(table);
      __builtin_prefetch(table + 64);
      __builtin_prefetch(&band.distances[ahead]);
      if (surface.moving) {
        const char* frame = reinterpret_cast<const char*>(&surface.extrinsic.frames[ahead]);
        __builtin_prefetch(frame);
        __builtin_prefetch(frame + sizeof(Matrix3) - 1);
      }
    }
    band.bandMask[ii] = 1;
    if (level == 1) band.haloMask[ii] = 1;
    extendVelocity(surface, level, i, subSteps, attempt, band, state);
    bound.add(surface, state, i);
  }
}

// Grows the rings around the wet set and extends u onto them, attempt after
// attempt (growLiquidBand's comment in the header): first with the foot
// points in their stars where that can hold, then by the distance labels,
// grown again from the wet set while a "no" was decided below the final d,
// covering the component after two tries (attempt.everything on return).
// Returns the final attempt with its d; bound holds the final U.
RingAttempt growRings(const BandSurface& surface, double wetStarRadius, SurfaceGeometry* toPrepare,
                      SubStepReach& subSteps, SpeedBound& bound, LiquidBand& band, StainState& state) {
  const SpeedBound wetBound = bound;
  RingAttempt attempt;
  attempt.everything = surface.inputs.coverComponent;
  // First with the foot points in their stars (the reach set's one ring),
  // kept if the final d is below the reach set's least star radius; not tried
  // where the wet set's own d already reaches its least star radius (d only
  // grows and the radius only shrinks as the band grows).
  attempt.inStars = !attempt.everything && footDistance(surface, bound) < wetStarRadius;
  band.footInStar = false;
  for (int tries = 0;; ++tries) {
    attempt.distance = footDistance(surface, bound);
    attempt.rejected = std::numeric_limits<double>::infinity();
    attempt.starLimit = wetStarRadius;
    while (true) {
      const int level = band.rings + 1;
      const int begin = band.rings == 0 ? 0 : band.ringEnds[static_cast<size_t>(band.rings) - 1];
      const int end = band.ringEnds[static_cast<size_t>(band.rings)];
      growRing(surface.topology, level, begin, end, attempt, band);
      const int ringEnd = static_cast<int>(band.vertices.size());
      if (ringEnd == end) break;
      extendRing(surface, level, end, ringEnd, toPrepare, subSteps, attempt, bound, band, state);
      band.ringEnds.push_back(ringEnd);
      band.rings = level;
      attempt.distance = footDistance(surface, bound);
      // The stars cannot hold: to the labels.
      if (attempt.inStars && !(attempt.distance < attempt.starLimit)) break;
    }
    if (attempt.inStars) {
      if (!(attempt.rejected < attempt.distance) && attempt.distance < attempt.starLimit) {
        band.footInStar = true;
        return attempt;
      }
      // Grown again by the labels from the wet set's speed bound: what the
      // band would have been without the star rule.
      shrinkBandToWetSet(band);  // not counted in regrowths: those are the labels'
      attempt.inStars = false;
      bound = wetBound;
      --tries;  // not a try towards covering the component
      continue;
    }
    // Every "no" holds with the final d: the band is complete. Otherwise grow
    // it again with the final d (the speed bound is kept); after two tries,
    // cover the component (the reach set is then marked again below).
    if (!(attempt.rejected < attempt.distance) || attempt.everything) return attempt;
    shrinkBandToWetSet(band);
    ++band.regrowths;
    if (tries == 1) attempt.everything = true;
  }
}

// Marking, over the grown band with the final d (m): the reach set again when
// covering the component (everything; level by level, as the growth would
// have with the final d), reachRings, and the velocity solve's rows
// (diffusionMask: a vertex with a neighbour outside the band is its boundary
// data instead; none when the band is the component) with interiorCount and
// haloCount.
void markReachAndRows(const SurfaceTopology& topology, int wetCount, double distance, bool everything,
                      SubStepReach& subSteps, LiquidBand& band) {
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  band.reachRings = 0;
  band.interiorCount = wetCount;  // wet vertices are rows of the velocity solve
  int deepestCentre = 0;          // deepest level of a reach centre so far (marking again)
  for (int k = wetCount; k < band.size(); ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    const size_t ii = static_cast<size_t>(i);
    const int level = band.levels[ii];
    if (everything && level > deepestCentre + 1) {
      band.reachMask[ii] = 0;  // no reach centre at the level below
    } else if (everything) {
      char inReach = 0;
      for (int m = offsets[ii]; m < offsets[ii + 1] && inReach == 0; ++m) {
        const size_t jj = static_cast<size_t>(neighbors[static_cast<size_t>(m)]);
        if (band.levels[jj] >= 0 && band.levels[jj] < level && band.reachMask[jj] != 0 &&
            (band.levels[jj] == 0 || band.distances[jj].nearestWet < distance)) {
          inReach = 1;
        }
      }
      if (inReach != 0 && level > 1 && !(subSteps.distanceTo(level) < distance)) inReach = 0;
      band.reachMask[ii] = inReach;
      if (inReach != 0 && band.distances[ii].nearestWet < distance) deepestCentre = level;
    }
    if (band.reachMask[ii] != 0) band.reachRings = std::max(band.reachRings, level);
    // Those the band grew past are marked already.
    char interior = 1;
    for (int m = offsets[ii]; m < offsets[ii + 1] && !everything && band.diffusionMask[ii] == 0; ++m) {
      if (band.levels[static_cast<size_t>(neighbors[static_cast<size_t>(m)])] < 0) {
        interior = 0;
        break;
      }
    }
    band.diffusionMask[ii] = interior;
    band.interiorCount += interior;
  }
  band.haloCount = band.rings >= 1 ? band.ringEnds[1] - band.ringEnds[0] : 0;
}

}  // namespace

void growLiquidBand(const LiquidBandInputs& inputs, const SurfaceTopology& topology,
                    const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry& extrinsic, LiquidBand& band,
                    StainState& state, SurfaceGeometry* toPrepare) {
  sizeRingTables(topology, band);  // first call only
  const int wetCount = band.wetCount();
  if (wetCount == 0) return;
  const BandSurface surface = bandSurface(inputs, topology, intrinsic, extrinsic);
  SpeedBound bound;
  const double wetStarRadius = weighWetSet(surface, wetCount, bound, band, state);
  SubStepReach subSteps(topology, intrinsic, extrinsic, band, wetCount);
  const RingAttempt last = growRings(surface, wetStarRadius, toPrepare, subSteps, bound, band, state);
  band.speedBound = bound.speed(inputs.h);
  markReachAndRows(topology, wetCount, last.distance, last.everything, subSteps, band);
}

}  // namespace blot::stain
