// Scene files: good scenes parse into the EngineDef fields they name, and bad
// ones fail with a message that names the source and the key path.
#include <blot/engine/scene.h>
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

namespace blot::engine {
namespace {

/// A minimal valid scene: a 10 x 10 patch (121 vertices, 200 faces), static.
const char* const kMinimal = R"({"mesh": {"patch": {"size": [1, 1], "resolution": [10, 10]}},
                                 "cloth": {"source": "static"}})";

std::string withAbsorbance() {
  return R"({"mesh": {"patch": {"size": [1, 1], "resolution": [4, 4]}}, "cloth": {"source": "static"},
             "display": {"pigment_absorbance": [0.5, 2, 4]}})";
}

std::string withCloth(const std::string& cloth) {
  return R"({"mesh": {"patch": {"size": [1, 1], "resolution": [10, 10]}}, "cloth": )" + cloth + "}";
}
std::string withExtra(const std::string& extra) {
  return R"({"mesh": {"patch": {"size": [1, 1], "resolution": [10, 10]}}, "cloth": {"source": "static"}, )" + extra +
         "}";
}

/// The error message of parsing `json`, or "" when it parses.
std::string errorOf(const std::string& json) {
  try {
    parseScene(json, "scene.json");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneTest, MinimalSceneGetsDocumentedDefaults) {
  const SceneDef scene = parseScene(kMinimal, "scene.json");
  EXPECT_EQ(scene.engine.mesh.vertexPositions.rows(), 121);
  EXPECT_EQ(scene.engine.mesh.faces.rows(), 200);
  EXPECT_EQ(scene.engine.source, MotionSource::Static);
  EXPECT_EQ(scene.engine.coupling, coupling::CouplingMode::OneWay);
  EXPECT_DOUBLE_EQ(scene.engine.timeStep, 1.0 / 120.0);
  EXPECT_EQ(scene.engine.maxStepsPerCall, 8);
  EXPECT_DOUBLE_EQ(scene.engine.diffusivity, 0.01);
  EXPECT_EQ(scene.engine.stain.threads, 0);
  EXPECT_TRUE(scene.engine.stain.adaptiveThreads);
  EXPECT_EQ(scene.engine.stain.strainTest, stain::StrainTest::WholeMesh);
  EXPECT_EQ(scene.engine.stain.intrinsicRefresh, stain::IntrinsicRefresh::Full);
  EXPECT_EQ(scene.outputs.frames, 10);
  EXPECT_EQ(scene.outputs.directory, "out/scene");
  // The patch is centred on the origin in the xy plane.
  EXPECT_NEAR(scene.engine.mesh.vertexPositions.colwise().mean().norm(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(scene.engine.mesh.vertexPositions.col(2).cwiseAbs().maxCoeff(), 0.0);
}

TEST(SceneTest, EveryCommonKeyReachesItsField) {
  const std::string json = R"({
    "name": "flag", "description": "a test",
    "mesh": {"patch": {"size": [2, 1], "resolution": [20, 10], "plane": "xz", "center": [0, 0, 1]}},
    "cloth": {"source": "bullet", "total_mass": 0.3, "bend_stiffness": 0.1, "damping_rate": 0.2,
              "position_iterations": 6, "substeps": 2,
              "pins": [{"vertex": 0}, {"point": [1, 0, 1.5], "amplitude": [0, 0.1, 0], "frequency": 0.5}],
              "wind": {"velocity": [0, 3, 0], "drag_coefficient": 0.4, "model": "vertex-two-sided"},
              "colliders": [{"shape": "plane", "center": [0, 0, 0]}, {"shape": "sphere", "center": [0, 0.5, 0.5], "radius": 0.2}]},
    "fabric": {"diffusivity": 0.02, "viscosity": 0.001},
    "liquid": {"absorption_rate": 0.3, "evaporation_boundary": "wet-front"},
    "physics": {"coriolis": false, "film_pressure": true, "coriolis_scheme": "explicit", "boundary_wall": false,
                "diffusive_momentum": false},
    "gravity": [0, 0, -9.81],
    "coupling": "two-way", "time_step": 0.005, "max_steps_per_call": 4, "threads": 3, "adaptive_threads": false,
    "strain_test": "around-liquid", "intrinsic_refresh": "region",
    "drops": [{"vertex": 5, "radius": 0.1, "solvent_mass": 0.01, "solute_mass": 0.002, "time": 0.5},
              {"point": [0, 0, 1], "velocity": [0, 1, 0], "relative_velocity": [0.5, 0, 0]}],
    "held_regions": [{"vertices": [1, 2, 3], "solvent_density": 2}],
    "display": {"pigment": "ink"},
    "outputs": {"frames": 3, "steps_per_frame": 2, "ply_every": 0, "directory": "out/x",
                "preview": {"width": 64, "height": 48, "projection": "orthographic"}}})";
  const SceneDef scene = parseScene(json, "flag.json");
  const EngineDef& d = scene.engine;
  EXPECT_EQ(scene.name, "flag");
  EXPECT_EQ(d.mesh.vertexPositions.rows(), 21 * 11);
  // xz plane: y = 0 everywhere, z spans [0.5, 1.5] around the centre z = 1.
  EXPECT_DOUBLE_EQ(d.mesh.vertexPositions.col(1).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_DOUBLE_EQ(d.mesh.vertexPositions.col(2).maxCoeff(), 1.5);
  EXPECT_EQ(d.source, MotionSource::Bullet);
  EXPECT_DOUBLE_EQ(d.cloth.totalMass, 0.3);
  EXPECT_EQ(d.cloth.positionIterations, 6);
  EXPECT_EQ(d.cloth.substeps, 2);
  ASSERT_EQ(d.cloth.pins.size(), 2u);
  EXPECT_EQ(d.cloth.pins[0].vertex, 0);
  EXPECT_EQ(d.cloth.pins[1].vertex, 20 + 21 * 10);  // the top right corner, nearest to (1, 0, 1.5)
  EXPECT_DOUBLE_EQ(d.cloth.pins[1].motion.frequency, 0.5);
  EXPECT_EQ(d.cloth.wind.model, cloth::AeroModel::VertexTwoSided);
  ASSERT_EQ(d.cloth.colliders.size(), 2u);
  EXPECT_EQ(d.cloth.colliders[1].shape, cloth::ClothCollider::Shape::Sphere);
  EXPECT_DOUBLE_EQ(d.cloth.colliders[1].radius, 0.2);
  EXPECT_DOUBLE_EQ(d.cloth.gravity.z(), -9.81);
  EXPECT_DOUBLE_EQ(d.stain.gravity.z(), -9.81);
  EXPECT_DOUBLE_EQ(d.diffusivity, 0.02);
  EXPECT_DOUBLE_EQ(d.stain.liquid.absorptionRate, 0.3);
  EXPECT_EQ(d.stain.liquid.evaporationBoundary, stain::EvaporationBoundary::WetFront);
  EXPECT_FALSE(d.stain.switches.coriolis);
  EXPECT_TRUE(d.stain.switches.filmPressure);
  EXPECT_FALSE(d.stain.switches.boundaryWall);
  EXPECT_FALSE(d.stain.switches.diffusiveMomentum);
  EXPECT_EQ(d.stain.switches.coriolisScheme, stain::CoriolisScheme::Explicit);
  EXPECT_EQ(d.coupling, coupling::CouplingMode::TwoWay);
  EXPECT_DOUBLE_EQ(d.timeStep, 0.005);
  EXPECT_EQ(d.stain.threads, 3);
  EXPECT_FALSE(d.stain.adaptiveThreads);
  EXPECT_EQ(d.stain.strainTest, stain::StrainTest::AroundLiquid);
  EXPECT_EQ(d.stain.intrinsicRefresh, stain::IntrinsicRefresh::Region);
  ASSERT_EQ(d.drops.size(), 2u);
  EXPECT_EQ(d.drops[0].drop.centerVertex, 5);
  EXPECT_DOUBLE_EQ(d.drops[0].time, 0.5);
  EXPECT_EQ(d.drops[1].drop.centerVertex, -1);
  EXPECT_DOUBLE_EQ(d.drops[1].drop.velocity.y(), 1.0);
  EXPECT_DOUBLE_EQ(d.drops[1].drop.relativeVelocity.x(), 0.5);
  EXPECT_TRUE(d.drops[0].drop.relativeVelocity.isZero(0.0));
  EXPECT_FALSE(d.drops[0].drop.velocityIsWorld) << "no velocity key: the drop lands at rest on the cloth";
  EXPECT_TRUE(d.drops[1].drop.velocityIsWorld);
  ASSERT_EQ(d.heldRegions.size(), 1u);
  EXPECT_EQ(d.heldRegions[0].vertices.size(), 3u);
  EXPECT_EQ(scene.outputs.frames, 3);
  EXPECT_EQ(scene.outputs.plyEvery, 0);
  EXPECT_EQ(scene.outputs.preview.projection, Projection::Orthographic);
}

TEST(SceneTest, FabricPatchesWithTensorAndPreset) {
  const std::string json = withExtra(R"("fabric": {"viscosity": 0.001, "patches": [
      {"name": "left", "faces": [0, 1, 2], "tensor": [[2, 0], [0, 1]], "diffusivity": 0.03, "weft": [1, 1, 0]},
      {"preset": "twill-2-1", "faces": "all"}]})");
  const SceneDef scene = parseScene(json, "scene.json");
  ASSERT_EQ(scene.engine.fabricPatches.size(), 2u);
  const stain::FabricPatch& left = scene.engine.fabricPatches[0];
  EXPECT_EQ(left.name, "left");
  EXPECT_EQ(left.faces.size(), 3u);
  // Scaled so that trace / 2 = 0.03 with the 2:1 anisotropy kept.
  EXPECT_NEAR(left.tensor(0, 0), 0.04, 1e-15);
  EXPECT_NEAR(left.tensor(1, 1), 0.02, 1e-15);
  EXPECT_EQ(left.weftConstraints.size(), 3u);
  EXPECT_TRUE(scene.engine.fabricPatches[1].pattern.has_value());
  EXPECT_EQ(scene.engine.fabricPatches[1].name, "fabric.patches[1]");  // errors name the key path
  EXPECT_EQ(scene.engine.fabricPatches[1].faces.size(), 200u);
  // The loader's homogenization goes to the engine (no second solve there):
  // the pattern's S_eff, nothing for the tensor patch.
  ASSERT_EQ(scene.engine.fabricPatchEffectiveTensors.size(), 2u);
  EXPECT_TRUE(scene.engine.fabricPatchEffectiveTensors[0].isZero(0.0));
  EXPECT_EQ(scene.engine.fabricPatchEffectiveTensors[1],
            stain::homogenize(stain::presetWeavePattern("twill-2-1")).effective);
}

// A pattern whose homogenization bounds do not meet (here a fixed K = 1, far
// too coarse for the twill's corners) is refused at load time, naming the
// patch, unless the scene accepts the looser tensor explicitly.
TEST(SceneTest, UnconvergedHomogenizationIsRefusedUnlessAccepted) {
  const std::string coarse = R"("fabric": {"subdivisions": 1, "patches": [{"preset": "twill-2-1", "faces": "all"}]})";
  const std::string message = errorOf(withExtra(coarse));
  EXPECT_NE(message.find("fabric.patches[0].preset"), std::string::npos) << message;
  EXPECT_NE(message.find("did not converge"), std::string::npos) << message;
  EXPECT_NE(message.find("accept_unconverged"), std::string::npos) << message;
  const std::string accepted =
      R"("fabric": {"subdivisions": 1, "accept_unconverged": true, "patches": [{"preset": "twill-2-1", "faces": "all"}]})";
  EXPECT_EQ(errorOf(withExtra(accepted)), "");
  // The default (refine until the bounds meet) converges for every preset.
  EXPECT_EQ(errorOf(withExtra(R"("fabric": {"patches": [{"preset": "twill-2-1", "faces": "all"}]})")), "");
}

// A name is at most 200 bytes; one of 67 "€" (201 bytes) is refused, and the
// message echoes it cut at a whole character (it was cut inside one: invalid
// UTF-8 on stderr).
TEST(SceneTest, AnOverlongUtf8NameIsEchoedAsValidUtf8) {
  std::string name;
  for (int k = 0; k < 67; ++k) name += "\xE2\x82\xAC";
  const std::string message = errorOf(withExtra("\"name\": \"" + name + "\""));
  ASSERT_NE(message.find("name: expected a file name (1 to 200 bytes of UTF-8"), std::string::npos) << message;
  for (std::size_t i = 0; i < message.size();) {
    const auto lead = static_cast<unsigned char>(message[i]);
    const std::size_t length = lead < 0x80 ? 1 : (lead >> 5) == 0x6 ? 2 : (lead >> 4) == 0xE ? 3 : (lead >> 3) == 0x1E ? 4 : 0;
    ASSERT_NE(length, 0u) << "byte " << i << " starts no character";
    ASSERT_LE(i + length, message.size()) << "a character cut at the end";
    for (std::size_t k = 1; k < length; ++k)
      ASSERT_EQ(static_cast<unsigned char>(message[i + k]) & 0xC0, 0x80) << "byte " << i + k;
    i += length;
  }
  name.resize(198);  // 66 "€": accepted
  EXPECT_EQ(errorOf(withExtra("\"name\": \"" + name + "\"")), "");
}

TEST(SceneTest, FileMeshResolvesAgainstTheSceneFolder) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "blot_scene_test";
  std::filesystem::create_directories(dir / "meshes");
  {
    std::ofstream obj(dir / "meshes" / "tri.obj");
    obj << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";
    std::ofstream scene(dir / "s.json");
    scene << R"({"mesh": {"file": "meshes/tri.obj", "scale": 2}, "cloth": {"source": "rigid", "angular_velocity": [0, 0, 1]}})";
  }
  const SceneDef scene = loadScene((dir / "s.json").string());
  EXPECT_EQ(scene.engine.mesh.vertexPositions.rows(), 4);
  EXPECT_DOUBLE_EQ(scene.engine.mesh.vertexPositions(3, 0), 2.0);
  EXPECT_EQ(scene.engine.source, MotionSource::Rigid);
  EXPECT_DOUBLE_EQ(scene.engine.rigid.angularVelocity.z(), 1.0);
  EXPECT_EQ(scene.name, "s");
}

// ------------------------------------------------------------------ bad scenes
// Each case: the scene, the key path the message must name, and a fragment of
// what was expected.
struct BadScene {
  const char* label;
  std::string json;
  const char* keyPath;
  const char* expected;
};

class BadSceneTest : public ::testing::TestWithParam<BadScene> {};

TEST_P(BadSceneTest, MessageNamesSourceAndKey) {
  const BadScene& c = GetParam();
  const std::string message = errorOf(c.json);
  ASSERT_FALSE(message.empty()) << c.label << ": parsed without error";
  EXPECT_EQ(message.rfind("scene.json: ", 0), 0u) << message;
  EXPECT_NE(message.find(std::string("scene.json: ") + c.keyPath + ":"), std::string::npos)
      << c.label << ": message does not name '" << c.keyPath << "': " << message;
  EXPECT_NE(message.find(c.expected), std::string::npos) << c.label << ": " << message;
}

const std::string kBullet = R"({"source": "bullet", )";

INSTANTIATE_TEST_SUITE_P(
    Scenes, BadSceneTest,
    ::testing::Values(
        BadScene{"pin vertex out of range", withCloth(kBullet + R"("pins": [{"vertex": 0}, {"vertex": 1}, {"vertex": 9000}]})"),
                 "cloth.pins[2].vertex", "expected an integer in [0, 121), got 9000"},
        BadScene{"unknown top-level key", withExtra(R"("tme_step": 0.01)"), "tme_step", "unknown key"},
        BadScene{"a NUL in a mesh path", R"({"mesh": {"file": "a\u0000b.obj"}, "cloth": {"source": "static"}})",
                 "mesh.file", "expected a string without NUL characters, got one at byte 1"},
        // Tiny but positive values whose products underflowed or whose faces had no area
        // were refused later under the engine's names (EngineDef.diffusivity, face 0).
        BadScene{"a denormal diffusivity", withExtra(R"("fabric": {"diffusivity": 5e-324})"), "fabric.diffusivity",
                 "expected a number in [1e-12, 1000000]"},
        BadScene{"a denormal wicking factor", withExtra(R"("liquid": {"wicking_factor": 5e-324})"),
                 "liquid.wicking_factor", "expected a number in [1e-06, 1000000]"},
        BadScene{"a patch of 1e-300 m", R"({"mesh": {"patch": {"size": [1e-300, 1]}}, "cloth": {"source": "static"}})",
                 "mesh.patch.size[0]", "expected a number in [1e-06, 1000000]"},
        // Named before the drops are read, which without "liquid" fail on their own.
        BadScene{"misspelt liquid", withExtra(R"("drops": [{"vertex": 5, "mass": 0.001}], "liquid2": {"preset": "wine"})"),
                 "liquid2", "unknown key (expected one of: name, description, mesh, cloth, fabric, liquid,"},
        BadScene{"unknown nested key", withExtra(R"("liquid": {"absorption": 0.1})"), "liquid.absorption",
                 "unknown key (expected one of: preset, solute_fraction, wicking_factor, viscosity_factor, absorption_rate"},
        BadScene{"wrong type", withExtra(R"("time_step": "fast")"), "time_step", "expected a number in [1e-06, 1], got a string"},
        BadScene{"negative time step", withExtra(R"("time_step": -0.01)"), "time_step", "got -0.01"},
        BadScene{"bad enum", withExtra(R"("coupling": "both")"), "coupling", "expected one of \"one-way\", \"two-way\""},
        BadScene{"region refresh without the test around the liquid", withExtra(R"("intrinsic_refresh": "region")"),
                 "intrinsic_refresh", "needs strain_test \"around-liquid\""},
        BadScene{"two-way without bullet", withExtra(R"("coupling": "two-way")"), "coupling", "needs cloth.source \"bullet\""},
        BadScene{"unknown source", withCloth(R"({"source": "cloth"})"), "cloth.source", "expected one of \"static\""},
        BadScene{"missing cloth", R"({"mesh": {"patch": {}}})", "cloth", "required key is missing"},
        BadScene{"two meshes", R"({"mesh": {"patch": {}, "disc": {}}, "cloth": {"source": "static"}})", "mesh",
                 "exactly one of"},
        BadScene{"resolution not integer", R"({"mesh": {"patch": {"resolution": [10.5, 10]}}, "cloth": {"source": "static"}})",
                 "mesh.patch.resolution[0]", "expected an integer in [1, 2000]"},
        BadScene{"missing mesh file", R"({"mesh": {"file": "/nonexistent/x.obj"}, "cloth": {"source": "static"}})",
                 "mesh.file", "/nonexistent/x.obj"},
        BadScene{"stiffness out of range", withCloth(kBullet + R"("stretch_stiffness": 1.5})"), "cloth.stretch_stiffness",
                 "expected a number in (0, 1], got 1.5"},
        BadScene{"duplicate pin", withCloth(kBullet + R"("pins": [{"vertex": 3}, {"vertex": 3}]})"), "cloth.pins[1].vertex",
                 "already pinned by cloth.pins[0]"},
        BadScene{"collider shape", withCloth(kBullet + R"("colliders": [{"shape": "cone"}]})"), "cloth.colliders[0].shape",
                 "expected one of \"plane\", \"box\", \"sphere\""},
        BadScene{"sphere key on a box", withCloth(kBullet + R"("colliders": [{"shape": "box", "radius": 1}]})"),
                 "cloth.colliders[0].radius", "unknown key"},
        BadScene{"wind not an object", withCloth(kBullet + R"("wind": 3})"), "cloth.wind", "expected an object, got 3"},
        BadScene{"vector of 2", withCloth(R"({"source": "rigid", "angular_velocity": [0, 1]})"), "cloth.angular_velocity",
                 "expected an array of 3 numbers"},
        BadScene{"drop without a place", withExtra(R"("drops": [{"radius": 0.1}])"), "drops[0].vertex", "required"},
        BadScene{"drop negative mass", withExtra(R"("drops": [{"vertex": 1, "solute_mass": -1}])"), "drops[0].solute_mass",
                 "expected a number in [0, 1000000], got -1"},
        BadScene{"held region vertex", withExtra(R"("held_regions": [{"vertices": [1, 500]}])"),
                 "held_regions[0].vertices[1]", "[0, 121)"},
        BadScene{"held region empty ball", withExtra(R"("held_regions": [{"center": [9, 9, 9], "radius": 0.01}])"),
                 "held_regions[0].radius", "no rest-shape vertex"},
        BadScene{"physics switch type", withExtra(R"("physics": {"coriolis": 1})"), "physics.coriolis", "expected true or false"},
        BadScene{"boundary wall type", withExtra(R"("physics": {"boundary_wall": "on"})"), "physics.boundary_wall",
                 "expected true or false, got a string \"on\""},
        BadScene{"adaptive threads type", withExtra(R"("adaptive_threads": "yes")"), "adaptive_threads",
                 "expected true or false, got a string \"yes\""},
        BadScene{"fabric face out of range", withExtra(R"("fabric": {"patches": [{"faces": [0, 999], "tensor": [[1, 0], [0, 1]]}]})"),
                 "fabric.patches[0].faces[1]", "[0, 200)"},
        BadScene{"tensor not SPD", withExtra(R"("fabric": {"patches": [{"tensor": [[1, 2], [2, 1]]}]})"),
                 "fabric.patches[0].tensor", "positive definite"},
        BadScene{"unknown preset", withExtra(R"("fabric": {"patches": [{"preset": "denim"}]})"), "fabric.patches[0].preset",
                 "denim"},
        BadScene{"outputs frames zero", withExtra(R"("outputs": {"frames": 0})"), "outputs.frames", "[1, 1000000]"},
        BadScene{"preview key", withExtra(R"("outputs": {"preview": {"size": 3}})"), "outputs.preview.size", "unknown key"},
        BadScene{"pigment", withExtra(R"("display": {"pigment": "blood"})"), "display.pigment", "\"wine\", \"coffee\", \"ink\""},
        BadScene{"sequence without pattern", withCloth(R"({"source": "sequence"})"), "cloth.pattern", "required"},
        // Plausibility limits: refused at the key, not at a later stage.
        BadScene{"tiny time step", withExtra(R"("time_step": 1e-300)"), "time_step",
                 "expected a number in [1e-06, 1], got 1e-300"},
        BadScene{"huge gravity", withExtra(R"("gravity": [1e300, 0, 0])"), "gravity[0]",
                 "expected a number in [-1000000, 1000000], got 1e+300"},
        BadScene{"huge solvent mass", withExtra(R"("drops": [{"vertex": 1, "solvent_mass": 1e300}])"),
                 "drops[0].solvent_mass", "expected a number in [0, 1000000], got 1e+300"},
        BadScene{"far drop point", withExtra(R"("drops": [{"point": [1e200, 0, 0]}])"), "drops[0].point[0]",
                 "expected a number in [-1000000, 1000000], got 1e+200"},
        BadScene{"huge sequence", withCloth(R"({"source": "sequence", "pattern": "f_%04d.obj", "frame_count": 2000000000})"),
                 "cloth.frame_count", "expected an integer in [0, 100000], got 2000000000"},
        BadScene{"supersampling past the renderer's", withExtra(R"("outputs": {"preview": {"supersampling": 6}})"),
                 "outputs.preview.supersampling", "expected an integer in [1, 4], got 6"},
        BadScene{"preview past the sample budget",
                 withExtra(R"("outputs": {"preview": {"width": 8192, "height": 8192, "supersampling": 2}})"),
                 "outputs.preview", "width x height x supersampling^2 = 8192 x 8192 x 2^2 is more than the renderer's"},
        BadScene{"name with a folder", withExtra(R"("name": "../escape")"), "name",
                 "expected a file name (1 to 200 bytes of UTF-8, no '/'"},
        BadScene{"name starting with a dot", withExtra(R"("name": "..")"), "name", "not starting with '.'"},
        BadScene{"duplicate top-level key", withExtra(R"("time_step": 0.01, "time_step": 0.02)"), "time_step",
                 "duplicate key (an object gives it twice"},
        BadScene{"duplicate nested key", withExtra(R"("outputs": {"frames": 2, "frames": 3})"), "outputs.frames",
                 "duplicate key"},
        BadScene{"duplicate key in an array element", withExtra(R"("drops": [{"vertex": 1}, {"vertex": 1, "vertex": 2}])"),
                 "drops[1].vertex", "duplicate key"},
        BadScene{"pigment colour brighter than the cloth", withExtra(R"("display": {"pigment_color": [0.9, 0.1, 0.1]})"),
                 "display.pigment_color", "at most the cloth's"},
        BadScene{"two pigments", withExtra(R"("display": {"pigment": "ink", "pigment_color": [0.5, 0.1, 0.1]})"),
                 "display.pigment_color", "give one of"},
        // About 38 bytes a texel: 16384 x 16384 would have held about 10 GB after the run.
        BadScene{"a texture past the baking budget",
                 withExtra(R"("outputs": {"texture": {"width": 16384, "height": 16384}})"), "outputs.texture.width",
                 "more than 2^26 texels (8192 x 8192)"},
        // ε = −ln(0.1 / cloth) / 5e-324 is infinite: every dry vertex's colour was NaN.
        BadScene{"a denormal pigment colour density",
                 withExtra(R"("display": {"pigment_color": [0.1, 0.1, 0.1], "pigment_color_density": 5e-324})"),
                 "display.pigment_color_density", "more than 1e6 (pigment_absorbance's range): expected a density of at least"},
        BadScene{"unknown liquid", withExtra(R"("liquid": {"preset": "milk"})"), "liquid.preset",
                 "unknown liquid \"milk\" (expected one of water, wine, coffee, ink)"},
        BadScene{"unknown liquid shorthand", withExtra(R"("liquid": "blood")"), "liquid",
                 "unknown liquid \"blood\" (expected one of water, wine, coffee, ink)"},
        BadScene{"liquid name not a string", withExtra(R"("liquid": {"preset": 3})"), "liquid.preset",
                 "expected a liquid name (one of water, wine, coffee, ink), got 3"},
        BadScene{"drop mass without a liquid", withExtra(R"("drops": [{"vertex": 1, "mass": 5e-5}])"), "drops[0].mass",
                 "needs the liquid's solute fraction"},
        BadScene{"drop mass and solute mass", withExtra(R"("liquid": "wine", "drops": [{"vertex": 1, "mass": 5e-5, "solute_mass": 1e-6}])"),
                 "drops[0].mass", "not both"},
        BadScene{"solute fraction above 1", withExtra(R"("liquid": {"preset": "ink", "solute_fraction": 2})"),
                 "liquid.solute_fraction", "[0, 1]"},
        BadScene{"negative molecular diffusivity", withExtra(R"("liquid": {"preset": "ink", "molecular_diffusivity": -1e-9})"),
                 "liquid.molecular_diffusivity", "[0, 1]"},
        BadScene{"texture without UVs", R"({"mesh": {"icosphere": {"radius": 1}}, "cloth": {"source": "static"}, "outputs": {"texture": {}}})",
                 "outputs.texture", "no UVs"},
        BadScene{"stain maps without UVs",
                 R"({"mesh": {"icosphere": {"radius": 1}}, "cloth": {"source": "static"}, "outputs": {"texture": {"enabled": false, "maps": ["png8"]}}})",
                 "outputs.texture", "no UVs"},
        BadScene{"stain map format", withExtra(R"("outputs": {"texture": {"maps": ["png8", "tiff"]}})"),
                 "outputs.texture.maps[1]", "expected \"png8\", \"png16\" or \"exr\", got a string \"tiff\""},
        BadScene{"stain map format twice", withExtra(R"("outputs": {"texture": {"maps": ["exr", "exr"]}})"),
                 "outputs.texture.maps[1]", "\"exr\" is listed twice"},
        BadScene{"stain maps not a list", withExtra(R"("outputs": {"texture": {"maps": "exr"}})"), "outputs.texture.maps",
                 "expected a list of"},
        BadScene{"gloss wetness zero", withExtra(R"("outputs": {"gltf": {"gloss_wetness": 0}})"),
                 "outputs.gltf.gloss_wetness", "got 0"},
        BadScene{"images camera", withExtra(R"("outputs": {"images": {"camera": "top"}})"), "outputs.images.camera",
                 "\"follow\", \"rest\""}),
    [](const ::testing::TestParamInfo<BadScene>& param) {
      std::string name = param.param.label;
      for (char& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return name;
    });

// The stain maps' formats and the glTF's gloss wetness; maps alone, without
// the colour texture.
TEST(SceneTest, StainMapsAndGlossWetnessAreRead) {
  const SceneDef scene = parseScene(withExtra(R"("outputs": {"texture": {"enabled": false, "maps": ["png16", "exr"]},
                                                            "gltf": {"gloss_wetness": 0.25}})"),
                                    "scene.json", ".");
  EXPECT_FALSE(scene.outputs.texture.enabled);
  EXPECT_FALSE(scene.outputs.texture.maps.png8);
  EXPECT_TRUE(scene.outputs.texture.maps.png16);
  EXPECT_TRUE(scene.outputs.texture.maps.exr);
  EXPECT_EQ(scene.outputs.gltf.glossWetness, 0.25);
  EXPECT_FALSE(parseScene(kMinimal, "scene.json", ".").outputs.texture.maps.any());
}

// The loader's patch resolution override (benchmarks, regression runs): the
// quads across the width are replaced and the height keeps the aspect ratio;
// points still land, indices (which would name other elements) are refused.
TEST(SceneTest, PatchResolutionOverrideRemeshesThePatchAndRefusesIndices) {
  SceneLoadOptions options;
  options.patchResolution = 20;
  const SceneDef wide = parseScene(
      R"({"mesh": {"patch": {"size": [2, 1], "resolution": [10, 5]}}, "cloth": {"source": "static"},
          "drops": [{"point": [0.5, 0, 0]}]})",
      "scene.json", ".", options);
  EXPECT_EQ(wide.engine.mesh.vertexPositions.rows(), 21 * 11);  // 20 x 10 quads
  EXPECT_EQ(wide.engine.drops.size(), 1u);
  const auto error = [&](const std::string& json) {
    try {
      parseScene(json, "scene.json", ".", options);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error(withExtra(R"("drops": [{"vertex": 3}])")).find("scene.json: drops[0].vertex: an index cannot be used "
                                                                 "with a patch resolution override"),
            std::string::npos);
  EXPECT_NE(error(withExtra(R"("held_regions": [{"vertices": [1], "solvent_density": 1}])"))
                .find("held_regions[0].vertices: an index cannot be used"),
            std::string::npos);
  EXPECT_NE(error(R"({"mesh": {"icosphere": {"level": 1}}, "cloth": {"source": "static"}})")
                .find("scene.json: mesh: a patch resolution override needs a \"patch\" mesh"),
            std::string::npos);
  options.patchResolution = -1;
  EXPECT_NE(error(kMinimal).find("expected an integer in [1, 2000] (or 0: none), got -1"), std::string::npos);
}

// mesh.vertex_order: a bad value, a sequence cloth, and messages that name the
// file's indices on a renumbered mesh (tests/engine/mesh_order_scene_test.cpp
// has the renumbering itself).
TEST(SceneTest, VertexOrderMisusesAreRefusedNamingTheFilesIndices) {
  const std::string bad = errorOf(R"({"mesh": {"patch": {}, "vertex_order": "zigzag"}, "cloth": {"source": "static"}})");
  EXPECT_NE(bad.find("mesh.vertex_order"), std::string::npos) << bad;
  EXPECT_NE(bad.find("locality"), std::string::npos) << bad;
  const std::string sequence = errorOf(
      R"({"mesh": {"patch": {}, "vertex_order": "locality"}, "cloth": {"source": "sequence", "pattern": "f_%04d.obj"}})");
  EXPECT_NE(sequence.find("mesh.vertex_order"), std::string::npos) << sequence;
  EXPECT_NE(sequence.find("sequence"), std::string::npos) << sequence;
  // A message names the file's vertex, not the engine's.
  const std::string twice = errorOf(R"({"mesh": {"patch": {}, "vertex_order": "locality"},
      "cloth": {"source": "bullet", "pins": [{"vertex": 40}, {"vertex": 40}]}})");
  EXPECT_NE(twice.find("vertex 40 is already pinned"), std::string::npos) << twice;
  const std::string face = errorOf(R"({"mesh": {"patch": {}, "vertex_order": "locality"}, "cloth": {"source": "static"},
      "fabric": {"patches": [{"name": "a", "faces": [0, 1, 2], "tensor": [[1e-3, 0], [0, 1e-3]], "weft": [1, 0, 0]},
                             {"name": "b", "faces": [5, 2], "tensor": [[1e-3, 0], [0, 1e-3]], "weft": [1, 0, 0]}]}})");
  EXPECT_NE(face.find("fabric.patches[1].faces: face 2 already belongs to patch \"a\""), std::string::npos) << face;
  const std::string repeated = errorOf(R"({"mesh": {"patch": {}, "vertex_order": "locality"}, "cloth": {"source": "static"},
      "fabric": {"patches": [{"faces": [7, 3, 7], "tensor": [[1e-3, 0], [0, 1e-3]], "weft": [1, 0, 0]}]}})");
  EXPECT_NE(repeated.find("fabric.patches[0].faces: face 7 listed twice"), std::string::npos) << repeated;
}

TEST(SceneTest, InvalidJsonNamesTheSource) {
  const std::string message = errorOf("{\"mesh\": ");
  EXPECT_EQ(message.rfind("scene.json: invalid JSON", 0), 0u) << message;
}

TEST(SceneTest, MissingFileIsAnError) {
  EXPECT_THROW(loadScene("/nonexistent/scene.json"), SceneError);
}

// A value nested 100,000 deep is refused by the parser with a short message
// (it used to overflow the stack while the error message was formatted).
TEST(SceneTest, DeeplyNestedValueIsRefusedWithABoundedMessage) {
  for (const char* key : {"time_step", "name", "unknown"}) {
    const std::string deep = std::string(100000, '[') + std::string(100000, ']');
    const std::string message = errorOf(withExtra("\"" + std::string(key) + "\": " + deep));
    EXPECT_EQ(message.rfind("scene.json: nested deeper than 64 arrays or objects (at " + std::string(key) + "[0]", 0),
              0u)
        << message.substr(0, 200);
    EXPECT_LT(message.size(), 300u);
  }
  // Nested within the limit but wrong: the message quotes a bounded prefix.
  const std::string nested = std::string(60, '[') + std::string(60, ']');
  const std::string message = errorOf(withExtra("\"time_step\": " + nested));
  EXPECT_NE(message.find("scene.json: time_step: expected a number"), std::string::npos) << message;
  EXPECT_LT(message.size(), 200u) << message;
}

// Every loader refuses a file larger than its budget by its size, and an
// endless stream (/dev/zero) after reading at most the budget.
TEST(SceneTest, EndlessOrHugeSceneFileIsRefusedByTheByteBudget) {
  for (const char* path : {"/dev/zero", "/dev/urandom"}) {
    try {
      loadScene(path);
      ADD_FAILURE() << path << " loaded";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(path) + ": the scene file has more than the limit of "
                                           "16777216 bytes (not a regular file"),
                std::string::npos)
          << e.what();
    }
  }
  const std::filesystem::path big = std::filesystem::temp_directory_path() / "blot_scene_budget.json";
  {
    std::ofstream out(big);
  }
  std::filesystem::resize_file(big, (std::uintmax_t(16) << 20) + 1);  // sparse: no 16 MB written
  try {
    loadScene(big.string());
    ADD_FAILURE() << "loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("the scene file is 16777217 bytes, more than the limit of 16777216 bytes"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove(big);
  try {
    loadScene(std::filesystem::temp_directory_path().string());
    ADD_FAILURE() << "a directory loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("the scene file is a directory"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace blot::engine

// Found by tests/fuzz/scene_fuzz.cpp (fuzz_scene): regressions and the
// seed corpus replayed in the normal and the sanitized build.
namespace blot::engine {
namespace {

// A number too large for a double makes nlohmann throw out_of_range.406, not a
// parse_error; parseScene caught only the latter, so it escaped as a foreign
// exception ("terminate called" in `blot run`). Fuzz reproducer:
// tests/fuzz/corpus/scene/number_overflow.json.
TEST(SceneFuzzRegression, NumberTooLargeForADoubleIsASceneErrorNamingTheToken) {
  for (const std::string number : {"1e999", "0.1e3084", "-1e400"}) {
    const std::string message = errorOf(withExtra(R"("time_step": )" + number));
    EXPECT_EQ(message.rfind("scene.json: invalid JSON", 0), 0u) << message;
    EXPECT_NE(message.find("number overflow parsing '" + number + "'"), std::string::npos) << message;
  }
}

// Keys that are each finite can overflow together: a 10 m patch scaled by 1e308
// had infinite coordinates and parsed. Reproducer: corpus scale_overflow.json.
TEST(SceneFuzzRegression, MeshThatOverflowsAfterScaleNamesTheMeshAndVertex) {
  // Every number is at most kMaxSceneMagnitude (1e6): the key that would
  // overflow is refused where it is read.
  const std::string message = errorOf(
      R"({"mesh": {"patch": {"size": [10, 10], "resolution": [2, 2]}, "scale": 1e308}, "cloth": {"source": "static"}})");
  EXPECT_EQ(message.rfind("scene.json: mesh.scale: expected a number in (0, 1000000], got 1e+308", 0), 0u) << message;
  const std::string centered = errorOf(
      R"({"mesh": {"patch": {"size": [1, 1], "resolution": [2, 2], "center": [1e308, 0, 0]}, "translate": [1e308, 0, 0]},
          "cloth": {"source": "static"}})");
  EXPECT_NE(centered.find("scene.json: mesh.patch.center[0]: expected a number in [-1000000, 1000000], got 1e+308"),
            std::string::npos)
      << centered;
  // Keys each in range whose product is not: the vertex is named.
  const std::string scaled = errorOf(
      R"({"mesh": {"patch": {"size": [1000000, 1000000], "resolution": [2, 2]}, "scale": 1000000},
          "cloth": {"source": "static"}})");
  EXPECT_NE(scaled.find("scene.json: mesh: vertex 0 has a coordinate of 500000000000 m after scale and translate; expected "
                        "at most 1000000 m"),
            std::string::npos)
      << scaled;
}

// Every seed of fuzz_scene (shipped scenes, hand-written ones for the other
// mesh and cloth kinds, and reproducers of findings) parses, or fails with a
// SceneError that starts with its source name: the fuzz target's oracle.
TEST(SceneFuzzCorpus, EverySeedParsesOrFailsWithASceneErrorNamingTheSource) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(BLOT_TEST_DATA_DIR) / ".." / "fuzz" / "corpus" / "scene";
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  int files = 0, parsed = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string source = entry.path().filename().string();
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ++files;
    try {
      parseScene(text, source, std::string(BLOT_ASSETS_DIR) + "/scenes");
      ++parsed;
    } catch (const SceneError& error) {
      EXPECT_EQ(std::string(error.what()).rfind(source + ": ", 0), 0u) << error.what();
    } catch (const std::exception& error) {
      ADD_FAILURE() << source << ": not a SceneError: " << error.what();
    }
  }
  EXPECT_GE(files, 12);
  EXPECT_GE(parsed, 8) << "the corpus should hold valid scenes too";
}

// A custom pigment colour: the stain at pigment_color_density has exactly
// that (linear) colour on the scene's cloth (Beer–Lambert solved for ε).
TEST(Scene, CustomPigmentColourIsReachedAtItsDensity) {
  const SceneDef scene = parseScene(R"({"mesh": {"patch": {"size": [1, 1], "resolution": [4, 4]}},
      "cloth": {"source": "static"},
      "display": {"cloth_color": [0.8, 0.8, 0.7], "pigment_color": [0.6, 0.2, 0.05], "pigment_color_density": 0.5}})",
                                    "pigment.json");
  const Eigen::Array3d c = stainColor(scene.engine.colors, 0, 0.5, 0, 0);
  EXPECT_NEAR(c[0], 0.6, 1e-14);
  EXPECT_NEAR(c[1], 0.2, 1e-14);
  EXPECT_NEAR(c[2], 0.05, 1e-14);
  const SceneDef direct = parseScene(withAbsorbance(), "absorbance.json");
  EXPECT_TRUE((direct.engine.colors.soluteAbsorbance == Eigen::Array3d(0.5, 2, 4)).all());
}

// Liquid presets: each sets the documented values (stain_color.cpp, docs/rendering.md).
TEST(Scene, LiquidPresetSetsItsDocumentedValues) {
  const std::string base = R"({"mesh": {"patch": {"size": [0.1, 0.1], "resolution": [4, 4]}},
      "cloth": {"source": "static"}, "fabric": {"diffusivity": 1e-4, "viscosity": 1e-5},
      "drops": [{"vertex": 12, "radius": 0.01, "mass": 5e-5}], )";
  struct Expected {
    const char* name;
    double density, soluteFraction, wicking, viscosity;
    Eigen::Array3d absorbance;
  };
  // ε = 2 ln10 A(1 cm) / (0.01 m · ρ · f); wicking (γ/γ_w)(μ_w/μ); viscosity (μ/ρ)/(μ_w/ρ_w).
  const double ln10 = std::log(10.0);
  const Expected expected[] = {
      {"water", 998.2, 0.0, 1.0, 1.0, {0, 0, 0}},
      {"wine", 994.0, 0.025, (0.046 / 0.07275) * (1.002 / 1.6), (1.6 / 994.0) / (1.002 / 998.2),
       Eigen::Array3d(1.2, 5.0, 3.5) * 2 * ln10 / (0.01 * 994.0 * 0.025)},
      {"coffee", 1003.0, 0.0125, (0.065 / 0.07275) * (1.002 / 1.03), (1.03 / 1003.0) / (1.002 / 998.2),
       Eigen::Array3d(1.0, 1.8, 3.1) * 2 * ln10 / (0.01 * 1003.0 * 0.0125)},
      {"ink", 1010.0, 0.03, (0.045 / 0.07275) * (1.002 / 1.2), (1.2 / 1010.0) / (1.002 / 998.2),
       Eigen::Array3d(11.0, 7.8, 2.3) * 2 * ln10 / (0.01 * 1010.0 * 0.03)},
  };
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.name);
    for (const std::string& liquid : {std::string("\"") + e.name + "\"", std::string(R"({"preset": ")") + e.name + "\"}"}) {
      const SceneDef scene = parseScene(base + R"("liquid": )" + liquid + "}", "liquid.json");
      const EngineDef& def = scene.engine;
      EXPECT_DOUBLE_EQ(def.stain.liquid.liquidDensity, e.density);
      EXPECT_DOUBLE_EQ(def.stain.liquid.evaporationRate, 4.2e-5);
      EXPECT_DOUBLE_EQ(def.stain.liquid.molecularDiffusivity, liquidPresetFromName(e.name).molecularDiffusivity);
      EXPECT_TRUE(def.stain.switches.soluteWithSolvent);  // the film model, the default
      ASSERT_EQ(def.drops.size(), 1u);
      EXPECT_NEAR(def.drops[0].drop.soluteMass, e.soluteFraction * 5e-5, 1e-20);
      EXPECT_NEAR(def.drops[0].drop.solventMass + def.drops[0].drop.soluteMass, 5e-5, 1e-20);
      EXPECT_NEAR(def.diffusivity, 1e-4 * e.wicking, 1e-18);
      EXPECT_NEAR(def.viscosity, 1e-5 * e.viscosity, 1e-18);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(def.colors.soluteAbsorbance[c], e.absorbance[c], 1e-9 * (1 + e.absorbance[c]));
    }
  }
  // Wine's measured hue: green absorbed most, then blue, red least.
  const Eigen::Array3d wine = liquidSoluteAbsorbance(liquidPresetFromName("wine"));
  EXPECT_GT(wine[1], wine[2]);
  EXPECT_GT(wine[2], wine[0]);
  // A pipette drop of wine (0.05 ml spread over 1.5 cm) leaves a visible stain:
  // σ_solute = 0.025 · 0.05 g / (π 7.5 mm²); green dims to about half.
  const double solute = 0.025 * 5e-5 / (M_PI * 0.0075 * 0.0075);
  StainColorMapping mapping;
  mapping.soluteAbsorbance = wine;
  const Eigen::Array3d c = stainColor(mapping, 0, solute, 0, 0);
  EXPECT_GT(c[1] / kDefaultClothColor[1], 0.4);
  EXPECT_LT(c[1] / kDefaultClothColor[1], 0.65);
}

TEST(Scene, ExplicitKeysOverrideTheLiquidPreset) {
  const SceneDef scene = parseScene(R"({"mesh": {"patch": {"size": [0.1, 0.1], "resolution": [4, 4]}},
      "cloth": {"source": "static"}, "fabric": {"diffusivity": 1e-4, "viscosity": 1e-5,
        "patches": [{"tensor": [[2e-4, 0], [0, 1e-4]]}]},
      "liquid": {"preset": "coffee", "evaporation_rate": 0.02, "liquid_density": 1100, "solute_fraction": 0.1,
                 "wicking_factor": 2, "molecular_diffusivity": 2e-9},
      "physics": {"solute_with_solvent": false},
      "drops": [{"vertex": 12, "mass": 1e-4}, {"vertex": 3, "solvent_mass": 3e-5, "solute_mass": 2e-5}],
      "display": {"pigment": "ink"}})",
                                    "override.json");
  const EngineDef& def = scene.engine;
  EXPECT_DOUBLE_EQ(def.stain.liquid.evaporationRate, 0.02);
  EXPECT_DOUBLE_EQ(def.stain.liquid.liquidDensity, 1100);
  EXPECT_DOUBLE_EQ(def.stain.liquid.molecularDiffusivity, 2e-9);
  EXPECT_FALSE(def.stain.switches.soluteWithSolvent);  // the film model's, overridden
  EXPECT_TRUE(def.stain.switches.filmFriction);
  EXPECT_NEAR(def.drops[0].drop.soluteMass, 1e-5, 1e-20);
  EXPECT_NEAR(def.drops[0].drop.solventMass, 9e-5, 1e-20);
  EXPECT_DOUBLE_EQ(def.drops[1].drop.soluteMass, 2e-5);
  EXPECT_DOUBLE_EQ(def.drops[1].drop.solventMass, 3e-5);
  // The wicking factor scales the patch tensor; the viscosity keeps coffee's factor.
  ASSERT_EQ(def.fabricPatches.size(), 1u);
  EXPECT_NEAR(def.fabricPatches[0].tensor(0, 0), 4e-4, 1e-18);
  EXPECT_NEAR(def.fabricPatches[0].tensor(1, 1), 2e-4, 1e-18);
  EXPECT_NEAR(def.viscosity, 1e-5 * liquidViscosityFactor(liquidPresetFromName("coffee")), 1e-18);
  EXPECT_TRUE((def.colors.soluteAbsorbance == pigmentAbsorbance(PigmentPreset::Ink)).all());
  // Without display keys naming a pigment, the preset's stays (a cloth colour alone keeps it).
  const SceneDef keeps = parseScene(R"({"mesh": {"patch": {"size": [0.1, 0.1], "resolution": [4, 4]}},
      "cloth": {"source": "static"}, "liquid": "ink", "display": {"cloth_color": [0.5, 0.5, 0.5]}})",
                                    "keeps.json");
  EXPECT_TRUE((keeps.engine.colors.soluteAbsorbance == liquidSoluteAbsorbance(liquidPresetFromName("ink"))).all());
  EXPECT_DOUBLE_EQ(keeps.engine.colors.clothColor[0], 0.5);
  // No liquid key: the defaults of before (no factor on the fabric).
  const SceneDef plain = parseScene(kMinimal, "plain.json");
  EXPECT_DOUBLE_EQ(plain.engine.diffusivity, 0.01);
  EXPECT_DOUBLE_EQ(plain.engine.stain.liquid.liquidDensity, 1000);
}

}  // namespace
}  // namespace blot::engine
