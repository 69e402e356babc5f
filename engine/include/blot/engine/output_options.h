#pragma once
/// The output choices a scene file can make (SceneOutputs), declared in the
/// engine core so that scenes parse without the outputs library; the writers
/// that act on them are in blot_outputs (engine/outputs/).

namespace blot::engine {

/// Camera projection of the PNG previews (Renderer).
enum class Projection { Perspective, Orthographic };

/// Image limits of the Renderer, checked by the scene parser too so that a
/// preview it cannot draw is refused at load, not after the simulation.
inline constexpr int kMaxImageSide = 16384;           ///< width and height, pixels
inline constexpr int kMaxSupersampling = 4;           ///< samples per pixel along each axis
inline constexpr double kMaxImageSamples = 1 << 26;   ///< width x height x supersampling^2 (16 bytes each)

/// Encoding of the PLY frames (PlyFrameWriter).
enum class PlyFormat { BinaryLittleEndian, Ascii };

}  // namespace blot::engine
