#pragma once
/// glTF 2.0 binary (.glb) export of the stained cloth, through tinygltf.
///
/// One self-contained file per call (geometry, colours and texture inside):
///   scene 0 "stain_texture" (the default scene): node -> mesh "cloth" with
///     POSITION, NORMAL, TEXCOORD_0 and the material "stain" whose
///     baseColorTexture is the baked colour texture (sRGB PNG, as glTF requires)
///     and, when given, whose metallicRoughnessTexture carries the wetness as
///     roughness (linear PNG: wet = smooth, so viewers show a wet sheen);
///   scene 1 "stain_vertex_color": node -> mesh "cloth_vertex_color" with the
///     same POSITION/NORMAL accessors and COLOR_0 (linear float RGB, as glTF
///     requires) and a white, untextured material.
/// Two meshes rather than one primitive with both, because glTF multiplies
/// COLOR_0 into the base colour: one primitive holding the stain twice would
/// show it squared. Without UVs (or a texture) only the vertex-colour mesh is
/// written, as scene 0.
/// TEXCOORD_0 is (u, 1 − v): glTF's texture origin is the image's top-left
/// corner, and Blot's texture puts v = 1 on the top row (uv_texture.h).
#include <blot/stain/types.h>

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace blot::engine {

struct GltfFrame {
  stain::RowVectors3 positions;  ///< #V by 3, metres
  Eigen::MatrixX3d normals;      ///< #V by 3 unit normals
  Eigen::MatrixX2d uvs;          ///< #V by 2 (Blot's convention, v up) or 0 rows
  stain::Triangles faces;        ///< #F by 3
  Eigen::MatrixX3d colors;       ///< #V by 3 linear RGB in [0, 1]
  std::vector<std::uint8_t> texturePng;  ///< the baked colour texture's PNG bytes, or empty
  /// The material's metallicRoughness texture as PNG bytes (linear: G =
  /// roughness, B = metallic; stain_maps.h, metallicRoughnessMap), or empty
  /// for a uniform roughness 1; used only with texturePng.
  std::vector<std::uint8_t> metallicRoughnessPng;
  std::string name = "cloth";
};

/// Writes `frame` as a .glb file atomically (temporary file + rename). Throws
/// std::invalid_argument naming the array on a size mismatch, a face index out
/// of range, a non-finite value, a colour outside [0, 1] by more than
/// rounding (1e-9; within it the colour is clamped) or texture bytes (either
/// texture) that are not a PNG, std::runtime_error on a write failure; nothing is written on
/// error.
void writeGlb(const std::string& path, const GltfFrame& frame);

}  // namespace blot::engine
