// The bad-input catalogue of docs/reliability.md, the part not covered by
// mesh_io_test and weave_pattern_test: pattern files, stain-solver parameters
// and time steps, drops and held regions, and a replay of the fuzz seed
// corpora. Every case checks that the error names the problem (what was
// expected) and where it is (file and key/row/column, field, vertex).
#include <blot/stain/io/bounded_read.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/geometry/surface_geometry.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "mesh_fixture.h"

namespace blot::stain {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Expects `message` to contain every fragment.
void expectMentions(const std::string& message, std::initializer_list<std::string> fragments) {
  for (const std::string& fragment : fragments)
    EXPECT_NE(message.find(fragment), std::string::npos)
        << "message lacks \"" << fragment << "\": " << message;
}

/// The PatternError message for `json` parsed as "cloth.json"; it must start
/// with the source name.
std::string patternError(const std::string& json) {
  try {
    parseWeavePattern(json, "cloth.json");
  } catch (const PatternError& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind("cloth.json: ", 0), 0u) << message;
    return message;
  } catch (const std::exception& error) {
    ADD_FAILURE() << "non-PatternError for " << json << ": " << error.what();
    return {};
  }
  ADD_FAILURE() << "accepted: " << json;
  return {};
}

// ---------------------------------------------------------------------------
// Pattern files

TEST(BadPattern, NumberTooLargeForADoubleIsAPatternErrorNamingTheToken) {
  // nlohmann reports overflow as out_of_range, not parse_error; it used to
  // escape parseWeavePattern as a foreign exception (found by fuzz_pattern).
  expectMentions(patternError(R"({"tensors": [[[1, 0, 0, 1e999]]]})"),
                 {"not valid JSON", "number overflow", "1e999"});
  expectMentions(patternError(R"({"cells": ["WF"], "pair_coefficients": {"FW": 1e400, "WW": 1, "FF": 1}})"),
                 {"not valid JSON", "1e400"});
}

TEST(BadPattern, NullEntryIsNotANumber) {
  expectMentions(patternError(R"({"tensors": [[[1, 0, 0, 1], [1, null, 0, 1]]]})"),
                 {"\"tensors\" row 1, column 2", "entry 2", "expected a number, got null"});
}

TEST(BadPattern, SemiDefiniteTensorHasAZeroEigenvalue) {
  // Positive diagonal, eigenvalues 0 and 2: the determinant test must catch it.
  expectMentions(patternError(R"({"tensors": [[[2, 0, 0, 2]], [[1, 1, 1, 1]]]})"),
                 {"\"tensors\" row 2, column 1", "not positive definite", "det = 0"});
}

TEST(BadPattern, EmptyTileRowsAndCells) {
  expectMentions(patternError(R"({"tensors": []})"), {"\"tensors\"", "non-empty array"});
  expectMentions(patternError(R"({"tensors": [[]]})"), {"\"tensors\" row 1", "at least one cell"});
  expectMentions(patternError(R"({"cells": [], "pair_coefficients": {"FW": 1}})"),
                 {"\"cells\"", "at least one row"});
  expectMentions(patternError(R"({"cells": [""], "pair_coefficients": {"FW": 1}})"),
                 {"\"cells\" row 1", "at least one cell letter"});
}

TEST(BadPattern, NegativePairCoefficient) {
  expectMentions(patternError(R"({"cells": ["WF"], "pair_coefficients": {"FW": 2, "WW": -1, "FF": 1}})"),
                 {"\"pair_coefficients\" \"WW\"", "expected a positive number", "-1"});
}

TEST(BadPattern, TrailingGarbageNamesLineAndColumn) {
  expectMentions(patternError("{\"tensors\": [[[1, 0, 0, 1]]]}\n  x"),
                 {"not valid JSON", "line 2, column 3"});
}

// Strict and bounded JSON: a key given twice is refused (nlohmann keeps the
// last), nesting past 64 is refused while parsing, and an endless stream is
// refused after the 16 MiB budget.
TEST(BadPattern, DuplicateKeysDeepNestingAndEndlessStreamsAreRefused) {
  expectMentions(patternError(R"({"tensors": [[[1, 0, 0, 1]]], "tensors": [[[2, 0, 0, 2]]]})"),
                 {"cloth.json: tensors: duplicate key"});
  expectMentions(patternError(R"({"name": "a", "cells": ["W"], "name": "b"})"), {"cloth.json: name: duplicate key"});
  const std::string deep = "{\"tensors\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
  const std::string message = patternError(deep);
  expectMentions(message, {"cloth.json: nested deeper than 64 arrays or objects (at tensors[0]"});
  EXPECT_LT(message.size(), 300u);
  try {
    loadWeavePattern("/dev/zero");
    ADD_FAILURE() << "/dev/zero loaded";
  } catch (const PatternError& error) {
    expectMentions(error.what(), {"/dev/zero: pattern file has more than the limit of 16777216 bytes"});
  }
}

TEST(BadPattern, MissingFileNamesThePath) {
  try {
    loadWeavePattern("/nonexistent/dir/cloth.json");
    FAIL() << "a missing pattern file was accepted";
  } catch (const PatternError& error) {
    expectMentions(error.what(), {"/nonexistent/dir/cloth.json", "cannot open"});
  }
}

// ---------------------------------------------------------------------------
// Stain solver: liquid parameters, time steps, positions, drops, held regions

struct SolverFixture {
  TriangleMesh mesh = gridMesh(6, 5, 1.0, 0.8);
  SurfaceTopology topology{mesh.faces, static_cast<int>(mesh.vertexPositions.rows())};
  FabricField fabric = isotropicFabricField(static_cast<int>(mesh.faces.rows()), 1e-3, 1e-3);
};

/// The std::invalid_argument message of building a solver with `def`.
std::string definitionError(const StainSolverDef& def) {
  const SolverFixture f;
  try {
    StainSolver solver(f.topology, f.mesh.vertexPositions, f.fabric, def);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  ADD_FAILURE() << "the solver accepted the definition";
  return {};
}

TEST(BadSolverDefinition, NegativeOrNonFiniteLiquidParametersNameTheField) {
  struct Case {
    const char* field;
    std::function<void(StainSolverDef&)> spoil;
    const char* value;
  };
  const Case cases[] = {
      {"liquid.absorptionRate", [](StainSolverDef& d) { d.liquid.absorptionRate = -0.1; }, "-0.1"},
      {"liquid.saturationDensity", [](StainSolverDef& d) { d.liquid.saturationDensity = 0; }, "got 0"},
      {"liquid.desorptionRate", [](StainSolverDef& d) { d.liquid.desorptionRate = kNaN; }, "nan"},
      {"liquid.adsorptionCapacity", [](StainSolverDef& d) { d.liquid.adsorptionCapacity = -2; }, "-2"},
      {"liquid.evaporationRate", [](StainSolverDef& d) { d.liquid.evaporationRate = kInf; }, "inf"},
      {"liquid.boundaryEvaporationFactor",
       [](StainSolverDef& d) { d.liquid.boundaryEvaporationFactor = -1.2; }, "-1.2"},
      {"liquid.wetThreshold", [](StainSolverDef& d) { d.liquid.wetThreshold = kNaN; }, "nan"},
      {"liquid.liquidDensity", [](StainSolverDef& d) { d.liquid.liquidDensity = -1000; }, "-1000"},
      {"gravity", [](StainSolverDef& d) { d.gravity.y() = kNaN; }, "nan"},
      {"strainTolerance", [](StainSolverDef& d) { d.strainTolerance = 0; }, "got 0"},
  };
  for (const Case& c : cases) {
    StainSolverDef def;
    c.spoil(def);
    const std::string message = definitionError(def);
    expectMentions(message, {std::string("StainSolverDef::") + c.field, "must be", c.value});
  }
  // The defaults and zero rates (a term switched off by its rate) are accepted.
  StainSolverDef zeroRates;
  zeroRates.liquid.absorptionRate = zeroRates.liquid.evaporationRate = 0;
  zeroRates.liquid.desorptionRate = zeroRates.liquid.adsorptionCapacity = 0;
  const SolverFixture f;
  EXPECT_NO_THROW(StainSolver(f.topology, f.mesh.vertexPositions, f.fabric, zeroRates));
}

TEST(BadSolverStep, NonPositiveOrNonFiniteTimeStepIsRefusedAndChangesNothing) {
  const SolverFixture f;
  StainSolver solver(f.topology, f.mesh.vertexPositions, f.fabric, StainSolverDef{});
  DropDef drop;
  drop.centerVertex = 14;
  drop.radius = 0.3;
  solver.addDrop(drop);
  const Vector before = solver.state().solvent;
  for (const double h : {0.0, -0.01, kNaN, kInf}) {
    const StepReport report = solver.step(h, f.mesh.vertexPositions);
    EXPECT_EQ(report.status, StepStatus::InvalidArgument) << "h = " << h;
    EXPECT_EQ(report.stage, Stage::Guard);
    expectMentions(report.message, {"time step must be finite and positive"});
  }
  EXPECT_EQ(solver.stepCount(), 0);
  EXPECT_EQ(solver.time(), 0.0);
  EXPECT_TRUE(solver.state().solvent == before);
  EXPECT_EQ(solver.step(0.01, f.mesh.vertexPositions).status, StepStatus::Ok);
}

TEST(BadSolverStep, NonFiniteOrMissizedPositionsAndNonRotations) {
  const SolverFixture f;
  StainSolver solver(f.topology, f.mesh.vertexPositions, f.fabric, StainSolverDef{});
  const auto vertexCount = std::to_string(f.mesh.vertexPositions.rows());
  RowVectors3 nanPositions = f.mesh.vertexPositions;
  nanPositions(3, 1) = kNaN;
  StepReport report = solver.step(0.01, nanPositions);
  EXPECT_EQ(report.status, StepStatus::InvalidArgument);
  expectMentions(report.message, {"next positions must be " + vertexCount + " finite rows"});
  report = solver.step(0.01, f.mesh.vertexPositions.topRows(4));
  EXPECT_EQ(report.status, StepStatus::InvalidArgument);
  expectMentions(report.message, {vertexCount + " finite rows"});
  Matrix3 shear = Matrix3::Identity();
  shear(0, 1) = 0.1;
  report = solver.stepRigid(0.01, f.mesh.vertexPositions, shear);
  EXPECT_EQ(report.status, StepStatus::InvalidArgument);
  expectMentions(report.message, {"stepRigid", "rotation matrix"});
  EXPECT_THROW(solver.setInitialMotion(f.mesh.vertexPositions.topRows(2), f.mesh.vertexPositions),
               std::invalid_argument);
  EXPECT_EQ(solver.stepCount(), 0);
}

TEST(BadSolverInput, DropsNameTheFieldAndHeldRegionsTheVertex) {
  const SolverFixture f;
  StainSolver solver(f.topology, f.mesh.vertexPositions, f.fabric, StainSolverDef{});
  const auto dropError = [&](const std::function<void(DropDef&)>& spoil) -> std::string {
    DropDef drop;
    drop.centerVertex = 3;
    spoil(drop);
    try {
      solver.addDrop(drop);
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    ADD_FAILURE() << "the drop was accepted";
    return {};
  };
  expectMentions(dropError([](DropDef& d) { d.centerVertex = 999; }),
                 {"DropDef::centerVertex", "999", "out of range"});
  expectMentions(dropError([](DropDef& d) { d.radius = -0.1; }), {"DropDef::radius", "positive"});
  expectMentions(dropError([](DropDef& d) { d.solventMass = kNaN; }), {"DropDef::solventMass", "not finite"});
  expectMentions(dropError([](DropDef& d) { d.soluteMass = -1e-4; }), {"DropDef::soluteMass", "negative"});
  EXPECT_EQ(solver.state().addedSolvent, 0.0);

  HeldRegion region;
  region.vertices = {0, 5, 42};  // the 6 x 5 grid has 7 x 6 = 42 vertices
  try {
    solver.addHeldRegion(region);
    FAIL() << "a held region with vertex 42 of 42 was accepted";
  } catch (const std::invalid_argument& error) {
    expectMentions(error.what(), {"held region", "vertex 42 out of range [0, 41]"});
  }
  region.vertices = {0, 5};
  region.solventDensity = -1;
  try {
    solver.addHeldRegion(region);
    FAIL() << "a negative held density was accepted";
  } catch (const std::invalid_argument& error) {
    expectMentions(error.what(), {"held region", "densities must be finite and >= 0"});
  }
}

// ---------------------------------------------------------------------------
// Fuzz seed corpora (tests/fuzz/corpus): every file, valid or not, must load
// or fail with its loader's own error naming the source; the fuzzers' past
// findings live there, so this replays them in every build, sanitized or not.

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(FuzzCorpus, EveryMeshSeedLoadsOrFailsWithAMeshErrorNamingTheSource) {
  const fs::path root = fs::path(test::testDataPath("")) / ".." / "fuzz" / "corpus";
  int files = 0, loaded = 0;
  for (const char* format : {"obj", "ply", "off"}) {
    const fs::path folder = root / (std::string("mesh_") + format);
    ASSERT_TRUE(fs::is_directory(folder)) << folder;
    for (const auto& entry : fs::directory_iterator(folder)) {
      const std::string source = entry.path().filename().string();
      ++files;
      try {
        parseMesh(fileBytes(entry.path()), format, source);
        ++loaded;
      } catch (const MeshError& error) {
        EXPECT_EQ(std::string(error.what()).rfind(source + ": ", 0), 0u) << error.what();
      } catch (const std::exception& error) {
        ADD_FAILURE() << source << ": non-MeshError " << error.what();
      }
    }
  }
  EXPECT_GE(files, 12);
  EXPECT_GE(loaded, 6) << "the corpora should hold valid seeds too";
}

TEST(FuzzCorpus, EveryPatternSeedParsesOrFailsWithAPatternErrorNamingTheSource) {
  const fs::path folder = fs::path(test::testDataPath("")) / ".." / "fuzz" / "corpus" / "pattern";
  ASSERT_TRUE(fs::is_directory(folder)) << folder;
  int files = 0, parsed = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string source = entry.path().filename().string();
    ++files;
    try {
      parseWeavePattern(fileBytes(entry.path()), source);
      ++parsed;
    } catch (const PatternError& error) {
      EXPECT_EQ(std::string(error.what()).rfind(source + ": ", 0), 0u) << error.what();
    } catch (const std::exception& error) {
      ADD_FAILURE() << source << ": non-PatternError " << error.what();
    }
  }
  EXPECT_GE(files, 4);
  EXPECT_GE(parsed, 2);
}

TEST(BadMesh, ParseMeshNamesTheSourceAndRejectsUnknownFormats) {
  try {
    parseMesh("v 0 0 0\n", "stl", "embedded");
    FAIL() << "format 'stl' was accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {"embedded: ", "unknown mesh format 'stl'"});
  }
  try {
    parseMesh("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n", ".OFF", "embedded");
    FAIL() << "index 5 of 3 vertices was accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {"embedded: ", "face 0 (line 6): vertex index 5 out of range [0, 2]"});
  }
  EXPECT_EQ(parseMesh("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "off", "embedded").faces.rows(), 1);
}

/// The MeshError message of loading tests/data/<relative>; it must start with the path.
std::string meshError(const std::string& relative) {
  const std::string path = test::testDataPath(relative);
  try {
    loadMesh(path);
  } catch (const MeshError& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    return message;
  }
  ADD_FAILURE() << "accepted: " << relative;
  return {};
}

double totalArea(const TriangleMesh& mesh, Eigen::Vector3d* normalSum = nullptr) {
  double area = 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Eigen::Vector3d a = mesh.vertexPositions.row(mesh.faces(f, 0)), b = mesh.vertexPositions.row(mesh.faces(f, 1)),
                          c = mesh.vertexPositions.row(mesh.faces(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    area += 0.5 * n.norm();
    if (normalSum) *normalSum += n;
  }
  return area;
}

// A concave quad is ear-clipped, not fanned into folded triangles (a fan from
// its first corner gives areas 4.5 and 1.5 with opposite normals, 6 in all).
TEST(BadMesh, ConcavePolygonIsTriangulatedInsideItsOutline) {
  const TriangleMesh mesh = loadMesh(test::testDataPath("good/concave_quad.obj"));
  ASSERT_EQ(mesh.faces.rows(), 2);
  Eigen::Vector3d normals = Eigen::Vector3d::Zero();
  EXPECT_NEAR(totalArea(mesh, &normals), 3.0, 1e-14);
  EXPECT_NEAR(normals.z(), 6.0, 1e-14);  // both triangles face +z: no fold
  // The same outline as an OFF with one more concave corner (an L of area 3).
  const TriangleMesh l = parseMesh("OFF\n6 1 0\n0 0 0\n2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n6 0 1 2 3 4 5\n", "off", "L");
  EXPECT_EQ(l.faces.rows(), 4);
  EXPECT_NEAR(totalArea(l), 3.0, 1e-14);
  // A convex polygon keeps the fan it always had.
  const TriangleMesh square = parseMesh("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", "off", "square");
  EXPECT_EQ(square.faces.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(square.faces.row(1), Eigen::RowVector3i(0, 2, 3));
}

TEST(BadMesh, SelfIntersectingPolygonIsRefusedNamingFaceAndLine) {
  expectMentions(meshError("bad/self_intersecting_quad.obj"),
                 {"face 0 (line 6): the polygon of 4 corners intersects itself"});
}

// Strict where the formats are: a property or element declared twice, words
// after an OFF face's corners; coordinates whose squares overflow.
TEST(BadMesh, DuplicatedPropertiesTrailingWordsAndHugeCoordinatesAreRefused) {
  expectMentions(meshError("bad/duplicate_property.ply"), {"bad PLY header (line 7)", "declares property 'y' twice"});
  expectMentions(meshError("bad/trailing_word_face.off"),
                 {"line 6: face 0: unexpected 'oops' after its 3 corners (only a colour of 3 or 4 numbers may follow)"});
  EXPECT_EQ(parseMesh("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n", "off", "colour").faces.rows(), 1);
  expectMentions(meshError("bad/huge_coordinates.off"), {"the bounding box", "squared lengths overflow a double"});
  try {
    parseMesh("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
              "element vertex 1\nproperty float x\nend_header\n",
              "ply", "twice.ply");
    ADD_FAILURE() << "two vertex elements accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {"twice.ply: ", "element 'vertex' declared twice"});
  }
}

// A UTF-8 byte-order mark before the first statement is skipped (it made
// tinyobjloader drop the first vertex line).
TEST(BadMesh, ByteOrderMarkBeforeTheFirstVertexIsSkipped) {
  const TriangleMesh mesh = loadMesh(test::testDataPath("good/bom_triangle.obj"));
  EXPECT_EQ(mesh.vertexPositions.rows(), 3);
  EXPECT_EQ(mesh.faces.rows(), 1);
}

// A named pipe nobody writes to: open() waited for a writer forever (a scene,
// a mesh or a pattern path naming a stray FIFO hung blot). It reads as empty
// at once and is named as what it is.
TEST(BadMesh, ANamedPipeWithoutAWriterIsRefusedAtOnce) {
  const fs::path fifo = fs::temp_directory_path() / "blot_mesh_fifo.obj";
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  try {
    loadMesh(fifo.string());
    ADD_FAILURE() << "accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {fifo.string() + ": file is a named pipe with nothing written to it (no writer)"});
  }
  try {
    loadWeavePattern(fifo.string());
    ADD_FAILURE() << "accepted";
  } catch (const PatternError& error) {
    expectMentions(error.what(), {"pattern file is a named pipe with nothing written to it"});
  }
  fs::remove(fifo);
}

// An endless stream or a file past the 1 GiB budget is refused before it is read.
TEST(BadMesh, EndlessStreamIsRefusedByTheByteBudget) {
  // The budget is read before failing on a stream; /dev/zero would take 1 GiB,
  // so the check on a regular file's size is what runs here (a sparse file).
  const fs::path big = fs::temp_directory_path() / "blot_mesh_budget.obj";
  {
    std::ofstream out(big);
  }
  fs::resize_file(big, (std::uintmax_t(1) << 30) + 1);
  try {
    loadMesh(big.string());
    ADD_FAILURE() << "accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {big.string() + ": file is 1073741825 bytes, more than the limit of 1073741824 bytes"});
  }
  fs::remove(big);
}

/// Peak resident memory of this process so far (bytes).
long long peakResidentBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<long long>(usage.ru_maxrss) * 1024;  // kilobytes on Linux
}

// An .obj that leads to an endless device is refused at the stream budget,
// naming the file and the limit, after holding at most that budget (with the
// buffer's doubling), not the 1 GiB a regular mesh file may have.
TEST(BadMesh, ObjLinkedToDevZeroIsRefusedAtTheStreamBudget) {
  const fs::path link = fs::temp_directory_path() / ("blot_zero_" + std::to_string(::getpid()) + ".obj");
  fs::remove(link);
  fs::create_symlink("/dev/zero", link);
  const long long before = peakResidentBytes();
  try {
    loadMesh(link.string());
    ADD_FAILURE() << "accepted";
  } catch (const MeshError& error) {
    expectMentions(error.what(), {link.string() + ": file has more than the limit of " +
                                  std::to_string(kMeshStreamByteLimit) + " bytes (not a regular file"});
  }
  const long long grown = peakResidentBytes() - before;
  EXPECT_LT(grown, static_cast<long long>(3 * kMeshStreamByteLimit)) << grown << " bytes more at the peak";
  fs::remove(link);
}

}  // namespace
}  // namespace blot::stain
