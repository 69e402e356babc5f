#pragma once
/// What an artist keeps from a run, beside the PLY cache: a PNG per frame from
/// a chosen camera, videos assembled from them with ffmpeg, the stain baked
/// into the mesh's UV layout (sRGB colour PNG + 16-bit linear density map),
/// the wetness, saturation and stain maps (stain_maps.h; 8/16-bit PNG, float
/// EXR), and glTF 2.0 files. Driven by the scene's `outputs` (SceneImages, SceneVideo,
/// SceneTexture, SceneGltf); file names and formats in docs/rendering.md.
#include <blot/engine/engine.h>
#include <blot/engine/output_options.h>
#include <blot/engine/renderer.h>
#include <blot/engine/uv_texture.h>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace blot::engine {

struct FrameExportSettings {
  SceneImages images;
  SceneVideo video;
  SceneTexture texture;
  SceneGltf gltf;
};

/// Every file written so far, by kind, in the order written.
struct ExportedFiles {
  std::vector<std::string> images, colorTextures, densityMaps, gltf, videos;
  /// Wetness, saturation and stain maps, in that order per frame and format.
  std::vector<std::string> stainMaps;
};

/// Thrown before anything runs when a requested tool is missing (ffmpeg).
class MissingToolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Full path of `program` on $PATH, or empty when it is not there.
std::string findOnPath(const std::string& program);

class FrameExporter {
 public:
  /// Checks the settings against the engine's mesh (texture and stain maps
  /// need UVs: std::invalid_argument), when a video is asked for that ffmpeg
  /// is on PATH (MissingToolError, with how to install it), and when EXR maps
  /// are asked for that this build has OpenEXR (MissingFeatureError, with
  /// what to install).
  FrameExporter(const FrameExportSettings& settings, std::string directory, std::string name, const Engine& engine);

  /// Writes what frame `frame` calls for; `last` marks the final frame (its
  /// image, texture and glTF are always written).
  void writeFrame(int frame, const Engine& engine, bool last);
  /// Records frame `frame`'s files as already on disk (a resumed run); they
  /// go into the videos and files().
  void adoptFrame(int frame, bool last);
  /// Assembles the videos from the frame images (ffmpeg reads raw RGB frames
  /// on its standard input; output written to a temporary name, then renamed).
  /// `progress(done, total)` is called after each frame fed. Throws
  /// std::runtime_error with ffmpeg's exit status on failure.
  void finish(const std::function<void(const std::string& video, int done, int total)>& progress = {});

  const ExportedFiles& files() const { return files_; }
  /// Work units finish() will do (frames fed to ffmpeg, over all videos).
  int encodeFrames() const;

  std::string imagePath(int frame) const;

 private:
  bool imageDue(int frame, bool last) const;
  std::string numbered(const std::string& kind, int frame, const std::string& extension) const;
  /// `<name>_<kind>_<frame>.<ext>` when the texture is written every frame, else `<name>_<kind>.<ext>`.
  std::string texturePath(const std::string& kind, int frame, const std::string& extension) const;
  void writeStainMaps(int frame, const UvBake& baked);
  Camera camera(const Engine& engine);

  FrameExportSettings settings_;
  std::string directory_, name_;
  std::string ffmpeg_;
  std::optional<Camera> baseCamera_;
  Eigen::Vector3d baseCentroid_ = Eigen::Vector3d::Zero();
  ExportedFiles files_;
};

}  // namespace blot::engine
