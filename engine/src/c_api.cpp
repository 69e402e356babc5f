// The C API (blot.h): an opaque handle over blot::Engine.
//
// Design note: every entry point is a try/catch that turns C++ exceptions into
// a status code and a per-thread message, since exceptions must not cross a C
// boundary. The message lives in a thread_local string because creation
// failures have no engine to hang it on (the usual C-library choice, as
// errno and dlerror make); it is the only state outside the engines.
// Rejected: one error buffer per engine only (creation errors would be lost)
// and exposing C++ types through void* (the layout would leak into callers).
#include <blot/blot.h>
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>
#include <blot/stain/fabric/weave_pattern.h>

#include "c_struct_copy.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string>

// The C output structs' members, each with the listed field it holds
// (c_struct_copy.h): a field added to MassBudget::fields or
// EngineStatistics::fields without its member here and in blot.h, or a member
// added to blot.h without its line here, fails the static_asserts below.
namespace blot::engine::c_struct_copy {

// A C member that holds the listed field of the same name.
#define BLOT_SAME_NAME(name) v.member(#name, c.name)

template <class Visitor>
constexpr void cMembers(blotMassBudget& c, Visitor& v) {
  BLOT_SAME_NAME(freeSolvent);
  BLOT_SAME_NAME(absorbedSolvent);
  BLOT_SAME_NAME(evaporatedSolvent);
  BLOT_SAME_NAME(addedSolvent);
  BLOT_SAME_NAME(freeSolute);
  BLOT_SAME_NAME(absorbedSolute);
  BLOT_SAME_NAME(adsorbedSolute);
  BLOT_SAME_NAME(addedSolute);
  BLOT_SAME_NAME(solventError);
  BLOT_SAME_NAME(soluteError);
}

template <class Visitor>
constexpr void cMembers(blotLiquidEnergy& c, Visitor& v) {
  BLOT_SAME_NAME(kinetic);
  BLOT_SAME_NAME(gravitational);
  BLOT_SAME_NAME(pressure);
}

template <class Visitor>
constexpr void cMembers(blotStatistics& c, Visitor& v) {
  BLOT_SAME_NAME(steps);
  BLOT_SAME_NAME(time);
  BLOT_SAME_NAME(droppedTime);
  BLOT_SAME_NAME(dropsApplied);
  BLOT_SAME_NAME(intrinsicRefreshes);
  BLOT_SAME_NAME(wallSeconds);
  BLOT_SAME_NAME(stepsPerSecond);
  v.member("lastTimes.total", c.lastStepMilliseconds);
  v.member("lastTimes.cloth", c.lastClothMilliseconds);
  v.member("lastTimes.stain", c.lastStainMilliseconds);
  v.member("lastTimes.coupling", c.lastCouplingMilliseconds);
  v.nested("massBudget", c.massBudget);
  v.nested("liquidEnergy", c.liquidEnergy);
}

#undef BLOT_SAME_NAME

static_assert(cStructMirrors<stain::MassBudget, blotMassBudget>(),
              "blotMassBudget and MassBudget::fields disagree: give each listed field its member in blot.h and in "
              "cMembers(blotMassBudget&), with the same type");
static_assert(cStructMirrors<EngineStatistics, blotStatistics>(),
              "blotStatistics and EngineStatistics::fields disagree: give each field listed for C its member in "
              "blot.h and in cMembers(blotStatistics&), with the same type (or keep it out: notIn(kCOutput))");

}  // namespace blot::engine::c_struct_copy

struct blotEngine {
  std::unique_ptr<blot::engine::Engine> engine;
  /// The scene's mesh renumbering (SceneDef::meshOrder.vertices; empty: the file's numbering).
  std::vector<int> fileVertices;
};

namespace {

using blot::engine::c_struct_copy::copyToC;

thread_local std::string gLastError;

blotStatus fail(blotStatus status, const std::string& message) {
  gLastError = message;
  return status;
}

/// Runs `body`, mapping exceptions to statuses.
template <typename Body>
blotStatus guarded(const char* function, Body&& body) {
  try {
    return body();
  } catch (const blot::engine::SceneError& e) {
    return fail(BLOT_ERROR_SCENE, e.what());
  } catch (const blot::engine::StateFileError& e) {
    return fail(BLOT_ERROR_IO, e.what());
  } catch (const std::invalid_argument& e) {
    return fail(BLOT_ERROR_INVALID_ARGUMENT, std::string(function) + ": " + e.what());
  } catch (const std::exception& e) {
    return fail(BLOT_ERROR_INTERNAL, std::string(function) + ": " + e.what());
  } catch (...) {
    return fail(BLOT_ERROR_INTERNAL, std::string(function) + ": unknown error");
  }
}

blot::stain::DropDef toDropDef(const blotDropDef& d) {
  blot::stain::DropDef drop;
  drop.radius = d.radius;
  drop.solventMass = d.solventMass;
  drop.soluteMass = d.soluteMass;
  drop.velocity = Eigen::Vector3d(d.velocity[0], d.velocity[1], d.velocity[2]);
  drop.splashSpeed = d.splashSpeed;
  drop.splashSeed = d.splashSeed;
  return drop;
}

/// Whether a float copy of `value` would not be the finite number it is.
/// Design note: the engine computes in double, and a finite double can lie
/// beyond float's range: a liquid under a gravity of 1e308 m/s^2 (any finite
/// gravity is accepted) moves at 1e306 m/s after one step. Such a copy is
/// refused with BLOT_ERROR_NUMERICAL, naming the entry and its value, and
/// writes nothing. Rejected: writing the infinity (a caller's vertex buffer
/// would silently hold it) and clamping to FLT_MAX (a wrong number that
/// looks valid).
bool outsideFloat(double value) { return !(std::fabs(value) <= double(std::numeric_limits<float>::max())); }

blotStatus refuseOutsideFloat(const char* function, const std::string& entry, double value) {
  char text[64];
  std::snprintf(text, sizeof text, "%.17g", value);
  return fail(BLOT_ERROR_NUMERICAL, std::string(function) + ": " + entry + " is " + text +
                                        ", beyond float range (|value| <= 3.4028235e+38); nothing copied");
}

/// Copies a #V by 3 view into `out` as interleaved floats (the engine's
/// views are in place: no temporary); refused, with nothing written, when an
/// entry does not fit in a float.
template <typename View>
blotStatus copyRows(const char* function, const blotEngine* engine, View view, float* out, int capacity) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, std::string(function) + ": null argument");
  const Eigen::MatrixX3d& rows = view(*engine->engine);
  const Eigen::Index n = rows.rows();
  if (capacity < 3 * n)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, std::string(function) + ": capacity " + std::to_string(capacity) +
                                                 " floats, need " + std::to_string(3 * n));
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (outsideFloat(rows(i, c)))
        return refuseOutsideFloat(function, "vertex " + std::to_string(i) + " " + "xyz"[c], rows(i, c));
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) out[3 * i + c] = static_cast<float>(rows(i, c));
  return BLOT_OK;
}

/// A file the caller named that cannot be opened is an I/O error, told apart
/// from a scene the parser rejects.
bool checkReadable(const char* function, const char* path, blotStatus& status) {
  // A directory opens as a stream on Linux; it is a file that cannot be read.
  std::error_code ignored;
  const std::filesystem::file_status kind = std::filesystem::status(path, ignored);
  if (std::filesystem::is_directory(kind)) {
    status = fail(BLOT_ERROR_IO, std::string(function) + ": " + path + ": cannot open (a directory, not a file)");
    return false;
  }
  // Opening a named pipe as a stream waits for a writer (a stray FIFO hung
  // here); the loaders read one without waiting (stain::readFileBounded).
  if (std::filesystem::is_fifo(kind)) return true;
  std::ifstream in(path, std::ios::binary);
  if (in) return true;
  const int error = errno;
  status = fail(BLOT_ERROR_IO, std::string(function) + ": " + path + ": cannot open (" +
                                   (error != 0 ? std::strerror(error) : "unreadable") + ")");
  return false;
}

Eigen::Vector3d vec3(const double v[3]) { return Eigen::Vector3d(v[0], v[1], v[2]); }

/// A C enum argument as the int a C caller passed. C lets any int through an
/// enum parameter, but in C++ loading a value outside the enumerators' range
/// (e.g. (blotDensity)-1) is undefined, so the bytes are copied, not loaded
/// as the enum.
template <typename Enum>
int enumValue(const Enum& value) {
  static_assert(sizeof(Enum) == sizeof(int), "C enums are int-sized");
  int raw = 0;
  std::memcpy(&raw, &value, sizeof raw);
  return raw;
}

void setVec3(double out[3], const Eigen::Vector3d& v) {
  for (int c = 0; c < 3; ++c) out[c] = v[c];
}

/// blotEngineDef -> EngineDef; throws std::invalid_argument naming the field
/// (the Engine constructor checks ranges and the mesh itself).
blot::engine::EngineDef toEngineDef(const blotEngineDef& d) {
  using blot::engine::MotionSource;
  if (d.vertexCount < 3 || d.faceCount < 1)
    throw std::invalid_argument("vertexCount " + std::to_string(d.vertexCount) + " and faceCount " +
                                std::to_string(d.faceCount) + ": expected at least 3 vertices and 1 face");
  if (d.positions == nullptr || d.faces == nullptr) throw std::invalid_argument("positions and faces must not be NULL");
  blot::engine::EngineDef def;
  def.mesh.vertexPositions.resize(d.vertexCount, 3);
  for (int i = 0; i < d.vertexCount; ++i)
    for (int c = 0; c < 3; ++c) def.mesh.vertexPositions(i, c) = d.positions[3 * i + c];
  def.mesh.faces.resize(d.faceCount, 3);
  for (int f = 0; f < d.faceCount; ++f)
    for (int c = 0; c < 3; ++c) def.mesh.faces(f, c) = d.faces[3 * f + c];

  switch (enumValue(d.source)) {
    case BLOT_MOTION_STATIC: def.source = MotionSource::Static; break;
    case BLOT_MOTION_RIGID: def.source = MotionSource::Rigid; break;
    case BLOT_MOTION_BULLET: def.source = MotionSource::Bullet; break;
    case BLOT_MOTION_CALLER: def.source = MotionSource::Caller; break;
    default: throw std::invalid_argument("source " + std::to_string(enumValue(d.source)) + ": expected a blotMotionSource");
  }
  def.rigid.angularVelocity = vec3(d.rigidAngularVelocity);
  def.rigid.pivot = vec3(d.rigidPivot);
  def.rigid.linearVelocity = vec3(d.rigidLinearVelocity);

  const blotClothDef& c = d.cloth;
  def.cloth.totalMass = c.totalMass;
  def.cloth.stretchStiffness = c.stretchStiffness;
  def.cloth.bendStiffness = c.bendStiffness;
  def.cloth.dampingRate = c.dampingRate;
  def.cloth.positionIterations = c.positionIterations;
  def.cloth.substeps = c.substeps;
  def.cloth.tethers = c.tethers != 0;
  def.cloth.tetherSlack = c.tetherSlack;
  if (c.pinnedVertexCount < 0 || (c.pinnedVertexCount > 0 && c.pinnedVertices == nullptr))
    throw std::invalid_argument("cloth.pinnedVertexCount " + std::to_string(c.pinnedVertexCount) +
                                ": expected >= 0, with cloth.pinnedVertices set when > 0");
  for (int k = 0; k < c.pinnedVertexCount; ++k) {
    if (c.pinnedVertices[k] < 0 || c.pinnedVertices[k] >= d.vertexCount)
      throw std::invalid_argument("cloth.pinnedVertices[" + std::to_string(k) + "]: expected a vertex in [0, " +
                                  std::to_string(d.vertexCount) + "), got " + std::to_string(c.pinnedVertices[k]));
    blot::cloth::ClothPin pin;
    pin.vertex = c.pinnedVertices[k];
    def.cloth.pins.push_back(pin);
  }
  def.coupling = c.twoWay != 0 ? blot::coupling::CouplingMode::TwoWay : blot::coupling::CouplingMode::OneWay;

  const blotFabricDef& fabric = d.fabric;
  def.diffusivity = fabric.diffusivity;
  def.viscosity = fabric.viscosity;
  if (fabric.weavePreset != nullptr && fabric.weavePreset[0] != '\0') {
    blot::stain::FabricPatch patch;
    patch.name = fabric.weavePreset;
    patch.pattern = blot::stain::presetWeavePattern(fabric.weavePreset);
    const Eigen::Vector3d weft = vec3(fabric.weft);
    if (!(weft.norm() > 0)) throw std::invalid_argument("fabric.weft: expected a non-zero direction");
    for (int f = 0; f < d.faceCount; ++f) {
      patch.faces.push_back(f);
      patch.weftConstraints.push_back({f, weft});
    }
    def.fabricPatches.push_back(std::move(patch));
    def.fabricPatchDiffusivities.push_back(fabric.diffusivity);
  }

  // The model first: it sets the film terms and the evaporation boundary.
  switch (enumValue(d.model)) {
    case BLOT_PHYSICS_FILM: blot::stain::applyPhysicsModel(blot::stain::PhysicsModel::Film, def.stain.switches, def.stain.liquid); break;
    case BLOT_PHYSICS_PAPER: blot::stain::applyPhysicsModel(blot::stain::PhysicsModel::Paper, def.stain.switches, def.stain.liquid); break;
    default: throw std::invalid_argument("model " + std::to_string(enumValue(d.model)) + ": expected a blotPhysicsModel");
  }
  def.stain.liquid.slipLength = fabric.slipLength;
  def.stain.liquid.liquidDensity = d.liquid.liquidDensity;
  def.stain.liquid.kinematicViscosity = d.liquid.kinematicViscosity;
  def.stain.liquid.molecularDiffusivity = d.liquid.molecularDiffusivity;
  def.stain.liquid.absorptionRate = d.liquid.absorptionRate;
  def.stain.liquid.saturationDensity = d.liquid.saturationDensity;
  def.stain.liquid.desorptionRate = d.liquid.desorptionRate;
  def.stain.liquid.adsorptionCapacity = d.liquid.adsorptionCapacity;
  def.stain.liquid.evaporationRate = d.liquid.evaporationRate;
  def.stain.gravity = vec3(d.gravity);
  // A Bullet cloth's links jitter by percents near pins: the scene loader's
  // default strain tolerance for it (docs/scene-format.md, strain_tolerance).
  if (def.source == MotionSource::Bullet) def.stain.strainTolerance = blot::engine::kBulletStrainTolerance;
  def.timeStep = d.timeStep;
  def.maxStepsPerCall = d.maxStepsPerCall;
  return def;
}

/// BLOT_OK, or a step's report as the status and message both stepping calls
/// give: an invalid argument as such, anything else numerical.
blotStatus failedStep(const char* function, const blot::stain::StepReport& report) {
  if (report.status == blot::stain::StepStatus::Ok) return BLOT_OK;
  const blotStatus status = report.status == blot::stain::StepStatus::InvalidArgument ? BLOT_ERROR_INVALID_ARGUMENT
                                                                                       : BLOT_ERROR_NUMERICAL;
  return fail(status, std::string(function) + ": stage '" + report.stageName() + "'" +
                          (report.vertex >= 0 ? ", vertex " + std::to_string(report.vertex) : std::string()) + ": " +
                          report.message);
}

}  // namespace

extern "C" {

blotClothDef blotDefaultClothDef(void) {
  const blot::cloth::ClothDef c;
  blotClothDef out;
  out.totalMass = c.totalMass;
  out.stretchStiffness = c.stretchStiffness;
  out.bendStiffness = c.bendStiffness;
  out.dampingRate = c.dampingRate;
  out.positionIterations = c.positionIterations;
  out.substeps = c.substeps;
  out.tethers = c.tethers ? 1 : 0;
  out.tetherSlack = c.tetherSlack;
  out.pinnedVertices = nullptr;
  out.pinnedVertexCount = 0;
  out.twoWay = 0;
  return out;
}

blotFabricDef blotDefaultFabricDef(void) {
  const blot::engine::EngineDef e;
  blotFabricDef out;
  out.diffusivity = e.diffusivity;
  out.viscosity = e.viscosity;
  out.weavePreset = nullptr;
  out.weft[0] = 1.0;
  out.weft[1] = out.weft[2] = 0.0;
  out.slipLength = e.stain.liquid.slipLength;
  return out;
}

blotLiquidDef blotDefaultLiquidDef(void) {
  const blot::stain::LiquidParameters l;
  blotLiquidDef out;
  out.absorptionRate = l.absorptionRate;
  out.saturationDensity = l.saturationDensity;
  out.desorptionRate = l.desorptionRate;
  out.adsorptionCapacity = l.adsorptionCapacity;
  out.evaporationRate = l.evaporationRate;
  out.liquidDensity = l.liquidDensity;
  out.kinematicViscosity = l.kinematicViscosity;
  out.molecularDiffusivity = l.molecularDiffusivity;
  return out;
}

blotEngineDef blotDefaultEngineDef(void) {
  const blot::engine::EngineDef e;
  blotEngineDef out;
  out.positions = nullptr;
  out.vertexCount = 0;
  out.faces = nullptr;
  out.faceCount = 0;
  out.source = BLOT_MOTION_STATIC;
  setVec3(out.rigidAngularVelocity, e.rigid.angularVelocity);
  setVec3(out.rigidPivot, e.rigid.pivot);
  setVec3(out.rigidLinearVelocity, e.rigid.linearVelocity);
  out.cloth = blotDefaultClothDef();
  out.fabric = blotDefaultFabricDef();
  out.liquid = blotDefaultLiquidDef();
  setVec3(out.gravity, e.stain.gravity);
  out.timeStep = e.timeStep;
  out.maxStepsPerCall = e.maxStepsPerCall;
  out.model = BLOT_PHYSICS_FILM;
  return out;
}

blotStatus blotCreateEngine(const blotEngineDef* def, blotEngine** outEngine) {
  if (def == nullptr || outEngine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotCreateEngine: null argument");
  return guarded("blotCreateEngine", [&] {
    try {
      auto handle = std::make_unique<blotEngine>();
      handle->engine = std::make_unique<blot::engine::Engine>(toEngineDef(*def));
      *outEngine = handle.release();
      return BLOT_OK;
    } catch (const std::invalid_argument&) {
      throw;
    } catch (const std::bad_alloc&) {
      throw;
    } catch (const std::runtime_error& e) {
      // Mesh, fabric and preset errors from the definition are bad arguments too.
      throw std::invalid_argument(e.what());
    }
  });
}

blotStatus blotEngine_CopyLiquidWorldVelocities(const blotEngine* engine, float* out, int capacity) {
  return copyRows("blotEngine_CopyLiquidWorldVelocities", engine,
                  [](const blot::engine::Engine& e) -> const Eigen::MatrixX3d& { return e.liquidWorldVelocities(); },
                  out, capacity);
}

blotStatus blotEngine_CopyLiquidRelativeVelocities(const blotEngine* engine, float* out, int capacity) {
  return copyRows("blotEngine_CopyLiquidRelativeVelocities", engine,
                  [](const blot::engine::Engine& e) -> const Eigen::MatrixX3d& { return e.liquidVelocities(); }, out,
                  capacity);
}

blotStatus blotEngine_GetStatistics(const blotEngine* engine, blotStatistics* out) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_GetStatistics: null argument");
  return guarded("blotEngine_GetStatistics", [&] {
    copyToC(engine->engine->statistics(), *out);
    return BLOT_OK;
  });
}

blotStatus blotEngine_GetMassBudget(const blotEngine* engine, blotMassBudget* out) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_GetMassBudget: null argument");
  return guarded("blotEngine_GetMassBudget", [&] {
    copyToC(engine->engine->surface().stain().massBudget(), *out);
    return BLOT_OK;
  });
}

blotDropDef blotDefaultDropDef(void) {
  const blot::stain::DropDef d;
  blotDropDef out;
  out.radius = d.radius;
  out.solventMass = d.solventMass;
  out.soluteMass = d.soluteMass;
  out.velocity[0] = out.velocity[1] = out.velocity[2] = 0.0;
  out.splashSpeed = d.splashSpeed;
  out.splashSeed = d.splashSeed;
  return out;
}

const char* blotGetLastError(void) { return gLastError.c_str(); }

blotStatus blotCreateEngineFromSceneFile(const char* path, blotEngine** outEngine) {
  if (path == nullptr || outEngine == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotCreateEngineFromSceneFile: null argument");
  if (blotStatus status; !checkReadable("blotCreateEngineFromSceneFile", path, status)) return status;
  return guarded("blotCreateEngineFromSceneFile", [&] {
    auto handle = std::make_unique<blotEngine>();
    blot::engine::SceneDef scene = blot::engine::loadScene(path);
    handle->fileVertices = std::move(scene.meshOrder.vertices);
    handle->engine = std::make_unique<blot::engine::Engine>(scene.engine);
    *outEngine = handle.release();
    return BLOT_OK;
  });
}

blotStatus blotCreateEngineFromSceneJson(const char* json, const char* baseDirectory, blotEngine** outEngine) {
  if (json == nullptr || outEngine == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotCreateEngineFromSceneJson: null argument");
  return guarded("blotCreateEngineFromSceneJson", [&] {
    auto handle = std::make_unique<blotEngine>();
    blot::engine::SceneDef scene =
        blot::engine::parseScene(json, "<json>", baseDirectory != nullptr ? baseDirectory : ".");
    handle->fileVertices = std::move(scene.meshOrder.vertices);
    handle->engine = std::make_unique<blot::engine::Engine>(scene.engine);
    *outEngine = handle.release();
    return BLOT_OK;
  });
}

void blotDestroyEngine(blotEngine* engine) { delete engine; }

blotStatus blotEngine_Step(blotEngine* engine, double frameDt) {
  if (engine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Step: null engine");
  return guarded("blotEngine_Step", [&] { return failedStep("blotEngine_Step", engine->engine->step(frameDt)); });
}

blotStatus blotEngine_AddDropAtVertex(blotEngine* engine, int vertex, const blotDropDef* drop) {
  if (engine == nullptr || drop == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_AddDropAtVertex: null argument");
  return guarded("blotEngine_AddDropAtVertex", [&] {
    blot::stain::DropDef d = toDropDef(*drop);
    if (vertex < 0) throw std::invalid_argument("vertex " + std::to_string(vertex) + " is negative");
    d.centerVertex = vertex;
    engine->engine->addDrop(d);
    return BLOT_OK;
  });
}

blotStatus blotEngine_AddDropAtPoint(blotEngine* engine, const double point[3], const blotDropDef* drop, int* outFace) {
  if (engine == nullptr || point == nullptr || drop == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_AddDropAtPoint: null argument");
  return guarded("blotEngine_AddDropAtPoint", [&] {
    const blot::engine::SurfaceHit hit =
        engine->engine->addDropAtPoint(Eigen::Vector3d(point[0], point[1], point[2]), toDropDef(*drop));
    if (outFace != nullptr) *outFace = hit.face;
    return BLOT_OK;
  });
}

int blotEngine_GetVertexCount(const blotEngine* engine) { return engine != nullptr ? engine->engine->vertexCount() : 0; }

int blotEngine_GetFaceCount(const blotEngine* engine) {
  return engine != nullptr ? static_cast<int>(engine->engine->faces().rows()) : 0;
}

blotStatus blotEngine_SetThreadCount(blotEngine* engine, int threads) {
  if (engine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_SetThreadCount: null engine");
  return guarded("blotEngine_SetThreadCount", [&] {
    engine->engine->setThreadCount(threads);
    return BLOT_OK;
  });
}

blotStatus blotEngine_SetAdaptiveThreads(blotEngine* engine, int adaptive) {
  if (engine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_SetAdaptiveThreads: null engine");
  if (adaptive != 0 && adaptive != 1)
    return fail(BLOT_ERROR_INVALID_ARGUMENT,
                "blotEngine_SetAdaptiveThreads: expected 0 or 1, got " + std::to_string(adaptive));
  return guarded("blotEngine_SetAdaptiveThreads", [&] {
    engine->engine->setAdaptiveThreads(adaptive == 1);
    return BLOT_OK;
  });
}

blotStatus blotEngine_AdvanceSteps(blotEngine* engine, int count) {
  if (engine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_AdvanceSteps: null engine");
  if (count < 0)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_AdvanceSteps: count " + std::to_string(count) + " is negative");
  return guarded("blotEngine_AdvanceSteps",
                 [&] { return failedStep("blotEngine_AdvanceSteps", engine->engine->advanceSteps(count)); });
}

blotStatus blotEngine_SetPinTarget(blotEngine* engine, int vertex, const double position[3]) {
  if (engine == nullptr || position == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_SetPinTarget: null engine or position");
  return guarded("blotEngine_SetPinTarget", [&] {
    engine->engine->setPinTarget(vertex, Eigen::Vector3d(position[0], position[1], position[2]));
    return BLOT_OK;
  });
}

blotStatus blotEngine_SetSurfaceFrame(blotEngine* engine, const double* positions, const double* velocities,
                                      int vertexCount) {
  if (engine == nullptr || positions == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_SetSurfaceFrame: null engine or positions");
  if (vertexCount != engine->engine->vertexCount())
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_SetSurfaceFrame: vertexCount " + std::to_string(vertexCount) +
                                                 ", the engine has " + std::to_string(engine->engine->vertexCount()));
  return guarded("blotEngine_SetSurfaceFrame", [&] {
    engine->engine->setSurfaceFrame(positions, velocities);
    return BLOT_OK;
  });
}

double blotEngine_GetTime(const blotEngine* engine) { return engine != nullptr ? engine->engine->time() : 0.0; }

blotStatus blotEngine_CopyPositions(const blotEngine* engine, float* out, int capacity) {
  return copyRows("blotEngine_CopyPositions", engine,
                  [](const blot::engine::Engine& e) -> const Eigen::MatrixX3d& { return e.positions(); }, out, capacity);
}

blotStatus blotEngine_CopyNormals(const blotEngine* engine, float* out, int capacity) {
  return copyRows("blotEngine_CopyNormals", engine,
                  [](const blot::engine::Engine& e) -> const Eigen::MatrixX3d& { return e.normals(); }, out, capacity);
}

blotStatus blotEngine_CopyColors(const blotEngine* engine, float* out, int capacity) {
  return copyRows("blotEngine_CopyColors", engine,
                  [](const blot::engine::Engine& e) -> const Eigen::MatrixX3d& { return e.colors(); }, out, capacity);
}

blotStatus blotEngine_CopyDensities(const blotEngine* engine, blotDensity which, float* out, int capacity) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyDensities: null argument");
  const blot::engine::Engine& e = *engine->engine;
  const Eigen::VectorXd* field = nullptr;
  const int kind = enumValue(which);
  switch (kind) {
    case BLOT_DENSITY_SOLVENT: field = &e.solvent(); break;
    case BLOT_DENSITY_SOLUTE: field = &e.solute(); break;
    case BLOT_DENSITY_ABSORBED_SOLVENT: field = &e.absorbedSolvent(); break;
    case BLOT_DENSITY_ABSORBED_SOLUTE: field = &e.absorbedSolute(); break;
    case BLOT_DENSITY_ADSORBED_SOLUTE: field = &e.adsorbedSolute(); break;
  }
  if (field == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyDensities: unknown density " + std::to_string(kind));
  if (capacity < field->size())
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyDensities: capacity " + std::to_string(capacity) +
                                                 ", need " + std::to_string(field->size()));
  for (Eigen::Index i = 0; i < field->size(); ++i)
    if (outsideFloat((*field)[i]))
      return refuseOutsideFloat("blotEngine_CopyDensities", "vertex " + std::to_string(i), (*field)[i]);
  for (Eigen::Index i = 0; i < field->size(); ++i) out[i] = static_cast<float>((*field)[i]);
  return BLOT_OK;
}

blotStatus blotEngine_CopyFaces(const blotEngine* engine, int32_t* out, int capacity) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyFaces: null argument");
  const blot::stain::Triangles& f = engine->engine->faces();
  if (capacity < 3 * f.rows())
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyFaces: capacity " + std::to_string(capacity) + ", need " +
                                                 std::to_string(3 * f.rows()));
  for (Eigen::Index k = 0; k < f.rows(); ++k)
    for (int c = 0; c < 3; ++c) out[3 * k + c] = f(k, c);
  return BLOT_OK;
}

blotStatus blotEngine_CopyFileVertexIndices(const blotEngine* engine, int32_t* out, int capacity) {
  if (engine == nullptr || out == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyFileVertexIndices: null argument");
  const int n = engine->engine->vertexCount();
  if (capacity < n)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyFileVertexIndices: capacity " + std::to_string(capacity) +
                                                 ", need " + std::to_string(n));
  for (int k = 0; k < n; ++k) out[k] = engine->fileVertices.empty() ? k : engine->fileVertices[size_t(k)];
  return BLOT_OK;
}

blotStatus blotEngine_Save(const blotEngine* engine, const char* path) {
  if (engine == nullptr || path == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Save: null argument");
  return guarded("blotEngine_Save", [&] {
    try {
      engine->engine->save(path);
    } catch (const std::runtime_error& e) {  // the atomic writer's failures name the file
      return fail(BLOT_ERROR_IO, std::string("blotEngine_Save: ") + e.what());
    }
    return BLOT_OK;
  });
}

blotStatus blotEngine_Load(blotEngine* engine, const char* path) {
  if (engine == nullptr || path == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Load: null argument");
  if (blotStatus status; !checkReadable("blotEngine_Load", path, status)) return status;
  return guarded("blotEngine_Load", [&] {
    engine->engine->load(path);
    return BLOT_OK;
  });
}

}  // extern "C"
