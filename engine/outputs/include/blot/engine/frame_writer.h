#pragma once
/// What a headless run writes about an Engine, in one place: the PLY frame
/// (the per-vertex attribute list, DESIGN.md "Outputs"), the preview PNG (the
/// scene's camera on the current or the rest shape) and the mass budget as
/// JSON. `blot run`, `blot demo` and `blot figure` all write through these, so
/// a new output (another PLY attribute, a PNG per frame, another format) is
/// one addition here: a field in FrameWriterOptions and the code that acts on it.
#include <blot/engine/engine.h>
#include <blot/engine/image.h>
#include <blot/engine/output_json.h>
#include <blot/engine/ply_frame_writer.h>
#include <blot/engine/renderer.h>
#include <blot/engine/scene.h>

#include <nlohmann/json.hpp>

#include <functional>
#include <string>

namespace blot::engine {

/// The engine's state now as a PLY frame: positions (m) and faces, then
/// solvent, solute, absorbed_solvent, absorbed_solute, adsorbed_solute
/// (kg/m²), the liquid's world velocity vx vy vz and its velocity relative to
/// the cloth rel_vx rel_vy rel_vz (m/s), all float32, and the display colours.
PlyFrame plyFrame(const Engine& engine);

/// The mass budget (kg): {"solvent": {added, free, absorbed, evaporated,
/// relative_error}, "solute": {added, free, absorbed, adsorbed, relative_error}}
/// (MassBudget::fields, output_json.h).
nlohmann::json massBudgetJson(const stain::MassBudget& budget);
/// The statistics in a run's summary (EngineStatistics::fields, output_json.h):
/// steps, simulated_time_s, drops_applied, steps_per_second,
/// intrinsic_refreshes, mean_ms_per_step (the stain stages "stain_geometry",
/// ..., "cloth", "stain", "coupling", "total": ms per internal step) and
/// mass_budget_kg (massBudgetJson).
nlohmann::json statisticsJson(const EngineStatistics& statistics);

/// Which shape a preview shows the stain on: the surface now, or the rest
/// shape (the stain as it lies on the flat, undeformed cloth).
enum class PreviewShape { Current, Rest };

/// Render settings of a preview: its size and supersampling, the shared background.
RenderSettings previewRenderSettings(const ScenePreview& preview);
/// The preview camera fitted to `positions`: the scene's view direction and
/// projection; its up, or +z (+y when the view is within ~25° of vertical).
Camera previewCamera(const ScenePreview& preview, const stain::RowVectors3& positions);

/// Draws on top of a preview after the mesh (e.g. a path, `blot figure`).
using PreviewOverlay = std::function<void(Renderer&)>;

/// The engine's colours now, on `shape`, through the preview camera.
Image renderPreview(const Engine& engine, const ScenePreview& preview, PreviewShape shape,
                    const PreviewOverlay& overlay = {});

struct FrameWriterOptions {
  std::string directory;  ///< output folder; created by the FrameWriter
  std::string name;       ///< file prefix: <name>_0003.ply, <name>.png, <name>_rest.png
  PlyWriteOptions ply;
  ScenePreview preview;   ///< size, camera; `enabled` and `restShape` decide writePreviews
};

/// Writes one engine's frames and previews into one folder. The engine is
/// read when a method is called (its state then), never stored.
class FrameWriter {
 public:
  /// Creates options.directory if needed; throws std::invalid_argument for an empty name.
  FrameWriter(const Engine& engine, FrameWriterOptions options);

  const FrameWriterOptions& options() const { return options_; }

  /// <directory>/<name>_<frame, 4+ digits>.ply.
  std::string plyPath(int frame) const;
  /// Writes plyFrame(engine) there (atomically; errors as writePlyFrame) and returns the path.
  std::string writePly(int frame) const;

  /// <directory>/<name>.png (Current) or <directory>/<name>_rest.png (Rest).
  std::string previewPath(PreviewShape shape) const;
  /// renderPreview with these options' preview.
  Image renderPreview(PreviewShape shape, const PreviewOverlay& overlay = {}) const;
  /// renderPreview(shape) to previewPath(shape); returns the path.
  std::string writePreview(PreviewShape shape) const;

 private:
  const Engine& engine_;
  FrameWriterOptions options_;
  PlyFrameWriter ply_;
};

}  // namespace blot::engine
