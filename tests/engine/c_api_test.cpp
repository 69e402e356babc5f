// The C API (blot.h): statuses and messages for bad input, copies that match
// the C++ views, and save/load through the handle.
#include <blot/blot.h>
#include <blot/engine/engine.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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
  EXPECT_EQ(blotCreateEngineFromSceneFile("/nonexistent.json", &engine), BLOT_ERROR_SCENE);
  EXPECT_EQ(blotCreateEngineFromSceneFile(nullptr, &engine), BLOT_ERROR_INVALID_ARGUMENT);
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

// Frame times the engine cannot use and state files that are not its own
// are statuses, and the engine steps normally afterwards.
TEST(CApiTest, AbsurdFrameTimesAndTamperedStatesAreRefusedAndTheEngineStaysUsable) {
  blotEngine* engine = nullptr;
  ASSERT_EQ(blotCreateEngineFromSceneJson(kScene, nullptr, &engine), BLOT_OK) << blotGetLastError();
  for (const double dt : {1e308, 2.0, std::numeric_limits<double>::infinity(), std::nan("")}) {
    EXPECT_EQ(blotEngine_Step(engine, dt), BLOT_ERROR_INVALID_ARGUMENT) << dt;
    EXPECT_NE(std::string(blotGetLastError()).find("frameDt must be finite and in [0, 1"), std::string::npos)
        << blotGetLastError();
  }
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

  // A state with a NaN density, and an endless stream: IO errors, the engine unchanged.
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
  EXPECT_NE(std::string(blotGetLastError()).find("step count -1 is outside"), std::string::npos) << blotGetLastError();
  EXPECT_EQ(blotEngine_Load(engine, "/dev/zero"), BLOT_ERROR_IO);
  EXPECT_NE(std::string(blotGetLastError()).find("more than the limit of"), std::string::npos) << blotGetLastError();
  EXPECT_NEAR(blotEngine_GetTime(engine), 0.10, 1e-12);
  EXPECT_EQ(blotEngine_Step(engine, 0.01), BLOT_OK);
  std::remove(path.c_str());
  blotDestroyEngine(engine);
}

}  // namespace
