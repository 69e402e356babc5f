#pragma once
/// Scene files (JSON): everything an Engine is built from plus what `blot run`
/// writes. Every key, unit and default is documented in docs/scene-format.md.
///
/// Parsing is strict: an unknown key, a value of the wrong type or outside its
/// range is a SceneError whose message starts with the source name and the key
/// path, e.g.
///   "scene.json: cloth.pins[2].vertex: expected an integer in [0, 2601), got 9000".
/// The mesh is loaded or generated while parsing (vertex indices are checked
/// against it), and weave-pattern files are read; homogenization and the
/// fabric layout happen when the Engine is built.
#include <blot/engine/engine.h>
#include <blot/engine/output_options.h>
#include <blot/stain/geometry/mesh_order.h>

#include <stdexcept>
#include <cstdint>
#include <string>

namespace blot::engine {

/// Default `strain_tolerance` of scenes on a Bullet cloth (relative edge
/// strain): Bullet's edges jitter by 1-4 % per step near pins, so the stain
/// solver's own default (1e-3, right for mesh sequences) would rebuild its
/// operators on most steps. 5e-2 from the strain-tolerance chart
/// (docs/accuracy.md, "Strain tolerance"): on the two-way flag it rebuilds on
/// 20 % of the steps instead of 57 % at 2e-2, for a stain 0.3 % (L2) and
/// 0.2 mm (centroid) off a run that rebuilds every step.
constexpr double kBulletStrainTolerance = 0.05;

/// Input-data error in a scene (tier b): names the source and the key path.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// PNG preview of the last frame.
struct ScenePreview {
  bool enabled = true;
  int width = 480, height = 360;  ///< pixels
  int supersampling = 3;          ///< samples per pixel side
  Eigen::Vector3d viewDirection = Eigen::Vector3d(-0.3, -0.6, -1.0);  ///< camera looks along it (world)
  Projection projection = Projection::Perspective;
  /// Camera up (world); zero: +z, or +y when the view is within ~25° of vertical.
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  /// Also render the last frame's densities on the rest shape (the stain as it
  /// lies on the flat, undeformed cloth): <directory>/<name>_rest.png.
  bool restShape = false;
};

/// What `blot run` writes. A frame is `stepsPerFrame` internal steps.
struct SceneOutputs {
  int frames = 10;          ///< frames after the initial one (≥ 1)
  int stepsPerFrame = 4;    ///< internal steps per frame (≥ 1)
  int plyEvery = 1;         ///< write a PLY every this many frames (0: none); frame 0 and the last always
  PlyFormat plyFormat = PlyFormat::BinaryLittleEndian;
  std::string directory;    ///< output folder; empty: "out/<scene file stem>"
  ScenePreview preview;
  SceneImages images;
  SceneVideo video;
  SceneTexture texture;
  SceneGltf gltf;
};

/// Plausibility limits of scene values (docs/scene-format.md): every number,
/// coordinate and vector component at most this in size; the time step at
/// least kMinTimeStep seconds; a mesh sequence at most kMaxSequenceFrames frames.
inline constexpr double kMaxSceneMagnitude = 1e6;
inline constexpr double kMinTimeStep = 1e-6;
inline constexpr int kMaxSequenceFrames = 100000;

/// A parsed scene: the engine definition and the outputs.
struct SceneDef {
  std::string sourceName;       ///< file path or the name given for JSON text
  /// FNV-1a of the JSON text as read (with the patch resolution override):
  /// blot run's checkpoints record it, and --resume refuses a changed scene.
  std::uint64_t sourceHash = 0;
  std::string name;             ///< "name" key, or the file stem
  std::string description;      ///< "description" key (free text)
  std::string meshDescription;  ///< e.g. "patch 1 x 1 m, 50 x 50 quads (2601 vertices)"
  /// mesh.vertex_order "locality": engine vertex k is the file's vertex
  /// meshOrder.vertices[k], engine face k its face meshOrder.faces[k]
  /// (everything the engine writes uses the engine's numbering; the scene's
  /// own indices name the file's). Empty: the file's numbering.
  stain::MeshOrder meshOrder;
  EngineDef engine;
  SceneOutputs outputs;
};

/// What a loader may change in a scene as it reads it.
struct SceneLoadOptions {
  /// > 0: a "patch" mesh gets this many quads across its width, the height
  /// keeping the aspect ratio (round(ny · r / nx), at least 1), e.g. to run a
  /// scene at another size in a benchmark or a regression test. Other meshes
  /// are refused, and so are vertex or face indices (drops, pins, held
  /// regions, fabric faces), which would name other elements of the new grid;
  /// points, "all" and radii work at any resolution.
  int patchResolution = 0;
};

/// Parses scene JSON. `baseDirectory` resolves relative paths (mesh files,
/// sequences, patterns); `sourceName` prefixes every error message.
SceneDef parseScene(const std::string& jsonText, const std::string& sourceName,
                    const std::string& baseDirectory = ".", const SceneLoadOptions& options = {});
/// Reads and parses a scene file (relative paths resolve against its folder).
SceneDef loadScene(const std::string& path, const SceneLoadOptions& options = {});
/// The engine definition of a scene (a copy of scene.engine).
EngineDef engineDef(const SceneDef& scene);

}  // namespace blot::engine
