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

#include <exception>
#include <memory>
#include <string>

struct blotEngine {
  std::unique_ptr<blot::engine::Engine> engine;
};

namespace {

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

/// Copies a #V by 3 view into `out` as interleaved floats (the engine's
/// views are in place: no temporary).
template <typename View>
blotStatus copyRows(const char* function, const blotEngine* engine, View view, float* out, int capacity) {
  if (engine == nullptr || out == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, std::string(function) + ": null argument");
  const Eigen::MatrixX3d& rows = view(*engine->engine);
  const Eigen::Index n = rows.rows();
  if (capacity < 3 * n)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, std::string(function) + ": capacity " + std::to_string(capacity) +
                                                 " floats, need " + std::to_string(3 * n));
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) out[3 * i + c] = static_cast<float>(rows(i, c));
  return BLOT_OK;
}

}  // namespace

extern "C" {

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
  return guarded("blotCreateEngineFromSceneFile", [&] {
    auto handle = std::make_unique<blotEngine>();
    handle->engine = blot::engine::Engine::fromSceneFile(path);
    *outEngine = handle.release();
    return BLOT_OK;
  });
}

blotStatus blotCreateEngineFromSceneJson(const char* json, const char* baseDirectory, blotEngine** outEngine) {
  if (json == nullptr || outEngine == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotCreateEngineFromSceneJson: null argument");
  return guarded("blotCreateEngineFromSceneJson", [&] {
    auto handle = std::make_unique<blotEngine>();
    handle->engine = blot::engine::Engine::fromSceneJson(json, baseDirectory != nullptr ? baseDirectory : ".", "<json>");
    *outEngine = handle.release();
    return BLOT_OK;
  });
}

void blotDestroyEngine(blotEngine* engine) { delete engine; }

blotStatus blotEngine_Step(blotEngine* engine, double frameDt) {
  if (engine == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Step: null engine");
  return guarded("blotEngine_Step", [&] {
    const blot::stain::StepReport report = engine->engine->step(frameDt);
    if (report.status == blot::stain::StepStatus::Ok) return BLOT_OK;
    const blotStatus status = report.status == blot::stain::StepStatus::InvalidArgument ? BLOT_ERROR_INVALID_ARGUMENT
                                                                                         : BLOT_ERROR_NUMERICAL;
    return fail(status, "blotEngine_Step: stage '" + std::string(report.stageName()) + "'" +
                            (report.vertex >= 0 ? ", vertex " + std::to_string(report.vertex) : std::string()) + ": " +
                            report.message);
  });
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
  switch (which) {
    case BLOT_DENSITY_SOLVENT: field = &e.solvent(); break;
    case BLOT_DENSITY_SOLUTE: field = &e.solute(); break;
    case BLOT_DENSITY_ABSORBED_SOLVENT: field = &e.absorbedSolvent(); break;
    case BLOT_DENSITY_ABSORBED_SOLUTE: field = &e.absorbedSolute(); break;
    case BLOT_DENSITY_ADSORBED_SOLUTE: field = &e.adsorbedSolute(); break;
  }
  if (field == nullptr)
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyDensities: unknown density " + std::to_string(int(which)));
  if (capacity < field->size())
    return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_CopyDensities: capacity " + std::to_string(capacity) +
                                                 ", need " + std::to_string(field->size()));
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

blotStatus blotEngine_Save(const blotEngine* engine, const char* path) {
  if (engine == nullptr || path == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Save: null argument");
  return guarded("blotEngine_Save", [&] {
    engine->engine->save(path);
    return BLOT_OK;
  });
}

blotStatus blotEngine_Load(blotEngine* engine, const char* path) {
  if (engine == nullptr || path == nullptr) return fail(BLOT_ERROR_INVALID_ARGUMENT, "blotEngine_Load: null argument");
  return guarded("blotEngine_Load", [&] {
    engine->engine->load(path);
    return BLOT_OK;
  });
}

}  // extern "C"
