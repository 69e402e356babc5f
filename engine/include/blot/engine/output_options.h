#pragma once
/// The output choices a scene file can make (SceneOutputs), declared in the
/// engine core so that scenes parse without the outputs library; the writers
/// that act on them are in blot_outputs (engine/outputs/).

namespace blot::engine {

/// Camera projection of the PNG previews (Renderer).
enum class Projection { Perspective, Orthographic };

/// Encoding of the PLY frames (PlyFrameWriter).
enum class PlyFormat { BinaryLittleEndian, Ascii };

}  // namespace blot::engine
