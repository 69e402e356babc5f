// libFuzzer target for state files and checkpoints (Engine::load, which
// blotEngine_Load and `blot run --resume` call after their own checks).
//
// Design note: an input is one byte choosing the engine (state_fuzz_engines.h:
// static, rigid, two-way Bullet, each a 3 x 3 vertex patch) and the bytes of
// a state file, written to a scratch file and loaded. Engine::load reads a
// path, so the bytes go through a file (tmpfs or the page cache: microseconds)
// rather than a second, in-memory entry point that the shipped code would not
// use. The seeds are real saved states (the corpus test StateFuzzCorpus in
// tests/engine/engine_test.cpp checks they still load and rewrites them with
// BLOT_UPDATE_FUZZ_SEEDS=1 when the format changes), so mutations reach every
// block of the format: header, pending drops, cloth nodes, coupling, the stain
// snapshot with its sparse matrices, the run counters.
// The oracle is load()'s contract: either the state loads, or a StateFileError
// whose message starts with the path, and the engine is unchanged (same
// stateHash, same step count). A state that loads must be usable as it
// stands: it saves and loads again to the same hash, and one more step either
// succeeds with finite positions and densities or reports a numerical fault
// (a state can be consistent and still blow up: that is the step's checks'
// business, not a crash). Any other exception, a crash or a sanitizer report
// is a finding.
#include "state_fuzz_engines.h"

#include <blot/stain/content_hash.h>

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>

namespace {

using blot::engine::Engine;
using blot::engine::StateFileError;

struct Fixture {
  std::unique_ptr<Engine> engines[blot::engine::fuzz::kStateFuzzEngineCount];
  std::string input, resaved;
};

Fixture& fixture() {
  static Fixture* f = [] {
    auto* made = new Fixture;
    for (int k = 0; k < blot::engine::fuzz::kStateFuzzEngineCount; ++k) {
      made->engines[k] = std::make_unique<Engine>(blot::engine::fuzz::stateFuzzEngineDef(k));
      made->engines[k]->setThreadCount(1);
    }
    const std::string folder = std::getenv("TMPDIR") != nullptr ? std::getenv("TMPDIR") : "/tmp";
    const std::string stem = folder + "/blot_fuzz_state_" + std::to_string(::getpid());
    made->input = stem + ".state";
    made->resaved = stem + ".resaved.state";
    std::atexit([] {
      std::remove(fixture().input.c_str());
      std::remove(fixture().resaved.c_str());
    });
    return made;
  }();
  return *f;
}

bool finiteView(const Engine& e) {
  return e.positions().allFinite() && e.solvent().allFinite() && e.solute().allFinite() &&
         e.absorbedSolvent().allFinite() && e.absorbedSolute().allFinite() && e.adsorbedSolute().allFinite();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  Fixture& f = fixture();
  Engine& engine = *f.engines[data[0] % blot::engine::fuzz::kStateFuzzEngineCount];
  // The file ends with a checksum of the bytes before it (Engine::save). A
  // mutation would almost always stop there, so unless the choice byte's
  // high bit is set the checksum is recomputed and the fields' own checks
  // meet the mutation.
  std::string file(reinterpret_cast<const char*>(data + 1), size - 1);
  std::uint64_t checksum = blot::stain::kContentHashBasis;
  if ((data[0] & 0x80) == 0 && file.size() >= sizeof checksum) {
    blot::stain::hashBytes(checksum, file.data(), file.size() - sizeof checksum);
    std::memcpy(&file[file.size() - sizeof checksum], &checksum, sizeof checksum);
  }
  {
    std::ofstream out(f.input, std::ios::binary | std::ios::trunc);
    out.write(file.data(), static_cast<std::streamsize>(file.size()));
    if (!out) std::abort();  // the scratch file, not the input
  }
  const std::uint64_t hashBefore = engine.stateHash();
  const std::int64_t stepsBefore = engine.stepCount();
  try {
    engine.load(f.input);
  } catch (const StateFileError& error) {
    if (std::string(error.what()).rfind(f.input + ": ", 0) != 0) std::abort();
    if (engine.stateHash() != hashBefore || engine.stepCount() != stepsBefore) std::abort();
    return 0;
  }
  // Loaded: the state is what a save of it holds.
  const std::uint64_t loaded = engine.stateHash();
  if (!finiteView(engine)) std::abort();
  engine.save(f.resaved);
  engine.load(f.resaved);  // a StateFileError here escapes: a finding
  if (engine.stateHash() != loaded) std::abort();
  const blot::stain::StepReport report = engine.step(engine.timeStep());
  if (report.ok() && !finiteView(engine)) std::abort();
  return 0;
}
