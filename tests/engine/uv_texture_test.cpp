// UV bake: a linear colour field is reproduced exactly (P1 interpolation is
// exact for linear fields), coverage follows the UV triangles, the gutter is
// exactly `padding` texels wide, and bad input names the argument.
#include <blot/engine/uv_texture.h>
#include <blot/engine/color_space.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>

namespace blot::engine {
namespace {

Eigen::Vector3d linearField(const Eigen::Vector2d& uv) {
  return {uv.x(), uv.y(), 0.5 * uv.x() + 0.25 * uv.y() + 0.1};
}

// The bake interpolates linear colour and stores sRGB bytes.
int byteOf(double c) { return linearToSrgbByte(c); }

TEST(UvTexture, LinearFieldOnAGridIsReproducedAtEveryTexel) {
  const stain::TriangleMesh grid = stain::gridMesh(7, 5, 2.0, 1.0);
  ASSERT_EQ(grid.vertexUVs.rows(), grid.vertexPositions.rows());
  Eigen::MatrixX3d colors(grid.vertexUVs.rows(), 3);
  for (int v = 0; v < colors.rows(); ++v) colors.row(v) = linearField(grid.vertexUVs.row(v)).transpose();
  UvBakeOptions options;
  options.width = 64;
  options.height = 48;
  const Image texture = bakeVertexColorsToUv(grid.vertexUVs, grid.faces, colors, options);
  ASSERT_EQ(texture.width(), 64);
  ASSERT_EQ(texture.height(), 48);
  ASSERT_EQ(texture.channels(), 4);
  int worst = 0;
  for (int y = 0; y < texture.height(); ++y) {
    for (int x = 0; x < texture.width(); ++x) {
      const Rgba8 p = texture.pixel(x, y);
      ASSERT_EQ(p.a, 255) << "texel (" << x << ", " << y << ") not covered by the unit-square grid";
      const Eigen::Vector3d expected = linearField(texelCenterUv(x, y, texture.width(), texture.height()));
      worst = std::max({worst, std::abs(p.r - byteOf(expected.x())), std::abs(p.g - byteOf(expected.y())),
                        std::abs(p.b - byteOf(expected.z()))});
    }
  }
  // Barycentric interpolation of a linear field is exact up to rounding; a
  // value exactly between two bytes may round either way after it.
  EXPECT_LE(worst, 1);
}

TEST(UvTexture, VOneIsTheTopRow) {
  const Eigen::Vector2d top = texelCenterUv(0, 0, 4, 4), bottom = texelCenterUv(0, 3, 4, 4);
  EXPECT_DOUBLE_EQ(top.y(), 1.0 - 0.125);
  EXPECT_DOUBLE_EQ(bottom.y(), 0.125);
}

TEST(UvTexture, CoverageAndGutterFollowTheTriangle) {
  // One triangle covering the lower-left half of [0.25, 0.75]² in UV space.
  Eigen::MatrixX2d uvs(3, 2);
  uvs << 0.25, 0.25, 0.75, 0.25, 0.25, 0.75;
  Eigen::MatrixX3i faces(1, 3);
  faces << 0, 1, 2;
  Eigen::MatrixX3d colors(3, 3);
  colors.rowwise() = Eigen::RowVector3d(0.2, 0.4, 0.6);
  UvBakeOptions options;
  options.width = options.height = 40;
  options.padding = 3;
  const Image texture = bakeVertexColorsToUv(uvs, faces, colors, options);
  const Rgba8 expected{linearToSrgbByte(0.2), linearToSrgbByte(0.4), linearToSrgbByte(0.6), 255};
  int covered = 0, gutter = 0;
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 40; ++x) {
      const Eigen::Vector2d p = texelCenterUv(x, y, 40, 40);
      const bool inside = p.x() >= 0.25 && p.y() >= 0.25 && p.x() + p.y() <= 1.0;
      const Rgba8 texel = texture.pixel(x, y);
      if (inside) {
        ++covered;
        ASSERT_EQ(texel.a, 255) << "(" << x << ", " << y << ")";
        EXPECT_EQ(texel, expected);
      } else if (texel.a == 255) {
        ++gutter;
        EXPECT_EQ(texel, expected) << "gutter texels copy a constant field";
      }
    }
  }
  // 20 x 20 texel square cut on its diagonal: 210 centres on or below it.
  EXPECT_EQ(covered, 210);
  EXPECT_GT(gutter, 0);
  // No texel more than `padding` steps (4-neighbour) from the covered set.
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 40; ++x) {
      const Eigen::Vector2d p = texelCenterUv(x, y, 40, 40);
      const int dx = p.x() < 0.25 ? static_cast<int>(std::ceil((0.25 - p.x()) * 40 - 1e-9)) : 0;
      const int dy = p.y() < 0.25 ? static_cast<int>(std::ceil((0.25 - p.y()) * 40 - 1e-9)) : 0;
      if (dx + dy > options.padding) {
        EXPECT_EQ(texture.pixel(x, y).a, 0) << "(" << x << ", " << y << ")";
      }
    }
  }
}

TEST(UvTexture, BakingTwiceGivesTheSameBytes) {
  const stain::TriangleMesh grid = stain::gridMesh(9, 9, 1.0, 1.0);
  Eigen::MatrixX3d colors(grid.vertexUVs.rows(), 3);
  for (int v = 0; v < colors.rows(); ++v) colors.row(v) << std::sin(3.0 * v), 0.5, std::cos(v) * 0.5 + 0.5;
  colors = colors.cwiseMax(0.0).cwiseMin(1.0);
  const Image a = bakeVertexColorsToUv(grid.vertexUVs, grid.faces, colors);
  const Image b = bakeVertexColorsToUv(grid.vertexUVs, grid.faces, colors);
  EXPECT_TRUE(a == b);
}

void expectInvalid(const Eigen::MatrixX2d& uvs, const Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& colors,
                   const UvBakeOptions& options, const std::string& needle) {
  try {
    bakeVertexColorsToUv(uvs, faces, colors, options);
    ADD_FAILURE() << "expected an error mentioning " << needle;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(UvTexture, BadInputNamesTheArgument) {
  Eigen::MatrixX2d uvs(3, 2);
  uvs << 0, 0, 1, 0, 0, 1;
  Eigen::MatrixX3i faces(1, 3);
  faces << 0, 1, 2;
  Eigen::MatrixX3d colors = Eigen::MatrixX3d::Constant(3, 3, 0.5);
  UvBakeOptions options;
  options.width = options.height = 8;

  Eigen::MatrixX3i badFaces = faces;
  badFaces(0, 2) = 7;
  expectInvalid(uvs, badFaces, colors, options, "faces(0, 2) = 7");
  expectInvalid(uvs, faces, Eigen::MatrixX3d::Constant(2, 3, 0.5), options, "vertexColors has 2");
  expectInvalid(Eigen::MatrixX2d(0, 2), Eigen::MatrixX3i(0, 3), Eigen::MatrixX3d(0, 3), options, "no UVs");
  Eigen::MatrixX2d nanUvs = uvs;
  nanUvs(1, 0) = std::nan("");
  expectInvalid(nanUvs, faces, colors, options, "uvs row 1");
  UvBakeOptions tiny = options;
  tiny.width = 0;
  expectInvalid(uvs, faces, colors, tiny, "0x8");
  UvBakeOptions huge = options;  // refused before anything is allocated
  huge.width = huge.height = 16384;
  expectInvalid(uvs, faces, colors, huge, "16384x16384, expected each side at most 16384 and at most 2^26 texels");
  huge.width = 1 << 20;
  huge.height = 1;
  expectInvalid(uvs, faces, colors, huge, "1048576x1, expected each side at most 16384");
}

}  // namespace
}  // namespace blot::engine

namespace blot::engine {
namespace {

// The 16-bit density map of a linear density field: every texel within half a
// unit of 1/65535 of round(65535 σ/scale) at its centre, coverage 65535.
TEST(UvTexture, DensityMapOfALinearFieldIsExactToOneUnit) {
  const stain::TriangleMesh grid = stain::gridMesh(7, 5, 2.0, 1.0);
  const double scale = 4.0;
  Eigen::MatrixXd densities(grid.vertexUVs.rows(), 2);
  for (Eigen::Index v = 0; v < densities.rows(); ++v) {
    densities(v, 0) = 3.0 * grid.vertexUVs(v, 0) + 0.5 * grid.vertexUVs(v, 1);  // kg/m²
    densities(v, 1) = 1.0 + 2.0 * grid.vertexUVs(v, 1);
  }
  UvBakeOptions options;
  options.width = 50;
  options.height = 30;
  const Image16 map = densityMap(bakeVertexValuesToUv(grid.vertexUVs, grid.faces, densities, options), scale);
  ASSERT_EQ(map.channels, 3);
  int worst = 0;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const Eigen::Vector2d p = texelCenterUv(x, y, map.width, map.height);
      const double exact[2] = {3.0 * p.x() + 0.5 * p.y(), 1.0 + 2.0 * p.y()};
      const std::uint16_t* t = map.samples.data() + (static_cast<std::size_t>(y) * map.width + x) * 3;
      ASSERT_EQ(t[2], 65535);
      for (int k = 0; k < 2; ++k)
        worst = std::max(worst, std::abs(int(t[k]) - int(std::lround(65535.0 * exact[k] / scale))));
    }
  EXPECT_LE(worst, 1);
  EXPECT_THROW(densityMap(bakeVertexValuesToUv(grid.vertexUVs, grid.faces, densities, options), 0.0),
               std::invalid_argument);
}

}  // namespace
}  // namespace blot::engine
