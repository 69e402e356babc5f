// UV-space bake of per-vertex colours.
//
// Rasterization: for every face, the texels whose centres lie inside its UV
// triangle (edge functions, a top-left-style tie rule via a small inclusive
// epsilon so that texel centres exactly on a shared edge are never missed)
// get c = Σ λ_k c_k with the barycentric λ of the texel centre. Coverage is
// decided per texel centre, so a texture does not depend on face order except
// where charts overlap (then the last face wins, documented).
//
// Gutter: `padding` rounds of a 4-neighbour dilation; a new texel takes the
// mean of its already-filled neighbours in a fixed (up, down, left, right)
// order. A conservative rasterizer (every texel the triangle touches) was the
// alternative; it extrapolates the P1 field outside the triangle for texels
// that are then also written by the neighbour, making the result order
// dependent — dilation only writes texels no triangle covers.
#include <blot/engine/uv_texture.h>

#include <blot/engine/color_space.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::engine {
namespace {

// Colours are baked linearly and stored as sRGB bytes (color_space.h).
std::uint8_t toByte(double value) { return linearToSrgbByte(value); }

void checkInputs(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& colors,
                 const UvBakeOptions& options) {
  if (options.width < 1 || options.height < 1)
    throw std::invalid_argument("bakeVertexColorsToUv: texture size " + std::to_string(options.width) + "x" +
                                std::to_string(options.height) + ", expected at least 1x1");
  if (options.padding < 0)
    throw std::invalid_argument("bakeVertexColorsToUv: padding " + std::to_string(options.padding) +
                                ", expected >= 0");
  if (uvs.rows() != colors.rows())
    throw std::invalid_argument("bakeVertexColorsToUv: uvs has " + std::to_string(uvs.rows()) +
                                " rows but vertexColors has " + std::to_string(colors.rows()));
  if (uvs.rows() == 0) throw std::invalid_argument("bakeVertexColorsToUv: uvs is empty (the mesh has no UVs)");
  const int n = static_cast<int>(uvs.rows());
  for (int v = 0; v < n; ++v) {
    if (!uvs.row(v).allFinite())
      throw std::invalid_argument("bakeVertexColorsToUv: uvs row " + std::to_string(v) + " is not finite");
    if (!colors.row(v).allFinite())
      throw std::invalid_argument("bakeVertexColorsToUv: vertexColors row " + std::to_string(v) +
                                  " is not finite");
  }
  for (int f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (faces(f, k) < 0 || faces(f, k) >= n)
        throw std::invalid_argument("bakeVertexColorsToUv: faces(" + std::to_string(f) + ", " +
                                    std::to_string(k) + ") = " + std::to_string(faces(f, k)) +
                                    ", expected a vertex index in [0, " + std::to_string(n) + ")");
}

}  // namespace

Eigen::Vector2d texelCenterUv(int x, int y, int width, int height) {
  return {(x + 0.5) / width, 1.0 - (y + 0.5) / height};
}

Image bakeVertexColorsToUv(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces,
                           const Eigen::MatrixX3d& vertexColors, const UvBakeOptions& options) {
  checkInputs(uvs, faces, vertexColors, options);
  const int w = options.width, h = options.height;
  Image image(w, h, 4, options.background);
  // Linear colour per texel while baking, so the gutter averages are not
  // rounded twice; `filled` marks covered (1) and gutter (2) texels.
  std::vector<Eigen::Vector3d> color(static_cast<std::size_t>(w) * h, Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> filled(static_cast<std::size_t>(w) * h, 0);
  const auto at = [w](int x, int y) { return static_cast<std::size_t>(y) * w + x; };

  for (int f = 0; f < faces.rows(); ++f) {
    const Eigen::Vector2d a = uvs.row(faces(f, 0)), b = uvs.row(faces(f, 1)), c = uvs.row(faces(f, 2));
    const double area2 = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (!(std::abs(area2) > 0)) continue;  // degenerate in UV space: covers no texel centre
    // Texel range of the UV bounding box (texel x covers u in [x/W, (x+1)/W]).
    const double uMin = std::min({a.x(), b.x(), c.x()}), uMax = std::max({a.x(), b.x(), c.x()});
    const double vMin = std::min({a.y(), b.y(), c.y()}), vMax = std::max({a.y(), b.y(), c.y()});
    const int x0 = std::max(0, static_cast<int>(std::floor(uMin * w - 0.5)));
    const int x1 = std::min(w - 1, static_cast<int>(std::ceil(uMax * w - 0.5)));
    const int y0 = std::max(0, static_cast<int>(std::floor((1.0 - vMax) * h - 0.5)));
    const int y1 = std::min(h - 1, static_cast<int>(std::ceil((1.0 - vMin) * h - 0.5)));
    // A texel centre on a shared edge must land in one of the two faces:
    // accept barycentrics down to −eps (relative), the later face overwrites.
    const double eps = 1e-12;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d p = texelCenterUv(x, y, w, h);
        const double la = ((b - p).x() * (c - p).y() - (b - p).y() * (c - p).x()) / area2;
        const double lb = ((c - p).x() * (a - p).y() - (c - p).y() * (a - p).x()) / area2;
        const double lc = 1.0 - la - lb;
        if (la < -eps || lb < -eps || lc < -eps) continue;
        color[at(x, y)] = la * vertexColors.row(faces(f, 0)).transpose() +
                          lb * vertexColors.row(faces(f, 1)).transpose() +
                          lc * vertexColors.row(faces(f, 2)).transpose();
        filled[at(x, y)] = 1;
      }
    }
  }

  // Gutter: each round fills the empty texels next to filled ones, reading
  // only texels filled in earlier rounds (a copy of the mask per round).
  std::vector<std::uint8_t> previous;
  for (int round = 0; round < options.padding; ++round) {
    previous = filled;
    bool grew = false;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (previous[at(x, y)]) continue;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int count = 0;
        const int nx[4] = {x, x, x - 1, x + 1}, ny[4] = {y - 1, y + 1, y, y};
        for (int k = 0; k < 4; ++k) {
          if (nx[k] < 0 || nx[k] >= w || ny[k] < 0 || ny[k] >= h || !previous[at(nx[k], ny[k])]) continue;
          sum += color[at(nx[k], ny[k])];
          ++count;
        }
        if (count == 0) continue;
        color[at(x, y)] = sum / count;
        filled[at(x, y)] = 2;
        grew = true;
      }
    }
    if (!grew) break;
  }

  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!filled[at(x, y)]) continue;
      const Eigen::Vector3d& c = color[at(x, y)];
      image.setPixel(x, y, Rgba8{toByte(c.x()), toByte(c.y()), toByte(c.z()), 255});
    }
  }
  return image;
}

}  // namespace blot::engine
