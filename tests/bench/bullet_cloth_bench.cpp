// Bare Bullet cloth (blot::cloth::BulletCloth), no stain: the reference the
// coupled benchmarks compare against.
//  - BM_ClothFrame: one 1/60 s frame of a 1 m flag hanging from its two top
//    corners (scene 0) or of a 1 m sheet draped over a sphere on the ground
//    (scene 1), at 2.5K, 10K and 35K nodes, with the ClothDef defaults
//    (settings 0: 4 position iterations × 4 substeps, tethers) or with Bullet's
//    own defaults (settings 1: 1 iteration, 1 substep, no damping, no
//    tethers). Counter `healthy` is 0 when the run ended with a blown-up or
//    Bullet-disabled body: Bullet's defaults look fast at 10K+ because the
//    body is dead (docs/cloth.md).
//  - BM_ClothBuild: building the body from a grid of 35K and 140K vertices
//    (CreateFromTriMesh would need 3 s and 1.2 GB at 35K, and overflow at 140K).
// Run: bullet_cloth_bench --benchmark_counters_tabular=true
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/surface_topology.h>

#include <benchmark/benchmark.h>

#include <chrono>

namespace blot::cloth {
namespace {

constexpr double kFrame = 1.0 / 60;

ClothDef scene(int cells, int sceneId, int settings) {
  stain::TriangleMesh mesh = stain::gridMesh(cells, cells, 1.0, 1.0);
  if (sceneId == 0) {
    for (int i = 0; i < mesh.vertexPositions.rows(); ++i) {
      const double x = mesh.vertexPositions(i, 0), y = mesh.vertexPositions(i, 1);
      mesh.vertexPositions.row(i) << x, 0, y;
    }
  } else {
    mesh.vertexPositions.col(2).setConstant(0.5);
  }
  ClothDef def;
  coupling::describeClothMesh(mesh, stain::SurfaceTopology(mesh.faces, static_cast<int>(mesh.vertexPositions.rows())),
                              def);
  if (sceneId == 0) {
    def.pins = {ClothPin{cells * (cells + 1), {}}, ClothPin{cells * (cells + 1) + cells, {}}};
  } else {
    def.colliders = {ClothCollider::plane(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()),
                     ClothCollider::sphere(Eigen::Vector3d(0.5, 0.5, 0.1), 0.25)};
  }
  if (settings == 1) {
    def.positionIterations = 1;
    def.substeps = 1;
    def.dampingRate = 0;
    def.bendStiffness = 0;
    def.tethers = false;
  }
  return def;
}

// Args: grid cells per side (49, 99, 186 → 2,500, 10,000, 34,969 nodes),
// scene (0 hanging flag, 1 drape), settings (0 ClothDef defaults, 1 Bullet's).
void BM_ClothFrame(benchmark::State& state) {
  const int cells = static_cast<int>(state.range(0));
  const ClothDef def = scene(cells, static_cast<int>(state.range(1)), static_cast<int>(state.range(2)));
  BulletCloth cloth(def);
  for (int frame = 0; frame < 60; ++frame) cloth.advance(kFrame);  // past the first fall
  double seconds = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    cloth.advance(kFrame);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    benchmark::DoNotOptimize(cloth.positions().data());
  }
  state.counters["nodes"] = cloth.vertexCount();
  state.counters["links"] = static_cast<double>(cloth.linkVertices().rows());
  state.counters["ms_per_substep"] = 1e3 * seconds / (static_cast<double>(state.iterations()) * def.substeps);
  state.counters["healthy"] = cloth.isHealthy() ? 1 : 0;
  state.counters["max_strain"] = cloth.maxEdgeStrain();
}
BENCHMARK(BM_ClothFrame)
    ->ArgNames({"cells", "scene", "settings"})
    ->ArgsProduct({{49, 99, 186}, {0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

// Arg: grid cells per side (186 → 34,969 vertices, 373 → 139,876).
void BM_ClothBuild(benchmark::State& state) {
  const int cells = static_cast<int>(state.range(0));
  ClothDef def = scene(cells, 0, 0);
  for (auto _ : state) {
    BulletCloth cloth(def);
    benchmark::DoNotOptimize(cloth.positions().data());
  }
  state.counters["vertices"] = static_cast<double>(def.restPositions.rows());
}
BENCHMARK(BM_ClothBuild)->ArgName("cells")->Arg(186)->Arg(373)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::cloth

BENCHMARK_MAIN();
