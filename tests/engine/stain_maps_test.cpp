// Wetness, saturation and stain maps: the free functions on a constant field
// (constant maps, exact to the format's rounding), and what `blot run` writes
// through FrameExporter on a flat patch: a small stain's maps integrate over
// the UV layout to Σ A_i σ_i of the mesh's fields in every format (the EXR
// read back with OpenEXR's reader, the PNGs with the project's), a dry cloth
// gives zero maps, and the glTF material carries the wetness as its
// metallicRoughness texture. Without OpenEXR the EXR checks are skipped and
// asking for EXR maps is refused with what to install.
#include <blot/engine/engine.h>
#include <blot/engine/exr_image.h>
#include <blot/engine/frame_exports.h>
#include <blot/engine/image.h>
#include <blot/engine/stain_maps.h>
#include <blot/engine/uv_texture.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#if BLOT_HAVE_OPENEXR
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStringAttribute.h>
#endif

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace blot::engine {
namespace {

namespace fs = std::filesystem;

constexpr int kSide = 64;           // texels of every map here
constexpr double kPatchSide = 0.2;  // m: the patch fills the unit UV square
constexpr double kScale = 5.0;      // density_scale (kg/m²), SceneTexture's default

std::string folder(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("blot_stain_maps_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

/// The samples of an EXR file's one channel "Y", read with OpenEXR's reader.
std::vector<float> readExrY(const std::string& path, int& width, int& height) {
#if BLOT_HAVE_OPENEXR
  Imf::InputFile file(path.c_str());
  const Imath::Box2i window = file.header().dataWindow();
  width = window.max.x - window.min.x + 1;
  height = window.max.y - window.min.y + 1;
  EXPECT_NE(file.header().channels().findChannel("Y"), nullptr) << path;
  EXPECT_EQ(file.header().channels().findChannel("Y")->type, Imf::FLOAT) << path;
  const auto* units = file.header().findTypedAttribute<Imf::StringAttribute>("blot:units");
  EXPECT_TRUE(units != nullptr && units->value() == "kg/m^2") << path;
  std::vector<float> samples(static_cast<std::size_t>(width) * height);
  Imf::FrameBuffer frame;
  frame.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(samples.data()) -
                                               (window.min.x + window.min.y * width) * sizeof(float),
                               sizeof(float), sizeof(float) * width));
  file.setFrameBuffer(frame);
  file.readPixels(window.min.y, window.max.y);
  return samples;
#else
  (void)path;
  width = height = 0;
  return {};
#endif
}

/// An 8-bit grey map read with readPng (grey comes back as R = G = B).
std::vector<double> readPng8Values(const std::string& path, double scale) {
  const PngFileInfo info = readPngInfo(path);
  EXPECT_EQ(info.bitDepth, 8) << path;
  EXPECT_EQ(info.channels, 1) << path;
  EXPECT_EQ(info.srgbIntent, -1) << path << ": a data map carries no sRGB chunk";
  EXPECT_DOUBLE_EQ(info.gamma, 1.0) << path;
  const Image image = readPng(path);
  std::vector<double> values;
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) values.push_back(image.pixel(x, y).r / 255.0 * scale);
  return values;
}

std::vector<double> readPng16Values(const std::string& path, double scale) {
  const PngFileInfo info = readPngInfo(path);
  EXPECT_EQ(info.srgbIntent, -1) << path;
  EXPECT_DOUBLE_EQ(info.gamma, 1.0) << path;
  const Image16 image = readPng16(path);
  EXPECT_EQ(image.channels, 1) << path;
  std::vector<double> values;
  for (std::uint16_t s : image.samples) values.push_back(s / 65535.0 * scale);
  return values;
}

/// Σ A_i σ_i with A_i the barycentric (lumped) vertex area, one third of
/// the one-ring's area: the mesh's mass of field σ (kg).
double meshIntegral(const Eigen::MatrixX3d& positions, const stain::Triangles& faces, const Eigen::VectorXd& sigma) {
  double total = 0;
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(faces(f, 0)), b = positions.row(faces(f, 1)), c = positions.row(faces(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) total += area / 3.0 * sigma[faces(f, k)];
  }
  return total;
}

double mapIntegral(const std::vector<double>& values, double texelArea) {
  double total = 0;
  for (double v : values) total += v * texelArea;
  return total;
}

EngineDef patch(bool withDrop) {
  EngineDef def;
  def.mesh = stain::gridMesh(12, 12, kPatchSide, kPatchSide);
  def.timeStep = 0.01;
  def.stain.liquid.absorptionRate = 0.4;
  def.stain.liquid.saturationDensity = 1.5;
  if (withDrop) {
    TimedDrop drop;
    drop.drop.centerVertex = 84;
    drop.drop.radius = 0.04;
    drop.drop.solventMass = 0.002;
    drop.drop.soluteMass = 0.0012;
    def.drops.push_back(drop);
  }
  return def;
}

FrameExportSettings mapSettings() {
  FrameExportSettings s;
  s.texture.width = s.texture.height = kSide;
  s.texture.maps.png8 = s.texture.maps.png16 = true;
  s.texture.maps.exr = exrSupported();
  s.gltf.enabled = true;
  return s;
}

TEST(StainMaps, ValuesAreTheDocumentedSums) {
  Eigen::VectorXd solvent(2), solute(2), absorbedSolvent(2), absorbedSolute(2), adsorbedSolute(2);
  solvent << 0.3, 0;
  solute << 0.1, 0;
  absorbedSolvent << 0.5, 0;
  absorbedSolute << 0.2, 0;
  adsorbedSolute << 0.4, 0;
  const Eigen::MatrixX3d v = stainMapValues(solvent, solute, absorbedSolvent, absorbedSolute, adsorbedSolute);
  EXPECT_DOUBLE_EQ(v(0, static_cast<int>(StainMap::Wetness)), 0.4);
  EXPECT_DOUBLE_EQ(v(0, static_cast<int>(StainMap::Saturation)), 0.7);
  EXPECT_DOUBLE_EQ(v(0, static_cast<int>(StainMap::Stain)), 0.6000000000000001);
  EXPECT_EQ(v.row(1).norm(), 0.0);
  EXPECT_THROW(stainMapValues(solvent, solute, absorbedSolvent, absorbedSolute, Eigen::VectorXd(3)),
               std::invalid_argument);
}

TEST(StainMaps, AConstantFieldGivesAConstantMapInEveryFormat) {
  const stain::TriangleMesh grid = stain::gridMesh(7, 5, 2.0, 1.0);
  const Eigen::Index n = grid.vertexPositions.rows();
  const Eigen::VectorXd solvent = Eigen::VectorXd::Constant(n, 0.3), solute = Eigen::VectorXd::Constant(n, 0.1),
                        absorbedSolvent = Eigen::VectorXd::Constant(n, 0.5),
                        absorbedSolute = Eigen::VectorXd::Constant(n, 0.2),
                        adsorbedSolute = Eigen::VectorXd::Constant(n, 0.4);
  UvBakeOptions options;
  options.width = options.height = 40;
  const UvBake baked = bakeVertexValuesToUv(
      grid.vertexUVs, grid.faces, stainMapValues(solvent, solute, absorbedSolvent, absorbedSolute, adsorbedSolute),
      options);
  const std::string dir = folder("constant");
  const double expected[3] = {0.4, 0.7, 0.6};
  for (int m = 0; m < kStainMapCount; ++m) {
    const std::string name = stainMapName(static_cast<StainMap>(m));
    const std::string png8 = dir + "/" + name + ".png", png16 = dir + "/" + name + "16.png";
    writeDataPng(dataMapChannel(baked, m, 8, kScale), 8, png8);
    writeDataPng(dataMapChannel(baked, m, 16, kScale), 16, png16);
    const long byte = std::lround(255 * expected[m] / kScale), word = std::lround(65535 * expected[m] / kScale);
    for (double v : readPng8Values(png8, kScale)) ASSERT_EQ(std::lround(v / kScale * 255), byte) << name;
    for (double v : readPng16Values(png16, kScale)) ASSERT_EQ(std::lround(v / kScale * 65535), word) << name;
    if (!exrSupported()) continue;
    const std::string exr = dir + "/" + name + ".exr";
    writeExr(floatMapChannel(baked, m), exr, {{"blot:units", "kg/m^2"}});
    int width = 0, height = 0;
    const std::vector<float> samples = readExrY(exr, width, height);
    EXPECT_EQ(width, 40);
    EXPECT_EQ(height, 40);
    for (float s : samples) ASSERT_NEAR(s, expected[m], 1e-6) << name;  // float of a sum of three λ c
  }
}

// The patch of tests/engine/data/outputs_scene.json after 10 steps: a drop
// partly absorbed and adsorbed, every map non-zero somewhere, all below the
// 5 kg/m² full scale. The patch fills the unit UV square, so each of the
// 64 x 64 texels stands for (0.2 m / 64)² of cloth.
TEST(StainMaps, ASmallStainsMapsIntegrateToTheMeshFields) {
  Engine engine(patch(true));
  engine.advanceSteps(10);
  const std::string dir = folder("stain");
  FrameExporter exporter(mapSettings(), dir, "patch", engine);
  exporter.writeFrame(0, engine, true);
  const std::vector<std::string>& files = exporter.files().stainMaps;
  ASSERT_EQ(files.size(), exrSupported() ? 9u : 6u);
  const Eigen::MatrixX3d fields = stainMapValues(engine.solvent(), engine.solute(), engine.absorbedSolvent(),
                                                 engine.absorbedSolute(), engine.adsorbedSolute());
  const double texelArea = kPatchSide * kPatchSide / (kSide * kSide);
  const double patchArea = kPatchSide * kPatchSide;
  for (int m = 0; m < kStainMapCount; ++m) {
    const std::string name = stainMapName(static_cast<StainMap>(m));
    const double mesh = meshIntegral(engine.positions(), engine.faces(), fields.col(m));
    ASSERT_GT(mesh, 1e-6) << name << ": the stain should reach every map";
    ASSERT_LT(fields.col(m).maxCoeff(), kScale) << name << ": a clamped map would not integrate to the mesh's";
    // Each PNG sample is rounded by at most half a step: the integral moves by
    // at most half a step times the patch's area, plus the bake's own error
    // (below; the 16-bit bound is 256 times tighter).
    const std::vector<double> png8 = readPng8Values(dir + "/patch_" + name + ".png", kScale);
    const std::vector<double> png16 = readPng16Values(dir + "/patch_" + name + "16.png", kScale);
    ASSERT_EQ(png8.size(), static_cast<std::size_t>(kSide * kSide));
    const double bake = 1e-3 * mesh;
    EXPECT_NEAR(mapIntegral(png8, texelArea), mesh, 0.5 * kScale / 255 * patchArea + bake) << name;
    EXPECT_NEAR(mapIntegral(png16, texelArea), mesh, 0.5 * kScale / 65535 * patchArea + bake) << name;
    std::printf("%-10s  mesh %.6e kg  png8 %.6e  png16 %.6e", name.c_str(), mesh, mapIntegral(png8, texelArea),
                mapIntegral(png16, texelArea));
    if (exrSupported()) {
      int width = 0, height = 0;
      const std::vector<float> exr = readExrY(dir + "/patch_" + name + ".exr", width, height);
      ASSERT_EQ(width, kSide);
      ASSERT_EQ(height, kSide);
      double total = 0;
      for (float s : exr) total += s * texelArea;
      // The bake samples the P1 field at texel centres: exact inside each
      // triangle, off only in the texels a mesh edge crosses (measured:
      // 1.1e-4 to 1.4e-4 relative; the bound is 1e-3).
      EXPECT_NEAR(total, mesh, bake) << name;
      std::printf("  exr %.6e (%+.2e relative)", total, total / mesh - 1);
    }
    std::printf("\n");
  }
}

TEST(StainMaps, ADryClothGivesZeroMapsAndARoughMaterial) {
  const Engine engine(patch(false));
  const std::string dir = folder("dry");
  FrameExporter exporter(mapSettings(), dir, "dry", engine);
  exporter.writeFrame(0, engine, true);
  for (int m = 0; m < kStainMapCount; ++m) {
    const std::string name = stainMapName(static_cast<StainMap>(m));
    for (double v : readPng8Values(dir + "/dry_" + name + ".png", kScale)) ASSERT_EQ(v, 0.0) << name;
    for (double v : readPng16Values(dir + "/dry_" + name + "16.png", kScale)) ASSERT_EQ(v, 0.0) << name;
    if (!exrSupported()) continue;
    int width = 0, height = 0;
    for (float s : readExrY(dir + "/dry_" + name + ".exr", width, height)) ASSERT_EQ(s, 0.0f) << name;
  }
}

/// The JSON chunk of a .glb file and its binary chunk.
nlohmann::json glbJson(const std::string& path, std::string& binary) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (int k = 3; k >= 0; --k) v = v << 8 | static_cast<unsigned char>(bytes.at(at + k));
    return v;
  };
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  const std::uint32_t jsonLength = u32(12);
  EXPECT_EQ(bytes.substr(16, 4), "JSON");
  const std::size_t bin = 20 + jsonLength;
  binary = bytes.substr(bin + 8, u32(bin));
  return nlohmann::json::parse(bytes.substr(20, jsonLength));
}

/// The G channel (roughness) of the material's metallicRoughness texture, as written.
Image roughnessTexture(const std::string& glb, const std::string& dir) {
  std::string binary;
  const nlohmann::json gltf = glbJson(glb, binary);
  const nlohmann::json& pbr = gltf.at("materials").at(0).at("pbrMetallicRoughness");
  EXPECT_EQ(pbr.at("metallicFactor").get<double>(), 0.0);
  EXPECT_TRUE(pbr.contains("baseColorTexture")) << "the stain as base colour";
  if (!pbr.contains("metallicRoughnessTexture")) {
    ADD_FAILURE() << glb << ": the material has no metallicRoughnessTexture";
    return {};
  }
  const int texture = pbr.at("metallicRoughnessTexture").at("index").get<int>();
  const nlohmann::json& image = gltf.at("images").at(gltf.at("textures").at(texture).at("source").get<int>());
  EXPECT_EQ(image.at("mimeType"), "image/png");
  const nlohmann::json& view = gltf.at("bufferViews").at(image.at("bufferView").get<int>());
  const std::string png = dir + "/roughness.png";
  std::ofstream(png, std::ios::binary) << binary.substr(view.value("byteOffset", 0u), view.at("byteLength").get<std::size_t>());
  EXPECT_EQ(readPngInfo(png).srgbIntent, -1) << "glTF reads metallicRoughness as linear data";
  return readPng(png);
}

TEST(StainMaps, TheGltfMaterialCarriesTheWetnessAsRoughness) {
  Engine wet(patch(true));
  wet.advanceSteps(10);
  const std::string dir = folder("gltf");
  FrameExportSettings settings;
  settings.texture.width = settings.texture.height = kSide;
  settings.gltf.enabled = true;
  FrameExporter exporter(settings, dir, "wet", wet);
  exporter.writeFrame(0, wet, true);
  ASSERT_EQ(exporter.files().gltf.size(), 1u);
  const Image rough = roughnessTexture(exporter.files().gltf[0], dir);
  ASSERT_EQ(rough.width(), kSide);
  // Wet at the drop (vertex 84, the patch's centre), dry far from it.
  int smooth = 0, dry = 0;
  for (int y = 0; y < rough.height(); ++y)
    for (int x = 0; x < rough.width(); ++x) {
      const Rgba8 p = rough.pixel(x, y);
      ASSERT_EQ(p.b, 0) << "metallic 0";
      smooth += p.g < 255;
      dry += p.g == 255;
    }
  EXPECT_GT(smooth, 0) << "no wet sheen anywhere";
  EXPECT_GT(dry, 0) << "the whole cloth glossy";
  const GlossSettings gloss;
  EXPECT_EQ(roughnessOfWetness(0, gloss), 1.0);
  EXPECT_EQ(roughnessOfWetness(gloss.glossWetness, gloss), gloss.wetRoughness);
  EXPECT_EQ(roughnessOfWetness(10 * gloss.glossWetness, gloss), gloss.wetRoughness);

  const Engine dryCloth(patch(false));
  FrameExporter dryExporter(settings, dir, "dry", dryCloth);
  dryExporter.writeFrame(0, dryCloth, true);
  const Image dryRough = roughnessTexture(dryExporter.files().gltf[0], dir);
  for (int y = 0; y < dryRough.height(); ++y)
    for (int x = 0; x < dryRough.width(); ++x) ASSERT_EQ(dryRough.pixel(x, y).g, 255) << "dry cloth is rough";
}

TEST(StainMaps, ExrMapsWithoutOpenExrAreRefusedWithWhatToInstall) {
  const Engine engine(patch(false));
  FrameExportSettings settings;
  settings.texture.maps.exr = true;
  if (exrSupported()) {
    EXPECT_NO_THROW(FrameExporter(settings, folder("exr_refused"), "x", engine));
    GTEST_SKIP() << "this build has OpenEXR";
  }
  try {
    FrameExporter exporter(settings, folder("exr_refused"), "x", engine);
    ADD_FAILURE() << "EXR maps accepted without OpenEXR";
  } catch (const MissingFeatureError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--maps"), std::string::npos) << what;
    EXPECT_NE(what.find("libopenexr-dev"), std::string::npos) << what;
    EXPECT_NE(what.find("BLOT_WITH_OPENEXR"), std::string::npos) << what;
  }
}

TEST(StainMaps, BadArgumentsAreNamed) {
  UvBake baked;
  baked.width = baked.height = 2;
  baked.channels = 3;
  baked.values.assign(12, 0.0);
  baked.coverage.assign(4, 1);
  EXPECT_THROW(dataMapChannel(baked, 3, 8, kScale), std::invalid_argument);
  EXPECT_THROW(dataMapChannel(baked, 0, 12, kScale), std::invalid_argument);
  EXPECT_THROW(dataMapChannel(baked, 0, 8, 0.0), std::invalid_argument);
  Image16 tooBright;
  tooBright.width = tooBright.height = 1;
  tooBright.channels = 1;
  tooBright.samples = {256};
  EXPECT_THROW(encodeDataPng(tooBright, 8), ImageError);
}

}  // namespace
}  // namespace blot::engine
