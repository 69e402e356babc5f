#pragma once
/// Per-vertex colours baked into a texture in UV space: what a game engine
/// samples on its own cloth mesh instead of reading vertex colours.
///
/// Each triangle is rasterized in UV space and its vertex colours are
/// interpolated linearly (barycentric) at texel centres, which is exactly the
/// P1 field the solver computes. Texels no triangle covers are then filled
/// from covered neighbours for `padding` rings (a gutter), so bilinear
/// filtering and mip-mapping at chart seams do not bleed the background in.
#include <blot/engine/image.h>

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace blot::engine {

struct UvBakeOptions {
  int width = 1024;   ///< texels (>= 1)
  int height = 1024;  ///< texels (>= 1)
  /// Rings of gutter texels filled from their covered neighbours (>= 0).
  int padding = 4;
  /// Colour of texels outside every triangle and its gutter (alpha 0 by default).
  Rgba8 background = {0, 0, 0, 0};
};

/// Texel (x, y) samples UV (u, v) = ((x + ½)/W, 1 − (y + ½)/H): v points up,
/// the top image row is v = 1 (the OpenGL/glTF convention for a PNG on disk
/// flipped back by the loader; see docs/rendering.md).
Eigen::Vector2d texelCenterUv(int x, int y, int width, int height);

/// Bakes vertexColors (#V by 3, linear in [0, 1], interpolated linearly and
/// written sRGB-encoded, round(255 · srgbEncode(c)): a texture for an sRGB
/// sampler, e.g. glTF baseColorTexture or an engine's *_SRGB format)
/// over the faces (#F by 3) at per-vertex uvs (#V by 2) into an RGBA image;
/// alpha is 255 on covered and gutter texels, background.a elsewhere. Where
/// triangles overlap in UV space the one with the larger face index wins
/// (deterministic). Throws std::invalid_argument naming the argument for
/// mismatched sizes, an index out of range, non-finite UVs or colours, or a
/// size below 1.
Image bakeVertexColorsToUv(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces,
                           const Eigen::MatrixX3d& vertexColors, const UvBakeOptions& options = {});

/// Any per-vertex values baked the same way, kept in double: `values` holds
/// width * height * channels numbers (texel (x, y) at (y * width + x) * channels),
/// `coverage` 1 on covered texels, 2 on gutter texels, 0 elsewhere (values 0 there).
struct UvBake {
  int width = 0, height = 0, channels = 0;
  std::vector<double> values;
  std::vector<std::uint8_t> coverage;
};
/// vertexValues is #V by channels (>= 1); errors as for bakeVertexColorsToUv
/// (options.background is unused).
UvBake bakeVertexValuesToUv(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces,
                            const Eigen::MatrixXd& vertexValues, const UvBakeOptions& options = {});

/// A 16-bit map of 1-3 baked density channels for shaders that shade the stain
/// themselves: sample = round(65535 · clamp(value / fullScale, 0, 1)), one more
/// channel for coverage (65535 on covered and gutter texels, 0 elsewhere).
/// Linear data: write it with writePng16 (gAMA 1.0, no sRGB chunk).
Image16 densityMap(const UvBake& baked, double fullScale);

}  // namespace blot::engine
