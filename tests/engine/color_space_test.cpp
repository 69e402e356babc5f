// The colour convention end to end: linear values in, sRGB bytes out, and the
// PNG says so (sRGB chunk); data maps are marked linear. The preset table in
// docs/rendering.md is recomputed here.
#include <blot/engine/color_space.h>
#include <blot/engine/image.h>
#include <blot/engine/renderer.h>
#include <blot/engine/stain_color.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

namespace blot::engine {
namespace {

TEST(ColorSpace, KnownLinearValuesGiveTheDocumentedBytes) {
  // IEC 61966-2-1: 1.055 · 0.5^(1/2.4) − 0.055 = 0.735357 -> 187.52 -> 188.
  EXPECT_EQ(linearToSrgbByte(0.5), 188);
  EXPECT_EQ(linearToSrgbByte(0.2), 124);
  EXPECT_EQ(linearToSrgbByte(0.0), 0);
  EXPECT_EQ(linearToSrgbByte(1.0), 255);
  EXPECT_EQ(linearToSrgbByte(0.001), 3);  // linear segment: 12.92 · 0.001 · 255 = 3.29
  EXPECT_EQ(linearToSrgbByte(-1.0), 0);
  EXPECT_EQ(linearToSrgbByte(2.0), 255);
  EXPECT_EQ(linearToSrgbByte(std::nan("")), 0);
  for (int b = 0; b < 256; ++b) {
    EXPECT_EQ(linearToSrgbByte(srgbByteToLinear(static_cast<std::uint8_t>(b))), b) << b;
  }
  for (double x = 0; x <= 1.0; x += 1.0 / 1024) EXPECT_NEAR(srgbDecode(srgbEncode(x)), x, 1e-12);
}

TEST(ColorSpace, RenderedLinearValueRoundTripsThroughThePngWithItsSrgbChunk) {
  RenderSettings settings;
  settings.width = settings.height = 32;
  settings.supersampling = 1;
  settings.ambient = 1.0;
  settings.diffuse = 0.0;
  settings.background = {0.2, 0.2, 0.2};
  Camera camera;
  camera.projection = Projection::Orthographic;
  camera.orthographicHeight = 2.0;
  stain::RowVectors3 positions(4, 3);
  positions << -0.5, -0.5, 0, 0.5, -0.5, 0, 0.5, 0.5, 0, -0.5, 0.5, 0;
  stain::Triangles faces(2, 3);
  faces << 0, 1, 2, 0, 2, 3;
  const Image image = renderMesh(positions, faces, Eigen::MatrixX3d::Constant(4, 3, 0.5), camera, settings);
  const std::string path = (std::filesystem::temp_directory_path() / "blot_color_space_test.png").string();
  writePng(image, path);
  const Image back = readPng(path);
  EXPECT_EQ(back.pixel(16, 16), (Rgba8{188, 188, 188, 255})) << "linear 0.5 in the middle";
  EXPECT_EQ(back.pixel(1, 1), (Rgba8{124, 124, 124, 255})) << "linear 0.2 background";
  const PngFileInfo info = readPngInfo(path);
  EXPECT_EQ(info.srgbIntent, 0);  // sRGB chunk, perceptual intent
  EXPECT_NEAR(info.gamma, 1.0 / 2.2, 1e-5);
  EXPECT_EQ(info.bitDepth, 8);
  std::filesystem::remove(path);
}

TEST(ColorSpace, SixteenBitDataMapsAreMarkedLinearAndExact) {
  Image16 map;
  map.width = 3;
  map.height = 2;
  map.channels = 2;
  map.samples = {0, 1, 255, 256, 65535, 12345, 40000, 2, 3, 4, 5, 6};
  const std::string path = (std::filesystem::temp_directory_path() / "blot_color_space_16.png").string();
  writePng16(map, path, {"blot:density_scale", "10"});
  const PngFileInfo info = readPngInfo(path);
  EXPECT_EQ(info.bitDepth, 16);
  EXPECT_EQ(info.channels, 2);
  EXPECT_EQ(info.srgbIntent, -1);
  EXPECT_DOUBLE_EQ(info.gamma, 1.0);
  const Image16 back = readPng16(path);
  EXPECT_EQ(back.width, 3);
  EXPECT_EQ(back.height, 2);
  EXPECT_EQ(back.samples, map.samples);
  std::filesystem::remove(path);
}

// docs/rendering.md, "Presets": colour on the default cloth, sRGB bytes, no water.
TEST(ColorSpace, PresetTableInTheDocsIsWhatTheCodeWrites) {
  const int expected[3][3][3] = {{{200, 105, 129}, {168, 43, 73}, {118, 2, 18}},
                                 {{190, 155, 110}, {152, 102, 51}, {95, 41, 5}},
                                 {{102, 129, 187}, {40, 69, 157}, {2, 14, 110}}};
  const PigmentPreset presets[3] = {PigmentPreset::Wine, PigmentPreset::Coffee, PigmentPreset::Ink};
  const double sigmas[3] = {0.5, 1.0, 2.0};
  for (int p = 0; p < 3; ++p)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Array3d c = stainColor(stainColorMapping(presets[p]), 0, sigmas[k], 0, 0);
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_EQ(linearToSrgbByte(c[ch]), expected[p][k][ch]) << pigmentPresetName(presets[p]) << " sigma " << sigmas[k];
    }
  const Eigen::Array3d clean = stainColor(stainColorMapping(PigmentPreset::Wine), 0, 0, 0, 0);
  EXPECT_EQ(linearToSrgbByte(clean[0]), 237);
  EXPECT_EQ(linearToSrgbByte(clean[1]), 232);
  EXPECT_EQ(linearToSrgbByte(clean[2]), 222);
}

}  // namespace
}  // namespace blot::engine
