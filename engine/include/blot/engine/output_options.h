#pragma once
/// The output choices a scene file can make (SceneOutputs), declared in the
/// engine core so that scenes parse without the outputs library; the writers
/// that act on them are in blot_outputs (engine/outputs/).

#include <Eigen/Core>

namespace blot::engine {

/// Camera projection of the PNG previews (Renderer).
enum class Projection { Perspective, Orthographic };

/// Image limits of the Renderer, checked by the scene parser too so that a
/// preview it cannot draw is refused at load, not after the simulation.
inline constexpr int kMaxImageSide = 16384;           ///< width and height, pixels
inline constexpr int kMaxSupersampling = 4;           ///< samples per pixel along each axis
inline constexpr double kMaxImageSamples = 1 << 26;   ///< width x height x supersampling^2 (16 bytes each)
/// UV texture limits (UvBakeOptions), checked by the scene parser and the
/// command line too, before the simulation: a side of at most kMaxImageSide
/// and at most kMaxTextureTexels in all (8192 x 8192). Baking holds about 38
/// bytes a texel (measured: 633 MB at 4096 x 4096), so about 2.5 GB at the
/// limit; 16384 x 16384 would have needed about 10 GB.
inline constexpr double kMaxTextureTexels = 1 << 26;

/// Encoding of the PLY frames (PlyFrameWriter).
enum class PlyFormat { BinaryLittleEndian, Ascii };

/// Where a frame image's camera looks from.
enum class FrameCamera {
  /// World view: framed on frame 0's shape, then translated with the cloth's
  /// centroid, so the cloth's motion (swing, wrinkles) shows but it stays in view.
  Follow,
  /// The current densities drawn on the rest (undeformed) shape, fixed camera.
  Rest,
};

/// A PNG per frame (`<name>_frame_<k>.png`), and the video made of them.
struct SceneImages {
  bool enabled = false;
  int every = 1;                  ///< write every this many frames (frame 0 and the last always)
  int width = 640, height = 480;  ///< pixels
  int supersampling = 2;
  FrameCamera camera = FrameCamera::Follow;
  Eigen::Vector3d viewDirection = Eigen::Vector3d(-0.3, -0.6, -1.0);
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< zero: +z, or +y for a near-vertical view
  Projection projection = Projection::Perspective;
};

/// Videos assembled from the frame images with ffmpeg (found on PATH).
struct SceneVideo {
  bool mp4 = false;  ///< <name>.mp4, H.264, yuv420p
  bool gif = false;  ///< <name>.gif, palette per file
  double fps = 24;
};

/// File formats of the wetness, saturation and stain maps (stain_maps.h);
/// none set: no maps.
struct StainMapFormats {
  bool png8 = false;   ///< `<name>_<map>[_<k>].png`, 8-bit grey, value / densityScale
  bool png16 = false;  ///< `<name>_<map>16[_<k>].png`, 16-bit grey, value / densityScale
  bool exr = false;    ///< `<name>_<map>[_<k>].exr`, float, kg/m² (needs a build with OpenEXR)
  bool any() const { return png8 || png16 || exr; }
};

/// The stain baked into the mesh's UV layout (needs a mesh with UVs):
/// `<name>_color[_<k>].png` (sRGB) and `<name>_density[_<k>].png` (16-bit,
/// linear) when enabled; the wetness, saturation and stain maps in `maps`'s
/// formats, at the same size and frames, whether enabled or not.
struct SceneTexture {
  bool enabled = false;
  bool everyFrame = false;  ///< each written frame, or only the last
  int width = 1024, height = 1024, padding = 4;
  /// kg/m² written as full scale (65535, or 255 in an 8-bit map) in the density
  /// map and the PNG stain maps
  double densityScale = 5.0;
  StainMapFormats maps;
};

/// glTF 2.0 binary files (`<name>.glb`, or `<name>_<k>.glb` per frame).
struct SceneGltf {
  bool enabled = false;
  bool everyFrame = false;
  /// Wetness (free film σ_f + σ_s, kg/m²) at which the material's roughness
  /// reaches its wet value (stain_maps.h, GlossSettings).
  double glossWetness = 0.1;
};

}  // namespace blot::engine
