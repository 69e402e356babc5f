// Test mesh corpus: CGAL sample meshes, primitives and a jittered grid.
//
// Design note: the corpus is a value a test suite owns, not a cached global,
// because our style bans function-local mutable statics and so that a suite
// decides what it pays for. The jitter uses raw std::mt19937 output (whose
// sequence the standard fixes) rather than std::uniform_real_distribution
// (whose algorithm each standard library chooses), so the mesh is identical
// on every platform.
#include "mesh_fixture.h"

#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <utility>

namespace blot::test {

namespace {

bool isReadable(const std::string& path) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file) std::fclose(file);
  return file != nullptr;
}

}  // namespace

std::string externalMesh(const char* name) {
  const std::string path = std::string(BLOT_EXTERNAL_MESH_DIR) + "/" + name;
  if (!isReadable(path)) {
    ADD_FAILURE() << "missing external mesh " << path
                  << ": run scripts/setup (it extracts the CGAL sample meshes)";
  }
  return path;
}

std::string testDataPath(const std::string& relative) {
  return std::string(BLOT_TEST_DATA_DIR) + "/" + relative;
}

stain::TriangleMesh jitteredGridMesh(int nx, int ny, double width, double height, double jitter,
                                     std::uint32_t seed) {
  stain::TriangleMesh mesh = stain::gridMesh(nx, ny, width, height);
  std::mt19937 generator(seed);
  // Uniform in [-1, 1] from one 32-bit draw.
  const auto draw = [&generator]() { return 2.0 * (generator() / 4294967295.0) - 1.0; };
  const double dx = width / nx, dy = height / ny;
  for (int j = 1; j < ny; ++j) {
    for (int i = 1; i < nx; ++i) {
      const int v = j * (nx + 1) + i;
      mesh.vertexPositions(v, 0) += jitter * dx * draw();
      mesh.vertexPositions(v, 1) += jitter * dy * draw();
      mesh.vertexUVs(v, 0) = mesh.vertexPositions(v, 0) / width;
      mesh.vertexUVs(v, 1) = mesh.vertexPositions(v, 1) / height;
    }
  }
  return mesh;
}

namespace {

/// Loads a CGAL mesh into `group`, or records why it could not.
void addExternal(const char* name, std::vector<NamedMesh>& group) {
  const std::string path = externalMesh(name);
  if (!isReadable(path)) return;  // externalMesh has recorded the failure
  try {
    group.push_back({name, stain::loadMesh(path)});
  } catch (const std::exception& error) {
    ADD_FAILURE() << "cannot load " << name << ": " << error.what();
  }
}

/// Adds a mesh built in code after checking it the way a loaded mesh is.
void addGenerated(std::string name, stain::TriangleMesh mesh, std::vector<NamedMesh>& group) {
  try {
    stain::validateMesh(mesh, name);
    group.push_back({std::move(name), std::move(mesh)});
  } catch (const std::exception& error) {
    ADD_FAILURE() << "generated mesh is invalid: " << error.what();
  }
}

}  // namespace

MeshCorpus::MeshCorpus(CorpusSize size) {
  for (int level = 1; level <= 3; ++level)
    addGenerated("icosphere level " + std::to_string(level), stain::icosphereMesh(level), closed_);
  if (size == CorpusSize::kFull) addExternal("bunny00.off", closed_);
  addExternal("elephant.off", closed_);

  addGenerated("grid 12 x 8", stain::gridMesh(12, 8, 1.5, 1.0), withBoundary_);
  addGenerated("disc 8 rings", stain::discMesh(8, 1.0), withBoundary_);

  addExternal("camel.off", irregular_);
  addExternal("fandisk.off", irregular_);
  addGenerated("jittered grid 16 x 16", jitteredGridMesh(16, 16, 1.0, 1.0, 0.2, 20240611u),
               irregular_);
}

}  // namespace blot::test
