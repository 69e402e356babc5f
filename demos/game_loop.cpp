// Headless game loop: what embedding Blot in a 60 Hz game looks like.
//
// Loads a scene (default: assets/scenes/two_way_flag.json, a 2.6K-vertex
// two-way Bullet flag pinned at two corners), then runs frames of 1/60 s
// through Engine::step (fixed internal steps behind the accumulator), adding
// drops at random times (exponential gaps, mean --drop-interval s) at random
// points in front of the cloth — each lands where it hits the surface, as a
// thrown glass of wine would. Prints p50/p99/max of the per-frame step time and
// how many frames overran the 16.7 ms budget, the drops, and the mass budget.
// Deterministic: the same --seed gives the same drops and the same state (the
// final state hash is printed). Timings are wall-clock and vary with the machine.
#include <blot/engine/engine.h>
#include <blot/stain/io/atomic_file.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Options {
  std::string scene = BLOT_DEFAULT_GAME_SCENE;
  double seconds = 10.0;
  double frameRate = 60.0;
  double dropInterval = 0.7;  // mean seconds between drops
  unsigned seed = 1;
  std::string framesCsv;  // per-frame timings, empty: none
};

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    if (a == "--scene" && hasValue) o.scene = argv[++i];
    else if (a == "--seconds" && hasValue) o.seconds = std::atof(argv[++i]);
    else if (a == "--rate" && hasValue) o.frameRate = std::atof(argv[++i]);
    else if (a == "--drop-interval" && hasValue) o.dropInterval = std::atof(argv[++i]);
    else if (a == "--seed" && hasValue) o.seed = static_cast<unsigned>(std::atoi(argv[++i]));
    else if (a == "--frames-csv" && hasValue) o.framesCsv = argv[++i];
    else {
      std::fprintf(stderr,
                   "usage: %s [--scene SCENE.json] [--seconds S] [--rate HZ] [--drop-interval S] [--seed N]\n"
                   "          [--frames-csv FILE]  (one row per frame: times, stain stages, rebuilds, drops; threads, wet and band vertices, band and reach rings, advection sub-steps of its last step)\n", argv[0]);
      return false;
    }
  }
  return o.seconds > 0 && o.frameRate > 0 && o.dropInterval > 0;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const auto k = static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5);
  return values[std::min(k, values.size() - 1)];
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (!parse(argc, argv, options)) return 2;
  std::unique_ptr<blot::Engine> engine;
  try {
    engine = blot::Engine::fromSceneFile(options.scene);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "game_loop: %s\n", e.what());
    return 1;
  }
  const Eigen::AlignedBox3d box(engine->positions().colwise().minCoeff().transpose(),
                                engine->positions().colwise().maxCoeff().transpose());
  std::mt19937 rng(options.seed);
  std::exponential_distribution<double> gap(1.0 / options.dropInterval);
  std::uniform_real_distribution<double> unit(0.0, 1.0);

  const double frameDt = 1.0 / options.frameRate;
  const int frames = static_cast<int>(options.seconds * options.frameRate + 0.5);
  std::vector<double> stepMs, clothMs, stainMs;  // per frame; the last two from the engine's phase totals
  stepMs.reserve(static_cast<size_t>(frames));
  clothMs.reserve(static_cast<size_t>(frames));
  stainMs.reserve(static_cast<size_t>(frames));
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
  double nextDrop = gap(rng);
  int drops = 0;
  for (int frame = 0; frame < frames; ++frame) {
    const double now = frame * frameDt;
    int frameDrops = 0;
    while (nextDrop <= now) {
      // A point inside the cloth's box, pushed 0.3 m off its thinnest side: the
      // drop lands on the nearest point of the surface.
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) p[c] = box.min()[c] + unit(rng) * box.sizes()[c];
      Eigen::Index thin = 0;
      box.sizes().minCoeff(&thin);
      p[thin] = box.min()[thin] - 0.3;
      blot::stain::DropDef drop;
      // A splash of 6.5-26 ml landing as a film about 1 mm thick (docs/gallery.md,
      // "Drop sizes"): radius sqrt(V / (pi * 1 mm)), 4.5-9.1 cm.
      drop.solventMass = 0.005 + 0.015 * unit(rng);
      drop.soluteMass = 0.3 * drop.solventMass;
      const double volume = (drop.solventMass + drop.soluteMass) / 1000.0;  // m^3 at 1000 kg/m^3
      drop.radius = std::sqrt(volume / (M_PI * 1e-3));
      engine->addDropAtPoint(p, drop);
      ++drops;
      ++frameDrops;
      nextDrop += gap(rng);
    }
    const auto start = std::chrono::steady_clock::now();
    const blot::stain::StepReport report = engine->step(frameDt);
    stepMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    const blot::engine::PhaseTotals after = engine->statistics().totals;
    clothMs.push_back(after.cloth - before.cloth);
    stainMs.push_back((after.stain + after.coupling) - (before.stain + before.coupling));
    if (!options.framesCsv.empty()) {
      const blot::engine::EngineStatistics stats = engine->statistics();
      csv << frame << "," << stepMs.back() << "," << clothMs.back() << "," << after.stain - before.stain << ","
          << after.coupling - before.coupling;
      for (int k = static_cast<int>(blot::stain::kFirstStainStage); k <= static_cast<int>(blot::stain::kLastStainStage);
           ++k)
        csv << "," << after.stageMilliseconds[static_cast<size_t>(k)] - before.stageMilliseconds[static_cast<size_t>(k)];
      csv << "," << stats.steps - stepsBefore << "," << stats.intrinsicRefreshes - rebuildsBefore << "," << frameDrops
          << "," << stats.lastProfile.threads << "," << stats.lastProfile.wetVertices << ","
          << stats.lastProfile.bandVertices << "," << stats.lastProfile.bandRings << ","
          << stats.lastProfile.reachRings << "," << stats.lastProfile.advectionSubsteps << "\n";
      stepsBefore = stats.steps;
      rebuildsBefore = stats.intrinsicRefreshes;
    }
    before = after;
    if (report.status != blot::stain::StepStatus::Ok) {
      std::fprintf(stderr, "game_loop: frame %d: stage '%s': %s\n", frame, report.stageName(), report.message.c_str());
      return 3;
    }
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
  const blot::engine::EngineStatistics s = engine->statistics();
  const double budget = 1000.0 * frameDt;
  const long over = std::count_if(stepMs.begin(), stepMs.end(), [budget](double ms) { return ms > budget; });
  std::printf("game_loop: %s, %d vertices, %d frames at %.0f Hz (%.2f s), %lld internal steps of %.4f s\n",
              options.scene.c_str(), engine->vertexCount(), frames, options.frameRate, engine->time(),
              static_cast<long long>(s.steps), engine->timeStep());
  std::printf("drops added: %d (seed %u)\n", drops, options.seed);
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
