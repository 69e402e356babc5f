// The C API (blot.h): statuses and messages for bad input, copies that match
// the C++ views, and save/load through the handle.
#include <blot/blot.h>
#include <blot/engine/engine.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "../fuzz/capi_enum_shim.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace {

const char* const kScene = R"({"mesh": {"patch": {"size": [0.5, 0.5], "resolution": [10, 10]}},
                               "cloth": {"source": "rigid", "angular_velocity": [0, 0, 1]}, "time_step": 0.01})";

TEST(CApiTest, BadSceneIsASceneErrorNamingTheKey) {
  blotEngine* engine = nullptr;
  EXPECT_EQ(blotCreateEngineFromSceneJson(R"({"mesh": {"patch": {}}, "cloth": {"source": "rigid", "spin": 1}})", nullptr,
                                          &engine),
            BLOT_ERROR_SCENE);
  EXPECT_EQ(engine, nullptr);
  EXPECT_NE(std::string(blotGetLastError()).find("cloth.spin"), std::string::npos) << blotGetLastError();
  // A file that cannot be opened is an I/O error, not a rejected scene.
  EXPECT_EQ(blotCreateEngineFromSceneFile("/nonexistent.json", &engine), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find("/nonexistent.json: cannot open"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotCreateEngineFromSceneFile(nullptr, &engine), BLOT_ERROR_INVALID_ARGUMENT);
  // So is a directory, which opens as a stream on Linux (it was a rejected scene).
  const std::string folder = std::filesystem::temp_directory_path().string();
  EXPECT_EQ(blotCreateEngineFromSceneFile(folder.c_str(), &engine), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find(folder + ": cannot open (a directory, not a file)"),
            std::string::npos)
      << blotGetLastError();
  EXPECT_EQ(engine, nullptr);
  // A named pipe nobody writes to: refused at once (opening it as a stream
  // waited for a writer forever).
  const std::string fifo = (std::filesystem::temp_directory_path() / "blot_c_api_test_fifo.json").string();
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_NE(blotCreateEngineFromSceneFile(fifo.c_str(), &engine), BLOT_OK);
  EXPECT_NE(std::string(blotGetLastError()).find("named pipe with nothing written to it"), std::string::npos)
      << blotGetLastError();
  EXPECT_EQ(engine, nullptr);
  std::filesystem::remove(fifo);
}

TEST(CApiTest, CopiesMatchTheEngineAndBadArgumentsAreStatuses) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  const int n = blotEngine_GetVertexCount(engine);
  ASSERT_EQ(n, 121);
  EXPECT_EQ(blotEngine_GetFaceCount(engine), 200);
  blotDropDef drop = blotDefaultDropDef();
  drop.solventMass = 0.004;
  drop.soluteMass = 0.002;
  drop.radius = 0.1;
  EXPECT_EQ(blotEngine_AddDropAtVertex(engine, 60, &drop), BLOT_OK);
  EXPECT_EQ(blotEngine_AddDropAtVertex(engine, 121, &drop), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("centerVertex"), std::string::npos) << blotGetLastError();
  drop.radius = -1;
  EXPECT_EQ(blotEngine_AddDropAtVertex(engine, 3, &drop), BLOT_ERROR_INVALID_ARGUMENT);
  for (int k = 0; k < 10; ++k) ASSERT_EQ(blotEngine_Step(engine, 1.0 / 60.0), BLOT_OK);
  EXPECT_EQ(blotEngine_Step(engine, -1.0), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NEAR(blotEngine_GetTime(engine), 0.16, 1e-12);  // 10/60 s of frames = 16 whole steps of 0.01 s

  std::vector<float> solute(static_cast<size_t>(n)), positions(static_cast<size_t>(3 * n));
  ASSERT_EQ(blotEngine_CopyDensities(engine, BLOT_DENSITY_SOLUTE, solute.data(), n), BLOT_OK);
  ASSERT_EQ(blotEngine_CopyPositions(engine, positions.data(), 3 * n), BLOT_OK);
  double mass = 0;
  for (float s : solute) mass += s;
  EXPECT_GT(mass, 0.0);
  EXPECT_EQ(blotEngine_CopyDensities(engine, BLOT_DENSITY_SOLUTE, solute.data(), n - 1), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(blotEngine_CopyPositions(engine, nullptr, 3 * n), BLOT_ERROR_INVALID_ARGUMENT);
  std::vector<int32_t> faces(600);
  EXPECT_EQ(blotEngine_CopyFaces(engine, faces.data(), 600), BLOT_OK);
  EXPECT_GE(*std::min_element(faces.begin(), faces.end()), 0);
  EXPECT_LT(*std::max_element(faces.begin(), faces.end()), n);

  // Save, step, load, step again: the same colours bit for bit.
  const std::string path = (std::filesystem::temp_directory_path() / "blot_c_api_test.state").string();
  ASSERT_EQ(blotEngine_Save(engine, path.c_str()), BLOT_OK) << blotGetLastError();
  std::vector<float> first(static_cast<size_t>(3 * n)), second(static_cast<size_t>(3 * n));
  for (int k = 0; k < 5; ++k) blotEngine_Step(engine, 0.02);
  blotEngine_CopyColors(engine, first.data(), 3 * n);
  ASSERT_EQ(blotEngine_Load(engine, path.c_str()), BLOT_OK) << blotGetLastError();
  for (int k = 0; k < 5; ++k) blotEngine_Step(engine, 0.02);
  blotEngine_CopyColors(engine, second.data(), 3 * n);
  EXPECT_EQ(first, second);
  EXPECT_EQ(blotEngine_Load(engine, "/nonexistent.state"), BLOT_ERROR_IO);
  std::remove(path.c_str());
  blotDestroyEngine(engine);
  blotDestroyEngine(nullptr);
}

TEST(CApiTest, FileVertexIndicesMapARenumberedMeshBackToItsFile) {
  const std::string scene = R"({"mesh": {"patch": {"size": [1, 1], "resolution": [10, 10]}ORDER},
                                "cloth": {"source": "static"}})";
  const auto create = [&](const std::string& order) {
    std::string json = scene;
    json.replace(json.find("ORDER"), 5, order);
    blotEngine* engine = nullptr;
    EXPECT_EQ(blotCreateEngineFromSceneJson(json.c_str(), nullptr, &engine), BLOT_OK) << blotGetLastError();
    return engine;
  };
  blotEngine* file = create("");
  blotEngine* renumbered = create(R"(, "vertex_order": "locality")");
  const int n = blotEngine_GetVertexCount(renumbered);
  ASSERT_EQ(n, 121);
  std::vector<int32_t> identity(static_cast<size_t>(n)), fileIndex(static_cast<size_t>(n));
  ASSERT_EQ(blotEngine_CopyFileVertexIndices(file, identity.data(), n), BLOT_OK);
  for (int k = 0; k < n; ++k) EXPECT_EQ(identity[size_t(k)], k);
  ASSERT_EQ(blotEngine_CopyFileVertexIndices(renumbered, fileIndex.data(), n), BLOT_OK);
  std::vector<float> a(static_cast<size_t>(3 * n)), b(static_cast<size_t>(3 * n));
  ASSERT_EQ(blotEngine_CopyPositions(file, a.data(), 3 * n), BLOT_OK);
  ASSERT_EQ(blotEngine_CopyPositions(renumbered, b.data(), 3 * n), BLOT_OK);
  int moved = 0;
  std::vector<int32_t> sorted = fileIndex;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, identity);  // a permutation
  for (int k = 0; k < n; ++k) {
    moved += fileIndex[size_t(k)] != k;
    for (int c = 0; c < 3; ++c) EXPECT_EQ(b[size_t(3 * k + c)], a[size_t(3 * fileIndex[size_t(k)] + c)]) << k;
  }
  EXPECT_GT(moved, n / 2);
  EXPECT_EQ(blotEngine_CopyFileVertexIndices(renumbered, fileIndex.data(), n - 1), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("capacity 120, need 121"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotEngine_CopyFileVertexIndices(nullptr, fileIndex.data(), n), BLOT_ERROR_INVALID_ARGUMENT);
  blotDestroyEngine(file);
  blotDestroyEngine(renumbered);
}

// Every finite gravity is accepted, so a liquid's speed can pass float's
// range (1e45 m/s^2 for 0.01 s: 1e43 m/s) while the engine's doubles stay
// finite. Found by fuzz_capi in CI (docs/reliability.md, finding 9): the copy
// wrote infinities. It is refused, names the entry, and writes nothing; a
// copy whose values fit still works.
TEST(CApiTest, ACopyBeyondFloatRangeIsRefusedAndWritesNothing) {
  std::vector<double> positions;
  std::vector<int32_t> faces;
  for (int j = 0; j <= 3; ++j)
    for (int i = 0; i <= 3; ++i) positions.insert(positions.end(), {0.1 * i, 0.0, 0.1 * j});
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const int a = j * 4 + i, b = a + 1, c = a + 4, d = c + 1;
      faces.insert(faces.end(), {a, b, d, a, d, c});
    }
  blotEngineDef def = blotDefaultEngineDef();
  def.positions = positions.data();
  def.vertexCount = 16;
  def.faces = faces.data();
  def.faceCount = 18;
  def.source = BLOT_MOTION_STATIC;
  // The paper's equations: no friction or viscosity that would hold the
  // liquid below float's range under this gravity (1e45 m/s² × 0.01 s).
  def.model = BLOT_PHYSICS_PAPER;
  def.gravity[0] = 1e45;
  def.gravity[1] = def.gravity[2] = 0.0;
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngine(&def, &engine), BLOT_OK) << blotGetLastError();
  const blotDropDef drop = blotDefaultDropDef();
  ASSERT_EQ(blotEngine_AddDropAtVertex(engine, 5, &drop), BLOT_OK) << blotGetLastError();
  ASSERT_EQ(blotEngine_Step(engine, 0.01), BLOT_OK) << blotGetLastError();
  std::vector<float> out(48, 7.0f);
  for (const auto copy : {blotEngine_CopyLiquidRelativeVelocities, blotEngine_CopyLiquidWorldVelocities}) {
    EXPECT_EQ(copy(engine, out.data(), 48), BLOT_ERROR_NUMERICAL);
    const std::string message = blotGetLastError();
    EXPECT_NE(message.find("blotEngine_CopyLiquid"), std::string::npos) << message;
    EXPECT_NE(message.find("beyond float range (|value| <= 3.4028235e+38); nothing copied"), std::string::npos)
        << message;
    // "...: vertex <i> <axis> is <value>, beyond...": the value is the
    // engine's, finite in double and past float's range.
    const std::size_t is = message.find(" is ");
    ASSERT_NE(message.find(": vertex "), std::string::npos) << message;
    ASSERT_NE(is, std::string::npos) << message;
    const double value = std::strtod(message.c_str() + is + 4, nullptr);
    EXPECT_TRUE(std::isfinite(value)) << message;
    EXPECT_GT(std::fabs(value), 3.4028235e38) << message;
    EXPECT_EQ(std::count(out.begin(), out.end(), 7.0f), 48);
  }
  EXPECT_EQ(blotEngine_CopyPositions(engine, out.data(), 48), BLOT_OK);
  EXPECT_EQ(out[3], 0.1f);
  std::vector<float> densities(16, 7.0f);
  EXPECT_EQ(blotEngine_CopyDensities(engine, BLOT_DENSITY_SOLVENT, densities.data(), 16), BLOT_OK);
  EXPECT_GT(*std::max_element(densities.begin(), densities.end()), 0.0f);
  blotDestroyEngine(engine);
}

// Definitions without files: the same engine as the scene JSON, step for step.
blotEngineDef definitionOf(const blot::Engine& engine, std::vector<double>& positions, std::vector<int32_t>& faces) {
  const blot::stain::TriangleMesh& mesh = engine.definition().mesh;
  positions.clear();
  faces.clear();
  for (Eigen::Index i = 0; i < mesh.vertexPositions.rows(); ++i)
    for (int c = 0; c < 3; ++c) positions.push_back(mesh.vertexPositions(i, c));
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    for (int c = 0; c < 3; ++c) faces.push_back(mesh.faces(f, c));
  blotEngineDef def = blotDefaultEngineDef();
  def.positions = positions.data();
  def.vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  def.faces = faces.data();
  def.faceCount = static_cast<int>(mesh.faces.rows());
  return def;
}

TEST(CApiTest, DefaultDefinitionsAreTheEngineDefaults) {
  const blot::EngineDef e;
  const blot::cloth::ClothDef c;
  const blotEngineDef d = blotDefaultEngineDef();
  EXPECT_EQ(d.source, BLOT_MOTION_STATIC);
  EXPECT_EQ(d.positions, nullptr);
  EXPECT_EQ(d.timeStep, e.timeStep);
  EXPECT_EQ(d.maxStepsPerCall, e.maxStepsPerCall);
  EXPECT_EQ(d.gravity[2], e.stain.gravity.z());
  EXPECT_EQ(d.fabric.diffusivity, e.diffusivity);
  EXPECT_EQ(d.fabric.viscosity, e.viscosity);
  EXPECT_EQ(d.fabric.weavePreset, nullptr);
  EXPECT_EQ(d.liquid.absorptionRate, e.stain.liquid.absorptionRate);
  EXPECT_EQ(d.liquid.evaporationRate, e.stain.liquid.evaporationRate);
  EXPECT_EQ(d.liquid.saturationDensity, e.stain.liquid.saturationDensity);
  EXPECT_EQ(d.cloth.totalMass, c.totalMass);
  EXPECT_EQ(d.cloth.substeps, c.substeps);
  EXPECT_EQ(d.cloth.pinnedVertexCount, 0);
  EXPECT_EQ(d.cloth.twoWay, 0);
  const blotClothDef cloth = blotDefaultClothDef();
  EXPECT_EQ(cloth.bendStiffness, d.cloth.bendStiffness);
  EXPECT_EQ(blotDefaultLiquidDef().desorptionRate, e.stain.liquid.desorptionRate);
  EXPECT_EQ(blotDefaultFabricDef().weft[0], 1.0);
}

TEST(CApiTest, EngineFromDefinitionsStepsLikeTheSameSceneAndReportsItsState) {
  // kScene without absorption, so that free liquid stays to move.
  const char* const scene = R"({"mesh": {"patch": {"size": [0.5, 0.5], "resolution": [10, 10]}},
                               "cloth": {"source": "rigid", "angular_velocity": [0, 0, 1]}, "time_step": 0.01,
                               "liquid": {"absorption_rate": 0}})";
  const auto reference = blot::Engine::fromSceneJson(scene);
  std::vector<double> positions;
  std::vector<int32_t> faces;
  blotEngineDef def = definitionOf(*reference, positions, faces);
  def.source = BLOT_MOTION_RIGID;
  def.rigidAngularVelocity[2] = 1.0;
  def.timeStep = 0.01;
  def.liquid.absorptionRate = 0;
  blotEngine* fromDef = nullptr;
  blotEngine* fromJson = nullptr;
  ASSERT_EQ(blotCreateEngine(&def, &fromDef), BLOT_OK) << blotGetLastError();
  ASSERT_EQ(blotCreateEngineFromSceneJson(scene, nullptr, &fromJson), BLOT_OK) << blotGetLastError();
  const blotDropDef drop = blotDefaultDropDef();
  for (blotEngine* e : {fromDef, fromJson}) {
    ASSERT_EQ(blotEngine_AddDropAtVertex(e, 40, &drop), BLOT_OK);
    for (int frame = 0; frame < 10; ++frame) ASSERT_EQ(blotEngine_Step(e, 0.02), BLOT_OK) << blotGetLastError();
  }
  const int n = blotEngine_GetVertexCount(fromDef);
  ASSERT_EQ(n, 121);
  // Bit-identical results: the definition is the scene, field for field.
  std::vector<float> a(3 * n), b(3 * n);
  for (blotDensity which : {BLOT_DENSITY_SOLVENT, BLOT_DENSITY_ABSORBED_SOLVENT, BLOT_DENSITY_ADSORBED_SOLUTE}) {
    ASSERT_EQ(blotEngine_CopyDensities(fromDef, which, a.data(), n), BLOT_OK);
    ASSERT_EQ(blotEngine_CopyDensities(fromJson, which, b.data(), n), BLOT_OK);
    EXPECT_TRUE(std::equal(a.begin(), a.begin() + n, b.begin())) << "density " << int(which);
  }

  // Statistics and the mass budget: 20 internal steps, liquid conserved to rounding.
  blotStatistics stats;
  blotMassBudget budget;
  ASSERT_EQ(blotEngine_GetStatistics(fromDef, &stats), BLOT_OK);
  ASSERT_EQ(blotEngine_GetMassBudget(fromDef, &budget), BLOT_OK);
  EXPECT_EQ(stats.steps, 20);
  EXPECT_DOUBLE_EQ(stats.time, 0.2);
  EXPECT_EQ(stats.dropsApplied, 1);
  EXPECT_GT(stats.lastStepMilliseconds, 0.0);
  EXPECT_EQ(stats.massBudget.addedSolvent, budget.addedSolvent);
  EXPECT_EQ(stats.massBudget.freeSolvent, budget.freeSolvent);
  EXPECT_DOUBLE_EQ(budget.addedSolvent, drop.solventMass);
  EXPECT_LT(budget.solventError, 1e-12);
  EXPECT_LT(budget.soluteError, 1e-12);

  // World velocity = relative velocity + the cloth's, where there is liquid.
  // The cloth's velocity is the spin omega x p up to the step's finite
  // difference: a chord of the circle, off the tangent by omega h / 2 at most
  // (measured 1.4e-3 m/s at |omega x p| = 0.28 m/s); bound omega h |omega x p|, plus 1e-5 for the float copies.
  std::vector<float> world(3 * n), relative(3 * n), p(3 * n), solvent(n);
  ASSERT_EQ(blotEngine_CopyLiquidWorldVelocities(fromDef, world.data(), 3 * n), BLOT_OK);
  ASSERT_EQ(blotEngine_CopyLiquidRelativeVelocities(fromDef, relative.data(), 3 * n), BLOT_OK);
  ASSERT_EQ(blotEngine_CopyPositions(fromDef, p.data(), 3 * n), BLOT_OK);
  ASSERT_EQ(blotEngine_CopyDensities(fromDef, BLOT_DENSITY_SOLVENT, solvent.data(), n), BLOT_OK);
  int wet = 0;
  double largestRelative = 0;
  for (int i = 0; i < n; ++i) {
    if (solvent[i] < 1e-6f) continue;
    ++wet;
    const double cloth[3] = {-p[3 * i + 1], p[3 * i + 0], 0.0};  // (0, 0, 1) x p
    const double tolerance = 0.01 * std::hypot(cloth[0], cloth[1]) + 1e-5;  // omega h = 0.01
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(world[3 * i + c] - relative[3 * i + c], cloth[c], tolerance) << "vertex " << i << " axis " << c;
      largestRelative = std::max(largestRelative, std::abs(double(relative[3 * i + c])));
    }
  }
  EXPECT_GT(wet, 5);
  EXPECT_GT(largestRelative, 0.0);  // the spin drives the liquid outward
  EXPECT_EQ(blotEngine_CopyLiquidWorldVelocities(fromDef, world.data(), 3), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(blotEngine_GetStatistics(nullptr, &stats), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(blotEngine_GetMassBudget(fromDef, nullptr), BLOT_ERROR_INVALID_ARGUMENT);
  blotDestroyEngine(fromDef);
  blotDestroyEngine(fromJson);
}

TEST(CApiTest, BadDefinitionsAreInvalidArgumentsNamingTheField) {
  const auto reference = blot::Engine::fromSceneJson(kScene);
  std::vector<double> positions;
  std::vector<int32_t> faces;
  blotEngine* engine = nullptr;

  blotEngineDef def = definitionOf(*reference, positions, faces);
  def.positions = nullptr;
  EXPECT_EQ(blotCreateEngine(&def, &engine), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("positions"), std::string::npos) << blotGetLastError();

  def = definitionOf(*reference, positions, faces);
  def.fabric.weavePreset = "no-such-weave";
  EXPECT_EQ(blotCreateEngine(&def, &engine), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("no-such-weave"), std::string::npos) << blotGetLastError();

  def = definitionOf(*reference, positions, faces);
  def.source = BLOT_MOTION_BULLET;
  const int32_t pins[1] = {5000};
  def.cloth.pinnedVertices = pins;
  def.cloth.pinnedVertexCount = 1;
  EXPECT_EQ(blotCreateEngine(&def, &engine), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("5000"), std::string::npos) << blotGetLastError();

  def = definitionOf(*reference, positions, faces);
  def.timeStep = -1;
  EXPECT_EQ(blotCreateEngine(&def, &engine), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(engine, nullptr);
  EXPECT_EQ(blotCreateEngine(nullptr, &engine), BLOT_ERROR_INVALID_ARGUMENT);

  // A twill flag from definitions, two-way with two pins: builds and steps.
  def = definitionOf(*reference, positions, faces);
  def.source = BLOT_MOTION_BULLET;
  const int32_t corners[2] = {0, 10};
  def.cloth.pinnedVertices = corners;
  def.cloth.pinnedVertexCount = 2;
  def.cloth.twoWay = 1;
  def.fabric.weavePreset = "twill-2-1";
  ASSERT_EQ(blotCreateEngine(&def, &engine), BLOT_OK) << blotGetLastError();
  EXPECT_EQ(blotEngine_Step(engine, 0.05), BLOT_OK) << blotGetLastError();
  blotDestroyEngine(engine);
}

TEST(CApiTest, TheErrorStringLivesUntilTheNextFailure) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneFile("/nonexistent/first.json", &engine), BLOT_ERROR_IO);
  const char* message = blotGetLastError();
  const std::string copy = message;
  // Successful calls leave it alone.
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK);
  ASSERT_EQ(blotEngine_Step(engine, 0.01), BLOT_OK);
  EXPECT_EQ(std::string(blotGetLastError()), copy);
  EXPECT_EQ(std::string(message), copy);
  // Saving into a folder that does not exist is an I/O error too.
  EXPECT_EQ(blotEngine_Save(engine, "/nonexistent/dir/x.state"), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find("/nonexistent/dir/x.state"), std::string::npos) << blotGetLastError();
  blotDestroyEngine(engine);
}

// Frame times the engine cannot use and state files that are not its own
// are statuses, and the engine steps normally afterwards.
TEST(CApiTest, AbsurdFrameTimesAndTamperedStatesAreRefusedAndTheEngineStaysUsable) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  for (const double dt : {1e308, 2.0, std::numeric_limits<double>::infinity(), std::nan("")}) {
    EXPECT_EQ(blotEngine_Step(engine, dt), BLOT_ERROR_INVALID_ARGUMENT) << dt;
    EXPECT_NE(std::string(blotGetLastError()).find("blotEngine_Step: stage 'guard': Engine::step: frameDt must be finite and in [0, 1] s, got"), std::string::npos)
        << blotGetLastError();
  }
  // Just past the limit reads as past it (std::to_string printed 1.000000 for both).
  EXPECT_EQ(blotEngine_Step(engine, 1.0000001), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("in [0, 1] s, got 1.0000001"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotEngine_GetTime(engine), 0.0);
  ASSERT_EQ(blotEngine_Step(engine, 1.0), BLOT_OK) << blotGetLastError();  // the limit itself: 8 steps (the cap)
  EXPECT_NEAR(blotEngine_GetTime(engine), 0.08, 1e-12);
  ASSERT_EQ(blotEngine_Step(engine, 0.02), BLOT_OK);
  EXPECT_NEAR(blotEngine_GetTime(engine), 0.10, 1e-12);

  // A drop point far outside the world (its squared distance would overflow).
  blotDropDef drop = blotDefaultDropDef();
  const double far[3] = {1e200, 0, 0};
  int face = -1;
  EXPECT_EQ(blotEngine_AddDropAtPoint(engine, far, &drop, &face), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("point must be finite and at most 1000000"), std::string::npos)
      << blotGetLastError();
  // A drop of 1e300 kg (as large as a scene may give: 1e6): refused, naming
  // the field and the value; none of it reaches the cloth.
  const double near[3] = {0, 0, 0};
  blotStatistics beforeRefusal;
  ASSERT_EQ(blotEngine_GetStatistics(engine, &beforeRefusal), BLOT_OK);
  for (const bool solute : {false, true}) {
    blotDropDef heavy = blotDefaultDropDef();
    (solute ? heavy.soluteMass : heavy.solventMass) = 1e300;
    EXPECT_EQ(blotEngine_AddDropAtPoint(engine, near, &heavy, nullptr), BLOT_ERROR_INVALID_ARGUMENT);
    const std::string error = blotGetLastError();
    const std::string expected = std::string(solute ? "soluteMass" : "solventMass") + " must be finite and at most 1000000";
    EXPECT_NE(error.find(expected), std::string::npos) << error;
    EXPECT_NE(error.find("got 1e+300"), std::string::npos) << error;  // the value given, in 12 digits (not 301)
  }
  blotStatistics afterRefusal;
  ASSERT_EQ(blotEngine_GetStatistics(engine, &afterRefusal), BLOT_OK);
  EXPECT_EQ(afterRefusal.massBudget.addedSolvent, beforeRefusal.massBudget.addedSolvent);
  EXPECT_EQ(afterRefusal.massBudget.addedSolute, beforeRefusal.massBudget.addedSolute);

  // A state with an edited step count (its checksum no longer matches), and
  // an endless stream: IO errors, the engine unchanged.
  const std::string path = (std::filesystem::temp_directory_path() / "blot_c_api_tampered.state").string();
  ASSERT_EQ(blotEngine_Save(engine, path.c_str()), BLOT_OK) << blotGetLastError();
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::int64_t stepCount = 10;  // the header's step count (offset 48): 8 + 2 internal steps
  ASSERT_EQ(std::memcmp(&bytes[48], &stepCount, 8), 0);
  const std::int64_t negative = -1;
  std::memcpy(&bytes[48], &negative, 8);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  EXPECT_EQ(blotEngine_Load(engine, path.c_str()), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find("checksum mismatch"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotEngine_Load(engine, "/dev/zero"), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find("more than the limit of"), std::string::npos) << blotGetLastError();
  EXPECT_NEAR(blotEngine_GetTime(engine), 0.10, 1e-12);
  EXPECT_EQ(blotEngine_Step(engine, 0.01), BLOT_OK);
  std::remove(path.c_str());
  blotDestroyEngine(engine);
}

// A C game moves a pin at runtime and feeds a surface it simulates itself.
TEST(CApiTest, PinsMoveAtRuntimeAndCallerSurfacesTakeTheirFrames) {
  // A 10 x 10 patch pinned at two corners (Bullet), one of them moved.
  const blot::stain::TriangleMesh mesh = blot::stain::gridMesh(10, 10, 0.5, 0.5);
  std::vector<double> positions(mesh.vertexPositions.size());
  std::vector<int32_t> faces(mesh.faces.size());
  for (Eigen::Index i = 0; i < mesh.vertexPositions.rows(); ++i)
    for (int c = 0; c < 3; ++c) positions[static_cast<size_t>(3 * i + c)] = mesh.vertexPositions(i, c);
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f)
    for (int c = 0; c < 3; ++c) faces[static_cast<size_t>(3 * f + c)] = mesh.faces(f, c);
  const int32_t pins[2] = {0, 10};
  blotEngineDef def = blotDefaultEngineDef();
  def.positions = positions.data();
  def.vertexCount = static_cast<int>(mesh.vertexPositions.rows());
  def.faces = faces.data();
  def.faceCount = static_cast<int>(mesh.faces.rows());
  def.source = BLOT_MOTION_BULLET;
  def.cloth.pinnedVertices = pins;
  def.cloth.pinnedVertexCount = 2;
  def.timeStep = 0.01;
  blotEngine* cloth = nullptr;
  ASSERT_EQ(blotCreateEngine(&def, &cloth), BLOT_OK) << blotGetLastError();
  const double target[3] = {0.1, 0.05, 0.2};
  ASSERT_EQ(blotEngine_SetPinTarget(cloth, 0, target), BLOT_OK) << blotGetLastError();
  ASSERT_EQ(blotEngine_AdvanceSteps(cloth, 1), BLOT_OK) << blotGetLastError();
  std::vector<float> p(positions.size());
  ASSERT_EQ(blotEngine_CopyPositions(cloth, p.data(), static_cast<int>(p.size())), BLOT_OK);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(p[static_cast<size_t>(c)], target[c], 1e-6);
  EXPECT_EQ(blotEngine_SetPinTarget(cloth, 5, target), BLOT_ERROR_INVALID_ARGUMENT);  // not a pin
  EXPECT_NE(std::string(blotGetLastError()).find("vertex 5 is not a pin"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotEngine_AdvanceSteps(cloth, -1), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(blotEngine_SetSurfaceFrame(cloth, positions.data(), nullptr, def.vertexCount), BLOT_ERROR_INVALID_ARGUMENT);
  // A target past a scene's magnitudes is refused; one within them that tears
  // the cloth apart fails the step, reported as blotEngine_Step reports one,
  // and the engine keeps its last good state.
  const double beyond[3] = {1e39, 0.0, 0.5};
  EXPECT_EQ(blotEngine_SetPinTarget(cloth, 0, beyond), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(blotGetLastError()).find("each coordinate within 1e+06 m"), std::string::npos)
      << blotGetLastError();
  const double tearing[3] = {1e6, 0.0, 0.5};
  ASSERT_EQ(blotEngine_SetPinTarget(cloth, 0, tearing), BLOT_OK) << blotGetLastError();
  EXPECT_EQ(blotEngine_AdvanceSteps(cloth, 1), BLOT_ERROR_NUMERICAL);
  EXPECT_EQ(std::string(blotGetLastError()).rfind("blotEngine_AdvanceSteps: stage '", 0), 0u) << blotGetLastError();
  std::vector<float> kept(positions.size());
  EXPECT_EQ(blotEngine_CopyPositions(cloth, kept.data(), static_cast<int>(kept.size())), BLOT_OK);
  EXPECT_TRUE(kept == p);
  ASSERT_EQ(blotEngine_SetPinTarget(cloth, 0, target), BLOT_OK);
  EXPECT_EQ(blotEngine_AdvanceSteps(cloth, 1), BLOT_OK) << blotGetLastError();
  blotDestroyEngine(cloth);

  // The same patch as a caller surface, lifted 1 cm per step.
  def.source = BLOT_MOTION_CALLER;
  blotEngine* caller = nullptr;
  ASSERT_EQ(blotCreateEngine(&def, &caller), BLOT_OK) << blotGetLastError();
  std::vector<double> frame = positions;
  for (int k = 1; k <= 3; ++k) {
    for (size_t i = 2; i < frame.size(); i += 3) frame[i] = positions[i] + 0.01 * k;
    ASSERT_EQ(blotEngine_SetSurfaceFrame(caller, frame.data(), nullptr, def.vertexCount), BLOT_OK) << blotGetLastError();
    ASSERT_EQ(blotEngine_AdvanceSteps(caller, 1), BLOT_OK) << blotGetLastError();
  }
  ASSERT_EQ(blotEngine_CopyPositions(caller, p.data(), static_cast<int>(p.size())), BLOT_OK);
  EXPECT_FLOAT_EQ(p[2], static_cast<float>(frame[2]));
  EXPECT_EQ(blotEngine_SetSurfaceFrame(caller, frame.data(), nullptr, 3), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(blotEngine_SetPinTarget(caller, 0, target), BLOT_ERROR_INVALID_ARGUMENT);
  blotDestroyEngine(caller);
}

}  // namespace

namespace {

// The thread limit of the scene key and `blot run --threads` holds here too:
// 10,000 threads would start 10,000 OpenMP threads at the next step.
TEST(CApiTest, ThreadCountBeyondTheLimitIsAnInvalidArgumentNamingTheRange) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  for (int threads : {1025, 10000, -1}) {
    EXPECT_EQ(blotEngine_SetThreadCount(engine, threads), BLOT_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(std::string(blotGetLastError()),
              "blotEngine_SetThreadCount: StainSolver::setThreadCount: expected a count in [0, 1024], got " +
                  std::to_string(threads));
  }
  EXPECT_EQ(blotEngine_SetThreadCount(engine, 1024), BLOT_OK);
  EXPECT_EQ(blotEngine_SetThreadCount(engine, 1), BLOT_OK);
  EXPECT_EQ(blotEngine_Step(engine, 0.02), BLOT_OK) << blotGetLastError();
  blotDestroyEngine(engine);
}

// Adaptive threads are a switch: 0 or 1, anything else names the values.
TEST(CApiTest, AdaptiveThreadsTakeZeroOrOne) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  EXPECT_EQ(blotEngine_SetAdaptiveThreads(nullptr, 1), BLOT_ERROR_INVALID_ARGUMENT);
  for (int adaptive : {2, -1}) {
    EXPECT_EQ(blotEngine_SetAdaptiveThreads(engine, adaptive), BLOT_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(std::string(blotGetLastError()),
              "blotEngine_SetAdaptiveThreads: expected 0 or 1, got " + std::to_string(adaptive));
  }
  EXPECT_EQ(blotEngine_SetThreadCount(engine, 2), BLOT_OK);
  EXPECT_EQ(blotEngine_SetAdaptiveThreads(engine, 0), BLOT_OK);
  EXPECT_EQ(blotEngine_Step(engine, 0.02), BLOT_OK) << blotGetLastError();
  EXPECT_EQ(blotEngine_SetAdaptiveThreads(engine, 1), BLOT_OK);
  EXPECT_EQ(blotEngine_Step(engine, 0.02), BLOT_OK) << blotGetLastError();
  blotDestroyEngine(engine);
}

// Found by fuzz_capi: C lets any int through an enum parameter, and loading
// (blotDensity)-1 as the enum in C++ was undefined behaviour (UBSan: "load of
// value 4294967295, which is not a valid value for type 'blotDensity'").
TEST(CApiTest, EnumArgumentsOutsideTheEnumeratorsAreInvalidArguments) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  std::vector<float> out(static_cast<std::size_t>(blotEngine_GetVertexCount(engine)));
  for (int kind : {-1, 5, 1 << 30}) {
    // Through a C shim: in C++ the value could not even be passed (capi_enum_shim.h).
    EXPECT_EQ(blotTestCopyDensitiesOfKind(engine, kind, out.data(), static_cast<int>(out.size())),
              BLOT_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(std::string(blotGetLastError()), "blotEngine_CopyDensities: unknown density " + std::to_string(kind));
  }
  std::vector<double> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::vector<int32_t> faces = {0, 1, 2};
  blotEngineDef def = blotDefaultEngineDef();
  def.positions = positions.data();
  def.vertexCount = 3;
  def.faces = faces.data();
  def.faceCount = 1;
  blotTestSetMotionSource(&def, -1);
  blotEngine* refused = nullptr;
  EXPECT_EQ(blotCreateEngine(&def, &refused), BLOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(refused, nullptr);
  EXPECT_EQ(std::string(blotGetLastError()), "blotCreateEngine: source -1: expected a blotMotionSource");
  blotDestroyEngine(engine);
}

}  // namespace

// The fuzz_capi target (tests/fuzz/capi_fuzz.cpp) compiled into this test: its
// seed corpus replays through the fuzzer's oracle (which aborts on a finding)
// in the normal and the sanitized builds.
#include "../fuzz/capi_fuzz.cpp"

namespace {

TEST(CApiFuzzCorpus, EverySeedKeepsTheCApiContract) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(BLOT_TEST_DATA_DIR) / ".." / "fuzz" / "corpus" / "capi";
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  int files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ++files;
    LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  EXPECT_GE(files, 8);
}

}  // namespace
