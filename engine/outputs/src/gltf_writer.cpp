// glTF 2.0 export through Debian's tinygltf (libtinygltf-dev).
//
// Design note: the model is built in memory and serialized by tinygltf into a
// string stream, which is written atomically like every other output. All
// arrays go into one binary buffer (float32 attributes, uint32 indices, the
// PNG); the image is referenced by a bufferView, so the .glb is self-contained.
// Rejected: .gltf + .bin + .png triples (three files per frame to keep
// together) and writing our own JSON/GLB framing (tinygltf is packaged).
#include <blot/engine/gltf_writer.h>

#include <blot/stain/io/atomic_file.h>

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace blot::engine {
namespace {

// How far past [0, 1] a colour may be and still count as rounding.
constexpr double kColorRounding = 1e-9;

void check(const std::string& path, const GltfFrame& f) {
  const Eigen::Index n = f.positions.rows();
  const auto fail = [&](const std::string& what) { throw std::invalid_argument(path + ": glTF export: " + what); };
  if (n == 0) fail("no vertices");
  if (f.normals.rows() != n) fail("normals has " + std::to_string(f.normals.rows()) + " rows, expected " + std::to_string(n));
  if (f.colors.rows() != n) fail("colors has " + std::to_string(f.colors.rows()) + " rows, expected " + std::to_string(n));
  if (f.uvs.rows() != 0 && f.uvs.rows() != n) fail("uvs has " + std::to_string(f.uvs.rows()) + " rows, expected 0 or " + std::to_string(n));
  const auto finite = [&](const auto& m, const char* name) {
    for (Eigen::Index i = 0; i < m.rows(); ++i)
      if (!m.row(i).allFinite()) fail(std::string(name) + " row " + std::to_string(i) + " is not finite");
  };
  finite(f.positions, "positions");
  finite(f.normals, "normals");
  finite(f.colors, "colors");
  finite(f.uvs, "uvs");
  // glTF's COLOR_0 is linear RGB in [0, 1]. Rounding past an end is clamped
  // when the accessor is written; anything further is another convention
  // (0-255, sRGB-encoded HDR) that would be written as white or black.
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (!(f.colors(i, c) >= -kColorRounding && f.colors(i, c) <= 1.0 + kColorRounding)) {
        std::ostringstream s;
        s << "colors row " << i << " channel " << c << " is " << f.colors(i, c) << ", expected linear RGB in [0, 1]";
        fail(s.str());
      }
  // The texture is stored with mimeType image/png: it must be one.
  static constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const auto notPng = [](const std::vector<std::uint8_t>& bytes) {
    return !bytes.empty() && (bytes.size() < sizeof kPngSignature ||
                              !std::equal(kPngSignature, kPngSignature + sizeof kPngSignature, bytes.begin()));
  };
  if (notPng(f.texturePng))
    fail("texturePng (" + std::to_string(f.texturePng.size()) + " bytes) is not a PNG (no PNG signature)");
  if (notPng(f.metallicRoughnessPng))
    fail("metallicRoughnessPng (" + std::to_string(f.metallicRoughnessPng.size()) +
         " bytes) is not a PNG (no PNG signature)");
  for (Eigen::Index t = 0; t < f.faces.rows(); ++t)
    for (int k = 0; k < 3; ++k)
      if (f.faces(t, k) < 0 || f.faces(t, k) >= n)
        fail("face " + std::to_string(t) + " vertex " + std::to_string(f.faces(t, k)) + " out of range [0, " +
             std::to_string(n) + ")");
}

class Builder {
 public:
  explicit Builder(tinygltf::Model& model) : model_(model) { model_.buffers.emplace_back(); }

  // Appends bytes (padded to 4) as a bufferView; returns its index.
  int view(const void* data, std::size_t bytes, int target) {
    std::vector<unsigned char>& buffer = model_.buffers[0].data;
    buffer.resize((buffer.size() + 3) / 4 * 4, 0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buffer.size();
    v.byteLength = bytes;
    if (target != 0) v.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    buffer.insert(buffer.end(), p, p + bytes);
    model_.bufferViews.push_back(v);
    return static_cast<int>(model_.bufferViews.size()) - 1;
  }

  // A float VECn accessor of the rows of `m` (optionally transformed per row).
  template <class Matrix, class Transform>
  int floats(const Matrix& m, int type, Transform transform, bool bounds) {
    const int cols = static_cast<int>(m.cols());
    std::vector<float> data(static_cast<std::size_t>(m.rows()) * cols);
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      Eigen::RowVectorXd row = m.row(i);
      transform(row);
      for (int k = 0; k < cols; ++k) data[static_cast<std::size_t>(i) * cols + k] = static_cast<float>(row[k]);
    }
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = static_cast<std::size_t>(m.rows());
    a.type = type;
    if (bounds) {  // POSITION requires min and max
      a.minValues.assign(static_cast<std::size_t>(cols), std::numeric_limits<double>::infinity());
      a.maxValues.assign(static_cast<std::size_t>(cols), -std::numeric_limits<double>::infinity());
      for (std::size_t i = 0; i < data.size(); ++i) {
        a.minValues[i % cols] = std::min<double>(a.minValues[i % cols], data[i]);
        a.maxValues[i % cols] = std::max<double>(a.maxValues[i % cols], data[i]);
      }
    }
    model_.accessors.push_back(a);
    return static_cast<int>(model_.accessors.size()) - 1;
  }

  int indices(const stain::Triangles& faces) {
    std::vector<std::uint32_t> data(static_cast<std::size_t>(faces.rows()) * 3);
    for (Eigen::Index t = 0; t < faces.rows(); ++t)
      for (int k = 0; k < 3; ++k) data[static_cast<std::size_t>(t) * 3 + k] = static_cast<std::uint32_t>(faces(t, k));
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    a.count = data.size();
    a.type = TINYGLTF_TYPE_SCALAR;
    model_.accessors.push_back(a);
    return static_cast<int>(model_.accessors.size()) - 1;
  }

 private:
  tinygltf::Model& model_;
};

int addMeshNodeScene(tinygltf::Model& model, const std::string& name, tinygltf::Primitive primitive) {
  tinygltf::Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(std::move(primitive));
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.name = name;
  node.mesh = static_cast<int>(model.meshes.size()) - 1;
  model.nodes.push_back(node);
  return static_cast<int>(model.nodes.size()) - 1;
}

}  // namespace

void writeGlb(const std::string& path, const GltfFrame& f) {
  check(path, f);
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "Blot (blot::engine::writeGlb)";
  Builder b(model);
  const auto same = [](Eigen::RowVectorXd&) {};
  const int position = b.floats(f.positions, TINYGLTF_TYPE_VEC3, same, true);
  const int normal = b.floats(f.normals, TINYGLTF_TYPE_VEC3, [](Eigen::RowVectorXd& r) {
    const double l = r.norm();
    if (l > 0) r /= l;  // glTF requires unit normals
  }, false);
  const int index = b.indices(f.faces);
  const bool textured = f.uvs.rows() > 0 && !f.texturePng.empty();

  int texturedNode = -1;
  if (textured) {
    const int uv = b.floats(f.uvs, TINYGLTF_TYPE_VEC2, [](Eigen::RowVectorXd& r) { r[1] = 1.0 - r[1]; }, false);
    tinygltf::Image image;
    image.name = "stain_color";
    image.mimeType = "image/png";
    image.bufferView = b.view(f.texturePng.data(), f.texturePng.size(), 0);
    model.images.push_back(image);
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    model.samplers.push_back(sampler);
    tinygltf::Texture texture;
    texture.source = 0;
    texture.sampler = 0;
    model.textures.push_back(texture);
    // Wetness as roughness: glTF reads roughness from G and metallic from B,
    // multiplied by the factors below (both left at their meaning: metallic 0,
    // roughness up to 1).
    const bool glossy = !f.metallicRoughnessPng.empty();
    if (glossy) {
      tinygltf::Image roughness;
      roughness.name = "stain_wetness_roughness";
      roughness.mimeType = "image/png";
      roughness.bufferView = b.view(f.metallicRoughnessPng.data(), f.metallicRoughnessPng.size(), 0);
      model.images.push_back(roughness);
      tinygltf::Texture t;
      t.source = 1;
      t.sampler = 0;
      model.textures.push_back(t);
    }
    tinygltf::Material material;
    material.name = "stain";
    material.doubleSided = true;  // cloth is seen from both sides
    material.pbrMetallicRoughness.baseColorTexture.index = 0;
    material.pbrMetallicRoughness.metallicFactor = 0.0;
    material.pbrMetallicRoughness.roughnessFactor = 1.0;
    if (glossy) material.pbrMetallicRoughness.metallicRoughnessTexture.index = 1;
    model.materials.push_back(material);
    tinygltf::Primitive p;
    p.attributes = {{"POSITION", position}, {"NORMAL", normal}, {"TEXCOORD_0", uv}};
    p.indices = index;
    p.material = static_cast<int>(model.materials.size()) - 1;
    p.mode = TINYGLTF_MODE_TRIANGLES;
    texturedNode = addMeshNodeScene(model, f.name, p);
  }
  const int color = b.floats(f.colors, TINYGLTF_TYPE_VEC3, [](Eigen::RowVectorXd& r) {
    for (int k = 0; k < 3; ++k) r[k] = std::min(1.0, std::max(0.0, r[k]));  // glTF: COLOR_0 in [0, 1]
  }, false);
  tinygltf::Material plain;
  plain.name = "stain_vertex_color";
  plain.doubleSided = true;
  plain.pbrMetallicRoughness.metallicFactor = 0.0;
  plain.pbrMetallicRoughness.roughnessFactor = 1.0;
  model.materials.push_back(plain);
  tinygltf::Primitive p;
  p.attributes = {{"POSITION", position}, {"NORMAL", normal}, {"COLOR_0", color}};
  p.indices = index;
  p.material = static_cast<int>(model.materials.size()) - 1;
  p.mode = TINYGLTF_MODE_TRIANGLES;
  const int colorNode = addMeshNodeScene(model, f.name + "_vertex_color", p);

  if (texturedNode >= 0) {
    tinygltf::Scene s;
    s.name = "stain_texture";
    s.nodes = {texturedNode};
    model.scenes.push_back(s);
  }
  tinygltf::Scene s;
  s.name = "stain_vertex_color";
  s.nodes = {colorNode};
  model.scenes.push_back(s);
  model.defaultScene = 0;
  model.buffers[0].data.resize((model.buffers[0].data.size() + 3) / 4 * 4, 0);

  std::stringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, true))
    throw std::runtime_error(path + ": glTF serialization failed");
  const std::string bytes = out.str();
  stain::writeFileAtomically(path, bytes.data(), bytes.size());
}

}  // namespace blot::engine
