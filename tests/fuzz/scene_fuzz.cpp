// libFuzzer target for scene files (JSON, docs/scene-format.md).
//
// Design note: parseScene is loadScene minus the read: it parses and checks
// every key and builds the mesh (generated, or loaded relative to the base
// folder), but builds neither Bullet nor the solver, so one input costs
// microseconds to milliseconds and the target can run thousands per second.
// Relative paths resolve against assets/scenes, as for the shipped scenes, so
// seeds that name a mesh or pattern file reach the keys after it.
// The oracle is the header's contract: a SceneDef, or a SceneError whose
// message starts with the source name; any other exception is a finding. A
// parsed scene must also be usable as it stands: a finite mesh, and every
// vertex and face index it holds (pins, drops, held regions, fabric patches,
// weft constraints) inside the mesh. Rejected: building an Engine per input
// (Bullet, homogenization and CHOLMOD): a thousand times slower, and the
// engine's own checks are unit-tested. Generated meshes that the parser
// accepts but that take seconds to build under ASan (a 2000 x 2000 patch: 54 s,
// 1000 disc rings: 66 s, icosphere level 7: 3.7 s) are skipped before parsing:
// they would only turn the 10 s hang limit into noise.
#include <blot/engine/scene.h>

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace {

using blot::engine::SceneDef;

bool inside(int index, Eigen::Index count) { return index >= 0 && index < count; }

/// A generated mesh of more than about 200,000 vertices.
bool tooLargeToFuzz(const std::string& text) {
  const nlohmann::json root = nlohmann::json::parse(text, nullptr, false);
  if (!root.is_object() || !root.contains("mesh") || !root["mesh"].is_object()) return false;
  const nlohmann::json& mesh = root["mesh"];
  const auto number = [](const nlohmann::json& object, const char* key, const char* inner) {
    if (!object.contains(key) || !object[key].is_object() || !object[key].contains(inner)) return 0.0;
    const nlohmann::json& v = object[key][inner];
    if (v.is_number()) return v.get<double>();
    if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number())
      return v[0].get<double>() * v[1].get<double>();
    return 0.0;
  };
  return number(mesh, "patch", "resolution") > 2e5 || number(mesh, "disc", "rings") > 250 ||
         number(mesh, "icosphere", "level") > 6;
}

/// Aborts (a finding) when a parsed scene holds something its parser promised to reject.
void checkParsedScene(const SceneDef& scene) {
  const blot::engine::EngineDef& def = scene.engine;
  const Eigen::Index vertices = def.mesh.vertexPositions.rows(), faces = def.mesh.faces.rows();
  if (vertices == 0 || faces == 0 || !def.mesh.vertexPositions.allFinite()) std::abort();
  if (def.mesh.faces.minCoeff() < 0 || def.mesh.faces.maxCoeff() >= vertices) std::abort();
  for (const auto& pin : def.cloth.pins)
    if (!inside(pin.vertex, vertices)) std::abort();
  for (const auto& timed : def.drops)
    if (timed.drop.centerVertex != -1 && !inside(timed.drop.centerVertex, vertices)) std::abort();
  for (const auto& held : def.heldRegions)
    for (int v : held.vertices)
      if (!inside(v, vertices)) std::abort();
  for (const auto& patch : def.fabricPatches) {
    for (int f : patch.faces)
      if (!inside(f, faces)) std::abort();
    for (const auto& weft : patch.weftConstraints)
      if (!inside(weft.face, faces) || !weft.direction.allFinite()) std::abort();
  }
  if (!(def.timeStep > 0) || scene.outputs.frames < 1 || scene.outputs.stepsPerFrame < 1) std::abort();
  // The plausibility limits of scene.h and the renderer's, enforced at load.
  using blot::engine::kMaxSceneMagnitude;
  if (!(def.timeStep >= blot::engine::kMinTimeStep && def.timeStep <= 1)) std::abort();
  if (def.mesh.vertexPositions.cwiseAbs().maxCoeff() > kMaxSceneMagnitude) std::abort();
  if (!(def.stain.gravity.cwiseAbs().maxCoeff() <= kMaxSceneMagnitude)) std::abort();
  for (const auto& timed : def.drops)
    if (!(timed.drop.centerPoint.cwiseAbs().maxCoeff() <= kMaxSceneMagnitude) ||
        !(timed.drop.solventMass <= kMaxSceneMagnitude) || !(timed.drop.soluteMass <= kMaxSceneMagnitude))
      std::abort();
  if (scene.name.empty() || scene.name.front() == '.' || scene.name.find('/') != std::string::npos) std::abort();
  const auto& preview = scene.outputs.preview;
  if (preview.supersampling > blot::engine::kMaxSupersampling ||
      double(preview.width) * preview.height * preview.supersampling * preview.supersampling >
          blot::engine::kMaxImageSamples)
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string source = "fuzz.json";
  const std::string text(reinterpret_cast<const char*>(data), size);
  // Reading a device or /proc file is not parsing (and /dev/zero never ends).
  for (const char* skip : {"/dev/", "/proc/", "/sys/"})
    if (text.find(skip) != std::string::npos) return 0;
  if (tooLargeToFuzz(text)) return 0;
  try {
    checkParsedScene(blot::engine::parseScene(text, source, BLOT_FUZZ_SCENE_BASE));
  } catch (const blot::engine::SceneError& error) {
    if (std::string(error.what()).rfind(source + ": ", 0) != 0) std::abort();
  }
  return 0;
}
