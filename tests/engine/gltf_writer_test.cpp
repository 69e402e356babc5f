// glTF export read back by tinygltf (the structural check CI runs): accessor
// counts and types, COLOR_0 equal to the linear colours, TEXCOORD_0 flipped to
// glTF's top-left origin, the embedded texture decodable at its size.
#include <blot/engine/gltf_writer.h>
#include <blot/engine/image.h>
#include <blot/engine/uv_texture.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cstring>
#include <filesystem>

namespace blot::engine {
namespace {

template <class T>
const T* accessorData(const tinygltf::Model& m, int accessor) {
  const tinygltf::Accessor& a = m.accessors[static_cast<size_t>(accessor)];
  const tinygltf::BufferView& v = m.bufferViews[static_cast<size_t>(a.bufferView)];
  return reinterpret_cast<const T*>(m.buffers[static_cast<size_t>(v.buffer)].data.data() + v.byteOffset + a.byteOffset);
}

GltfFrame gridFrame(bool textured) {
  const stain::TriangleMesh grid = stain::gridMesh(6, 4, 1.0, 0.5);
  GltfFrame f;
  f.positions = grid.vertexPositions;
  f.normals = Eigen::MatrixX3d::Zero(grid.vertexPositions.rows(), 3);
  f.normals.col(2).setOnes();
  f.faces = grid.faces;
  f.colors.resize(grid.vertexPositions.rows(), 3);
  for (Eigen::Index v = 0; v < f.colors.rows(); ++v)
    f.colors.row(v) << grid.vertexUVs(v, 0), grid.vertexUVs(v, 1), 0.25;
  if (textured) {
    f.uvs = grid.vertexUVs;
    UvBakeOptions o;
    o.width = 32;
    o.height = 16;
    f.texturePng = encodePng(bakeVertexColorsToUv(f.uvs, f.faces, f.colors, o));
  }
  return f;
}

tinygltf::Model load(const std::string& path) {
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string error, warning;
  EXPECT_TRUE(loader.LoadBinaryFromFile(&model, &error, &warning, path)) << error;
  EXPECT_TRUE(error.empty()) << error;
  return model;
}

TEST(GltfWriter, TexturedFileReadsBackWithItsCountsColoursUvsAndTexture) {
  const GltfFrame f = gridFrame(true);
  const std::string path = (std::filesystem::temp_directory_path() / "blot_gltf_test.glb").string();
  writeGlb(path, f);
  const tinygltf::Model m = load(path);
  const auto n = static_cast<size_t>(f.positions.rows());
  ASSERT_EQ(m.scenes.size(), 2u);
  EXPECT_EQ(m.defaultScene, 0);
  EXPECT_EQ(m.scenes[0].name, "stain_texture");
  ASSERT_EQ(m.meshes.size(), 2u);
  const tinygltf::Primitive& textured = m.meshes[0].primitives.at(0);
  const tinygltf::Primitive& colored = m.meshes[1].primitives.at(0);
  EXPECT_EQ(m.accessors[static_cast<size_t>(textured.attributes.at("POSITION"))].count, n);
  EXPECT_EQ(m.accessors[static_cast<size_t>(textured.indices)].count, static_cast<size_t>(3 * f.faces.rows()));
  EXPECT_EQ(textured.attributes.count("COLOR_0"), 0u) << "COLOR_0 would multiply the texture";
  ASSERT_EQ(colored.attributes.count("COLOR_0"), 1u);
  const tinygltf::Accessor& color = m.accessors[static_cast<size_t>(colored.attributes.at("COLOR_0"))];
  EXPECT_EQ(color.count, n);
  EXPECT_EQ(color.type, TINYGLTF_TYPE_VEC3);
  EXPECT_EQ(color.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  const float* c = accessorData<float>(m, colored.attributes.at("COLOR_0"));
  const float* uv = accessorData<float>(m, textured.attributes.at("TEXCOORD_0"));
  const std::uint32_t* index = accessorData<std::uint32_t>(m, textured.indices);
  for (size_t v = 0; v < n; ++v) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(c[3 * v + k], static_cast<float>(f.colors(static_cast<Eigen::Index>(v), k)));
    EXPECT_EQ(uv[2 * v], static_cast<float>(f.uvs(static_cast<Eigen::Index>(v), 0)));
    EXPECT_EQ(uv[2 * v + 1], static_cast<float>(1.0 - f.uvs(static_cast<Eigen::Index>(v), 1)));
  }
  for (Eigen::Index t = 0; t < f.faces.rows(); ++t)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(index[3 * t + k], static_cast<std::uint32_t>(f.faces(t, k)));
  ASSERT_EQ(m.materials.at(static_cast<size_t>(textured.material)).pbrMetallicRoughness.baseColorTexture.index, 0);
  ASSERT_EQ(m.images.size(), 1u);
  EXPECT_EQ(m.images[0].mimeType, "image/png");
  EXPECT_EQ(m.images[0].width, 32);  // decoded by tinygltf's PNG loader
  EXPECT_EQ(m.images[0].height, 16);
  std::filesystem::remove(path);
}

// The wetness as roughness: a second image, the material's
// metallicRoughnessTexture, decoded by tinygltf at its size; roughness factor
// 1 and metallic 0 leave the texture's values as they are.
TEST(GltfWriter, TheMetallicRoughnessTextureIsTheMaterialsSecondImage) {
  GltfFrame f = gridFrame(true);
  Image16 roughness;
  roughness.width = 8;
  roughness.height = 4;
  roughness.channels = 3;
  roughness.samples.assign(8 * 4 * 3, 0);
  for (std::size_t t = 0; t < 32; ++t) {
    roughness.samples[3 * t] = 255;
    roughness.samples[3 * t + 1] = t < 16 ? 51 : 255;  // 0.2 (wet) above, 1 (dry) below
  }
  f.metallicRoughnessPng = encodeDataPng(roughness, 8);
  const std::string path = (std::filesystem::temp_directory_path() / "blot_gltf_roughness.glb").string();
  writeGlb(path, f);
  const tinygltf::Model m = load(path);
  const tinygltf::Material& material = m.materials.at(static_cast<size_t>(m.meshes[0].primitives.at(0).material));
  EXPECT_EQ(material.pbrMetallicRoughness.baseColorTexture.index, 0);
  ASSERT_EQ(material.pbrMetallicRoughness.metallicRoughnessTexture.index, 1);
  EXPECT_EQ(material.pbrMetallicRoughness.metallicFactor, 0.0);
  EXPECT_EQ(material.pbrMetallicRoughness.roughnessFactor, 1.0);
  ASSERT_EQ(m.images.size(), 2u);
  const tinygltf::Image& image = m.images[static_cast<size_t>(m.textures.at(1).source)];
  EXPECT_EQ(image.width, 8);
  EXPECT_EQ(image.height, 4);
  ASSERT_GE(image.component, 3);
  EXPECT_EQ(image.image.at(1), 51);  // texel (0, 0), G
  EXPECT_EQ(image.image.at(static_cast<size_t>(image.component) * 31 + 1), 255);
  std::filesystem::remove(path);
  f.metallicRoughnessPng = {0xff, 0xd8, 0xff};
  EXPECT_THROW(writeGlb(path, f), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(GltfWriter, WithoutUvsOnlyTheVertexColourMeshIsWritten) {
  const std::string path = (std::filesystem::temp_directory_path() / "blot_gltf_plain.glb").string();
  writeGlb(path, gridFrame(false));
  const tinygltf::Model m = load(path);
  ASSERT_EQ(m.scenes.size(), 1u);
  EXPECT_EQ(m.meshes.size(), 1u);
  EXPECT_TRUE(m.images.empty());
  EXPECT_EQ(m.meshes[0].primitives.at(0).attributes.count("COLOR_0"), 1u);
  std::filesystem::remove(path);
}

TEST(GltfWriter, BadInputNamesTheArrayAndWritesNothing) {
  GltfFrame f = gridFrame(true);
  f.colors(3, 1) = std::nan("");
  const std::string path = (std::filesystem::temp_directory_path() / "blot_gltf_bad.glb").string();
  std::filesystem::remove(path);
  try {
    writeGlb(path, f);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("colors row 3 is not finite"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(GltfWriter, ColoursOutsideTheUnitRangeAndATextureThatIsNoPngAreRefused) {
  const std::string path = (std::filesystem::temp_directory_path() / "blot_gltf_range.glb").string();
  std::filesystem::remove(path);
  const auto refused = [&](const GltfFrame& f, const std::string& expected) {
    try {
      writeGlb(path, f);
      ADD_FAILURE() << "expected std::invalid_argument containing " << expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(path));
  };
  GltfFrame bright = gridFrame(true);
  bright.colors(2, 0) = 1.5;
  refused(bright, "colors row 2 channel 0 is 1.5");
  GltfFrame negative = gridFrame(true);
  negative.colors(4, 2) = -0.25;
  refused(negative, "colors row 4 channel 2 is -0.25");
  GltfFrame jpeg = gridFrame(true);
  jpeg.texturePng = {0xff, 0xd8, 0xff, 0xe0, 0, 16, 'J', 'F', 'I', 'F', 0};
  refused(jpeg, "texturePng (11 bytes) is not a PNG");
  GltfFrame stub = gridFrame(true);
  stub.texturePng = {0x89, 'P', 'N'};
  refused(stub, "texturePng (3 bytes) is not a PNG");
  // The edges of the range are colours, and so is rounding past them.
  GltfFrame edges = gridFrame(true);
  edges.colors.col(0).setZero();
  edges.colors.col(1).setOnes();
  edges.colors(0, 2) = 1.0 + 1e-12;
  edges.colors(1, 2) = -1e-12;
  writeGlb(path, edges);
  EXPECT_TRUE(std::filesystem::exists(path));
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace blot::engine
