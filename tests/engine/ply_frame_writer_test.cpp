// Tests for PLY frame caches: the bytes of every property (read back with a
// small independent reader), geometry read back by stain::loadMesh, refusal
// of non-finite values, and atomic replacement.
#include <blot/engine/ply_frame_writer.h>
#include <blot/stain/io/mesh_io.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <unistd.h>

namespace blot::engine {
namespace {

namespace fs = std::filesystem;

// ---- A minimal PLY reader for exactly what the writer produces. ----

struct ReadProperty {
  std::string type;  // "float", "double", "uchar"
  std::string name;
};

struct ReadPly {
  std::string format;
  std::vector<std::string> comments;
  long vertexCount = -1, faceCount = -1;
  std::vector<ReadProperty> vertexProperties;
  std::string faceProperty;
  std::vector<std::vector<double>> vertexValues;  // [property][vertex]
  std::vector<std::array<int, 3>> faces;
};

template <typename T>
T readLittleEndian(const std::string& bytes, std::size_t& offset) {
  // Assemble from bytes explicitly so the check does not rely on host order.
  std::uint64_t bits = 0;
  for (std::size_t b = 0; b < sizeof(T); ++b) {
    bits |= static_cast<std::uint64_t>(static_cast<unsigned char>(bytes.at(offset + b))) << (8 * b);
  }
  offset += sizeof(T);
  T value;
  if constexpr (sizeof(T) == 8) {
    std::memcpy(&value, &bits, 8);
  } else if constexpr (sizeof(T) == 4) {
    const auto narrow = static_cast<std::uint32_t>(bits);
    std::memcpy(&value, &narrow, 4);
  } else {
    const auto narrow = static_cast<std::uint8_t>(bits);
    std::memcpy(&value, &narrow, 1);
  }
  return value;
}

ReadPly readPly(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
  const std::size_t headerEnd = bytes.find("end_header\n");
  if (headerEnd == std::string::npos) throw std::runtime_error("no end_header");
  ReadPly ply;
  std::istringstream header(bytes.substr(0, headerEnd));
  std::string currentElement;
  for (std::string line; std::getline(header, line);) {
    std::istringstream tokens(line);
    std::string keyword;
    tokens >> keyword;
    if (keyword == "format") {
      tokens >> ply.format;
    } else if (keyword == "comment") {
      ply.comments.push_back(line.substr(8));
    } else if (keyword == "element") {
      long count = 0;
      tokens >> currentElement >> count;
      (currentElement == "vertex" ? ply.vertexCount : ply.faceCount) = count;
    } else if (keyword == "property") {
      ReadProperty property;
      tokens >> property.type;
      if (property.type == "list") {
        ply.faceProperty = line.substr(std::strlen("property list "));
      } else {
        tokens >> property.name;
        ply.vertexProperties.push_back(property);
      }
    }
  }
  ply.vertexValues.assign(ply.vertexProperties.size(), {});
  std::size_t offset = headerEnd + std::strlen("end_header\n");
  if (ply.format == "binary_little_endian") {
    for (long i = 0; i < ply.vertexCount; ++i) {
      for (std::size_t p = 0; p < ply.vertexProperties.size(); ++p) {
        const std::string& type = ply.vertexProperties[p].type;
        const double value = type == "float"    ? readLittleEndian<float>(bytes, offset)
                             : type == "double" ? readLittleEndian<double>(bytes, offset)
                                                : readLittleEndian<std::uint8_t>(bytes, offset);
        ply.vertexValues[p].push_back(value);
      }
    }
    for (long f = 0; f < ply.faceCount; ++f) {
      if (readLittleEndian<std::uint8_t>(bytes, offset) != 3) throw std::runtime_error("not a triangle");
      std::array<int, 3> face{};
      for (int& index : face) index = readLittleEndian<std::int32_t>(bytes, offset);
      ply.faces.push_back(face);
    }
    if (offset != bytes.size()) throw std::runtime_error("trailing bytes");
  } else {
    std::istringstream body(bytes.substr(offset));
    for (long i = 0; i < ply.vertexCount; ++i) {
      for (std::size_t p = 0; p < ply.vertexProperties.size(); ++p) {
        std::string text;
        body >> text;
        // A float property's text is the shortest one that reads back as that float.
        ply.vertexValues[p].push_back(ply.vertexProperties[p].type == "float"
                                          ? std::strtof(text.c_str(), nullptr)
                                          : std::strtod(text.c_str(), nullptr));
      }
    }
    for (long f = 0; f < ply.faceCount; ++f) {
      int count = 0;
      std::array<int, 3> face{};
      body >> count >> face[0] >> face[1] >> face[2];
      if (count != 3) throw std::runtime_error("not a triangle");
      ply.faces.push_back(face);
    }
    std::string rest;
    if (body >> rest) throw std::runtime_error("trailing text: " + rest);
  }
  return ply;
}

// ---- Fixture: a small closed mesh (octahedron) with attributes. ----

PlyFrame octahedronFrame() {
  PlyFrame frame;
  frame.vertexPositions.resize(6, 3);
  frame.vertexPositions << 1.1, 0, 0, -1, 0, 0, 0, 1.0 / 3.0, 0, 0, -1, 0, 0, 0, 1e-3, 0, 0, -1;
  frame.faces.resize(8, 3);
  frame.faces << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;
  Eigen::VectorXd solvent(6), solute(6), absorbedSolvent(6), absorbedSolute(6), adsorbed(6);
  solvent << 0.1, 0.2, 1.0 / 3.0, 4e-12, 5.5, 0.0;
  solute << 1e-30, 2, 3, 4, 5, 6;
  absorbedSolvent << 6, 5, 4, 3, 2, 1;
  absorbedSolute << 0.25, 0.5, 0.75, 1, 1.25, std::sqrt(2.0);
  adsorbed << -0.0, 1e20, -3.5, 0, 1, 2;
  frame.vertexAttributes = {{"solvent", solvent, PlyScalarType::Float32},
                            {"solute", solute, PlyScalarType::Float64},
                            {"absorbed_solvent", absorbedSolvent, PlyScalarType::Float32},
                            {"absorbed_solute", absorbedSolute, PlyScalarType::Float64},
                            {"adsorbed_solute", adsorbed, PlyScalarType::Float32}};
  stain::RowVectors3 velocity(6, 3);
  for (int i = 0; i < 6; ++i) velocity.row(i) << 0.1 * i, -0.2 * i, 1.0 / (i + 1);
  for (PlyVertexAttribute& attribute : velocityAttributes(velocity)) {
    frame.vertexAttributes.push_back(attribute);
  }
  Eigen::MatrixX3d colors(6, 3);
  for (int i = 0; i < 6; ++i) colors.row(i) << i / 5.0, 1.0 - i / 5.0, 0.5;
  frame.vertexColors = vertexColorsToBytes(colors);
  return frame;
}

class PlyFrameWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() /
                 ("blot_ply_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }
  std::string path(const std::string& name) const { return (directory_ / name).string(); }
  std::vector<std::string> directoryEntries() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(directory_)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path directory_;
};

void expectFrameBytes(const ReadPly& ply, const PlyFrame& frame, PlyScalarType positionType) {
  ASSERT_EQ(ply.vertexCount, frame.vertexPositions.rows());
  ASSERT_EQ(ply.faceCount, frame.faces.rows());
  // Layout: x y z, attributes in order, red green blue.
  ASSERT_EQ(ply.vertexProperties.size(), 3 + frame.vertexAttributes.size() + 3);
  const std::string positionTypeName = positionType == PlyScalarType::Float32 ? "float" : "double";
  const char* axes[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(ply.vertexProperties[k].name, axes[k]);
    EXPECT_EQ(ply.vertexProperties[k].type, positionTypeName);
    for (long i = 0; i < ply.vertexCount; ++i) {
      const double written = frame.vertexPositions(i, k);
      const double expected =
          positionType == PlyScalarType::Float32 ? static_cast<float>(written) : written;
      EXPECT_EQ(ply.vertexValues[k][i], expected) << axes[k] << " vertex " << i;
    }
  }
  for (std::size_t a = 0; a < frame.vertexAttributes.size(); ++a) {
    const PlyVertexAttribute& attribute = frame.vertexAttributes[a];
    const ReadProperty& property = ply.vertexProperties[3 + a];
    EXPECT_EQ(property.name, attribute.name);
    EXPECT_EQ(property.type, attribute.type == PlyScalarType::Float32 ? "float" : "double");
    for (long i = 0; i < ply.vertexCount; ++i) {
      const double expected = attribute.type == PlyScalarType::Float32
                                  ? static_cast<float>(attribute.values[i])
                                  : attribute.values[i];
      // Exact: binary stores the bit pattern, ASCII the shortest round-trip text.
      EXPECT_EQ(ply.vertexValues[3 + a][i], expected) << attribute.name << " vertex " << i;
    }
  }
  const char* channels[3] = {"red", "green", "blue"};
  for (int c = 0; c < 3; ++c) {
    const std::size_t p = 3 + frame.vertexAttributes.size() + c;
    EXPECT_EQ(ply.vertexProperties[p].name, channels[c]);
    EXPECT_EQ(ply.vertexProperties[p].type, "uchar");
    for (long i = 0; i < ply.vertexCount; ++i) {
      EXPECT_EQ(ply.vertexValues[p][i], frame.vertexColors(i, c));
    }
  }
  EXPECT_EQ(ply.faceProperty, "uchar int vertex_indices");
  for (long f = 0; f < ply.faceCount; ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(ply.faces[f][k], frame.faces(f, k));
  }
}

TEST_F(PlyFrameWriterTest, BinaryFrameHoldsEveryPropertyExactly) {
  const PlyFrame frame = octahedronFrame();
  PlyWriteOptions options;
  options.comment = "scene: unit test\nframe: 0";
  writePlyFrame(path("frame.ply"), frame, options);
  const ReadPly ply = readPly(path("frame.ply"));
  EXPECT_EQ(ply.format, "binary_little_endian");
  EXPECT_NE(std::find(ply.comments.begin(), ply.comments.end(), "frame: 0"), ply.comments.end());
  expectFrameBytes(ply, frame, PlyScalarType::Float32);
  // Linear colours become sRGB bytes, rounded to nearest:
  // 255 · srgbEncode(0.2) = 123.55, (0.8) = 231.11, (0.5) = 187.52.
  EXPECT_EQ(frame.vertexColors(1, 0), 124);
  EXPECT_EQ(frame.vertexColors(1, 1), 231);
  EXPECT_EQ(frame.vertexColors(1, 2), 188);
}

// Normals and UVs go right after x y z; stain::loadMesh (like Blender's and
// MeshLab's readers) reads u v back as the mesh's UVs.
TEST_F(PlyFrameWriterTest, NormalsAndUvsFollowThePositionsAndReadBackAsUvs) {
  PlyFrame frame = octahedronFrame();
  const Eigen::Index n = frame.vertexPositions.rows();
  Eigen::MatrixX3d normals = frame.vertexPositions.rowwise().normalized();
  Eigen::MatrixX2d uvs(n, 2);
  for (Eigen::Index v = 0; v < n; ++v) uvs.row(v) << 0.125 * v, 1.0 - 0.0625 * v;
  std::vector<PlyVertexAttribute> attributes = normalAndUvAttributes(normals, uvs);
  attributes.insert(attributes.end(), frame.vertexAttributes.begin(), frame.vertexAttributes.end());
  frame.vertexAttributes = attributes;
  writePlyFrame(path("uv.ply"), frame);
  const ReadPly ply = readPly(path("uv.ply"));
  expectFrameBytes(ply, frame, PlyScalarType::Float32);
  const stain::TriangleMesh mesh = stain::loadMesh(path("uv.ply"));
  ASSERT_EQ(mesh.vertexUVs.rows(), n);
  for (Eigen::Index v = 0; v < n; ++v) {
    EXPECT_EQ(mesh.vertexUVs(v, 0), uvs(v, 0)) << v;  // exact in float32
    EXPECT_EQ(mesh.vertexUVs(v, 1), uvs(v, 1)) << v;
  }
  std::ifstream in(path("uv.ply"));
  std::string header((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(header.find("property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                        "property float u\nproperty float v\n"),
            std::string::npos);
}

TEST_F(PlyFrameWriterTest, AsciiFrameRoundTripsExactly) {
  const PlyFrame frame = octahedronFrame();
  PlyWriteOptions options;
  options.format = PlyFormat::Ascii;
  options.positionType = PlyScalarType::Float64;
  writePlyFrame(path("frame.ply"), frame, options);
  const ReadPly ply = readPly(path("frame.ply"));
  EXPECT_EQ(ply.format, "ascii");
  expectFrameBytes(ply, frame, PlyScalarType::Float64);
}

TEST_F(PlyFrameWriterTest, LoadMeshReadsBackTheGeometry) {
  const PlyFrame frame = octahedronFrame();
  for (PlyFormat format : {PlyFormat::BinaryLittleEndian, PlyFormat::Ascii}) {
    for (PlyScalarType positionType : {PlyScalarType::Float32, PlyScalarType::Float64}) {
      PlyWriteOptions options;
      options.format = format;
      options.positionType = positionType;
      const std::string file = path("geometry.ply");
      writePlyFrame(file, frame, options);
      const stain::TriangleMesh mesh = stain::loadMesh(file);
      ASSERT_EQ(mesh.vertexPositions.rows(), 6);
      ASSERT_EQ(mesh.faces.rows(), 8);
      for (int i = 0; i < 6; ++i) {
        for (int k = 0; k < 3; ++k) {
          const double written = frame.vertexPositions(i, k);
          if (positionType == PlyScalarType::Float64) {
            EXPECT_EQ(mesh.vertexPositions(i, k), written) << "vertex " << i << " axis " << k;
          } else if (format == PlyFormat::BinaryLittleEndian) {
            EXPECT_EQ(mesh.vertexPositions(i, k), static_cast<float>(written))
                << "vertex " << i << " axis " << k;
          } else {
            // ASCII float text ("1.1") is read as a double: within float rounding.
            EXPECT_EQ(static_cast<float>(mesh.vertexPositions(i, k)), static_cast<float>(written))
                << "vertex " << i << " axis " << k;
          }
        }
      }
      EXPECT_TRUE(mesh.faces == frame.faces);
    }
  }
}

TEST_F(PlyFrameWriterTest, RefusesNonFiniteValuesNamingAttributeAndVertex) {
  const std::string file = path("frame.ply");
  writePlyFrame(file, octahedronFrame());
  const std::vector<std::string> before = directoryEntries();
  std::ifstream original(file, std::ios::binary);
  const std::string originalBytes{std::istreambuf_iterator<char>(original),
                                  std::istreambuf_iterator<char>()};

  const auto expectRefused = [&](const PlyFrame& frame, const std::string& name,
                                 const std::string& vertex) {
    try {
      writePlyFrame(file, frame);
      FAIL() << "expected std::invalid_argument for " << name;
    } catch (const std::invalid_argument& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find(name), std::string::npos) << message;
      EXPECT_NE(message.find(vertex), std::string::npos) << message;
    }
    // The previous frame is untouched and no temporary file is left behind.
    std::ifstream after(file, std::ios::binary);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(after), std::istreambuf_iterator<char>()),
              originalBytes);
    EXPECT_EQ(directoryEntries(), before);
  };
  PlyFrame frame = octahedronFrame();
  frame.vertexAttributes[1].values[3] = std::numeric_limits<double>::quiet_NaN();
  expectRefused(frame, "'solute'", "vertex 3 is nan");
  frame = octahedronFrame();
  frame.vertexAttributes[4].values[5] = -std::numeric_limits<double>::infinity();
  expectRefused(frame, "'adsorbed_solute'", "vertex 5 is -inf");
  frame = octahedronFrame();
  frame.vertexAttributes[0].values[2] = 1e300;  // finite, but infinite as float32
  expectRefused(frame, "'solvent'", "vertex 2 is 1e+300 (overflows float32)");
  frame = octahedronFrame();
  frame.vertexPositions(4, 1) = std::numeric_limits<double>::quiet_NaN();
  expectRefused(frame, "position y", "vertex 4 is nan");
  // The same large value is fine as a double attribute.
  frame = octahedronFrame();
  frame.vertexAttributes[1].values[2] = 1e300;
  writePlyFrame(file, frame);
  EXPECT_EQ(readPly(file).vertexValues[4][2], 1e300);
}

TEST_F(PlyFrameWriterTest, RefusesMalformedFrames) {
  const std::string file = path("bad.ply");
  PlyFrame frame = octahedronFrame();
  frame.vertexAttributes[2].values.resize(5);
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  frame = octahedronFrame();
  frame.vertexAttributes[2].name = "solute";  // duplicate
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  frame.vertexAttributes[2].name = "red";  // clashes with the colour channel
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  frame.vertexAttributes[2].name = "two words";
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  frame = octahedronFrame();
  frame.faces(7, 2) = 6;
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  frame = octahedronFrame();
  frame.vertexColors.conservativeResize(5, 3);
  EXPECT_THROW(writePlyFrame(file, frame), std::invalid_argument);
  EXPECT_FALSE(fs::exists(file));
  EXPECT_THROW(writePlyFrame(path("missing_dir/f.ply"), octahedronFrame()), std::runtime_error);
}

TEST_F(PlyFrameWriterTest, SequenceWriterNumbersFramesAndReplacesAtomically) {
  const PlyFrameWriter writer(directory_.string(), "bunny");
  EXPECT_EQ(writer.framePath(3), path("bunny_0003.ply"));
  EXPECT_EQ(writer.framePath(12345), path("bunny_12345.ply"));
  EXPECT_THROW(writer.framePath(-1), std::invalid_argument);
  PlyFrame frame = octahedronFrame();
  EXPECT_EQ(writer.write(7, frame), path("bunny_0007.ply"));
  frame.vertexAttributes.resize(1);
  frame.vertexColors.resize(0, 3);
  writer.write(7, frame);  // replaces the previous file
  const ReadPly ply = readPly(path("bunny_0007.ply"));
  EXPECT_EQ(ply.vertexProperties.size(), 4u);
  EXPECT_EQ(directoryEntries(), std::vector<std::string>{"bunny_0007.ply"});
}

}  // namespace
}  // namespace blot::engine
