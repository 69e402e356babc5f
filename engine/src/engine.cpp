// blot::Engine: the fixed-step loop, drops, views and statistics around one
// CoupledSurface (cloth → stain → coupling).
//
// Design note: docs/design-notes.md, "engine/src/engine.cpp".
#include <blot/engine/engine.h>

#include <blot/stain/content_hash.h>
#include <blot/engine/scene.h>

#include <blot/stain/io/mesh_io.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <type_traits>
#include <cstring>
#include <iomanip>
#include <limits>
#include <sstream>

namespace blot::engine {
namespace {

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// Closest point to p on triangle (a, b, c) as barycentric weights (Ericson,
/// Real-Time Collision Detection 5.1.5: Voronoi regions of vertices, edges, face).
Eigen::Vector3d closestBarycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                   const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denominator = 1.0 / (va + vb + vc);
  const double v = vb * denominator, w = vc * denominator;
  return {1 - v - w, v, w};
}

/// Checks a drop's fields before it is queued (stain::addDrop checks again when it lands).
void requirePlausible(double value, const char* field) {
  if (!(std::abs(value) <= kMaxSceneMagnitude)) {
    std::ostringstream message;  // 12 digits: std::to_string printed 1e200 as 201 digits
    message << std::setprecision(12) << "drop: " << field << " must be finite and at most "
            << static_cast<long>(kMaxSceneMagnitude) << " in size, got " << value;
    throw std::invalid_argument(message.str());
  }
}

/// A vector of the definition within a scene's magnitudes, or an error
/// naming it: past them values overflow Bullet's floats (gravity -1e39 made
/// every step fail as "non-finite position") or a rotation's positions
/// (1e300 rad/s was reported as a non-finite rest position).
void requireSceneMagnitude(const Eigen::Vector3d& v, const char* field) {
  if (!v.allFinite() || !(v.cwiseAbs().maxCoeff() <= kMaxSceneMagnitude)) {
    std::ostringstream message;
    message << std::setprecision(12) << "EngineDef." << field << " = (" << v.x() << ", " << v.y() << ", " << v.z()
            << "): each component must be finite and at most " << std::setprecision(3) << kMaxSceneMagnitude
            << " in size";
    throw std::invalid_argument(message.str());
  }
}

void validateDrop(const stain::DropDef& d, int vertexCount) {
  if (d.centerVertex < -1 || d.centerVertex >= vertexCount)
    throw std::invalid_argument("drop: centerVertex = " + std::to_string(d.centerVertex) + " is out of range [0, " +
                                std::to_string(vertexCount) + ") (or -1 to use centerPoint)");
  // Past kMaxSceneMagnitude a squared distance to the cloth could overflow
  // (every face at distance inf: the nearest one would be arbitrary).
  for (int c = 0; c < 3; ++c) requirePlausible(d.centerPoint[c], "centerPoint");
  for (int c = 0; c < 3; ++c) requirePlausible(d.velocity[c], "velocity");
  for (int c = 0; c < 3; ++c) requirePlausible(d.relativeVelocity[c], "relativeVelocity");
  if (!(d.radius > 0) || !std::isfinite(d.radius)) throw std::invalid_argument("drop: radius must be finite and > 0");
  // Masses as a scene's numbers are bounded (kMaxSceneMagnitude kg): a 1e300
  // kg drop gave densities past what the C API's float copies can hold.
  if (!(d.solventMass >= 0) || !std::isfinite(d.solventMass))
    throw std::invalid_argument("drop: solventMass must be finite and >= 0");
  requirePlausible(d.solventMass, "solventMass");
  if (!(d.soluteMass >= 0) || !std::isfinite(d.soluteMass))
    throw std::invalid_argument("drop: soluteMass must be finite and >= 0");
  requirePlausible(d.soluteMass, "soluteMass");
  if (!(d.splashSpeed >= 0) || !std::isfinite(d.splashSpeed))
    throw std::invalid_argument("drop: splashSpeed must be finite and >= 0");
  // As a scene's splash_speed: a 1e300 m/s splash made the first step's
  // velocities non-finite, and the queued drop failed every step after it.
  requirePlausible(d.splashSpeed, "splashSpeed");
}

/// Folds every field of a state struct into a content hash, in its field
/// list's order (the state hash is built on the same list as save/load).
struct HashVisitor {
  std::uint64_t& hash;
  template <typename T>
  void field(const char* /*name*/, const T& value) {
    if constexpr (std::is_arithmetic_v<T>) {
      stain::hashBytes(hash, &value, sizeof value);
    } else {
      stain::hashArray(hash, value);
    }
  }
};

}  // namespace

// ------------------------------------------------------------------ construction

Engine::Engine(const EngineDef& def) : def_(def) {
  // The range a scene's time_step has (docs/scene-format.md).
  if (!(def_.timeStep >= kMinTimeStep && def_.timeStep <= 1.0)) {
    std::ostringstream message;
    message << "EngineDef.timeStep must be in [" << kMinTimeStep << ", 1] s, got " << def_.timeStep;
    throw std::invalid_argument(message.str());
  }
  if (def_.maxStepsPerCall < 1)
    throw std::invalid_argument("EngineDef.maxStepsPerCall must be >= 1, got " + std::to_string(def_.maxStepsPerCall));
  // Reserved up front: 2e9 ended in bad_alloc instead of naming the field.
  if (def_.dropQueueCapacity < 0 || def_.dropQueueCapacity > 1000000)
    throw std::invalid_argument("EngineDef.dropQueueCapacity must be in [0, 1000000], got " +
                                std::to_string(def_.dropQueueCapacity));
  if (!(def_.diffusivity > 0) || !std::isfinite(def_.diffusivity))
    throw std::invalid_argument("EngineDef.diffusivity must be finite and > 0");
  if (!(def_.viscosity >= 0) || !std::isfinite(def_.viscosity))
    throw std::invalid_argument("EngineDef.viscosity must be finite and >= 0");
  // Finite but huge positions first: validateMesh would call the faces degenerate.
  for (Eigen::Index i = 0; i < def_.mesh.vertexPositions.rows(); ++i) {
    const auto row = def_.mesh.vertexPositions.row(i);
    if (row.allFinite() && row.cwiseAbs().maxCoeff() > kMaxSceneMagnitude) {
      const std::string field = "mesh.vertexPositions[" + std::to_string(i) + "]";
      requireSceneMagnitude(row.transpose(), field.c_str());
    }
  }
  stain::validateMesh(def_.mesh, "EngineDef.mesh");
  const int n = static_cast<int>(def_.mesh.vertexPositions.rows());
  // Gravity also goes into the Bullet cloth's floats; a static or moved
  // surface keeps it in double (the C API's copies refuse what then exceeds
  // float range).
  if (def_.source == MotionSource::Bullet) requireSceneMagnitude(def_.stain.gravity, "stain.gravity");
  requireSceneMagnitude(def_.rigid.angularVelocity, "rigid.angularVelocity");
  requireSceneMagnitude(def_.rigid.pivot, "rigid.pivot");
  requireSceneMagnitude(def_.rigid.linearVelocity, "rigid.linearVelocity");
  requireSceneMagnitude(def_.rigid.linearAcceleration, "rigid.linearAcceleration");
  // The colour mapping as a scene's display holds it: an infinite absorbance
  // times a zero density made colors() NaN on every dry vertex.
  const auto requireColorRange = [](const Eigen::Array3d& v, double most, const char* field) {
    if (!(v.allFinite() && v.minCoeff() >= 0 && v.maxCoeff() <= most)) {
      std::ostringstream message;
      message << std::setprecision(12) << "EngineDef.colors." << field << " = (" << v[0] << ", " << v[1] << ", "
              << v[2] << "): each channel must be in [0, " << most << "]";
      throw std::invalid_argument(message.str());
    }
  };
  requireColorRange(def_.colors.clothColor, 1.0, "clothColor");
  requireColorRange(def_.colors.soluteAbsorbance, 1e6, "soluteAbsorbance");
  requireColorRange(def_.colors.solventAbsorbance, 1e6, "solventAbsorbance");
  topology_ = std::make_unique<stain::SurfaceTopology>(def_.mesh.faces, n, "EngineDef.mesh");

  // Fabric: isotropic, or patches laid out with patterns homogenized once.
  const int faceCount = static_cast<int>(def_.mesh.faces.rows());
  if (def_.fabricPatches.empty()) {
    fabric_ = stain::isotropicFabricField(faceCount, def_.diffusivity, def_.viscosity);
  } else {
    stain::Homogenizer homogenizer;
    std::vector<stain::FabricPatch> patches = def_.fabricPatches;
    for (std::size_t i = 0; i < patches.size(); ++i) {
      if (!patches[i].pattern) continue;
      const bool known = i < def_.fabricPatchEffectiveTensors.size() && !def_.fabricPatchEffectiveTensors[i].isZero(0.0);
      const stain::Matrix2 s = known ? def_.fabricPatchEffectiveTensors[i]
                                     : homogenizer.homogenize(*patches[i].pattern, def_.homogenizationSubdivisions).effective;
      const double d = i < def_.fabricPatchDiffusivities.size() ? def_.fabricPatchDiffusivities[i] : 0.0;
      // The patch's mean diffusivity, given or (without one) the pattern's
      // tensor in its own units, m²/s: held to a scene's diffusivity range
      // (pair coefficients of 1e20 failed at the first step's factorization,
      // NotPositiveDefinite).
      const double mean = d > 0 ? d : 0.5 * s.trace();
      if (!(mean >= 1e-12 && mean <= kMaxSceneMagnitude)) {
        std::ostringstream message;
        message << std::setprecision(12) << "EngineDef.fabricPatches[" << i << "]: a mean diffusivity of " << mean
                << " m^2/s (" << (d > 0 ? "the patch's, with the liquid's wicking factor" : "the pattern's own units")
                << "), outside [1e-12, 1e6]";
        throw std::invalid_argument(message.str());
      }
      patches[i].tensor = d > 0 ? stain::Matrix2(s * (2.0 * d / s.trace())) : s;
      patches[i].pattern.reset();
    }
    const stain::FabricLayout layout =
        stain::fabricLayout(*topology_, def_.mesh.vertexPositions, patches, homogenizer, def_.homogenizationSubdivisions);
    fabric_.densityTensors = layout.faceTensors;
    fabric_.velocityTensors.resize(faceCount, 3);
    fabric_.velocityTensors.col(0).setConstant(def_.viscosity);
    fabric_.velocityTensors.col(1).setZero();
    fabric_.velocityTensors.col(2).setConstant(def_.viscosity);
    fabric_.weftDirections = layout.faceWeftDirections;
  }

  schedule_ = def_.drops;
  for (std::size_t i = 0; i < schedule_.size(); ++i) {
    if (!(schedule_[i].time >= 0) || !std::isfinite(schedule_[i].time))
      throw std::invalid_argument("EngineDef.drops[" + std::to_string(i) + "].time must be finite and >= 0");
    try {
      validateDrop(schedule_[i].drop, n);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("EngineDef.drops[" + std::to_string(i) + "]: " + e.what());
    }
  }
  std::stable_sort(schedule_.begin(), schedule_.end(),
                   [](const TimedDrop& a, const TimedDrop& b) { return a.time < b.time; });

  meshFingerprint_ = stain::kContentHashBasis;
  stain::hashArray(meshFingerprint_, def_.mesh.vertexPositions);
  stain::hashArray(meshFingerprint_, def_.mesh.faces);

  surface_ = buildSurface();
  pending_.reserve(static_cast<std::size_t>(def_.dropQueueCapacity));
  normals_.resize(n, 3);
  liquidVelocities_.resize(n, 3);
  liquidWorldVelocities_.resize(n, 3);
  colors_.resize(n, 3);
  applyDueDrops();  // drops scheduled at t = 0 show in the first views
  invalidateViews();
}

std::unique_ptr<coupling::CoupledSurface> Engine::buildSurface() const {
  std::unique_ptr<cloth::SurfaceMotion> motion;
  switch (def_.source) {
    case MotionSource::Static: motion = std::make_unique<cloth::StaticSurface>(def_.mesh.vertexPositions); break;
    case MotionSource::Rigid: motion = std::make_unique<cloth::RigidMotion>(def_.mesh.vertexPositions, def_.rigid); break;
    case MotionSource::Sequence: {
      const cloth::FrameReader read = [](const std::string& path, Eigen::MatrixX3d& positions, Eigen::MatrixX3i& faces) {
        stain::TriangleMesh frame = stain::loadMesh(path);
        positions = std::move(frame.vertexPositions);
        faces = std::move(frame.faces);
      };
      auto sequence = std::make_unique<cloth::MeshSequence>(def_.sequence, read);
      if (sequence->vertexCount() != def_.mesh.vertexPositions.rows() || sequence->faces() != def_.mesh.faces)
        throw std::invalid_argument("EngineDef.sequence: frames have " + std::to_string(sequence->vertexCount()) +
                                    " vertices and other faces than EngineDef.mesh (" +
                                    std::to_string(def_.mesh.vertexPositions.rows()) + " vertices)");
      motion = std::move(sequence);
      break;
    }
    case MotionSource::Bullet: {
      cloth::ClothDef cloth = def_.cloth;
      coupling::describeClothMesh(def_.mesh, *topology_, cloth);
      cloth.gravity = def_.stain.gravity;
      motion = std::make_unique<cloth::BulletCloth>(cloth);
      break;
    }
    case MotionSource::Caller:
      motion = std::make_unique<cloth::CallerMotion>(def_.mesh.vertexPositions, def_.callerInitialVelocities);
      break;
  }
  auto surface = std::make_unique<coupling::CoupledSurface>(std::move(motion), *topology_, fabric_, def_.stain,
                                                            def_.coupling);
  for (const stain::HeldRegion& region : def_.heldRegions) surface->stain().addHeldRegion(region);
  return surface;
}

std::unique_ptr<Engine> Engine::fromSceneFile(const std::string& path) {
  return std::make_unique<Engine>(loadScene(path).engine);
}

std::unique_ptr<Engine> Engine::fromSceneJson(const std::string& jsonText, const std::string& baseDirectory,
                                              const std::string& sourceName) {
  return std::make_unique<Engine>(parseScene(jsonText, sourceName, baseDirectory).engine);
}

Engine::~Engine() = default;

// ------------------------------------------------------------------ stepping

stain::StepReport Engine::step(double frameDt) {
  // Longer frames would only be cut to maxStepsPerCall steps, and a huge
  // frameDt / h would overflow the accumulator (inf - inf = NaN: the engine
  // would never step again), so they are refused and change nothing.
  if (!(frameDt >= 0) || !(frameDt <= kMaxFrameSeconds)) {
    stain::StepReport report;
    report.status = stain::StepStatus::InvalidArgument;
    report.stage = stain::Stage::Guard;
    std::ostringstream message;  // not std::to_string: 1.0000001 printed as 1.000000 contradicted the range
    message << "Engine::step: frameDt must be finite and in [0, " << kMaxFrameSeconds << "] s, got "
            << std::setprecision(12) << frameDt;
    report.message = message.str();
    return report;
  }
  accumulator_ += frameDt / def_.timeStep;
  double due = std::floor(accumulator_ + 1e-9);
  if (due > def_.maxStepsPerCall) {
    droppedTime_ += (due - def_.maxStepsPerCall) * def_.timeStep;
    accumulator_ -= due - def_.maxStepsPerCall;
    due = def_.maxStepsPerCall;
  }
  accumulator_ -= due;
  const double whole = std::round(accumulator_);
  if (std::abs(accumulator_ - whole) < 1e-9) accumulator_ = whole;
  if (accumulator_ < 0) accumulator_ = 0;
  return advanceSteps(static_cast<int>(due));
}

stain::StepReport Engine::advanceSteps(int count) {
  stain::StepReport report;
  if (count < 0) {  // as a bad frame time: a status, nothing changed (it returned Ok)
    report.status = stain::StepStatus::InvalidArgument;
    report.stage = stain::Stage::Guard;
    report.message = "Engine::advanceSteps: count " + std::to_string(count) + " is negative; expected >= 0";
    return report;
  }
  for (int k = 0; k < count; ++k) {
    report = runInternalStep();
    if (report.status != stain::StepStatus::Ok) {
      accumulator_ = 0;
      break;
    }
  }
  if (count > 0) invalidateViews();
  return report;
}

stain::StepReport Engine::runInternalStep() {
  const Clock::time_point start = Clock::now();
  try {
    applyDueDrops();
  } catch (const std::exception& e) {
    stain::StepReport report;
    report.status = stain::StepStatus::InvalidArgument;
    report.stage = stain::Stage::Drops;
    report.message = e.what();
    return report;
  }
  stain::StepReport report = surface_->step(def_.timeStep);
  wallSeconds_ += 1e-3 * millisecondsSince(start);
  if (report.status != stain::StepStatus::Ok) {
    // CoupledSurface undid the step: cloth and stain are at the last good
    // time, so the clock stays there too (drops applied above stay applied).
    report.message += " (internal step " + std::to_string(steps_ + 1) + " from t = " + std::to_string(time()) +
                      " s; the engine keeps the state at t)";
    return report;
  }
  ++steps_;
  const stain::StepProfile& p = surface_->stain().profile();
  const coupling::CoupledStepTimes& t = surface_->lastTimes();
  for (int k = 0; k < stain::kStageCount; ++k)
    totals_.stageMilliseconds[static_cast<size_t>(k)] += p.milliseconds[static_cast<size_t>(k)];
  for (int k = 0; k < stain::kStepTermCount; ++k) totals_.termSteps[static_cast<size_t>(k)] += (p.terms >> k) & 1u;
  totals_.stainTotal += p.total;
  totals_.cloth += t.cloth;
  totals_.stain += t.stain;
  totals_.coupling += t.coupling;
  totals_.total += t.total;
  intrinsicRefreshes_ += p.intrinsicRefreshes;
  return report;
}

void Engine::applyDueDrops() {
  const double now = static_cast<double>(steps_) * def_.timeStep;
  while (nextScheduled_ < schedule_.size() && schedule_[nextScheduled_].time <= now + 1e-9 * def_.timeStep) {
    stain::DropDef drop = schedule_[nextScheduled_].drop;
    if (drop.centerVertex < 0) drop.centerPoint = nearestSurfacePoint(drop.centerPoint).point;
    surface_->stain().addDrop(drop);
    ++nextScheduled_;
    ++dropsApplied_;
  }
  for (const stain::DropDef& drop : pending_) {
    surface_->stain().addDrop(drop);
    ++dropsApplied_;
  }
  pending_.clear();
}

void Engine::addDrop(const stain::DropDef& drop) {
  validateDrop(drop, vertexCount());
  if (drop.centerVertex >= 0) {
    pending_.push_back(drop);
  } else {
    addDropAtPoint(drop.centerPoint, drop);
  }
}

SurfaceHit Engine::addDropAtPoint(const Eigen::Vector3d& point, stain::DropDef drop) {
  for (int c = 0; c < 3; ++c) requirePlausible(point[c], "point");
  const SurfaceHit hit = nearestSurfacePoint(point);
  drop.centerVertex = -1;
  drop.centerPoint = hit.point;
  validateDrop(drop, vertexCount());
  pending_.push_back(drop);
  return hit;
}

SurfaceHit Engine::nearestSurfacePoint(const Eigen::Vector3d& point) const {
  const Eigen::MatrixX3d& x = positions();
  const stain::Triangles& f = def_.mesh.faces;
  SurfaceHit best;
  best.distance = std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 0; k < f.rows(); ++k) {
    const Eigen::Vector3d a = x.row(f(k, 0)).transpose(), b = x.row(f(k, 1)).transpose(), c = x.row(f(k, 2)).transpose();
    const Eigen::Vector3d w = closestBarycentric(point, a, b, c);
    const Eigen::Vector3d q = w[0] * a + w[1] * b + w[2] * c;
    const double d = (q - point).norm();
    if (d < best.distance) {  // strict: the lowest face index wins ties
      best.face = static_cast<int>(k);
      best.barycentric = w;
      best.point = q;
      best.distance = d;
    }
  }
  return best;
}

void Engine::setPinTarget(int vertex, const Eigen::Vector3d& position) {
  if (def_.source != MotionSource::Bullet)
    throw std::invalid_argument(std::string("Engine::setPinTarget: the motion source is \"") +
                                motionSourceName(def_.source) + "\"; pins belong to a \"bullet\" cloth");
  surface_->motion().setPinTarget(vertex, position);
}

void Engine::setSurfaceFrame(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d* velocities) {
  if (def_.source != MotionSource::Caller)
    throw std::invalid_argument(std::string("Engine::setSurfaceFrame: the motion source is \"") +
                                motionSourceName(def_.source) + "\"; frames are given to a \"caller\" source");
  surface_->motion().setNextFrame(positions, velocities);
}

void Engine::setSurfaceFrame(const double* positions, const double* velocities) {
  if (def_.source != MotionSource::Caller)
    throw std::invalid_argument(std::string("Engine::setSurfaceFrame: the motion source is \"") +
                                motionSourceName(def_.source) + "\"; frames are given to a \"caller\" source");
  surface_->motion().setNextFrame(positions, velocities);
}

// ------------------------------------------------------------------ views

void Engine::invalidateViews() {
  const std::lock_guard<std::mutex> lock(viewsMutex_);
  frameViewsCurrent_ = false;
  colorsCurrent_ = false;
}

// Design note: the views used to be written after every call that stepped,
// which fitted a frame at every vertex (completeGeometry) although the step
// had fitted them only on the liquid band: 0.5 ms of each 9.7 ms frame of the
// game loop's two-way flag, paid by loops that never read a normal. Computing
// a view at its first read gives the same values (a vertex's fitted frame is a
// function of the positions alone, whichever vertices were fitted before) and
// leaves the state, and so every later step, bit-identical.
void Engine::refreshFrameViews() const {
  const std::lock_guard<std::mutex> lock(viewsMutex_);
  if (frameViewsCurrent_) return;
  stain::StainSolver& stain = surface_->stain();
  stain.completeGeometry();  // the views read every vertex's frame
  const stain::ExtrinsicGeometry& ex = stain.geometry().extrinsic();
  const stain::StainState& s = stain.state();
  for (int i = 0; i < s.vertexCount(); ++i) {
    const stain::Matrix3& frame = ex.nextFrames[static_cast<std::size_t>(i)];
    normals_.row(i) = frame.col(2).transpose();
    // Where no free liquid is left the stored u is the last one it had (or
    // none at all): the view shows liquid moving with the cloth there.
    const bool hasFreeLiquid = s.solvent[i] + s.solute[i] > 0.0;
    const stain::Vector3 relative = hasFreeLiquid ? stain.relativeVelocity(i) : stain::Vector3::Zero();
    liquidVelocities_.row(i) = relative.transpose();
    liquidWorldVelocities_.row(i) = (stain.surfaceVelocity(i) + relative).transpose();
  }
  frameViewsCurrent_ = true;
}

void Engine::refreshColors() const {
  const std::lock_guard<std::mutex> lock(viewsMutex_);
  if (colorsCurrent_) return;
  const stain::StainState& s = surface_->stain().state();
  stainColors(def_.colors, s.solvent, s.solute, s.absorbedSolute, s.adsorbedSolute, colors_);
  colorsCurrent_ = true;
}

int Engine::vertexCount() const { return static_cast<int>(def_.mesh.vertexPositions.rows()); }
const stain::Triangles& Engine::faces() const { return def_.mesh.faces; }
const Eigen::MatrixX3d& Engine::positions() const { return surface_->motion().positions(); }
const Eigen::MatrixX3d& Engine::normals() const {
  refreshFrameViews();
  return normals_;
}
const Eigen::VectorXd& Engine::solvent() const { return surface_->stain().state().solvent; }
const Eigen::VectorXd& Engine::solute() const { return surface_->stain().state().solute; }
const Eigen::VectorXd& Engine::absorbedSolvent() const { return surface_->stain().state().absorbedSolvent; }
const Eigen::VectorXd& Engine::absorbedSolute() const { return surface_->stain().state().absorbedSolute; }
const Eigen::VectorXd& Engine::adsorbedSolute() const { return surface_->stain().state().adsorbedSolute; }
const Eigen::MatrixX3d& Engine::liquidVelocities() const {
  refreshFrameViews();
  return liquidVelocities_;
}
const Eigen::MatrixX3d& Engine::liquidWorldVelocities() const {
  refreshFrameViews();
  return liquidWorldVelocities_;
}
const Eigen::MatrixX3d& Engine::colors() const {
  refreshColors();
  return colors_;
}
double Engine::time() const { return static_cast<double>(steps_) * def_.timeStep; }

EngineStatistics Engine::statistics() const {
  EngineStatistics s;
  s.steps = steps_;
  s.time = time();
  s.droppedTime = droppedTime_;
  s.dropsApplied = dropsApplied_;
  s.wallSeconds = wallSeconds_;
  s.stepsPerSecond = wallSeconds_ > 0 ? static_cast<double>(steps_) / wallSeconds_ : 0.0;
  s.lastProfile = surface_->stain().profile();
  s.lastTimes = surface_->lastTimes();
  s.totals = totals_;
  s.intrinsicRefreshes = intrinsicRefreshes_;
  s.massBudget = surface_->stain().massBudget();
  s.liquidEnergy = surface_->stain().liquidEnergy();
  return s;
}

std::uint64_t Engine::stateHash() const {
  std::uint64_t h = stain::kContentHashBasis;
  HashVisitor hash{h};
  hash.field("motion.positions", surface_->motion().positions());
  hash.field("motion.velocities", surface_->motion().velocities());
  surface_->stain().state().visit(hash);
  hash.field("time", surface_->stain().time());
  hash.field("accumulator", accumulator_);
  hash.field("steps", steps_);
  return h;
}

}  // namespace blot::engine
