// The headless 60 Hz game loop (demos/game_loop.cpp), as a function: frames of
// a fixed length through Engine::step, with drops thrown at the cloth at
// random times and points from a seed. Shared by the blot_game_loop demo and
// tests/bench/game_loop_bench.cpp, so that the benchmark times the loop the
// demo runs, frame for frame and drop for drop.
#pragma once

#include <blot/engine/engine.h>

#include <functional>
#include <vector>

namespace blot::demos {

struct GameLoopOptions {
  double seconds = 10.0;      // simulated time
  double frameRate = 60.0;    // frames per second; each frame is one Engine::step(1 / frameRate)
  double dropInterval = 0.7;  // mean seconds between drops (exponential gaps)
  unsigned seed = 1;          // the drops' times, points and sizes
};

/// One frame: wall-clock ms of its Engine::step and the engine's phase totals
/// over it (EngineStatistics::totals), and the drops added before it.
struct GameLoopFrame {
  double stepMs = 0;
  double clothMs = 0;
  double stainMs = 0;
  double couplingMs = 0;
  int drops = 0;
};

struct GameLoopRun {
  std::vector<GameLoopFrame> frames;  // the frames stepped, the failed one last
  int drops = 0;
  int failedFrame = -1;  // the frame whose step did not return Ok, or -1
  stain::StepReport failure;
};

/// Called after each frame's step with the frame's index and record.
using GameLoopObserver = std::function<void(int frame, const Engine& engine, const GameLoopFrame& record)>;

/// Runs options.seconds × options.frameRate frames on `engine`, stopping at
/// the first step that does not return Ok. A drop is a splash of 6.5–26 ml
/// thrown at a point of the cloth's starting bounding box pushed 0.3 m off
/// its thinnest side (it lands on the nearest point of the surface).
/// Deterministic: the same engine state, options and seed give the same drops
/// and the same final state.
GameLoopRun runGameLoop(Engine& engine, const GameLoopOptions& options, const GameLoopObserver& observer = {});

/// The q-quantile (0 ≤ q ≤ 1) of `values` by the nearest rank (0 for none).
double percentile(std::vector<double> values, double q);

}  // namespace blot::demos
