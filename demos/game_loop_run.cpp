#include "game_loop_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

namespace blot::demos {

GameLoopRun runGameLoop(Engine& engine, const GameLoopOptions& options, const GameLoopObserver& observer) {
  const Eigen::AlignedBox3d box(engine.positions().colwise().minCoeff().transpose(),
                                engine.positions().colwise().maxCoeff().transpose());
  std::mt19937 rng(options.seed);
  std::exponential_distribution<double> gap(1.0 / options.dropInterval);
  std::uniform_real_distribution<double> unit(0.0, 1.0);

  const double frameDt = 1.0 / options.frameRate;
  const int frames = static_cast<int>(options.seconds * options.frameRate + 0.5);
  GameLoopRun run;
  run.frames.reserve(static_cast<size_t>(std::max(frames, 0)));
  engine::PhaseTotals before = engine.statistics().totals;
  double nextDrop = gap(rng);
  for (int frame = 0; frame < frames; ++frame) {
    const double now = frame * frameDt;
    GameLoopFrame record;
    while (nextDrop <= now) {
      // A point inside the cloth's box, pushed 0.3 m off its thinnest side: the
      // drop lands on the nearest point of the surface.
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) p[c] = box.min()[c] + unit(rng) * box.sizes()[c];
      Eigen::Index thin = 0;
      box.sizes().minCoeff(&thin);
      p[thin] = box.min()[thin] - 0.3;
      stain::DropDef drop;
      // A splash of 6.5-26 ml landing as a film about 1 mm thick (docs/gallery.md,
      // "Drop sizes"): radius sqrt(V / (pi * 1 mm)), 4.5-9.1 cm.
      drop.solventMass = 0.005 + 0.015 * unit(rng);
      drop.soluteMass = 0.3 * drop.solventMass;
      const double volume = (drop.solventMass + drop.soluteMass) / 1000.0;  // m^3 at 1000 kg/m^3
      drop.radius = std::sqrt(volume / (M_PI * 1e-3));
      engine.addDropAtPoint(p, drop);
      ++run.drops;
      ++record.drops;
      nextDrop += gap(rng);
    }
    const auto start = std::chrono::steady_clock::now();
    const stain::StepReport report = engine.step(frameDt);
    record.stepMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const engine::PhaseTotals after = engine.statistics().totals;
    record.clothMs = after.cloth - before.cloth;
    record.stainMs = after.stain - before.stain;
    record.couplingMs = after.coupling - before.coupling;
    before = after;
    run.frames.push_back(record);
    if (observer) observer(frame, engine, record);
    if (report.status != stain::StepStatus::Ok) {
      run.failedFrame = frame;
      run.failure = report;
      break;
    }
  }
  return run;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const auto k = static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5);
  return values[std::min(k, values.size() - 1)];
}

}  // namespace blot::demos
