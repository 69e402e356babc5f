// mesh.vertex_order "locality": the engine works on the renumbered mesh, the
// scene's indices keep naming the file's elements, and the stain is the same
// stain on the renumbered vertices, to about 1e-8 (sums run in another order).
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace blot::engine {
namespace {

/// A 12 x 12 patch whose scene names vertices and faces by index: a drop, two
/// pins (an index and a point), a held region, two fabric patches (a face
/// list, the other faces) and a weft constraint.
std::string indexedScene(const std::string& order) {
  std::string first, rest;
  for (int f = 0; f < 288; ++f) (f < 50 ? first : rest) += (f < 50 ? (f ? "," : "") : (f > 50 ? "," : "")) + std::to_string(f);
  return R"({"mesh": {"patch": {"size": [1, 1], "resolution": [12, 12]})" + order + R"(},
             "cloth": {"source": "bullet", "pins": [{"vertex": 5}, {"point": [1, 1, 0]}]},
             "fabric": {"patches": [
               {"faces": [)" + first + R"(], "tensor": [[0.004, 0], [0, 0.001]],
                "weft_constraints": [{"face": 7, "direction": [1, 0, 0]}]},
               {"faces": [)" + rest + R"(], "tensor": [[0.002, 0], [0, 0.002]], "weft": [1, 0, 0]}]},
             "drops": [{"vertex": 37, "radius": 0.1, "solvent_mass": 0.001, "solute_mass": 0.0005}],
             "held_regions": [{"vertices": [3, 4], "solvent_density": 0.5}]})";
}

std::set<std::vector<double>> cornersOf(const SceneDef& s, const std::vector<int>& faces) {
  std::set<std::vector<double>> out;
  for (const int f : faces) {
    std::vector<std::vector<double>> corners;
    for (int c = 0; c < 3; ++c) {
      const auto p = s.engine.mesh.vertexPositions.row(s.engine.mesh.faces(f, c));
      corners.push_back({p.x(), p.y(), p.z()});
    }
    std::sort(corners.begin(), corners.end());
    std::vector<double> key;
    for (const auto& c : corners) key.insert(key.end(), c.begin(), c.end());
    out.insert(key);
  }
  return out;
}

TEST(MeshOrderScene, SceneIndicesNameTheFilesElements) {
  const SceneDef plain = parseScene(indexedScene(""), "plain.json");
  const SceneDef ordered = parseScene(indexedScene(R"(, "vertex_order": "locality")"), "ordered.json");
  EXPECT_TRUE(plain.meshOrder.vertices.empty());
  ASSERT_EQ(ordered.meshOrder.vertices.size(), 169u);
  EXPECT_NE(ordered.meshDescription.find("renumbered for locality"), std::string::npos);
  const auto& p = plain.engine.mesh.vertexPositions;
  const auto& q = ordered.engine.mesh.vertexPositions;
  // The renumbering moved the named elements...
  const int drop = ordered.engine.drops.at(0).drop.centerVertex;
  EXPECT_NE(drop, 37);
  EXPECT_EQ(ordered.meshOrder.vertices[size_t(drop)], 37);
  // ...and each index still names the same place.
  EXPECT_EQ(q.row(drop), p.row(37));
  ASSERT_EQ(ordered.engine.cloth.pins.size(), 2u);
  for (int k = 0; k < 2; ++k)
    EXPECT_EQ(q.row(ordered.engine.cloth.pins[size_t(k)].vertex), p.row(plain.engine.cloth.pins[size_t(k)].vertex));
  ASSERT_EQ(ordered.engine.heldRegions.at(0).vertices.size(), 2u);
  for (int k = 0; k < 2; ++k)
    EXPECT_EQ(q.row(ordered.engine.heldRegions[0].vertices[size_t(k)]), p.row(plain.engine.heldRegions[0].vertices[size_t(k)]));
  for (int k = 0; k < 2; ++k)
    EXPECT_EQ(cornersOf(ordered, ordered.engine.fabricPatches.at(size_t(k)).faces),
              cornersOf(plain, plain.engine.fabricPatches.at(size_t(k)).faces));
  EXPECT_EQ(cornersOf(ordered, {ordered.engine.fabricPatches[0].weftConstraints.at(0).face}),
            cornersOf(plain, {plain.engine.fabricPatches[0].weftConstraints.at(0).face}));
}

/// A tilted plate turning about y, the liquid running under gravity: the
/// same run on both numberings.
std::string turningScene(const std::string& order) {
  return R"({"mesh": {"patch": {"size": [1, 1], "resolution": [30, 30]})" + order + R"(},
             "cloth": {"source": "rigid", "angular_velocity": [0, 1.5, 0.5]},
             "fabric": {"patches": [{"faces": "all", "tensor": [[0.004, 0], [0, 0.001]], "weft": [1, 1, 0]}]},
             "liquid": {"absorption_rate": 0.3, "saturation_density": 1.5, "evaporation_rate": 0.002},
             "time_step": 0.01,
             "drops": [{"vertex": 300, "radius": 0.15, "solvent_mass": 0.004, "solute_mass": 0.002}]})";
}

/// ‖b ∘ order − a‖₂ / ‖a‖₂: b on the renumbered mesh against a on the file's.
double relativeL2(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const std::vector<int>& fileVertex) {
  double difference = 0.0, norm = 0.0;
  for (Eigen::Index k = 0; k < b.size(); ++k) {
    const double d = b[k] - a[fileVertex[size_t(k)]];
    difference += d * d;
    norm += a[k] * a[k];
  }
  return std::sqrt(difference / norm);
}

double totalSolute(const Engine& e, const Eigen::VectorXd& areas) {
  return areas.dot(e.solute() + e.absorbedSolute() + e.adsorbedSolute());
}

TEST(MeshOrderScene, TheStainIsTheSameOnTheRenumberedMesh) {
  const SceneDef plainScene = parseScene(turningScene(""), "plain.json");
  const SceneDef orderedScene = parseScene(turningScene(R"(, "vertex_order": "locality")"), "ordered.json");
  Engine plain(plainScene.engine), ordered(orderedScene.engine);
  const std::vector<int>& fileVertex = orderedScene.meshOrder.vertices;
  // Not to the bit: sums over neighbours run in another order, and a trace
  // at the solves' flush floor (1e-9 of the largest density) can fall on
  // either side of it, so the runs part at about 1e-8 (measured: free
  // densities 2e-8, stain 6e-8 after 15 steps; the stain 1.5e-6 after 60,
  // once the last free liquid's traces decide it). A misplaced vertex is O(1).
  ASSERT_TRUE(plain.advanceSteps(15).ok());
  ASSERT_TRUE(ordered.advanceSteps(15).ok());
  EXPECT_LT(relativeL2(plain.solvent(), ordered.solvent(), fileVertex), 1e-6);
  EXPECT_LT(relativeL2(plain.solute(), ordered.solute(), fileVertex), 1e-6);
  EXPECT_LT(relativeL2(plain.absorbedSolvent(), ordered.absorbedSolvent(), fileVertex), 1e-6);
  int wet[2] = {0, 0};
  double worst = 0.0;
  const double floor = 1e-6 * plain.solvent().maxCoeff();
  for (int k = 0; k < ordered.vertexCount(); ++k) {
    const int i = fileVertex[size_t(k)];
    wet[0] += plain.solvent()[k] > floor;
    wet[1] += ordered.solvent()[k] > floor;
    if (ordered.solvent()[k] > floor && plain.solvent()[i] > floor)
      worst = std::max(worst, (ordered.liquidWorldVelocities().row(k) - plain.liquidWorldVelocities().row(i))
                                  .cwiseAbs()
                                  .maxCoeff());
  }
  EXPECT_EQ(wet[0], wet[1]);
  EXPECT_GT(wet[0], 20);  // the liquid is still there
  const double speed = plain.liquidWorldVelocities().cwiseAbs().maxCoeff();
  EXPECT_GT(speed, 0.1);
  EXPECT_LT(worst, 1e-6 * speed) << worst << " m/s of " << speed;

  ASSERT_TRUE(plain.advanceSteps(45).ok());
  ASSERT_TRUE(ordered.advanceSteps(45).ok());
  EXPECT_LT(relativeL2(plain.absorbedSolvent(), ordered.absorbedSolvent(), fileVertex), 1e-5);
  EXPECT_LT(relativeL2(plain.absorbedSolute(), ordered.absorbedSolute(), fileVertex), 1e-5);
  EXPECT_LT(relativeL2(plain.adsorbedSolute(), ordered.adsorbedSolute(), fileVertex), 1e-5);
  // Each run keeps its solute to rounding, so the two agree to rounding.
  const stain::Vector& plainAreas = plain.surface().stain().geometry().intrinsic().vertexDualAreas;
  const stain::Vector& orderedAreas = ordered.surface().stain().geometry().intrinsic().vertexDualAreas;
  EXPECT_NEAR(totalSolute(ordered, orderedAreas), totalSolute(plain, plainAreas), 1e-12 * totalSolute(plain, plainAreas));
}

// An engine built from a scene keeps the renumbering with its definition
// (EngineDef::meshOrder), so a C++ caller of fromSceneJson / fromSceneFile can
// map its vertices back to the file's, as the C API and the Python module do
// from the SceneDef: engine vertex k sits where the file's vertex
// meshOrder.vertices[k] does. Without the renumbering the order is empty.
TEST(MeshOrderScene, AnEngineFromASceneKeepsItsRenumbering) {
  const std::string text = indexedScene(R"(, "vertex_order": "locality")");
  const SceneDef scene = parseScene(text, "ordered.json");
  const std::unique_ptr<Engine> engine = Engine::fromSceneJson(text, ".", "ordered.json");
  const stain::MeshOrder& order = engine->definition().meshOrder;
  EXPECT_EQ(order.vertices, scene.meshOrder.vertices);
  EXPECT_EQ(order.faces, scene.meshOrder.faces);
  ASSERT_EQ(order.vertices.size(), 169u);
  const SceneDef plain = parseScene(indexedScene(""), "plain.json");
  const auto& rest = engine->definition().mesh.vertexPositions;
  for (int k = 0; k < 169; ++k)
    EXPECT_EQ(rest.row(k), plain.engine.mesh.vertexPositions.row(order.vertices[static_cast<size_t>(k)])) << k;
  EXPECT_TRUE(Engine::fromSceneJson(indexedScene(""), ".", "plain.json")->definition().meshOrder.vertices.empty());
}

}  // namespace
}  // namespace blot::engine
