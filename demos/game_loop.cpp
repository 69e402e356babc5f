// Headless game loop: what embedding Blot in a 60 Hz game looks like.
//
// Loads a scene (default: assets/scenes/two_way_flag.json, a 2.6K-vertex
// two-way Bullet flag pinned at two corners), then runs frames of 1/60 s
// through Engine::step (fixed internal steps behind the accumulator), adding
// drops at random times (exponential gaps, mean --drop-interval s) at random
// points in front of the cloth — each lands where it hits the surface, as a
// thrown glass of wine would (the loop is runGameLoop, game_loop_run.h, which
// tests/bench/game_loop_bench.cpp times as well). Prints p50/p99/max of the
// per-frame step time and how many frames overran the 16.7 ms budget, the
// drops, and the mass budget.
// Deterministic: the same --seed gives the same drops and the same state (the
// final state hash is printed). Timings are wall-clock and vary with the machine.
#include <blot/engine/engine.h>
#include <blot/stain/io/atomic_file.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "game_loop_run.h"

namespace {

struct Options {
  std::string scene = BLOT_DEFAULT_GAME_SCENE;
  blot::demos::GameLoopOptions loop;
  std::string framesCsv;  // per-frame timings, empty: none
};

constexpr const char* kUsage =
    "usage: %s [--scene SCENE.json] [--seconds S] [--rate HZ] [--drop-interval S] [--seed N]\n"
    "          [--frames-csv FILE]\n"
    "  --seconds S        simulated time, in [1e-6, 86400] (default 10)\n"
    "  --rate HZ          frames per second, in [1, 1000] (default 60)\n"
    "  --drop-interval S  mean seconds between drops, in [0.001, 1e6] (default 0.7)\n"
    "  --seed N           the drops' times, points and sizes, an integer in [0, 4294967295] (default 1)\n"
    "  --frames-csv FILE  one row per frame: times, stain stages, rebuilds, drops; threads, wet and band\n"
    "                     vertices, band and reach rings, advection sub-steps of its last step\n";

/// The whole of `text` as a number in [lo, hi], or an error naming the option
/// (atof read "abc" as 0 and 1e12 s overflowed the frame count).
bool number(const char* option, const char* text, double lo, double hi, double& out) {
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(value >= lo && value <= hi)) {
    std::fprintf(stderr, "game_loop: %s %s: expected a number in [%.10g, %.10g]\n", option, text, lo, hi);
    return false;
  }
  out = value;
  return true;
}

/// Options; false with a message (exit 2) on a bad one, true and help set for --help.
bool parse(int argc, char** argv, Options& o, bool& help) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    if (a == "--help" || a == "-h") {
      std::printf(kUsage, argv[0]);
      help = true;
      return true;
    }
    if (a == "--scene" && hasValue) {
      o.scene = argv[++i];
    } else if (a == "--seconds" && hasValue) {
      if (!number("--seconds", argv[++i], 1e-6, 86400, o.loop.seconds)) return false;
    } else if (a == "--rate" && hasValue) {
      if (!number("--rate", argv[++i], 1, 1000, o.loop.frameRate)) return false;
    } else if (a == "--drop-interval" && hasValue) {
      // Bounded below: drops are drawn until the next falls past the frame,
      // so 1e-9 s drew them forever inside the first frame.
      if (!number("--drop-interval", argv[++i], 1e-3, 1e6, o.loop.dropInterval)) return false;
    } else if (a == "--seed" && hasValue) {
      double seed = 0;
      if (!number("--seed", argv[++i], 0, 4294967295.0, seed) || seed != std::floor(seed)) {
        if (seed != std::floor(seed)) std::fprintf(stderr, "game_loop: --seed %s: expected an integer\n", argv[i]);
        return false;
      }
      o.loop.seed = static_cast<unsigned>(seed);
    } else if (a == "--frames-csv" && hasValue) {
      o.framesCsv = argv[++i];
      if (o.framesCsv.empty()) {
        std::fprintf(stderr, "game_loop: --frames-csv: expected a file name, got an empty string\n");
        return false;
      }
    } else {
      std::fprintf(stderr, "game_loop: %s: %s\n", a.c_str(),
                   hasValue || a.rfind("--", 0) != 0 ? "unknown option" : "needs a value");
      std::fprintf(stderr, kUsage, argv[0]);
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  bool help = false;
  if (!parse(argc, argv, options, help)) return 2;
  if (help) return 0;
  if (options.loop.seconds * options.loop.frameRate < 0.5) {
    std::fprintf(stderr, "game_loop: --seconds %g at --rate %g Hz is less than one frame\n", options.loop.seconds,
                 options.loop.frameRate);
    return 2;
  }
  std::unique_ptr<blot::Engine> engine;
  try {
    engine = blot::Engine::fromSceneFile(options.scene);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "game_loop: %s\n", e.what());
    return 1;
  }
  // One row per frame for --frames-csv: what the frame's internal steps spent
  // and did, from the engine's running totals.
  std::ostringstream csv;
  csv << "frame,step_ms,cloth_ms,stain_ms,coupling_ms";
  for (int k = static_cast<int>(blot::stain::kFirstStainStage); k <= static_cast<int>(blot::stain::kLastStainStage); ++k)
    csv << "," << blot::stain::stageName(static_cast<blot::stain::Stage>(k)) << "_ms";
  csv << ",internal_steps,metric_rebuilds,drops,threads,wet_vertices,band_vertices,band_rings,reach_rings,"
         "advection_substeps\n";
  csv.precision(6);
  blot::engine::PhaseTotals before = engine->statistics().totals;
  std::int64_t stepsBefore = engine->statistics().steps;
  int rebuildsBefore = engine->statistics().intrinsicRefreshes;
  blot::demos::GameLoopObserver writeRow;
  if (!options.framesCsv.empty()) {
    writeRow = [&](int frame, const blot::Engine& e, const blot::demos::GameLoopFrame& record) {
      const blot::engine::EngineStatistics stats = e.statistics();
      const blot::engine::PhaseTotals& after = stats.totals;
      csv << frame << "," << record.stepMs << "," << record.clothMs << "," << record.stainMs << ","
          << record.couplingMs;
      for (int k = static_cast<int>(blot::stain::kFirstStainStage); k <= static_cast<int>(blot::stain::kLastStainStage);
           ++k)
        csv << "," << after.stageMilliseconds[static_cast<size_t>(k)] - before.stageMilliseconds[static_cast<size_t>(k)];
      csv << "," << stats.steps - stepsBefore << "," << stats.intrinsicRefreshes - rebuildsBefore << "," << record.drops
          << "," << stats.lastProfile.threads << "," << stats.lastProfile.wetVertices << ","
          << stats.lastProfile.bandVertices << "," << stats.lastProfile.bandRings << ","
          << stats.lastProfile.reachRings << "," << stats.lastProfile.advectionSubsteps << "\n";
      before = after;
      stepsBefore = stats.steps;
      rebuildsBefore = stats.intrinsicRefreshes;
    };
  }
  const blot::demos::GameLoopRun run = blot::demos::runGameLoop(*engine, options.loop, writeRow);
  if (run.failedFrame >= 0) {
    std::fprintf(stderr, "game_loop: frame %d: stage '%s': %s\n", run.failedFrame, run.failure.stageName(),
                 run.failure.message.c_str());
    return 3;
  }
  std::vector<double> stepMs, clothMs, stainMs;  // per frame; stain + coupling in the last
  for (const blot::demos::GameLoopFrame& f : run.frames) {
    stepMs.push_back(f.stepMs);
    clothMs.push_back(f.clothMs);
    stainMs.push_back(f.stainMs + f.couplingMs);
  }
  if (!options.framesCsv.empty()) {
    const std::string text = csv.str();
    try {
      blot::stain::writeFileAtomically(options.framesCsv, text.data(), text.size());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "game_loop: %s\n", e.what());
      return 1;
    }
  }
  using blot::demos::percentile;
  const blot::engine::EngineStatistics s = engine->statistics();
  const double budget = 1000.0 / options.loop.frameRate;
  const long over = std::count_if(stepMs.begin(), stepMs.end(), [budget](double ms) { return ms > budget; });
  std::printf("game_loop: %s, %d vertices, %d frames at %.0f Hz (%.2f s), %lld internal steps of %.4f s\n",
              options.scene.c_str(), engine->vertexCount(), static_cast<int>(run.frames.size()), options.loop.frameRate,
              engine->time(), static_cast<long long>(s.steps), engine->timeStep());
  std::printf("drops added: %d (seed %u)\n", run.drops, options.loop.seed);
  std::printf("step time per frame (ms): p50 %.3f  p99 %.3f  max %.3f  (budget %.1f ms, %ld frames over)\n",
              percentile(stepMs, 0.5), percentile(stepMs, 0.99), percentile(stepMs, 1.0), budget, over);
  std::printf("per frame (ms): cloth p50 %.3f  p99 %.3f;  stain + coupling p50 %.3f  p99 %.3f\n",
              percentile(clothMs, 0.5), percentile(clothMs, 0.99), percentile(stainMs, 0.5), percentile(stainMs, 0.99));
  const double n = s.steps > 0 ? static_cast<double>(s.steps) : 1.0;
  std::printf("mean per internal step (ms): cloth %.3f  stain %.3f  coupling %.3f  total %.3f\n", s.totals.cloth / n,
              s.totals.stain / n, s.totals.coupling / n, s.totals.total / n);
  std::printf("mass budget relative error: solvent %.2e  solute %.2e\n", s.massBudget.solventError(),
              s.massBudget.soluteError());
  std::printf("state hash %016llx\n", static_cast<unsigned long long>(engine->stateHash()));
  return 0;
}
