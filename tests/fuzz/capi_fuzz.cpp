// libFuzzer target for C API call sequences (engine/include/blot/blot.h).
//
// Design note: the input is decoded, byte by byte, into an engine definition
// (motion source, coupling, weave preset, patch size, time step, steps per
// call, diffusivity, gravity, pins) and then into up to 48 calls of every
// entry point with arguments drawn from tables of hostile values (0, -1,
// 1e-300, 1e308, NaN, infinities, INT_MAX, off-by-one indices and
// capacities, NULL pointers), including save, load of the saved file, of a
// truncated copy and of a missing path. Values come from tables, not raw
// bytes: a raw double is almost never a boundary, and the tables hold every
// boundary the API documents. Buffers are always as large as the capacity
// passed (a caller that lies about a capacity is outside the contract).
// The oracle: nothing crashes or reports to a sanitizer; every status is one
// of blot.h's codes and never BLOT_ERROR_INTERNAL (which means an exception
// the API did not expect); every failure leaves a non-empty message; a failed
// frame time or load leaves the simulated time unchanged; whatever a successful
// call copies out (positions, normals, colours, densities, velocities,
// statistics, mass budget) is finite, and time never goes backwards except by
// a load. Rejected: raw bytes as doubles (see above) and scene JSON (the
// scene parser has its own target, fuzz_scene).
#include <blot/blot.h>

#include "capi_enum_shim.h"

#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Reads the input a byte at a time; past its end every byte is 0.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool done() const { return offset_ >= size_; }
  unsigned byte() { return offset_ < size_ ? data_[offset_++] : 0u; }
  template <typename T, std::size_t N>
  T pick(const T (&table)[N]) {
    return table[byte() % N];
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t offset_ = 0;
};

const double kAnyDouble[] = {0.0, 1.0, -1.0, 0.5, 1e-300, -1e-300, 1e-6, 1e6, -1e6, 1e7,
                             1e150, 1e308, -1e308, kNaN, kInf, -kInf, 0.01, 2.0, 1e-3, 0.1};
const double kFrameDt[] = {0.0, 0.01, 0.005, 0.02, 1.0 / 60, 0.04, 1.0, 1.0000001, -0.01,
                           1e308, kNaN, kInf, -kInf, 1e-300, 0.1};
const double kTimeStep[] = {0.01, 1.0 / 120, 0.02, 1e-6, 0.0, -0.01, kNaN, kInf, 1e-300, 2.0, 0.5};
const double kCoordinate[] = {0.0, 0.1, -0.1, 0.05, 1.0, 10.0, 1e6, -1e6, 1e7, 1e150, 1e308, -1e308, kNaN, kInf};
const double kMass[] = {0.001, 0.0, 0.01, -0.001, 1e-300, 1.0, 1e6, 1e7, 1e300, kNaN, kInf};
const double kRadius[] = {0.05, 0.02, 0.1, 0.0, -0.05, 1e-300, 1.0, 1e6, 1e300, kNaN, kInf};
const int kSteps[] = {1, 2, 4, 0, -1, INT_MIN};
const int kThreads[] = {1, 0, 2, -1, 1025, INT_MAX, INT_MIN};
const int kAdaptive[] = {0, 1, 2, -1, INT_MAX, INT_MIN};
const char* const kPresets[] = {nullptr, "", "plain", "twill-2-1", "no-such-weave", "plain\n"};

/// Checks one status against blot.h's contract.
void check(blotStatus status) {
  if (status == BLOT_OK) return;
  if (status != BLOT_ERROR_INVALID_ARGUMENT && status != BLOT_ERROR_SCENE && status != BLOT_ERROR_NUMERICAL &&
      status != BLOT_ERROR_IO)
    std::abort();  // INTERNAL, or no code at all
  if (blotGetLastError() == nullptr || blotGetLastError()[0] == '\0') std::abort();
}

bool finite(const float* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}

bool finite(const blotMassBudget& b) {
  for (double v : {b.freeSolvent, b.absorbedSolvent, b.evaporatedSolvent, b.addedSolvent, b.freeSolute,
                   b.absorbedSolute, b.adsorbedSolute, b.addedSolute, b.solventError, b.soluteError})
    if (!std::isfinite(v)) return false;
  return true;
}

std::string scratch(const char* suffix) {
  const char* folder = std::getenv("TMPDIR");
  return std::string(folder != nullptr ? folder : "/tmp") + "/blot_fuzz_capi_" + std::to_string(::getpid()) + suffix;
}

/// The engine of this input, or nullptr when its definition is refused.
blotEngine* create(Bytes& in, std::vector<double>& positions, std::vector<std::int32_t>& faces,
                   std::vector<std::int32_t>& pins) {
  const unsigned shape = in.byte();
  const int n = 1 + static_cast<int>(shape % 3);  // 2 x 2 to 4 x 4 vertices
  positions.clear();
  faces.clear();
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) positions.insert(positions.end(), {0.1 * i, 0.0, 0.1 * j});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      faces.insert(faces.end(), {a, b, d, a, d, c});
    }
  const int vertexCount = (n + 1) * (n + 1);
  if (shape & 0x08) positions[3 * (shape % static_cast<unsigned>(vertexCount))] = in.pick(kCoordinate);
  if (shape & 0x10) faces[shape % faces.size()] = static_cast<std::int32_t>(in.byte()) - 8;

  blotEngineDef def = blotDefaultEngineDef();
  def.positions = (shape & 0x20) && (shape & 0x40) ? nullptr : positions.data();
  def.vertexCount = vertexCount;
  def.faces = faces.data();
  def.faceCount = static_cast<int>(faces.size() / 3);
  const unsigned source = in.byte();
  const int sources[] = {0, 1, 2, 0, 1, 2, 3, -1};  // 3 and -1 are not sources
  blotTestSetMotionSource(&def, sources[source % 8]);
  def.cloth.twoWay = (source >> 7) & 1;
  def.cloth.substeps = (source & 0x08) ? 1 : 2;
  def.cloth.positionIterations = (source & 0x10) ? 1 : 2;
  pins.clear();
  if (source & 0x20) pins = {vertexCount - 1, vertexCount - 1 - n};
  if (source & 0x40) pins.push_back(static_cast<std::int32_t>(in.byte()) - 4);
  def.cloth.pinnedVertices = pins.empty() ? nullptr : pins.data();
  def.cloth.pinnedVertexCount = static_cast<int>(pins.size());
  const unsigned settings = in.byte();
  def.timeStep = (settings & 0x01) ? in.pick(kTimeStep) : 0.01;
  def.maxStepsPerCall = (settings & 0x02) ? in.pick(kSteps) : 2;
  if (settings & 0x04) def.fabric.diffusivity = in.pick(kAnyDouble);
  if (settings & 0x08) def.fabric.viscosity = in.pick(kAnyDouble);
  // (Each byte read in its own statement: the encoding must not depend on the
  // order in which an expression's operands are evaluated.)
  if (settings & 0x10) {
    const unsigned axis = in.byte() % 3;
    def.gravity[axis] = in.pick(kAnyDouble);
  }
  if (settings & 0x20) {
    const unsigned axis = in.byte() % 3;
    def.rigidAngularVelocity[axis] = in.pick(kAnyDouble);
  }
  if (settings & 0x40) {
    def.fabric.weavePreset = in.pick(kPresets);
    if (in.byte() & 1) def.fabric.weft[0] = 0;
  }
  if (settings & 0x80) def.liquid.evaporationRate = in.pick(kAnyDouble);

  blotEngine* engine = nullptr;
  const blotStatus status = blotCreateEngine(&def, &engine);
  check(status);
  if (status != BLOT_OK) {
    if (engine != nullptr) std::abort();  // *outEngine set only on success
    return nullptr;
  }
  if (engine == nullptr || blotEngine_GetVertexCount(engine) != vertexCount) std::abort();
  check(blotEngine_SetThreadCount(engine, 1));
  return engine;
}

blotDropDef drop(Bytes& in) {
  blotDropDef d = blotDefaultDropDef();
  const unsigned which = in.byte();
  if (which & 0x01) d.radius = in.pick(kRadius);
  if (which & 0x02) d.solventMass = in.pick(kMass);
  if (which & 0x04) d.soluteMass = in.pick(kMass);
  if (which & 0x08) {
    const unsigned axis = in.byte() % 3;
    d.velocity[axis] = in.pick(kAnyDouble);
  }
  if (which & 0x10) d.splashSpeed = in.pick(kAnyDouble);
  if (which & 0x20) d.splashSeed = in.byte();
  return d;
}

void copyOut(Bytes& in, blotEngine* engine) {
  const int vertices = blotEngine_GetVertexCount(engine), faces = blotEngine_GetFaceCount(engine);
  const unsigned what = in.byte() % 9;
  const int need = what == 6 || what == 8 ? vertices : what == 7 ? 3 * faces : 3 * vertices;
  const int capacities[] = {need, need, need + 5, need - 1, 0, -1, INT_MIN};
  const int capacity = in.pick(capacities);
  const bool null = in.byte() % 16 == 0;
  std::vector<float> floats(static_cast<std::size_t>(std::max(capacity, 0)) + 1);
  std::vector<std::int32_t> ints(floats.size());
  float* out = null ? nullptr : floats.data();
  blotStatus status = BLOT_OK;
  switch (what) {
    case 0: status = blotEngine_CopyPositions(engine, out, capacity); break;
    case 1: status = blotEngine_CopyNormals(engine, out, capacity); break;
    case 2: status = blotEngine_CopyColors(engine, out, capacity); break;
    case 3: status = blotEngine_CopyLiquidWorldVelocities(engine, out, capacity); break;
    case 4: status = blotEngine_CopyLiquidRelativeVelocities(engine, out, capacity); break;
    case 5: status = blotEngine_CopyNormals(null ? nullptr : engine, out, capacity); break;
    case 6: {
      const int kinds[] = {0, 1, 2, 3, 4, 5, -1};
      status = blotTestCopyDensitiesOfKind(engine, in.pick(kinds), out, capacity);
      break;
    }
    case 7: status = blotEngine_CopyFaces(engine, null ? nullptr : ints.data(), capacity); break;
    case 8: status = blotEngine_CopyFileVertexIndices(engine, null ? nullptr : ints.data(), capacity); break;
  }
  check(status);
  if (status != BLOT_OK) return;
  if (capacity < need) std::abort();  // a too-small buffer was written to
  if (what == 7 || what == 8) {
    for (int k = 0; k < need; ++k)
      if (ints[static_cast<std::size_t>(k)] < 0 || ints[static_cast<std::size_t>(k)] >= vertices) std::abort();
  } else if (!finite(floats.data(), static_cast<std::size_t>(need))) {
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string saved = scratch(".state"), truncated = scratch(".truncated.state");
  Bytes in(data, size);
  std::vector<double> positions;
  std::vector<std::int32_t> faces, pins;
  blotEngine* engine = create(in, positions, faces, pins);
  if (engine == nullptr) {
    // Every entry point refuses a NULL engine.
    check(blotEngine_Step(nullptr, 0.01));
    if (blotEngine_GetVertexCount(nullptr) != 0 || blotEngine_GetTime(nullptr) != 0) std::abort();
    blotDestroyEngine(nullptr);
    return 0;
  }
  bool haveSaved = false;
  for (int call = 0; call < 48 && !in.done(); ++call) {
    const double before = blotEngine_GetTime(engine);
    const unsigned op = in.byte() % 10;
    blotStatus status = BLOT_OK;
    switch (op) {
      case 0:
      case 1:
        status = blotEngine_Step(engine, in.pick(kFrameDt));
        break;
      case 2: {
        const int vertices = blotEngine_GetVertexCount(engine);
        const int choices[] = {0, vertices / 2, vertices - 1, vertices, -1, INT_MAX, INT_MIN};
        const blotDropDef d = drop(in);
        const int vertex = in.pick(choices);
        const bool null = in.byte() % 16 == 0;
        status = blotEngine_AddDropAtVertex(engine, vertex, null ? nullptr : &d);
        break;
      }
      case 3: {
        const double point[3] = {in.pick(kCoordinate), in.pick(kCoordinate), in.pick(kCoordinate)};
        const blotDropDef d = drop(in);
        int face = -2;
        const bool wantFace = in.byte() & 1;
        status = blotEngine_AddDropAtPoint(engine, point, &d, wantFace ? &face : nullptr);
        if (status == BLOT_OK && wantFace && (face < 0 || face >= blotEngine_GetFaceCount(engine))) std::abort();
        break;
      }
      case 4:
        copyOut(in, engine);
        break;
      case 5: {
        blotStatistics stats;
        status = blotEngine_GetStatistics(engine, in.byte() % 16 == 0 ? nullptr : &stats);
        if (status == BLOT_OK && (!std::isfinite(stats.time) || stats.steps < 0 || !finite(stats.massBudget)))
          std::abort();
        blotMassBudget budget;
        check(status);
        status = blotEngine_GetMassBudget(engine, &budget);
        if (status == BLOT_OK && !finite(budget)) std::abort();
        break;
      }
      case 6: {
        status = blotEngine_SetThreadCount(engine, in.pick(kThreads));
        check(status);
        status = blotEngine_SetThreadCount(engine, 1);  // never run the steps on many threads
        check(status);
        // 0 and 1 are the only values; anything else is refused, with a message.
        const int adaptive = in.pick(kAdaptive);
        status = blotEngine_SetAdaptiveThreads(engine, adaptive);
        if ((status == BLOT_OK) != (adaptive == 0 || adaptive == 1)) std::abort();
        break;
      }
      case 7:
        status = blotEngine_Save(engine, in.byte() % 8 == 0 ? "/nonexistent-folder/x.state" : saved.c_str());
        haveSaved = haveSaved || (status == BLOT_OK);
        break;
      case 8: {
        const unsigned which = in.byte() % 4;
        const char* path = saved.c_str();
        if (which == 1) path = "/nonexistent-folder/x.state";
        if (which == 2) path = "/dev/zero";
        if (which == 3 && haveSaved) {
          std::ifstream from(saved, std::ios::binary);
          const std::string bytes((std::istreambuf_iterator<char>(from)), std::istreambuf_iterator<char>());
          std::ofstream(truncated, std::ios::binary | std::ios::trunc)
              .write(bytes.data(), static_cast<std::streamsize>(bytes.size() * in.byte() / 256));
          path = truncated.c_str();
        }
        if (!haveSaved && which != 2) path = "/nonexistent-folder/x.state";
        status = blotEngine_Load(engine, path);
        if (status != BLOT_OK && blotEngine_GetTime(engine) != before) std::abort();  // unchanged on failure
        check(status);
        continue;  // a load may move time backwards
      }
      case 9: {
        const double t = blotEngine_GetTime(engine);
        if (!std::isfinite(t) || t < 0) std::abort();
        if (blotEngine_GetFaceCount(engine) < 1) std::abort();
        break;
      }
    }
    check(status);
    const double after = blotEngine_GetTime(engine);
    if (!std::isfinite(after) || after < before) std::abort();
    // A refused frame time runs no step (a numerical fault may follow good steps).
    if ((op == 0 || op == 1) && status == BLOT_ERROR_INVALID_ARGUMENT && after != before) std::abort();
  }
  blotDestroyEngine(engine);
  std::remove(saved.c_str());
  std::remove(truncated.c_str());
  return 0;
}
