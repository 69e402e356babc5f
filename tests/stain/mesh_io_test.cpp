// Tests for mesh_io: round trips through every format, polygon fans, labels
// and UVs, the CGAL sample meshes, and one test per kind of malformed input
// checking that the message names the file and the element or line at fault.
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "mesh_fixture.h"

namespace blot::stain {
namespace {

using test::externalMesh;
using test::testDataPath;

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "blot_mesh_io_test_" + name;
}

void writeFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << "cannot write " << path;
}

bool fileExists(const std::string& path) { return std::ifstream(path).good(); }

/// The MeshError message loadMesh throws for `path`; a test failure if none.
std::string loadError(const std::string& path) {
  try {
    loadMesh(path);
  } catch (const MeshError& error) {
    return error.what();
  }
  ADD_FAILURE() << "loading " << path << " did not throw MeshError";
  return std::string();
}

/// Expects loadMesh(path) to fail with a message that starts with the path
/// and contains every fragment (element, line, what is wrong).
void expectLoadError(const std::string& path, std::initializer_list<const char*> fragments) {
  const std::string message = loadError(path);
  EXPECT_EQ(message.rfind(path + ": ", 0), 0u)
      << "message does not start with the path: " << message;
  for (const char* fragment : fragments)
    EXPECT_NE(message.find(fragment), std::string::npos)
        << "missing '" << fragment << "' in: " << message;
}

void expectValidateError(const TriangleMesh& mesh, const std::string& source,
                         std::initializer_list<const char*> fragments) {
  std::string message;
  try {
    validateMesh(mesh, source);
    ADD_FAILURE() << source << ": validateMesh did not throw";
    return;
  } catch (const MeshError& error) {
    message = error.what();
  }
  EXPECT_EQ(message.rfind(source + ": ", 0), 0u) << message;
  for (const char* fragment : fragments)
    EXPECT_NE(message.find(fragment), std::string::npos)
        << "missing '" << fragment << "' in: " << message;
}

void expectSameMesh(const TriangleMesh& expected, const TriangleMesh& actual) {
  ASSERT_EQ(actual.vertexPositions.rows(), expected.vertexPositions.rows());
  ASSERT_EQ(actual.faces.rows(), expected.faces.rows());
  // Exact: every writer here prints round-trip precision.
  EXPECT_TRUE(actual.vertexPositions == expected.vertexPositions);
  EXPECT_TRUE(actual.faces == expected.faces);
  EXPECT_EQ(actual.faceLabels, expected.faceLabels);
  ASSERT_EQ(actual.vertexUVs.rows(), expected.vertexUVs.rows());
  EXPECT_TRUE(actual.vertexUVs == expected.vertexUVs);
}

std::string number(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

int eulerCharacteristic(const TriangleMesh& mesh) {
  const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()), "mesh");
  return topology.vertexCount() - topology.edgeCount() + topology.faceCount();
}

/// Little-endian binary PLY bytes, written value by value.
class BinaryPlyWriter {
 public:
  explicit BinaryPlyWriter(const std::string& header) : bytes_(header) {}
  template <class T>
  void put(T value) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof value);
    for (size_t b = 0; b < sizeof value; ++b)
      bytes_.push_back(static_cast<char>((bits >> (8 * b)) & 0xff));
  }
  const std::string& bytes() const { return bytes_; }
  /// The body of kTrianglePlyElements: vertices (0,0,0), (1,0,0), (0,1,0) as
  /// floats, then one face with these corners.
  void putTriangle(int a, int b, int c) {
    for (const float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put<float>(x);
    put<std::uint8_t>(3);
    for (const int i : {a, b, c}) put<std::int32_t>(i);
  }

 private:
  std::string bytes_;
};

/// Three float vertices and one face with uchar-counted int corners.
const char* const kTrianglePlyElements =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

TriangleMesh labelledGrid() {
  TriangleMesh mesh = gridMesh(5, 3, 1.5, 1.0);
  mesh.vertexPositions.col(2) = 0.1 * mesh.vertexPositions.col(0).array().sin().matrix();
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    mesh.faceLabels.push_back(static_cast<int>(f % 3) - 1);
  return mesh;
}

// ---------------------------------------------------------------------------
// Round trips

TEST(MeshIo, SavedPlyLoadsBackExactlyWithLabelsAndUVs) {
  const TriangleMesh mesh = labelledGrid();
  ASSERT_GT(mesh.vertexUVs.rows(), 0);
  const std::string path = tempPath("saved.ply");
  saveMeshPly(mesh, path);
  EXPECT_FALSE(fileExists(path + ".tmp")) << "temporary file left behind";
  expectSameMesh(mesh, loadMesh(path));

  // Saving again replaces the file as a whole.
  TriangleMesh other = icosphereMesh(1);
  saveMeshPly(other, path);
  expectSameMesh(other, loadMesh(path));
}

TEST(MeshIo, SaveIntoMissingDirectoryNamesThePath) {
  const std::string path = tempPath("no_such_dir/out.ply");
  try {
    saveMeshPly(icosphereMesh(1), path);
    FAIL() << "saveMeshPly into a missing directory did not throw";
  } catch (const MeshError& error) {
    EXPECT_EQ(std::string(error.what()).rfind(path + ": cannot write", 0), 0u) << error.what();
  }
}

TEST(MeshIo, ObjRoundTripKeepsDoublePrecision) {
  TriangleMesh mesh = icosphereMesh(2);
  mesh.vertexPositions *= 1.0 / 3.0;  // digits a float would lose
  std::ostringstream obj;
  for (Eigen::Index v = 0; v < mesh.vertexPositions.rows(); ++v) {
    obj << "v " << number(mesh.vertexPositions(v, 0)) << " " << number(mesh.vertexPositions(v, 1))
        << " " << number(mesh.vertexPositions(v, 2)) << "\n";
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    obj << "f " << mesh.faces(f, 0) + 1 << " " << mesh.faces(f, 1) + 1 << " "
        << mesh.faces(f, 2) + 1 << "\n";
  const std::string path = tempPath("icosphere.obj");
  writeFile(path, obj.str());
  const TriangleMesh loaded = loadMesh(path);
  expectSameMesh(mesh, loaded);  // no groups: no labels; no vt: no UVs
}

TEST(MeshIo, OffRoundTrip) {
  TriangleMesh mesh = discMesh(4, 0.7);
  mesh.vertexUVs.resize(0, 2);  // OFF carries no UVs
  std::ostringstream off;
  off << "OFF\n# disc\n" << mesh.vertexPositions.rows() << " " << mesh.faces.rows() << " 0\n";
  for (Eigen::Index v = 0; v < mesh.vertexPositions.rows(); ++v) {
    off << number(mesh.vertexPositions(v, 0)) << " " << number(mesh.vertexPositions(v, 1)) << " "
        << number(mesh.vertexPositions(v, 2)) << "\n";
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    off << "3 " << mesh.faces(f, 0) << " " << mesh.faces(f, 1) << " " << mesh.faces(f, 2) << "\n";
  const std::string path = tempPath("disc.off");
  writeFile(path, off.str());
  expectSameMesh(mesh, loadMesh(path));
}

TEST(MeshIo, BinaryPlyWithDoublesAndSkippedPropertiesRoundTrips) {
  const TriangleMesh mesh = labelledGrid();
  const auto V = mesh.vertexPositions.rows(), F = mesh.faces.rows();
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\ncomment written by mesh_io_test\n"
         << "element camera 1\nproperty list uchar int tags\nproperty float fov\n"
         << "element vertex " << V
         << "\nproperty double x\nproperty ushort flags\nproperty double y\n"
         << "property double z\nproperty list uchar short neighbours\nproperty double u\nproperty "
            "double v\n"
         << "element face " << F
         << "\nproperty uchar flags\nproperty list int uint vertex_indices\n"
         << "property short label\n"
         << "element edge 2\nproperty list uchar int vertex_pair\nend_header\n";
  BinaryPlyWriter ply(header.str());
  ply.put<std::uint8_t>(2);
  ply.put<std::int32_t>(-7);
  ply.put<std::int32_t>(9);
  ply.put<float>(0.75f);
  for (Eigen::Index v = 0; v < V; ++v) {
    ply.put<double>(mesh.vertexPositions(v, 0));
    ply.put<std::uint16_t>(0xbeef);
    ply.put<double>(mesh.vertexPositions(v, 1));
    ply.put<double>(mesh.vertexPositions(v, 2));
    ply.put<std::uint8_t>(static_cast<std::uint8_t>(v % 3));  // a list of 0-2 shorts
    for (Eigen::Index k = 0; k < v % 3; ++k) ply.put<std::int16_t>(-1);
    ply.put<double>(mesh.vertexUVs(v, 0));
    ply.put<double>(mesh.vertexUVs(v, 1));
  }
  for (Eigen::Index f = 0; f < F; ++f) {
    ply.put<std::uint8_t>(1);
    ply.put<std::int32_t>(3);
    for (int k = 0; k < 3; ++k)
      ply.put<std::uint32_t>(static_cast<std::uint32_t>(mesh.faces(f, k)));
    ply.put<std::int16_t>(static_cast<std::int16_t>(mesh.faceLabels[static_cast<size_t>(f)]));
  }
  for (int e = 0; e < 2; ++e) {
    ply.put<std::uint8_t>(2);
    ply.put<std::int32_t>(0);
    ply.put<std::int32_t>(1);
  }
  const std::string path = tempPath("binary_double.ply");
  writeFile(path, ply.bytes());
  expectSameMesh(mesh, loadMesh(path));
}

TEST(MeshIo, BinaryPlyWithFloatsAndQuadsLoadsAsFloatValues) {
  // 2 x 1 quads, float coordinates, uchar index items, no labels or UVs.
  BinaryPlyWriter ply(
      "ply\nformat binary_little_endian 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar uchar vertex_index\nend_header\n");
  const float coordinates[6][3] = {{0, 0, 0},    {0.1f, 0, 0},        {0.2f, 0, 0},
                                   {0, 0.1f, 0}, {0.1f, 0.1f, 0.01f}, {0.2f, 0.1f, 0}};
  for (const auto& p : coordinates)
    for (const float c : p) ply.put<float>(c);
  for (const int quad : {0, 1}) {
    ply.put<std::uint8_t>(4);
    for (const int c : {0, 1, 4, 3}) ply.put<std::uint8_t>(static_cast<std::uint8_t>(c + quad));
  }
  const std::string path = tempPath("binary_float.ply");
  writeFile(path, ply.bytes());
  const TriangleMesh mesh = loadMesh(path);
  ASSERT_EQ(mesh.vertexPositions.rows(), 6);
  for (int v = 0; v < 6; ++v)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(mesh.vertexPositions(v, k), static_cast<double>(coordinates[v][k]));
  Triangles expected(4, 3);
  expected << 0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4;
  EXPECT_TRUE(mesh.faces == expected) << mesh.faces;
  EXPECT_TRUE(mesh.faceLabels.empty());
  EXPECT_EQ(mesh.vertexUVs.rows(), 0);
}

TEST(MeshIo, ObjQuadsAreFanTriangulatedWithGroupLabelsAndUVs) {
  const TriangleMesh mesh = loadMesh(testDataPath("good/quad_grid.obj"));
  ASSERT_EQ(mesh.vertexPositions.rows(), 9);
  Triangles expected(8, 3);
  expected << 0, 1, 4, 0, 4, 3,  // quad 0: fan from its first corner
      1, 2, 5, 1, 5, 4,          //
      3, 4, 7, 3, 7, 6,          //
      4, 5, 8, 4, 8, 7;          // quad 3, written with relative indices
  EXPECT_TRUE(mesh.faces == expected) << mesh.faces;
  // (left, cotton) = 0, (right, cotton) = 1, (left, silk) = 2, numbered by first appearance.
  EXPECT_EQ(mesh.faceLabels, (std::vector<int>{0, 0, 1, 1, 0, 0, 2, 2}));
  ASSERT_EQ(mesh.vertexUVs.rows(), 9);
  for (int v = 0; v < 9; ++v) {
    EXPECT_EQ(mesh.vertexUVs(v, 0), 0.5 * mesh.vertexPositions(v, 0)) << "vertex " << v;
    EXPECT_EQ(mesh.vertexUVs(v, 1), 0.5 * mesh.vertexPositions(v, 1)) << "vertex " << v;
  }
}

TEST(MeshIo, ObjUVsWithSeamsAreDropped) {
  // Vertex 1 is used with two different texture coordinates (a seam):
  // one UV per position is impossible, so the mesh loads without UVs.
  const std::string path = tempPath("seam.obj");
  writeFile(path,
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 0.9 0\n"
            "f 1/1 2/2 3/3\nf 2/5 4/4 3/3\n");
  const TriangleMesh mesh = loadMesh(path);
  EXPECT_EQ(mesh.faces.rows(), 2);
  EXPECT_EQ(mesh.vertexUVs.rows(), 0);

  // Different texcoord indices carrying the same values are not a seam.
  writeFile(path,
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 1 0\n"
            "f 1/1 2/2 3/3\nf 2/5 4/4 3/3\n");
  const TriangleMesh same = loadMesh(path);
  ASSERT_EQ(same.vertexUVs.rows(), 4);
  EXPECT_EQ(same.vertexUVs(1, 0), 1.0);
  EXPECT_EQ(same.vertexUVs(1, 1), 0.0);
}

TEST(MeshIo, OffPolygonsCommentsAndBlankLines) {
  const TriangleMesh mesh = loadMesh(testDataPath("good/pyramid.off"));
  ASSERT_EQ(mesh.vertexPositions.rows(), 5);
  ASSERT_EQ(mesh.faces.rows(), 6);
  EXPECT_EQ(mesh.faces.row(0), Eigen::RowVector3i(0, 3, 2));
  EXPECT_EQ(mesh.faces.row(1), Eigen::RowVector3i(0, 2, 1));
  EXPECT_EQ(mesh.vertexPositions.row(4), Eigen::RowVector3d(0.5, 0.5, 1.0));
  EXPECT_EQ(eulerCharacteristic(mesh), 2);
}

TEST(MeshIo, AsciiPlyLabelsUVsAndUnknownElements) {
  const TriangleMesh mesh = loadMesh(testDataPath("good/labelled_patches.ply"));
  ASSERT_EQ(mesh.vertexPositions.rows(), 6);
  Triangles expected(4, 3);
  expected << 0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4;
  EXPECT_TRUE(mesh.faces == expected) << mesh.faces;
  EXPECT_EQ(mesh.faceLabels, (std::vector<int>{7, 7, -3, -3}));
  ASSERT_EQ(mesh.vertexUVs.rows(), 6);
  EXPECT_EQ(mesh.vertexUVs.row(5), Eigen::RowVector2d(1.0, 1.0));
  EXPECT_EQ(mesh.vertexUVs.row(1), Eigen::RowVector2d(0.5, 0.0));
}

TEST(MeshIo, ObjCommentsAfterStatementsAreIgnored) {
  const std::string path = tempPath("comments.obj");
  writeFile(path, "# a triangle\nv 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nf 1 2 3 # the face\n");
  const TriangleMesh mesh = loadMesh(path);
  EXPECT_EQ(mesh.faces.rows(), 1);
  EXPECT_EQ(mesh.vertexPositions.row(1), Eigen::RowVector3d(1.0, 0.0, 0.0));
}

TEST(MeshIo, ExtensionIsCaseInsensitive) {
  const std::string path = tempPath("UPPER.OBJ");
  writeFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_EQ(loadMesh(path).faces.rows(), 1);
}

TEST(MeshIo, ZeroAreaThresholdIsScaleFree) {
  // A micrometre-sized mesh is valid: the threshold scales with the bounding box.
  TriangleMesh tiny = icosphereMesh(2, 1e-6);
  EXPECT_NO_THROW(validateMesh(tiny, "tiny icosphere"));
  // A sliver just above 1e-14 * diagonal^2 passes, one just below fails.
  TriangleMesh sliver;
  sliver.vertexPositions.resize(3, 3);
  sliver.faces.resize(1, 3);
  sliver.faces << 0, 1, 2;
  const auto withHeight = [&](double h) {
    sliver.vertexPositions << 0, 0, 0, 1, 0, 0, 0.5, h, 0;
    return sliver;
  };
  // Diagonal^2 = 1 + h^2 ~ 1, area = h / 2.
  EXPECT_NO_THROW(validateMesh(withHeight(4e-14), "sliver above"));
  expectValidateError(withHeight(1e-14), "sliver below", {"face 0 has zero area"});
}

// ---------------------------------------------------------------------------
// In-memory validation names the source and the element

TEST(MeshIo, ValidateNamesSourceAndElement) {
  TriangleMesh mesh = gridMesh(2, 2, 1.0, 1.0);
  mesh.vertexPositions(4, 1) = std::numeric_limits<double>::quiet_NaN();
  expectValidateError(mesh, "generated grid", {"vertex 4 has a non-finite coordinate"});

  mesh = gridMesh(2, 2, 1.0, 1.0);
  mesh.faces(3, 2) = 9;
  expectValidateError(mesh, "generated grid", {"face 3: vertex index 9 out of range [0, 8]"});

  mesh = gridMesh(2, 2, 1.0, 1.0);
  mesh.faceLabels = {1, 2};
  expectValidateError(mesh, "generated grid", {"2 face labels for 8 faces"});

  expectValidateError(TriangleMesh{}, "nothing", {"mesh is empty (0 vertices, 0 faces)"});
}

TEST(MeshIo, NonManifoldVertexWhereTwoClosedFansMeet) {
  // Two tetrahedra sharing only vertex 0: each fan around it is closed.
  TriangleMesh mesh;
  mesh.vertexPositions.resize(7, 3);
  mesh.vertexPositions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, -1, 0, 0, 0, -1, 0, 0, 0, -1;
  mesh.faces.resize(8, 3);
  mesh.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3,  // tetrahedron (0,1,2,3), outward
      0, 4, 5, 0, 6, 4, 0, 5, 6, 4, 6, 5;            // its point reflection (0,4,5,6), outward
  expectValidateError(mesh, "two tetrahedra", {"non-manifold vertex 0"});
}

// ---------------------------------------------------------------------------
// Malformed files: each message names the file and the element or line.

TEST(MeshIoMalformed, NonManifoldEdge) {
  expectLoadError(testDataPath("bad/non_manifold_edge.obj"),
                  {"non-manifold edge (0, 1)", "3 faces (0, 1, 2)"});
}

TEST(MeshIoMalformed, NonManifoldVertexBowtie) {
  expectLoadError(testDataPath("bad/non_manifold_vertex.off"), {"non-manifold vertex 0"});
}

TEST(MeshIoMalformed, ZeroAreaFace) {
  expectLoadError(testDataPath("bad/zero_area_face.ply"), {"face 1 (line 16) has zero area"});
}

TEST(MeshIoMalformed, RepeatedVertexFace) {
  expectLoadError(testDataPath("bad/repeated_vertex_face.off"),
                  {"face 1 (line 9) repeats a vertex (1, 3, 1)"});
}

TEST(MeshIoMalformed, NanCoordinate) {
  expectLoadError(testDataPath("bad/nan_coordinate.off"),
                  {"vertex 1 (line 4) has a non-finite coordinate"});
}

TEST(MeshIoMalformed, InfCoordinate) {
  expectLoadError(testDataPath("bad/inf_coordinate.ply"),
                  {"vertex 2 (line 12) has a non-finite coordinate"});
}

TEST(MeshIoMalformed, ObjIndexOutOfRange) {
  expectLoadError(testDataPath("bad/index_out_of_range.obj"),
                  {"face 1 (line 7): vertex index 9 out of range [1, 4]"});
}

TEST(MeshIoMalformed, ObjZeroAndRelativeIndices) {
  const std::string path = tempPath("zero_index.obj");
  writeFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 0 1 2\n");
  expectLoadError(path, {"line 5: face 1: vertex index 0 is invalid"});
  writeFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  expectLoadError(path, {"line 4: face 0: relative vertex index -4"});
  writeFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n");
  expectLoadError(path, {"face 0 (line 5): texture coordinate index 2 out of range [1, 1]"});
}

TEST(MeshIoMalformed, PlyIndexOutOfRange) {
  expectLoadError(testDataPath("bad/index_out_of_range.ply"),
                  {"face 1 (line 15): vertex index 7 out of range [0, 3]"});
}

TEST(MeshIoMalformed, BinaryPlyIndexOutOfRangeNamesTheFace) {
  BinaryPlyWriter ply(std::string("ply\nformat binary_little_endian 1.0\n") + kTrianglePlyElements);
  ply.putTriangle(0, 1, -2);
  const std::string path = tempPath("binary_bad_index.ply");
  writeFile(path, ply.bytes());
  expectLoadError(path, {"face 0: vertex index -2 out of range [0, 2]"});
}

// A binary element without properties holds no bytes, so its count costs
// nothing to read: eight of them at the largest count a header takes (1.7e10
// instances) load at once. Before, each instance went round the element loop:
// fuzz_mesh_ply timed out on a 300-byte file (docs/reliability.md finding 11);
// this test then ran for minutes.
TEST(MeshIoMalformed, BinaryElementsWithoutPropertiesCostNothingWhateverTheirCount) {
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  for (int k = 0; k < 8; ++k) header += "element padding" + std::to_string(k) + " 2147483647\n";
  BinaryPlyWriter ply(header + kTrianglePlyElements);
  ply.putTriangle(0, 1, 2);
  const std::string path = tempPath("binary_empty_elements.ply");
  writeFile(path, ply.bytes());
  const TriangleMesh mesh = loadMesh(path);
  EXPECT_EQ(mesh.vertexPositions.rows(), 3);
  EXPECT_EQ(mesh.faces.rows(), 1);
  EXPECT_EQ(mesh.vertexPositions(1, 0), 1.0);
}

TEST(MeshIoMalformed, InconsistentOrientation) {
  expectLoadError(testDataPath("bad/inconsistent_orientation.obj"),
                  {"faces 0 and 1 disagree on orientation across edge (0, 1)"});
}

// The same triangle twice was reported as an orientation to fix.
TEST(MeshIoMalformed, ADuplicatedFaceIsNamedAsSuch) {
  const std::string path = tempPath("duplicated_face.obj");
  writeFile(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 2 3 1\n");
  expectLoadError(path, {"faces 0 and 2 are the same triangle (vertices 0, 1, 2): a duplicated face"});
}

TEST(MeshIoMalformed, EmptyFile) {
  expectLoadError(testDataPath("bad/empty.obj"), {"file is empty"});
  const std::string path = tempPath("blank.ply");
  writeFile(path, "\n  \n");
  expectLoadError(path, {"file is empty"});
  writeFile(
      path,
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n");
  expectLoadError(path, {"mesh is empty (0 vertices, 0 faces)"});
}

TEST(MeshIoMalformed, TruncatedBinaryPly) {
  const std::string header = std::string("ply\nformat binary_little_endian 1.0\n") + kTrianglePlyElements;
  BinaryPlyWriter ply(header);
  ply.putTriangle(0, 1, 2);
  const std::string& full = ply.bytes();
  const std::string path = tempPath("truncated.ply");

  writeFile(path, full);
  EXPECT_EQ(loadMesh(path).faces.rows(), 1);  // the untruncated file is fine

  // Cut inside vertex 2's y coordinate (2 * 12 + 4 + 2 bytes of data).
  writeFile(path, full.substr(0, header.size() + 30));
  expectLoadError(path, {"truncated binary data", "vertex 2 of 3", "property 'y'"});
  // Cut inside the face's index list.
  writeFile(path, full.substr(0, full.size() - 3));
  expectLoadError(path, {"truncated binary data", "face 0 of 1", "property 'vertex_indices'"});
  // Extra bytes: the header counts do not match the data.
  writeFile(path, full + std::string(5, '\0'));
  expectLoadError(path, {"5 bytes of binary data after the last element"});
}

TEST(MeshIoMalformed, BadPlyHeader) {
  expectLoadError(testDataPath("bad/bad_header.ply"),
                  {"bad PLY header (line 4): unknown type 'flaot'"});
  const std::string path = tempPath("no_end_header.ply");
  writeFile(path, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n");
  expectLoadError(path, {"bad PLY header: no 'end_header' line"});
  writeFile(path,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
            "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n");
  expectLoadError(path, {"bad PLY header: element 'vertex' has no property 'z'"});
  writeFile(path,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n0 0 0\n");
  expectLoadError(path, {"bad PLY header: no 'face' element"});
  writeFile(path, "PLY\nformat ascii 1.0\n");
  expectLoadError(path, {"bad PLY header (line 1): first line must be 'ply'"});
}

// A header is bounded in elements and properties: its duplicate-name checks
// are quadratic, and 300,000 empty elements in a 5 MB file took 54 s.
TEST(MeshIoMalformed, AHeaderOfManyElementsOrPropertiesIsRefusedAtOnce) {
  const std::string path = tempPath("many_elements.ply");
  std::string header = "ply\nformat ascii 1.0\n";
  for (int k = 0; k < 100000; ++k) header += "element e" + std::to_string(k) + " 0\n";
  writeFile(path, header + kTrianglePlyElements);
  expectLoadError(path, {"bad PLY header (line 67): more than 64 elements declared"});
  header = "ply\nformat ascii 1.0\nelement vertex 3\n";
  for (int k = 0; k < 100000; ++k) header += "property float p" + std::to_string(k) + "\n";
  writeFile(path, header + "end_header\n");
  expectLoadError(path, {"bad PLY header (line 260): element 'vertex' declares more than 256 properties"});
}

TEST(MeshIoMalformed, BigEndianPly) {
  expectLoadError(testDataPath("bad/big_endian.ply"),
                  {"line 2: binary_big_endian PLY is not supported"});
}

TEST(MeshIoMalformed, NonNumericToken) {
  expectLoadError(testDataPath("bad/non_numeric_token.ply"),
                  {"line 11: vertex 1, property 'y': expected a number, got 'abc'"});
  expectLoadError(testDataPath("bad/non_numeric_token.obj"),
                  {"line 3: vertex 2: expected a number, got '1,5'"});
  const std::string path = tempPath("non_numeric.off");
  writeFile(path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 one 2\n");
  expectLoadError(path, {"line 6: face 0: expected a vertex index, got 'one'"});
}

TEST(MeshIoMalformed, CountsDoNotMatchTheData) {
  expectLoadError(testDataPath("bad/vertex_count_mismatch.ply"),
                  {"line 13: vertex 3 has 4 values, more than its properties declare"});
  expectLoadError(
      testDataPath("bad/face_count_mismatch.off"),
      {"file ends after 1 of 2 faces (the counts on line 2 declare 3 vertices and 2 faces)"});
  const std::string path = tempPath("extra_lines.off");
  writeFile(path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n");
  expectLoadError(path, {"line 7: data after the last face"});
}

TEST(MeshIoMalformed, FaceWithTwoCorners) {
  expectLoadError(testDataPath("bad/two_corner_face.obj"), {"line 5: face 1 has 2 corners"});
}

TEST(MeshIoMalformed, UnreferencedVertex) {
  expectLoadError(testDataPath("bad/unreferenced_vertex.obj"),
                  {"vertex 3 is not referenced by any face"});
}

TEST(MeshIoMalformed, UnknownExtension) {
  expectLoadError(testDataPath("bad/unknown_extension.stl"),
                  {"unknown mesh file extension '.stl'; expected .obj, .ply or .off"});
}

TEST(MeshIoMalformed, MissingFile) {
  expectLoadError(testDataPath("bad/does_not_exist.obj"),
                  {"cannot open file: No such file or directory"});
}

TEST(MeshIoMalformed, EveryPrefixOfAValidFileLoadsOrThrowsMeshError) {
  // No cut-off point may crash the reader or escape as another exception.
  BinaryPlyWriter ply(
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nproperty list uchar int junk\nelement face 2\n"
      "property list uchar int vertex_indices\nproperty int label\nend_header\n");
  for (const float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 1.f, 0.f})
    ply.put<float>(c);
  std::string binary = ply.bytes();
  {
    // Splice a one-item `junk` list after each vertex (13 bytes per vertex: 12 + 1).
    std::string spliced = binary.substr(0, binary.size() - 48);
    for (int v = 0; v < 4; ++v) {
      spliced += binary.substr(binary.size() - 48 + 12 * static_cast<size_t>(v), 12);
      BinaryPlyWriter junk("");
      junk.put<std::uint8_t>(1);
      junk.put<std::int32_t>(5);
      spliced += junk.bytes();
    }
    BinaryPlyWriter faces(spliced);
    for (const auto& face : {std::vector<int>{0, 1, 2, 3}, std::vector<int>{1, 3, 2, 4}}) {
      faces.put<std::uint8_t>(3);
      for (size_t k = 0; k < 3; ++k) faces.put<std::int32_t>(face[k]);
      faces.put<std::int32_t>(face[3]);  // label
    }
    binary = faces.bytes();
  }
  std::ifstream objFile(testDataPath("good/quad_grid.obj"), std::ios::binary);
  std::ifstream plyFile(testDataPath("good/labelled_patches.ply"), std::ios::binary);
  const std::string obj((std::istreambuf_iterator<char>(objFile)),
                        std::istreambuf_iterator<char>());
  const std::string asciiPly((std::istreambuf_iterator<char>(plyFile)),
                             std::istreambuf_iterator<char>());
  ASSERT_FALSE(obj.empty());
  ASSERT_FALSE(asciiPly.empty());

  struct Case {
    std::string name, bytes;
    size_t step;
  };
  for (const Case& c : {Case{"prefix.ply", binary, 2}, Case{"prefix.obj", obj, 11},
                        Case{"prefix_ascii.ply", asciiPly, 11}}) {
    const std::string path = tempPath(c.name);
    int loaded = 0;
    for (size_t n = 0; n <= c.bytes.size(); n += c.step) {
      writeFile(path, c.bytes.substr(0, n));
      try {
        loadMesh(path);
        ++loaded;
      } catch (const MeshError&) {
      } catch (const std::exception& error) {
        ADD_FAILURE() << c.name << " cut at " << n
                      << " bytes threw a non-MeshError: " << error.what();
      }
    }
    writeFile(path, c.bytes);
    EXPECT_NO_THROW(loadMesh(path)) << c.name << " in full";
    EXPECT_LE(loaded, 3) << c.name << ": too many truncated files were accepted";
  }
}

// ---------------------------------------------------------------------------
// CGAL sample meshes (scripts/setup): counts from each file's OFF header.

TEST(MeshIoExternal, MissingExternalMeshFailsWithSetupHint) {
  EXPECT_NONFATAL_FAILURE(test::externalMesh("no_such_mesh.off"), "run scripts/setup");
}

struct ExternalMeshCase {
  const char* name;
  int vertices;
  int faces;
  int euler;  ///< 2 - 2 genus: all four are closed.
};

TEST(MeshIoExternal, CgalSampleMeshesLoadWithHeaderCountsAndGenus) {
  for (const ExternalMeshCase& c : {ExternalMeshCase{"bunny00.off", 37706, 75408, 2},
                                    ExternalMeshCase{"camel.off", 9770, 19536, 2},
                                    ExternalMeshCase{"elephant.off", 2775, 5558, -4},
                                    ExternalMeshCase{"fandisk.off", 6475, 12946, 2}}) {
    SCOPED_TRACE(c.name);
    const std::string path = externalMesh(c.name);
    TriangleMesh mesh;
    ASSERT_NO_THROW(mesh = loadMesh(path));
    EXPECT_EQ(mesh.vertexPositions.rows(), c.vertices);
    EXPECT_EQ(mesh.faces.rows(), c.faces);
    const SurfaceTopology topology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows()),
                                   c.name);
    EXPECT_EQ(topology.vertexCount() - topology.edgeCount() + topology.faceCount(), c.euler);
    EXPECT_TRUE(topology.boundaryLoops().empty());
  }
}

// ---------------------------------------------------------------------------
// The shared corpus (tests/support/mesh_fixture.h) hands out what it promises.

class MeshCorpusTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { corpus = new test::MeshCorpus(); }
  static void TearDownTestSuite() {
    delete corpus;
    corpus = nullptr;
  }
  static test::MeshCorpus* corpus;
};
test::MeshCorpus* MeshCorpusTest::corpus = nullptr;

TEST_F(MeshCorpusTest, GroupsHaveTheRightTopology) {
  ASSERT_EQ(corpus->closed().size(), 5u);
  ASSERT_EQ(corpus->withBoundary().size(), 2u);
  ASSERT_EQ(corpus->irregular().size(), 3u);
  for (const test::NamedMesh& named : corpus->closed()) {
    SCOPED_TRACE(named.name);
    const SurfaceTopology topology(named.mesh.faces,
                                   static_cast<int>(named.mesh.vertexPositions.rows()));
    EXPECT_TRUE(topology.boundaryLoops().empty());
  }
  for (const test::NamedMesh& named : corpus->withBoundary()) {
    SCOPED_TRACE(named.name);
    const SurfaceTopology topology(named.mesh.faces,
                                   static_cast<int>(named.mesh.vertexPositions.rows()));
    EXPECT_EQ(topology.boundaryLoops().size(), 1u);
    EXPECT_EQ(eulerCharacteristic(named.mesh), 1);  // a disc
  }
  EXPECT_EQ(corpus->closed()[3].name, "bunny00.off");
  EXPECT_EQ(corpus->irregular()[0].name, "camel.off");
}

TEST_F(MeshCorpusTest, JitteredGridIsIrregularButCounterClockwise) {
  const test::NamedMesh& jittered = corpus->irregular().back();
  const TriangleMesh regular = gridMesh(16, 16, 1.0, 1.0);
  ASSERT_EQ(jittered.mesh.vertexPositions.rows(), regular.vertexPositions.rows());
  EXPECT_TRUE(jittered.mesh.faces == regular.faces);
  const double moved =
      (jittered.mesh.vertexPositions - regular.vertexPositions).rowwise().norm().maxCoeff();
  EXPECT_GT(moved, 0.05 / 16);                          // really jittered...
  EXPECT_LE(moved, 0.2 * std::sqrt(2.0) / 16 + 1e-15);  // ...within the stated bound
  for (Eigen::Index f = 0; f < jittered.mesh.faces.rows(); ++f) {
    const Vector3 a = jittered.mesh.vertexPositions.row(jittered.mesh.faces(f, 0));
    const Vector3 b = jittered.mesh.vertexPositions.row(jittered.mesh.faces(f, 1));
    const Vector3 c = jittered.mesh.vertexPositions.row(jittered.mesh.faces(f, 2));
    EXPECT_GT((b - a).cross(c - a).z(), 0.0) << "face " << f;
  }
  // Same seed, same mesh.
  EXPECT_TRUE(test::jitteredGridMesh(16, 16, 1.0, 1.0, 0.2, 20240611u).vertexPositions ==
              jittered.mesh.vertexPositions);
}

}  // namespace
}  // namespace blot::stain
