// Initial conditions and sources: drops (with "splash" velocity fields) and
// regions held at fixed densities (paper sec. 6, Figs. 6 and 9).
//
// Design note: docs/design-notes.md, "stain/src/stages/sources.cpp".
#include <blot/stain/stages/sources.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSplashModes = 5;
constexpr double kSplashAmplitude = 0.4;  // a_k < kSplashAmplitude / k

[[noreturn]] void reject(const std::string& field, const std::string& why) {
  throw std::invalid_argument("addDrop: DropDef::" + field + " " + why);
}

void requireFinite(double value, const char* field) {
  if (!std::isfinite(value)) {
    std::ostringstream s;
    s << "= " << value << " is not finite";
    reject(field, s.str());
  }
}

void requireNonNegative(double value, const char* field) {
  requireFinite(value, field);
  if (value < 0.0) {
    std::ostringstream s;
    s << "= " << value << " is negative";
    reject(field, s.str());
  }
}

void validate(const DropDef& drop, int vertexCount) {
  if (drop.centerVertex < -1 || drop.centerVertex >= vertexCount) {
    std::ostringstream s;
    s << "= " << drop.centerVertex << " is out of range [0, " << vertexCount
      << ") (or -1 to use centerPoint)";
    reject("centerVertex", s.str());
  }
  if (drop.centerVertex == -1) {
    for (int c = 0; c < 3; ++c) requireFinite(drop.centerPoint[c], "centerPoint");
  }
  requireFinite(drop.radius, "radius");
  if (!(drop.radius > 0.0)) {
    std::ostringstream s;
    s << "= " << drop.radius << " must be positive";
    reject("radius", s.str());
  }
  requireNonNegative(drop.solventMass, "solventMass");
  requireNonNegative(drop.soluteMass, "soluteMass");
  for (int c = 0; c < 3; ++c) requireFinite(drop.velocity[c], "velocity");
  for (int c = 0; c < 3; ++c) requireFinite(drop.relativeVelocity[c], "relativeVelocity");
  requireNonNegative(drop.splashSpeed, "splashSpeed");
}

// Uniform in [0, 1) from the top 53 bits (same on every standard library).
double unitDouble(std::mt19937_64& generator) { return static_cast<double>(generator() >> 11) * 0x1.0p-53; }

struct SplashProfile {
  double amplitude[kSplashModes] = {};
  double phase[kSplashModes] = {};
  explicit SplashProfile(std::uint64_t seed) {
    std::mt19937_64 generator(seed);
    for (int k = 0; k < kSplashModes; ++k) {
      amplitude[k] = kSplashAmplitude / (k + 1) * unitDouble(generator);
      phase[k] = 2.0 * kPi * unitDouble(generator);
    }
  }
  double operator()(double angle) const {
    double m = 1.0;
    for (int k = 0; k < kSplashModes; ++k) m += amplitude[k] * std::cos((k + 1) * angle + phase[k]);
    return m;
  }
};

}  // namespace

void addDrop(const DropDef& drop, const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
             const ExtrinsicGeometry& extrinsic, StainState& state, const RowVectors3* surfaceVelocities) {
  const int n = topology.vertexCount();
  validate(drop, n);
  if (state.vertexCount() != n || intrinsic.vertexDualAreas.size() != n) {
    throw std::invalid_argument("addDrop: state or geometry size differs from the mesh's vertex count");
  }
  const bool useNext =
      extrinsic.nextPositions.rows() == n && static_cast<int>(extrinsic.nextFrames.size()) == n;
  const RowVectors3& positions = useNext ? extrinsic.nextPositions : extrinsic.positions;
  const std::vector<Matrix3>& frames = useNext ? extrinsic.nextFrames : extrinsic.frames;
  if (positions.rows() != n || static_cast<int>(frames.size()) != n) {
    throw std::invalid_argument("addDrop: extrinsic geometry has no positions/frames for this mesh");
  }
  if (surfaceVelocities != nullptr && surfaceVelocities->rows() != n) {
    throw std::invalid_argument("addDrop: surface velocities must have one row per vertex");
  }
  const Vector& areas = intrinsic.vertexDualAreas;

  // Centre: the given vertex, or the vertex nearest to the point (lowest index on ties).
  int center = drop.centerVertex;
  Vector3 origin;
  if (center >= 0) {
    origin = positions.row(center).transpose();
  } else {
    origin = drop.centerPoint;
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < n; ++i) {
      const double d = (positions.row(i).transpose() - origin).squaredNorm();
      if (d < best) {
        best = d;
        center = i;
      }
    }
  }

  // Footprint: breadth-first over edges, through vertices within the radius.
  const double radius = drop.radius;
  std::vector<int> footprint{center};
  std::vector<double> weights;
  std::vector<char> visited(static_cast<size_t>(n), 0);
  visited[static_cast<size_t>(center)] = 1;
  for (size_t next = 0; next < footprint.size(); ++next) {
    const int i = footprint[next];
    const double d = (positions.row(i).transpose() - origin).norm() / radius;
    weights.push_back(d < 1.0 ? (1.0 - d * d) * (1.0 - d * d) : 0.0);
    if (!(d < 1.0)) continue;  // only the centre can be outside; do not walk on from it
    for (int m = topology.ringOffsets()[static_cast<size_t>(i)];
         m < topology.ringOffsets()[static_cast<size_t>(i) + 1]; ++m) {
      const int j = topology.ringNeighbors()[static_cast<size_t>(m)];
      if (visited[static_cast<size_t>(j)]) continue;
      visited[static_cast<size_t>(j)] = 1;
      if ((positions.row(j).transpose() - origin).norm() < radius) footprint.push_back(j);
    }
  }
  // A bump below the floor is no liquid (the walk went on through it).
  size_t kept = 1;
  for (size_t k = 1; k < footprint.size(); ++k) {
    if (!(weights[k] >= kDropProfileFloor)) continue;
    footprint[kept] = footprint[k];
    weights[kept++] = weights[k];
  }
  footprint.resize(kept);
  weights.resize(kept);
  double weightedArea = 0.0;
  for (size_t k = 0; k < footprint.size(); ++k) weightedArea += areas[footprint[k]] * weights[k];
  if (!(weightedArea > 0.0)) {  // radius below the centre vertex's distance: all on the centre
    weights.assign(1, 1.0);
    footprint.resize(1);
    weightedArea = areas[center];
  }

  // Splash geometry around the centre, in the centre vertex's tangent frame.
  const bool splash = drop.splashSpeed > 0.0;
  const SplashProfile profile(drop.splashSeed);
  const Vector3 centerX = frames[static_cast<size_t>(center)].col(0);
  const Vector3 centerY = frames[static_cast<size_t>(center)].col(1);

  for (size_t k = 0; k < footprint.size(); ++k) {
    const int i = footprint[k];
    const double share = weights[k] / weightedArea;  // 1/m²
    const double addedSolvent = drop.solventMass * share;
    const double oldSolvent = state.solvent[i];

    Vector3 velocity = drop.velocity + drop.relativeVelocity;  // relative to the cloth below
    if (surfaceVelocities != nullptr && drop.velocityIsWorld) velocity -= surfaceVelocities->row(i).transpose();
    if (splash) {
      const Matrix3& frame = frames[static_cast<size_t>(i)];
      const Vector3 offset = positions.row(i).transpose() - origin;
      const Vector3 normal = frame.col(2);
      const Vector3 inPlane = offset - offset.dot(normal) * normal;
      const double distance = inPlane.norm();
      if (distance > 0.0) {
        const double angle = std::atan2(offset.dot(centerY), offset.dot(centerX));
        const double speed = drop.splashSpeed * std::min(distance / radius, 1.0) * profile(angle);
        velocity += speed / distance * inPlane;
      }
    }
    const Matrix3& frame = frames[static_cast<size_t>(i)];
    const Complex dropVelocity(velocity.dot(frame.col(0)), velocity.dot(frame.col(1)));
    const double total = oldSolvent + addedSolvent;
    if (total > 0.0) {
      state.velocities[i] = (oldSolvent * state.velocities[i] + addedSolvent * dropVelocity) / total;
    }
    state.solvent[i] = total;
    state.solute[i] += drop.soluteMass * share;
  }
  state.addedSolvent += drop.solventMass;
  state.addedSolute += drop.soluteMass;
}

void applySources(const StepContext& ctx, const std::vector<HeldRegion>& regions,
                  const IntrinsicGeometry& geometry, StainState& state) {
  if (!ctx.switches.sources) return;
  const int n = state.vertexCount();
  const Vector& areas = geometry.vertexDualAreas;
  for (const HeldRegion& region : regions) {
    for (const int i : region.vertices) {
      // Indices are validated when a region is added; never trust them blindly here.
      assert(i >= 0 && i < n);
      if (i < 0 || i >= n) continue;
      const double oldSolvent = state.solvent[i];
      if (region.solventDensity > oldSolvent) {
        state.addedSolvent += (region.solventDensity - oldSolvent) * areas[i];
        // The added liquid is at rest: keep the momentum σ_f u.
        state.velocities[i] *= std::max(oldSolvent, 0.0) / region.solventDensity;
        state.solvent[i] = region.solventDensity;
      }
      if (region.soluteDensity > state.solute[i]) {
        state.addedSolute += (region.soluteDensity - state.solute[i]) * areas[i];
        state.solute[i] = region.soluteDensity;
      }
    }
  }
}

}  // namespace blot::stain
