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
  band.rings = band.reachRings = band.haloCount = 0;
  band.speedBound = 0;
}

// Rings R = ceil(h U / ℓ_min) + 1 for the speed bound U (m/s), capped so that
// the conversion to int cannot overflow.
int reachRingsFor(double h, double speed, double minEdgeLength) {
  if (!(minEdgeLength > 0.0) || !std::isfinite(speed)) return std::numeric_limits<int>::max() / 4;
  const double rings = std::ceil(h * speed / minEdgeLength);
  return rings >= 1e8 ? std::numeric_limits<int>::max() / 4 : static_cast<int>(rings) + 1;
}

}  // namespace

void LiquidBand::resize(int vertexCount) {
  const size_t n = static_cast<size_t>(vertexCount);
  vertices.clear();
  vertices.reserve(n);
  ringEnds.clear();
  ringEnds.reserve(n + 1);
  dampVertices.clear();
  dampVertices.reserve(n);
  absorbingVertices.clear();
  absorbingVertices.reserve(n);
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
  rings = reachRings = haloCount = 0;
  speedBound = 0;
}

namespace {

// Files vertex i under the wet set, the damp or the absorbing list (index
// order when called in index order); false when it is none of them.
bool classify(double wetThreshold, const StainState& state, int i, LiquidBand& band) {
  if (!(state.solvent[i] > wetThreshold || state.absorbedSolvent[i] > wetThreshold ||
        state.solute[i] > wetThreshold)) {
    const bool damp = state.solvent[i] + state.solute[i] > 0;
    const bool absorbing = state.absorbedSolvent[i] > 0;
    if (damp) band.dampVertices.push_back(i);
    if (absorbing) band.absorbingVertices.push_back(i);
    return damp || absorbing;
  }
  const size_t k = static_cast<size_t>(i);
  band.vertices.push_back(i);
  band.levels[k] = 0;
  band.wetMask[k] = band.haloMask[k] = band.reachMask[k] = band.bandMask[k] = band.diffusionMask[k] =
      LiquidBand::kHoldsLiquid;
  return true;
}

}  // namespace

void markWetVertices(double wetThreshold, const StainState& state, LiquidBand& band) {
  clearBand(band);
  for (const int v : band.candidates) band.candidateMarks[static_cast<size_t>(v)] = 0;
  band.candidates.clear();
  const int n = state.vertexCount();
  for (int i = 0; i < n; ++i)
    if (classify(wetThreshold, state, i, band)) band.noteChanged(i);
  band.ringEnds.push_back(static_cast<int>(band.vertices.size()));
  band.scanAll = false;
}

void updateWetVertices(double wetThreshold, const StainState& state, LiquidBand& band) {
  // Sorting more than an eighth of the mesh costs more than the scan.
  if (band.scanAll || 8 * band.candidates.size() > band.candidateMarks.size()) {
    markWetVertices(wetThreshold, state, band);
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
    if (classify(wetThreshold, state, i, band)) {
      list[kept++] = i;
    } else {
      band.candidateMarks[static_cast<size_t>(i)] = 0;
    }
  }
  list.resize(kept);
  band.ringEnds.push_back(static_cast<int>(band.vertices.size()));
}

void growLiquidBand(const LiquidBandInputs& inputs, const SurfaceTopology& topology,
                    const IntrinsicGeometry& intrinsic, const ExtrinsicGeometry& extrinsic, LiquidBand& band,
                    StainState& state, SurfaceGeometry* toPrepare) {
  const int n = topology.vertexCount();
  const std::vector<int>& offsets = topology.ringOffsets();
  const std::vector<int>& neighbors = topology.ringNeighbors();
  if (band.ringTransports.size() != static_cast<Eigen::Index>(neighbors.size()) ||
      band.ringRebuildCounts.size() != static_cast<size_t>(n)) {  // first call only
    band.ringTransports.resize(static_cast<Eigen::Index>(neighbors.size()));
    band.ringRebuildCounts.assign(static_cast<size_t>(n), -1);
  }
  if (band.preparedRebuildCount != intrinsic.rebuildCount) {
    band.minEdgeLength = intrinsic.edgeLengths.size() > 0 ? intrinsic.edgeLengths.minCoeff() : 0.0;
    band.preparedRebuildCount = intrinsic.rebuildCount;
  }
  // Vertex v's ring entries of ringTransports, filled once per rebuild (the
  // velocity advection keeps its own copy: the band is built before it).
  const auto fillRingTransports = [&](int v) {
    int& filledFrom = band.ringRebuildCounts[static_cast<size_t>(v)];
    if (filledFrom == intrinsic.rebuildCount) return;
    const std::vector<int>& ringEdges = topology.ringEdges();
    for (int m = offsets[static_cast<size_t>(v)]; m < offsets[static_cast<size_t>(v) + 1]; ++m) {
      band.ringTransports(m) = ringTransport(intrinsic.edgeTransportAngles, v, neighbors[static_cast<size_t>(m)],
                                             ringEdges[static_cast<size_t>(m)]);
    }
    filledFrom = intrinsic.rebuildCount;
  };
  const int wetCount = band.wetCount();
  if (wetCount == 0) return;

  const Vector& areas = intrinsic.vertexDualAreas;
  const bool moving = inputs.surfaceMoved && extrinsic.previousPositions.rows() == n &&
                      extrinsic.positions.rows() == n && extrinsic.frames.size() == static_cast<size_t>(n);
  const bool inertia = inputs.useAccelerations && extrinsic.vertexAccelerations.rows() == n;
  const double invH = 1.0 / inputs.h;
  const auto surfaceVelocity = [&](int k) -> Vector3 {
    return (extrinsic.positions.row(k) - extrinsic.previousPositions.row(k)).transpose() * invH;
  };
  // Tangential part of g − p̈_i (m/s²): the kick the body forces give vertex
  // i's u per unit time (the normal part is lost, the liquid stays on the
  // surface).
  const bool haveFrames = extrinsic.frames.size() == static_cast<size_t>(n);
  const auto kick = [&](int k) {
    Vector3 a = inputs.gravity;
    if (inertia) a -= extrinsic.vertexAccelerations.row(k).transpose();
    if (!haveFrames) return a.norm();
    const Vector3 z = extrinsic.frames[static_cast<size_t>(k)].col(2);
    return (a - a.dot(z) * z).norm();
  };

  double speed = 0.0, acceleration = 0.0;
  for (int k = 0; k < wetCount; ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    band.weights[i] = areas[i] * (std::max(state.solvent[i], 0.0) + std::max(state.solute[i], 0.0));
    speed = std::max(speed, std::abs(state.velocities[i]));
    acceleration = std::max(acceleration, kick(i));
  }

  bool closed = false;  // the band covers its connected component: no ring left outside
  while (true) {
    const int reach = reachRingsFor(inputs.h, speed + inputs.h * acceleration, band.minEdgeLength);
    const long long target = 2LL * reach + inputs.extraRings;
    if (band.rings >= target) break;
    const int level = band.rings + 1;
    const int begin = band.rings == 0 ? 0 : band.ringEnds[static_cast<size_t>(band.rings) - 1];
    const int end = band.ringEnds[static_cast<size_t>(band.rings)];
    for (int k = begin; k < end; ++k) {
      const int i = band.vertices[static_cast<size_t>(k)];
      for (int m = offsets[static_cast<size_t>(i)]; m < offsets[static_cast<size_t>(i) + 1]; ++m) {
        const int j = neighbors[static_cast<size_t>(m)];
        if (band.levels[static_cast<size_t>(j)] >= 0) continue;
        band.levels[static_cast<size_t>(j)] = level;
        band.vertices.push_back(j);
      }
    }
    const int ringEnd = static_cast<int>(band.vertices.size());
    if (ringEnd == end) {
      closed = true;
      break;
    }
    if (toPrepare != nullptr) toPrepare->prepareVertices(band.vertices.data() + end, ringEnd - end);
    for (int k = end; k < ringEnd; ++k) {
      const int i = band.vertices[static_cast<size_t>(k)];
      const size_t ii = static_cast<size_t>(i);
      band.bandMask[ii] = 1;
      if (level == 1) band.haloMask[ii] = 1;
      Complex weighted(0.0, 0.0), plain(0.0, 0.0);
      double weightSum = 0.0;
      int count = 0;
      const Vector3 vi = moving ? surfaceVelocity(i) : Vector3::Zero();
      const Matrix3* frame = moving ? &extrinsic.frames[ii] : nullptr;
      fillRingTransports(i);
      for (int m = offsets[ii]; m < offsets[ii + 1]; ++m) {
        const int j = neighbors[static_cast<size_t>(m)];
        const int lj = band.levels[static_cast<size_t>(j)];
        if (lj < 0 || lj >= level) continue;
        Complex carried = band.ringTransports(m) * state.velocities[j];
        if (moving) {
          const Vector3 change = surfaceVelocity(j) - vi;
          carried += Complex(frame->col(0).dot(change), frame->col(1).dot(change));
        }
        const double w = band.weights[j];
        weighted += w * carried;
        plain += carried;
        weightSum += w;
        ++count;
      }
      // count >= 1: i was found from a vertex of the level below.
      state.velocities[i] = weightSum > 0.0 ? weighted / weightSum : plain / static_cast<double>(count);
      band.weights[i] = weightSum / static_cast<double>(count);
      speed = std::max(speed, std::abs(state.velocities[i]));
      acceleration = std::max(acceleration, kick(i));
    }
    band.ringEnds.push_back(ringEnd);
    band.rings = level;
  }

  band.speedBound = speed + inputs.h * acceleration;
  band.reachRings = std::min(reachRingsFor(inputs.h, band.speedBound, band.minEdgeLength), band.rings);
  band.haloCount = band.rings >= 1 ? band.ringEnds[1] - band.ringEnds[0] : 0;
  for (int k = wetCount; k < band.size(); ++k) {
    const int i = band.vertices[static_cast<size_t>(k)];
    const int level = band.levels[static_cast<size_t>(i)];
    band.reachMask[static_cast<size_t>(i)] = level <= band.reachRings ? 1 : 0;
    // The outermost ring is the velocity solve's boundary data, unless
    // nothing lies beyond it.
    band.diffusionMask[static_cast<size_t>(i)] = closed || level < band.rings ? 1 : 0;
  }
}

}  // namespace blot::stain
