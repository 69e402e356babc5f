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
#include <blot/engine/output_options.h>

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

void checkInputs(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces, const Eigen::MatrixXd& values,
                 const UvBakeOptions& options, const std::string& who, const std::string& valuesName) {
  if (options.width < 1 || options.height < 1)
    throw std::invalid_argument(who + ": texture size " + std::to_string(options.width) + "x" +
                                std::to_string(options.height) + ", expected at least 1x1");
  if (options.width > kMaxImageSide || options.height > kMaxImageSide ||
      double(options.width) * double(options.height) > kMaxTextureTexels)
    throw std::invalid_argument(who + ": texture size " + std::to_string(options.width) + "x" +
                                std::to_string(options.height) + ", expected each side at most " +
                                std::to_string(kMaxImageSide) + " and at most 2^26 texels in all (8192 x 8192)");
  if (options.padding < 0)
    throw std::invalid_argument(who + ": padding " + std::to_string(options.padding) + ", expected >= 0");
  if (uvs.rows() != values.rows())
    throw std::invalid_argument(who + ": uvs has " + std::to_string(uvs.rows()) + " rows but " + valuesName +
                                " has " + std::to_string(values.rows()));
  if (uvs.rows() == 0) throw std::invalid_argument(who + ": uvs is empty (the mesh has no UVs)");
  if (values.cols() < 1) throw std::invalid_argument(who + ": " + valuesName + " has no columns");
  const int n = static_cast<int>(uvs.rows());
  for (int v = 0; v < n; ++v) {
    if (!uvs.row(v).allFinite())
      throw std::invalid_argument(who + ": uvs row " + std::to_string(v) + " is not finite");
    if (!values.row(v).allFinite())
      throw std::invalid_argument(who + ": " + valuesName + " row " + std::to_string(v) + " is not finite");
  }
  for (int f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (faces(f, k) < 0 || faces(f, k) >= n)
        throw std::invalid_argument(who + ": faces(" + std::to_string(f) + ", " + std::to_string(k) + ") = " +
                                    std::to_string(faces(f, k)) + ", expected a vertex index in [0, " +
                                    std::to_string(n) + ")");
}

UvBake bake(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces, const Eigen::MatrixXd& values,
            const UvBakeOptions& options) {
  const int w = options.width, h = options.height, k = static_cast<int>(values.cols());
  UvBake out;
  out.width = w;
  out.height = h;
  out.channels = k;
  // Values stay in double while baking, so the gutter averages are not
  // rounded twice; `coverage` marks covered (1) and gutter (2) texels.
  out.values.assign(static_cast<std::size_t>(w) * h * k, 0.0);
  out.coverage.assign(static_cast<std::size_t>(w) * h, 0);
  std::vector<double>& value = out.values;
  std::vector<std::uint8_t>& filled = out.coverage;
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
        double* t = value.data() + at(x, y) * k;
        for (int j = 0; j < k; ++j)
          t[j] = la * values(faces(f, 0), j) + lb * values(faces(f, 1), j) + lc * values(faces(f, 2), j);
        filled[at(x, y)] = 1;
      }
    }
  }

  // Gutter: each round fills the empty texels next to filled ones, reading
  // only texels filled in earlier rounds (a copy of the mask per round).
  std::vector<std::uint8_t> previous;
  std::vector<double> sum(static_cast<std::size_t>(k));
  for (int round = 0; round < options.padding; ++round) {
    previous = filled;
    bool grew = false;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (previous[at(x, y)]) continue;
        std::fill(sum.begin(), sum.end(), 0.0);
        int count = 0;
        const int nx[4] = {x, x, x - 1, x + 1}, ny[4] = {y - 1, y + 1, y, y};
        for (int m = 0; m < 4; ++m) {
          if (nx[m] < 0 || nx[m] >= w || ny[m] < 0 || ny[m] >= h || !previous[at(nx[m], ny[m])]) continue;
          const double* t = value.data() + at(nx[m], ny[m]) * k;
          for (int j = 0; j < k; ++j) sum[static_cast<std::size_t>(j)] += t[j];
          ++count;
        }
        if (count == 0) continue;
        double* t = value.data() + at(x, y) * k;
        for (int j = 0; j < k; ++j) t[j] = sum[static_cast<std::size_t>(j)] / count;
        filled[at(x, y)] = 2;
        grew = true;
      }
    }
    if (!grew) break;
  }
  return out;
}

}  // namespace

Eigen::Vector2d texelCenterUv(int x, int y, int width, int height) {
  return {(x + 0.5) / width, 1.0 - (y + 0.5) / height};
}

UvBake bakeVertexValuesToUv(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces,
                            const Eigen::MatrixXd& vertexValues, const UvBakeOptions& options) {
  checkInputs(uvs, faces, vertexValues, options, "bakeVertexValuesToUv", "vertexValues");
  return bake(uvs, faces, vertexValues, options);
}

Image bakeVertexColorsToUv(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces,
                           const Eigen::MatrixX3d& vertexColors, const UvBakeOptions& options) {
  checkInputs(uvs, faces, vertexColors, options, "bakeVertexColorsToUv", "vertexColors");
  const UvBake baked = bake(uvs, faces, vertexColors, options);
  Image image(baked.width, baked.height, 4, options.background);
  for (int y = 0; y < baked.height; ++y) {
    for (int x = 0; x < baked.width; ++x) {
      const std::size_t t = static_cast<std::size_t>(y) * baked.width + x;
      if (!baked.coverage[t]) continue;
      const double* c = baked.values.data() + 3 * t;
      image.setPixel(x, y, Rgba8{toByte(c[0]), toByte(c[1]), toByte(c[2]), 255});
    }
  }
  return image;
}

Image16 densityMap(const UvBake& baked, double fullScale) {
  if (!(fullScale > 0) || !std::isfinite(fullScale))
    throw std::invalid_argument("densityMap: full scale " + std::to_string(fullScale) + ", expected > 0");
  if (baked.channels < 1 || baked.channels > 3)
    throw std::invalid_argument("densityMap: " + std::to_string(baked.channels) + " baked channels, expected 1-3");
  Image16 map;
  map.width = baked.width;
  map.height = baked.height;
  map.channels = baked.channels + 1;
  map.samples.assign(static_cast<std::size_t>(map.width) * map.height * map.channels, 0);
  for (std::size_t t = 0; t < baked.coverage.size(); ++t) {
    if (!baked.coverage[t]) continue;
    for (int j = 0; j < baked.channels; ++j) {
      const double q = baked.values[t * baked.channels + j] / fullScale;
      map.samples[t * map.channels + j] =
          static_cast<std::uint16_t>(std::lround(65535.0 * std::min(1.0, std::max(0.0, q))));
    }
    map.samples[t * map.channels + baked.channels] = 65535;
  }
  return map;
}

}  // namespace blot::engine
