#pragma once
/// The shared mesh corpus for tests: each asset is loaded once by the suite
/// that owns a MeshCorpus (typically in SetUpTestSuite) and handed out in three
/// groups, so property tests can loop over every mesh of a kind:
///
///   class MyTest : public ::testing::Test {
///    protected:
///     static void SetUpTestSuite() { corpus = new blot::test::MeshCorpus(); }
///     static void TearDownTestSuite() { delete corpus; corpus = nullptr; }
///     static blot::test::MeshCorpus* corpus;
///   };
///   blot::test::MeshCorpus* MyTest::corpus = nullptr;
///
/// The suite owns the corpus (no hidden cache, no function-local statics).
/// External meshes come from Debian's CGAL data, extracted by scripts/setup
/// into BLOT_EXTERNAL_MESH_DIR; a missing one fails the test that asks for it.
#include <blot/stain/geometry/triangle_mesh.h>

#include <cstdint>
#include <string>
#include <vector>

namespace blot::test {

/// A mesh and the name an assertion about it should print (use SCOPED_TRACE).
struct NamedMesh {
  std::string name;
  stain::TriangleMesh mesh;
};

/// Full path of a CGAL sample mesh (e.g. "bunny00.off") in BLOT_EXTERNAL_MESH_DIR.
/// Records a non-fatal test failure saying "run scripts/setup" when the file is
/// missing; the path is returned either way.
std::string externalMesh(const char* name);

/// Full path of a file under tests/data (BLOT_TEST_DATA_DIR), e.g. "bad/empty.obj".
std::string testDataPath(const std::string& relative);

/// gridMesh(nx, ny, width, height) with every interior vertex moved in the
/// z = 0 plane by up to `jitter` times the grid spacing per axis (jitter < 0.25
/// keeps every triangle counter-clockwise), drawn from std::mt19937(seed) so
/// the mesh is the same on every platform. Boundary vertices stay put.
stain::TriangleMesh jitteredGridMesh(int nx, int ny, double width, double height, double jitter,
                                     std::uint32_t seed);

/// What to load: the 37,706-vertex bunny costs ~0.1 s to load; suites whose
/// per-mesh work is superlinear can leave it out.
enum class CorpusSize { kFull, kWithoutLargeMeshes };

/// Test meshes in three groups:
///  - closed():        icospheres (levels 1-3), bunny00.off (genus 0),
///                     elephant.off (closed, genus 3);
///  - withBoundary():  a 12 x 8 grid (1.5 x 1 m) and an 8-ring disc (radius 1 m);
///  - irregular():     camel.off (many obtuse triangles), fandisk.off (sharp
///                     features, slivers), and a 16 x 16 unit grid jittered by
///                     0.2 spacing (seed 20240611).
/// Every mesh has passed validateMesh. A CGAL mesh that is missing or fails
/// to load is left out after recording a test failure.
class MeshCorpus {
 public:
  explicit MeshCorpus(CorpusSize size = CorpusSize::kFull);

  const std::vector<NamedMesh>& closed() const { return closed_; }
  const std::vector<NamedMesh>& withBoundary() const { return withBoundary_; }
  const std::vector<NamedMesh>& irregular() const { return irregular_; }

 private:
  std::vector<NamedMesh> closed_, withBoundary_, irregular_;
};

}  // namespace blot::test
