// Paper Fig. 4 reproduction: a spot diffusing on a flat rectangle tiled with
// many copies of a pattern, with (1) the fine per-cell tensor field, (2) the
// homogenized tensor S_eff everywhere, (3) the plain cell average everywhere.
// For the knit case (D = 1, 100, 500, 10, 50, 200 on the rib-knit layout,
// assets/patterns/fig4_knit.json) and the 1/100 columns case
// (assets/patterns/fig4_columns.json) it prints the relative L2 distance of
// (2) and (3) from (1) at equal times, asserts that (2) is clearly closer, and
// writes PNG panels (layout | original | effective | average) like the figure.
//
// Study (label "study", CI skips it): 148K-vertex grids (96 x 96 cells, 4 x 4
// squares per cell), three Cholesky factorizations per case, ~10 s CPU in all.
// tests/stain/homogenization_test.cpp runs a small version in CI. Images go to
// $BLOT_STUDY_OUTPUT_DIR/fig4_homogenization, or ./fig4_homogenization.
#include <blot/engine/image.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "tiled_spot_diffusion.h"

namespace blot::stain {
namespace {

/// White -> ink blue, t in [0, 1] (clamped); the gamma lifts faint values.
engine::Rgba8 inkColor(double t) {
  t = std::pow(std::clamp(t, 0.0, 1.0), 0.6);
  auto mix = [t](double a, double b) { return static_cast<std::uint8_t>(std::lround(a + (b - a) * t)); };
  return {mix(255, 18), mix(255, 32), mix(255, 110), 255};
}

/// One pixel per grid vertex, y up; all three panels share `maximum`.
engine::Image fieldImage(const Vector& values, int vx, int vy, double maximum) {
  engine::Image image(vx, vy);
  for (int j = 0; j < vy; ++j)
    for (int i = 0; i < vx; ++i) image.setPixel(i, vy - 1 - j, inkColor(values(j * vx + i) / maximum));
  return image;
}

/// The figure's "layout" column: each cell shaded by its tensor trace (log scale).
engine::Image layoutImage(const WeavePattern& pattern, int cellsX, int cellsY, int pixelsPerCell) {
  double lo = 1e300, hi = 0.0;
  for (const Matrix2& s : pattern.cellTensors()) {
    lo = std::min(lo, s.trace());
    hi = std::max(hi, s.trace());
  }
  engine::Image image(cellsX * pixelsPerCell, cellsY * pixelsPerCell);
  for (int cy = 0; cy < cellsY; ++cy) {
    for (int cx = 0; cx < cellsX; ++cx) {
      const int row = pattern.rows() - 1 - cy % pattern.rows();  // file row 0 = top
      const double trace = pattern.cellTensor(row, cx % pattern.cols()).trace();
      const double t = hi > lo ? std::log(trace / lo) / std::log(hi / lo) : 0.5;
      const auto grey = static_cast<std::uint8_t>(std::lround(235 - 200 * t));
      for (int y = 0; y < pixelsPerCell; ++y)
        for (int x = 0; x < pixelsPerCell; ++x)
          image.setPixel(cx * pixelsPerCell + x, (cellsY - 1 - cy) * pixelsPerCell + y, {grey, grey, grey, 255});
    }
  }
  return image;
}

std::string outputDirectory() {
  const char* env = std::getenv("BLOT_STUDY_OUTPUT_DIR");
  const std::filesystem::path dir = env && *env ? std::filesystem::path(env) / "fig4_homogenization"
                                                : std::filesystem::current_path() / "fig4_homogenization";
  std::filesystem::create_directories(dir);
  return dir.string();
}

test::TiledSpotResult runCase(const std::string& name, const WeavePattern& pattern, const test::TiledSpotSetup& setup) {
  const test::TiledSpotResult r = test::tiledSpotDiffusion(pattern, setup);
  const Matrix2& e = r.homogenized.effective;
  const Matrix2& a = r.homogenized.average;
  std::printf("%s: %d x %d cells (%d tiles), %d vertices, t = %.3g, %d implicit steps\n", name.c_str(), r.cellsX,
              r.cellsY, setup.tilesX * setup.tilesY, r.verticesX * r.verticesY, setup.duration, setup.steps);
  std::printf("  S_eff   = [%.6g %.3g; %.3g %.6g] (mean of the bounds, gap %.2g, %d unknowns)\n", e(0, 0),
              e(0, 1), e(1, 0), e(1, 1), r.homogenized.gap, r.homogenized.vertexCount);
  EXPECT_TRUE(r.homogenized.converged);
  std::printf("  average = [%.6g %.3g; %.3g %.6g]\n", a(0, 0), a(0, 1), a(1, 0), a(1, 1));
  std::printf("  relative L2 distance from the fine-field result: effective %.4f, average %.4f (ratio %.1f)\n",
              r.effectiveError, r.averageError, r.averageError / r.effectiveError);
  EXPECT_LT(r.massDrift, 1e-9);  // implicit Euler with zero-row-sum L conserves Σ Mσ

  const double peak = r.original.maxCoeff();
  const std::vector<engine::Image> panels = {
      layoutImage(pattern, r.cellsX, r.cellsY, setup.squaresPerCell),
      fieldImage(r.original, r.verticesX, r.verticesY, peak), fieldImage(r.effective, r.verticesX, r.verticesY, peak),
      fieldImage(r.average, r.verticesX, r.verticesY, peak)};
  const std::string dir = outputDirectory();
  engine::writePng(engine::sideBySide(panels, {"layout", "original tensor field", "effective tensor", "average tensor"}),
                   dir + "/" + name + ".png");
  const char* fields[3] = {"original", "effective", "average"};
  for (int i = 0; i < 3; ++i)
    engine::writePng(panels[static_cast<size_t>(i + 1)], dir + "/" + name + "_" + fields[i] + ".png");
  std::printf("  wrote %s/%s.png and %s_{original,effective,average}.png\n", dir.c_str(), name.c_str(), name.c_str());
  return r;
}

TEST(Fig4Homogenization, KnitPattern) {
  test::TiledSpotSetup setup;
  setup.tilesX = 12;  // 8-column tile -> 96 cells
  setup.tilesY = 24;  // 4-row tile -> 96 cells
  setup.squaresPerCell = 4;
  setup.spotRadius = 6.0;
  setup.duration = 1.2;
  setup.steps = 40;
  const auto r = runCase("knit", loadWeavePattern(std::string(BLOT_ASSETS_DIR) + "/patterns/fig4_knit.json"), setup);
  EXPECT_LT(r.effectiveError, 0.5 * r.averageError);
}

TEST(Fig4Homogenization, ColumnsOfOneAndHundred) {
  test::TiledSpotSetup setup;
  setup.tilesX = 48;  // 2-column tile -> 96 cells
  setup.tilesY = 96;
  setup.squaresPerCell = 4;
  setup.spotRadius = 6.0;
  setup.duration = 2.0;
  setup.steps = 40;
  const auto r = runCase("columns", loadWeavePattern(std::string(BLOT_ASSETS_DIR) + "/patterns/fig4_columns.json"), setup);
  EXPECT_LT(r.effectiveError, 0.2 * r.averageError);
}

}  // namespace
}  // namespace blot::stain
