// Coupled regression tests: every registered scene of assets/scenes/
// runs at a reduced mesh size for a few hundred internal steps, and a summary
// of the result is compared with a stored golden, tests/data/goldens/<scene>.json.
//
// Design note. The summary is what a user would notice change: the mass budget
// (kg, per reservoir), the stain's centroid and extent (solute-weighted mean
// position c = Σ mᵢxᵢ / Σ mᵢ and RMS radius r = (Σ mᵢ|xᵢ − c|² / Σ mᵢ)^½ with
// mᵢ = total solute density × vertex dual area), the peak densities, and the
// cloth's displacement from its rest shape (max and mean |xᵢ − x̄ᵢ|).
// Rejected alternative: comparing Engine::stateHash. It is bit-exact, so any
// change of the last digit (another compiler, CPU, Eigen/CHOLMOD build, or the
// ongoing solver optimizations that reorder sums) would fail the test without
// anything visible having changed; the hash is stored in the golden for
// information only. Tolerances (kTol below) are chosen instead:
//  - masses: 1e-6 relative to the mass added of that species. The budget is
//    conserved to ~1e-13 and every reservoir is a smooth function of the
//    state, so round-off differences stay many orders below this; a change of
//    the absorption/evaporation model or a mass leak shows at 1e-6.
//  - positions (centroid, RMS radius, cloth displacement): 1e-3 × the rest
//    mesh's bounding-box diagonal (1.4 mm on the 1 m scenes). Bullet runs in
//    float (7 digits) and the stain follows its positions, the intrinsic
//    rebuild decision is a threshold test on edge strain, so a last-digit
//    change can flip one rebuild and move the stain by ~1e-5 of the mesh size;
//    1e-3 leaves two orders for that and still catches any physical change
//    (a stain that spreads, drifts or sags differently by a millimetre).
//  - peak densities: 1e-3 relative: a maximum over vertices is as sensitive as
//    the positions above.
// The engine is deterministic for a given thread count; the test runs on one
// thread (OpenMP) so that the run is reproducible on any machine, and fast on
// a loaded CI box.
//
// Regenerating (deliberately, after a change that is meant to alter results):
//   scripts/goldens            (builds and runs this test with BLOT_UPDATE_GOLDENS=1)
// A missing golden is a failure whose message says the same. docs/testing.md
// describes how to add a scene to kScenes.
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sstream>
#include <string>

namespace blot::engine {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// One registered scene: assets/scenes/<name>.json. `resolution` (> 0)
/// replaces the patch's quads along its width (the height keeps the aspect
/// ratio); 0 runs the scene's own mesh. `steps` internal steps are run.
struct GoldenScene {
  const char* name;
  int resolution;
  int steps;
  /// The physics model the scene runs with (physics.model): "film" (the
  /// default; goldens in tests/data/goldens/) or "paper" (tests/data/goldens/paper/).
  const char* model = "film";
};

/// gtest prints the parameter in failure messages.
void PrintTo(const GoldenScene& scene, std::ostream* os) {
  *os << scene.name << " (" << scene.model << " model, resolution " << scene.resolution << ", " << scene.steps
      << " steps)";
}

// Add a scene here (and run scripts/goldens once to create its golden).
const GoldenScene kScenes[] = {
    {"static_drop", 30, 300},
    {"rotating_cloth", 32, 300},
    {"two_way_flag", 30, 300},
    {"anisotropy", 30, 300},
    {"anisotropy_halo", 30, 300},
    {"static_flag_splash", 30, 300},
    {"tablecloth", 30, 300},
    {"waving_flag", 30, 300},
    {"waving_flag_two_way", 30, 300},
};
// The same scenes with the paper's equations ("physics": {"model": "paper"}).
const GoldenScene kPaperScenes[] = {
    {"static_drop", 30, 300, "paper"},
    {"rotating_cloth", 32, 300, "paper"},
    {"two_way_flag", 30, 300, "paper"},
    {"anisotropy", 30, 300, "paper"},
    {"anisotropy_halo", 30, 300, "paper"},
    {"static_flag_splash", 30, 300, "paper"},
    {"tablecloth", 30, 300, "paper"},
    {"waving_flag", 30, 300, "paper"},
    {"waving_flag_two_way", 30, 300, "paper"},
};

/// Tolerances (see the design note for why each).
struct Tolerances {
  double massRelative = 1e-6;      ///< × added mass of the species
  double positionRelative = 1e-3;  ///< × rest bounding-box diagonal
  double peakRelative = 1e-3;      ///< × golden peak density
};
constexpr Tolerances kTol;

constexpr const char* kUpdateVariable = "BLOT_UPDATE_GOLDENS";
constexpr const char* kRegenerateHint =
    "regenerate deliberately with `scripts/goldens` (or `BLOT_UPDATE_GOLDENS=1 ctest -R golden`), "
    "check the diff of tests/data/goldens/ and say why the results changed";

fs::path goldenPath(const GoldenScene& scene) {
  const fs::path folder = fs::path(BLOT_TEST_DATA_DIR) / "goldens";
  const std::string file = std::string(scene.name) + ".json";
  return std::string(scene.model) == "film" ? folder / file : folder / scene.model / file;
}

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

json vectorJson(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

/// The scene's JSON with the patch refined or coarsened to `resolution` quads
/// across. Vertex indices (drops, pins) would point elsewhere on the new grid,
/// so they become the rest-shape points of those vertices on the full mesh.
json reducedScene(const json& scene, const std::string& name, int resolution, const fs::path& sceneFile) {
  json out = scene;
  if (resolution <= 0) return out;
  if (!scene.contains("mesh") || !scene["mesh"].contains("patch"))
    throw std::runtime_error(name + ": a resolution override needs a mesh.patch scene; register it with resolution 0");
  const SceneDef full = loadScene(sceneFile.string());
  const Eigen::MatrixX3d& rest = full.engine.mesh.vertexPositions;
  json& patch = out["mesh"]["patch"];
  const json resolutionIn = patch.value("resolution", json::array({32, 32}));
  const int nx = resolutionIn.at(0).get<int>(), ny = resolutionIn.at(1).get<int>();
  const int newNy = std::max(1, static_cast<int>(std::lround(static_cast<double>(ny) * resolution / nx)));
  patch["resolution"] = json::array({resolution, newNy});
  auto vertexToPoint = [&](json& item) {
    if (!item.contains("vertex")) return;
    const int v = item["vertex"].get<int>();
    item.erase("vertex");
    item["point"] = vectorJson(rest.row(v).transpose());
  };
  if (out.contains("drops"))
    for (json& drop : out["drops"]) vertexToPoint(drop);
  if (out.contains("cloth") && out["cloth"].contains("pins"))
    for (json& pin : out["cloth"]["pins"]) vertexToPoint(pin);
  if (out.contains("held_regions"))
    for (const json& region : out["held_regions"])
      if (region.contains("vertices"))
        throw std::runtime_error(name + ": held_regions[].vertices cannot be mapped to a coarser patch; use center + "
                                 "radius, or register the scene with resolution 0");
  return out;
}

/// The regression summary of an engine now (see the design note).
json summarize(const Engine& engine) {
  const stain::MassBudget b = engine.statistics().massBudget;
  const Eigen::VectorXd& area = engine.surface().stain().geometry().intrinsic().vertexDualAreas;
  const Eigen::MatrixX3d& x = engine.positions();
  const Eigen::MatrixX3d& rest = engine.definition().mesh.vertexPositions;
  const Eigen::VectorXd solute = engine.solute() + engine.absorbedSolute() + engine.adsorbedSolute();
  const Eigen::VectorXd solvent = engine.solvent() + engine.absorbedSolvent();
  const Eigen::VectorXd weight = solute.cwiseProduct(area);
  const double total = weight.sum();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double rms = 0;
  if (total > 0) {
    centroid = (x.transpose() * weight) / total;
    for (int i = 0; i < x.rows(); ++i) rms += weight[i] * (x.row(i).transpose() - centroid).squaredNorm();
    rms = std::sqrt(rms / total);
  }
  const Eigen::VectorXd displacement = (x - rest).rowwise().norm();
  std::ostringstream hash;
  hash << std::hex << engine.stateHash();
  return json{
      {"mass",
       {{"free_solvent", b.freeSolvent},
        {"absorbed_solvent", b.absorbedSolvent},
        {"evaporated_solvent", b.evaporatedSolvent},
        {"added_solvent", b.addedSolvent},
        {"free_solute", b.freeSolute},
        {"absorbed_solute", b.absorbedSolute},
        {"adsorbed_solute", b.adsorbedSolute},
        {"added_solute", b.addedSolute}}},
      {"stain_centroid", vectorJson(centroid)},
      {"stain_rms_radius", rms},
      {"peak_solvent_density", solvent.maxCoeff()},
      {"peak_solute_density", solute.maxCoeff()},
      {"cloth_max_displacement", displacement.maxCoeff()},
      {"cloth_mean_displacement", displacement.mean()},
      // Information only (not compared): see the design note.
      {"info", {{"state_hash", hash.str()}, {"intrinsic_refreshes", engine.statistics().intrinsicRefreshes}}},
  };
}

double restDiagonal(const Engine& engine) {
  const Eigen::MatrixX3d& rest = engine.definition().mesh.vertexPositions;
  return (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
}

class GoldenSceneTest : public ::testing::TestWithParam<GoldenScene> {};

TEST_P(GoldenSceneTest, MatchesGolden) {
  const GoldenScene& entry = GetParam();
  const std::string name = entry.name;
  const fs::path sceneFile = fs::path(BLOT_ASSETS_DIR) / "scenes" / (name + ".json");
  ASSERT_TRUE(fs::exists(sceneFile)) << sceneFile << " is registered in kScenes but does not exist";
  omp_set_num_threads(1);

  json scene = reducedScene(json::parse(readText(sceneFile)), name, entry.resolution, sceneFile);
  scene["physics"]["model"] = entry.model;
  auto engine = Engine::fromSceneJson(scene.dump(), sceneFile.parent_path().string(), sceneFile.string());
  const stain::StepReport report = engine->advanceSteps(entry.steps);
  ASSERT_EQ(report.status, stain::StepStatus::Ok)
      << name << ": stage " << report.stageName() << ", vertex " << report.vertex << ": " << report.message;

  const json config = {{"resolution", entry.resolution},
                       {"steps", entry.steps},
                       {"threads", 1},
                       {"vertices", engine->vertexCount()}};
  const json actual = summarize(*engine);
  const fs::path path = goldenPath(entry);

  const char* update = std::getenv(kUpdateVariable);
  if (update != nullptr && std::string(update) == "1") {
    fs::create_directories(path.parent_path());
    std::ofstream out(path);
    out << json{{"scene", name}, {"config", config}, {"summary", actual}}.dump(2) << "\n";
    ASSERT_TRUE(out.good()) << path << ": write failed";
    std::cout << "[ golden ] wrote " << path.string() << "\n";
    return;
  }

  ASSERT_TRUE(fs::exists(path)) << "no golden for scene '" << name << "': " << path.string() << " is missing; "
                                << kRegenerateHint;
  const json golden = json::parse(readText(path));
  ASSERT_EQ(golden.at("config"), config) << path.string() << " was made with another configuration; "
                                          << kRegenerateHint;
  const json& expected = golden.at("summary");

  const double lengthTol = kTol.positionRelative * restDiagonal(*engine);
  const double solventTol = kTol.massRelative * actual["mass"]["added_solvent"].get<double>();
  const double soluteTol = kTol.massRelative * actual["mass"]["added_solute"].get<double>();
  for (const auto& [key, value] : expected.at("mass").items()) {
    const double tol = key.find("solute") != std::string::npos ? soluteTol : solventTol;
    EXPECT_NEAR(actual["mass"][key].get<double>(), value.get<double>(), tol)
        << name << ": mass." << key << " (tolerance 1e-6 of the added mass); " << kRegenerateHint;
  }
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(actual["stain_centroid"][k].get<double>(), expected.at("stain_centroid")[k].get<double>(), lengthTol)
        << name << ": stain_centroid[" << k << "] (m, tolerance 1e-3 of the mesh diagonal); " << kRegenerateHint;
  for (const char* key : {"stain_rms_radius", "cloth_max_displacement", "cloth_mean_displacement"})
    EXPECT_NEAR(actual[key].get<double>(), expected.at(key).get<double>(), lengthTol)
        << name << ": " << key << " (m, tolerance 1e-3 of the mesh diagonal); " << kRegenerateHint;
  for (const char* key : {"peak_solvent_density", "peak_solute_density"}) {
    const double want = expected.at(key).get<double>();
    EXPECT_NEAR(actual[key].get<double>(), want, kTol.peakRelative * std::abs(want))
        << name << ": " << key << " (kg/m², tolerance 1e-3 relative); " << kRegenerateHint;
  }
}

// The summary must react to what it guards: a stain moved by 1 cm is caught
// by the centroid tolerance (the comparison above is not vacuous).
TEST(GoldenSummaryTest, CentroidFollowsTheStainAndMassesAddUp) {
  omp_set_num_threads(1);
  EngineDef def;
  def.mesh = stain::gridMesh(10, 10, 1.0, 1.0);
  TimedDrop drop;
  drop.drop.centerPoint = Eigen::Vector3d(0.3, 0.6, 0);
  drop.drop.radius = 0.15;
  drop.drop.solventMass = 0.01;
  drop.drop.soluteMass = 0.004;
  def.drops = {drop};
  const Engine engine(def);
  const json s = summarize(engine);
  // A symmetric bump on a uniform grid: the centroid sits at its centre to
  // the lumped-area asymmetry of a few boundary-free vertices (< 1 cm).
  EXPECT_NEAR(s["stain_centroid"][0].get<double>(), 0.3, 1e-2);
  EXPECT_NEAR(s["stain_centroid"][1].get<double>(), 0.6, 1e-2);
  EXPECT_GT(s["stain_rms_radius"].get<double>(), 0.02);
  EXPECT_LT(s["stain_rms_radius"].get<double>(), 0.15);
  EXPECT_NEAR(s["mass"]["free_solute"].get<double>(), 0.004, 1e-12);
  EXPECT_EQ(s["cloth_max_displacement"].get<double>(), 0.0);
}

std::string sceneName(const ::testing::TestParamInfo<GoldenScene>& info) { return info.param.name; }

// Instantiated as "golden" and "golden_paper" so that `ctest -R golden`
// selects these tests.
INSTANTIATE_TEST_SUITE_P(golden, GoldenSceneTest, ::testing::ValuesIn(kScenes), sceneName);
INSTANTIATE_TEST_SUITE_P(golden_paper, GoldenSceneTest, ::testing::ValuesIn(kPaperScenes), sceneName);

}  // namespace
}  // namespace blot::engine
