// The game loop of demos/game_loop.cpp (runGameLoop: the two-way flag of
// assets/scenes/two_way_flag.json, 600 frames at 60 Hz, splashes thrown at it
// from seed 1), run several times, each on a fresh engine, and the frame
// times' spread against the target "in the game loop the frame time's p99 is
// within 1.5× its p50 (no spikes from rebuilds or refactorizations)".
//
// Design note. On a shared machine one run's p99 counts the frames the
// process lost its core (the cloth alone, whose work is the same every frame,
// had p99/p50 1.23–1.56 in single runs of the demo). The loop is
// deterministic, so a frame does the same work in every run (the benchmark
// checks that every run ends in the same state hash), and the least time of a
// frame over the runs is its cost without those interruptions: the spikes
// that remain are the engine's own (the glass landing, a drop, a rebuild).
// Both are reported: the per-frame least over the runs ("frame_*", the
// target's measure of the engine), and each run's own ratio ("single_*",
// what one run on this machine shows), median and largest over the runs.
//  - Arg threads: 1 (the engine's steps on one thread) or 0 (the scene's
//    default: all cores, adaptive; docs/performance.md "Adaptive threads").
// Counters: frame_p50, frame_p99 (ms, of the per-frame least), frame_ratio =
// their quotient; single_ratio_median, single_ratio_max; cloth_ratio and
// cloth_single_ratio_median, the same for the cloth's phase alone;
// stain_over_cloth = (stain + coupling) / cloth over all frames of all runs;
// slowest_frame = the frame whose least time is largest; runs, frames.
// Run: game_loop_bench --benchmark_counters_tabular=true
#include <blot/engine/engine.h>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "game_loop_run.h"

namespace blot::demos {
namespace {

constexpr int kRuns = 5;

void BM_GameLoop(benchmark::State& state) {
  const std::string scene = std::string(BLOT_ASSETS_DIR) + "/scenes/two_way_flag.json";
  const int threads = static_cast<int>(state.range(0));
  const GameLoopOptions options;  // the demo's defaults: 10 s at 60 Hz, a drop every 0.7 s, seed 1
  std::vector<std::vector<GameLoopFrame>> runs;
  std::uint64_t hash = 0;
  for (auto _ : state) {
    std::unique_ptr<Engine> engine = Engine::fromSceneFile(scene);
    if (threads > 0) engine->setThreadCount(threads);
    GameLoopRun run = runGameLoop(*engine, options);
    if (run.failedFrame >= 0) {
      state.SkipWithError(("frame " + std::to_string(run.failedFrame) + ": " + run.failure.message).c_str());
      return;
    }
    double seconds = 0;
    for (const GameLoopFrame& f : run.frames) seconds += 1e-3 * f.stepMs;
    state.SetIterationTime(seconds);
    if (!runs.empty() && engine->stateHash() != hash) {
      state.SkipWithError("the runs ended in different states: the loop is not deterministic, and the "
                          "per-frame least time would compare different work");
      return;
    }
    hash = engine->stateHash();
    runs.push_back(std::move(run.frames));
  }
  const size_t frames = runs.front().size();
  std::vector<double> least(frames), clothLeast(frames);
  double stainSum = 0, clothSum = 0;
  for (size_t f = 0; f < frames; ++f) {
    least[f] = clothLeast[f] = 1e300;
    for (const std::vector<GameLoopFrame>& run : runs) {
      least[f] = std::min(least[f], run[f].stepMs);
      clothLeast[f] = std::min(clothLeast[f], run[f].clothMs);
      stainSum += run[f].stainMs + run[f].couplingMs;
      clothSum += run[f].clothMs;
    }
  }
  const auto ratio = [](const std::vector<double>& times) {
    return percentile(times, 0.99) / percentile(times, 0.5);
  };
  std::vector<double> single, clothSingle;
  for (const std::vector<GameLoopFrame>& run : runs) {
    std::vector<double> step, cloth;
    for (const GameLoopFrame& f : run) {
      step.push_back(f.stepMs);
      cloth.push_back(f.clothMs);
    }
    single.push_back(ratio(step));
    clothSingle.push_back(ratio(cloth));
  }
  // The median of the runs' ratios, the lower middle one for an even count.
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[(v.size() - 1) / 2];
  };
  state.counters["runs"] = static_cast<double>(runs.size());
  state.counters["frames"] = static_cast<double>(frames);
  state.counters["frame_p50"] = percentile(least, 0.5);
  state.counters["frame_p99"] = percentile(least, 0.99);
  state.counters["frame_ratio"] = ratio(least);
  state.counters["single_ratio_median"] = median(single);
  state.counters["single_ratio_max"] = *std::max_element(single.begin(), single.end());
  state.counters["cloth_ratio"] = ratio(clothLeast);
  state.counters["cloth_single_ratio_median"] = median(clothSingle);
  state.counters["stain_over_cloth"] = clothSum > 0 ? stainSum / clothSum : 0;
  state.counters["slowest_frame"] =
      static_cast<double>(std::max_element(least.begin(), least.end()) - least.begin());
  char label[96];
  std::snprintf(label, sizeof label, "two_way_flag.json, state hash %016llx", static_cast<unsigned long long>(hash));
  state.SetLabel(label);
}

BENCHMARK(BM_GameLoop)
    ->ArgNames({"threads"})
    ->Arg(1)
    ->Arg(0)
    ->Iterations(kRuns)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace blot::demos

BENCHMARK_MAIN();
