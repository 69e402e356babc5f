// Homogenization: exact laminate values, homogeneous tiles, Reuss/Voigt bounds
// and SPD-ness on random tiles, exact 90° rotation covariance, linearity in
// the coefficients, monotone convergence under mesh refinement with the
// observed order printed, eigen-decomposition conventions, and the cache.
// The two-sided bounds and the graded refinement: homogenization_bounds_test.cpp.
#include <blot/stain/fabric/homogenization.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "tiled_spot_diffusion.h"

namespace blot::stain {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// Smallest eigenvalue of a symmetric 2x2 matrix (PSD test in the Loewner order).
double minEigenvalue(const Matrix2& a) { return symmetricEigenvalues(0.5 * (a + a.transpose()))(0); }

Matrix2 rotation(double angle) {
  Matrix2 r;
  r << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  return r;
}

/// rows x cols tile of random SPD tensors: eigenvalues log-uniform in
/// [1, e^logContrast], random orientation. Fixed seed: same tile everywhere.
WeavePattern randomTile(int rows, int cols, double logContrast, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Matrix2> tensors;
  for (int i = 0; i < rows * cols; ++i) {
    const double a = std::exp(logContrast * unit(rng)), b = std::exp(logContrast * unit(rng));
    const Matrix2 q = rotation(kPi * unit(rng));
    tensors.push_back(q * Vector2(a, b).asDiagonal() * q.transpose());
  }
  return WeavePattern(rows, cols, tensors, "random tile");
}

TEST(Homogenization, LaminateOfColumnsIsHarmonicAcrossAndArithmeticAlong) {
  // Paper Fig. 4 bottom row: isotropic columns 1 and 100. Across the layers
  // (x) the harmonic mean 2/(1 + 1/100) = 200/101, along them (y) the
  // arithmetic mean 50.5.
  const WeavePattern columns(1, 2, {Matrix2::Identity(), 100.0 * Matrix2::Identity()}, "columns");
  const HomogenizationResult r = homogenize(columns);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.gap, 1e-6);
  EXPECT_NEAR(r.effective(0, 0), 200.0 / 101.0, 1e-6 * 200.0 / 101.0);
  EXPECT_NEAR(r.effective(1, 1), 50.5, 1e-6 * 50.5);
  EXPECT_NEAR(r.effective(0, 1), 0.0, 1e-9);
  EXPECT_NEAR(r.eigenvalues(0), 200.0 / 101.0, 1e-6);
  EXPECT_NEAR(r.principalAngle, kPi / 2, 1e-12);  // fast direction along the columns (y)
  // The plain average is isotropic (the paper's point): 50.5 both ways.
  EXPECT_NEAR(r.average(0, 0), 50.5, 1e-12);
  EXPECT_NEAR(r.average(1, 1), 50.5, 1e-12);
  // For a laminate the bounds are attained in their own directions.
  EXPECT_NEAR(r.reussBound(0, 0), 200.0 / 101.0, 1e-12);
  EXPECT_NEAR(r.voigtBound(1, 1), 50.5, 1e-12);
  std::printf("laminate 1/100 columns, K = %d: S_eff = [%.10f %.3g; %.3g %.10f]\n", r.subdivisions,
              r.effective(0, 0), r.effective(0, 1), r.effective(1, 0), r.effective(1, 1));
  // The cell interfaces lie on mesh lines and the exact corrector is piecewise
  // linear, so every K reproduces it; rows instead of columns swap the axes.
  const HomogenizationResult coarse = homogenize(columns, 1);
  EXPECT_NEAR(coarse.effective(0, 0), 200.0 / 101.0, 1e-9);
  const HomogenizationResult rows = homogenize(columns.rotated90());
  EXPECT_NEAR(rows.effective(1, 1), 200.0 / 101.0, 1e-6 * 200.0 / 101.0);
  EXPECT_NEAR(rows.effective(0, 0), 50.5, 1e-6 * 50.5);
}

TEST(Homogenization, HomogeneousTileIsItsOwnEffectiveTensor) {
  Matrix2 s;
  s << 3.0, -1.2, -1.2, 2.0;
  const WeavePattern tile(3, 2, std::vector<Matrix2>(6, s), "uniform");
  const HomogenizationResult r = homogenize(tile, 2);
  EXPECT_LT((r.effective - s).norm(), 1e-12 * s.norm());
  EXPECT_LT((r.reussBound - s).norm(), 1e-12 * s.norm());
}

// Extreme but valid tensors: a uniform tile is exactly its own tensor even
// where the cell problem cannot be factorized in doubles, and a tile scaled by
// 1e250 (or 1e-250) homogenizes to the scaled result.
TEST(Homogenization, ExtremeTensorsHomogenizeScaleAware) {
  Matrix2 s;
  s << 1e300, 0, 0, 1e-300;
  const WeavePattern uniform(1, 1, {s}, "extreme");
  const HomogenizationResult u = homogenize(uniform, 4);
  EXPECT_EQ(u.effective, s);
  EXPECT_TRUE(u.converged);
  EXPECT_EQ(u.eigenvalues(0), 1e-300);
  EXPECT_EQ(u.eigenvalues(1), 1e300);
  const WeavePattern tile = randomTile(2, 2, 5.0, 77u);
  const HomogenizationResult reference = homogenize(tile, 2);
  for (const double factor : {1e250, 1e-250}) {
    const HomogenizationResult r = homogenize(tile.scaled(factor), 2);
    EXPECT_LT((r.effective / factor - reference.effective).norm(), 1e-12 * reference.effective.norm()) << factor;
    EXPECT_NEAR(r.gap, reference.gap, 1e-12);
  }
}

TEST(Homogenization, RandomTilesAreSpdBetweenBoundsAndRotateExactly) {
  int tiles = 0;
  for (int rows : {1, 2, 3, 5}) {
    for (int cols : {2, 3, 4}) {
      const WeavePattern tile = randomTile(rows, cols, 5.0, 1000u + static_cast<unsigned>(10 * rows + cols));
      SCOPED_TRACE(std::to_string(rows) + "x" + std::to_string(cols));
      const HomogenizationResult r = homogenize(tile, defaultSubdivisions(tile));
      const double scale = r.voigtBound.norm();
      EXPECT_EQ(r.effective, r.effective.transpose());
      EXPECT_GT(r.eigenvalues(0), 0.0);
      EXPECT_GE(minEigenvalue(r.voigtBound - r.effective), -1e-12 * scale);  // S_eff <= Voigt
      EXPECT_GE(minEigenvalue(r.effective - r.reussBound), -1e-12 * scale);  // S_eff >= Reuss
      // For a genuinely 2D random tile both bounds are strict somewhere.
      if (rows > 1) {
        EXPECT_GT(minEigenvalue(r.voigtBound - r.effective) + minEigenvalue(r.effective - r.reussBound), 0.0);
      }
      // Quarter turn: the mesh maps to itself (alternating diagonals, even K),
      // so the discrete S_eff rotates exactly: diagonal swapped, xy negated.
      const HomogenizationResult q = homogenize(tile.rotated90(), r.subdivisions);
      EXPECT_NEAR(q.effective(0, 0), r.effective(1, 1), 1e-10 * scale);
      EXPECT_NEAR(q.effective(1, 1), r.effective(0, 0), 1e-10 * scale);
      EXPECT_NEAR(q.effective(0, 1), -r.effective(0, 1), 1e-10 * scale);
      // The graded mesh maps to itself under quarter turns too.
      const GradedMeshLevel level{2, gradedLayersFor(2, 1e-4)};
      const CellProblemBounds g = cellProblemBounds(tile, gradedCellMesh(rows, cols, level));
      const CellProblemBounds gq = cellProblemBounds(tile.rotated90(), gradedCellMesh(cols, rows, level));
      EXPECT_NEAR(gq.upper(0, 0), g.upper(1, 1), 1e-10 * scale);
      EXPECT_NEAR(gq.upper(1, 1), g.upper(0, 0), 1e-10 * scale);
      EXPECT_NEAR(gq.upper(0, 1), -g.upper(0, 1), 1e-10 * scale);
      EXPECT_NEAR(gq.lower(0, 1), -g.lower(0, 1), 1e-10 * scale);
      ++tiles;
    }
  }
  EXPECT_EQ(tiles, 12);
}

TEST(Homogenization, EffectiveTensorIsLinearInTheCoefficients) {
  const WeavePattern tile = randomTile(3, 3, 4.0, 77u);
  const HomogenizationResult r = homogenize(tile, 4);
  const HomogenizationResult s = homogenize(tile.scaled(1e-6), 4);  // e.g. a scene's diffusion scale
  EXPECT_LT((s.effective - 1e-6 * r.effective).norm(), 1e-12 * 1e-6 * r.effective.norm());
}

TEST(Homogenization, SymmetricPatternsHaveNoShear) {
  // Plain weave and basket are symmetric under x -> -x, so S_eff is diagonal.
  for (const char* name : {"plain", "basket", "rib-knit"}) {
    const HomogenizationResult r = homogenize(presetWeavePattern(name));
    EXPECT_LT(std::abs(r.effective(0, 1)), 1e-12 * r.effective.norm()) << name;
  }
}

TEST(Homogenization, RefinementConvergesMonotonicallyWithObservedOrder) {
  // Doubling K nests the P1 spaces (each square splits into four with
  // alternating diagonals), and the upper bound is an energy minimum over
  // them, so it can only decrease in the Loewner order as K doubles (and the
  // lower bound, the same for the dual tensors, only increase).
  struct Case {
    const char* name;
    WeavePattern pattern;
    double minOrder;
  };
  const std::vector<Case> cases = {
      {"twill-2-1 preset", presetWeavePattern("twill-2-1"), 1.6},
      {"random 3x3, contrast e^3", randomTile(3, 3, 3.0, 4242u), 0.8},
      {"random 2x3, contrast e^6", randomTile(2, 3, 6.0, 99u), 0.8}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<Matrix2> values, lowers;
    for (int K : {2, 4, 8, 16}) {
      const HomogenizationResult r = homogenize(c.pattern, K);
      values.push_back(r.upper);
      lowers.push_back(r.lower);
    }
    std::vector<double> differences;
    for (size_t i = 0; i + 1 < values.size(); ++i) {
      EXPECT_GE(minEigenvalue(values[i] - values[i + 1]), -1e-11 * values[i].norm());
      EXPECT_GE(minEigenvalue(lowers[i + 1] - lowers[i]), -1e-11 * values[i].norm());
      differences.push_back((values[i] - values[i + 1]).norm() / values.back().norm());
    }
    const double order01 = std::log2(differences[0] / differences[1]);
    const double order12 = std::log2(differences[1] / differences[2]);
    std::printf("%-26s |S(K)-S(2K)|/|S|: K=2 %.2e, K=4 %.2e, K=8 %.2e; observed order %.2f, %.2f\n", c.name,
                differences[0], differences[1], differences[2], order01, order12);
    EXPECT_GT(order12, c.minOrder);
    EXPECT_LT(differences[2], differences[1]);
  }
}

TEST(Homogenization, EigenvaluesAndPrincipalAngleConventions) {
  const Matrix2 q = rotation(kPi / 6);
  const Matrix2 s = q * Vector2(1.0, 4.0).asDiagonal() * q.transpose();  // major axis at 120°
  EXPECT_NEAR(symmetricEigenvalues(s)(0), 1.0, 1e-14);
  EXPECT_NEAR(symmetricEigenvalues(s)(1), 4.0, 1e-14);
  EXPECT_NEAR(principalAngle(s), -kPi / 3, 1e-14);  // 120° is −60° in (−90°, 90°]
  EXPECT_NEAR(principalAngle(Vector2(5.0, 1.0).asDiagonal().toDenseMatrix()), 0.0, 0.0);
  EXPECT_NEAR(principalAngle(Vector2(1.0, 5.0).asDiagonal().toDenseMatrix()), kPi / 2, 1e-15);
  EXPECT_EQ(principalAngle(2.0 * Matrix2::Identity()), 0.0);
  // Round-off shear of either sign keeps a y-major tensor at +90°, not −90°.
  Matrix2 roundOff;
  roundOff << 97.0, -2e-13, -2e-13, 165.0;
  EXPECT_EQ(principalAngle(roundOff), kPi / 2);
  EXPECT_EQ(principalAngle(homogenize(presetWeavePattern("plain")).effective), kPi / 2);
}

TEST(Homogenization, HomogenizerCachesByContentAndOptions) {
  Homogenizer homogenizer;
  const WeavePattern twill = presetWeavePattern("twill-2-1");
  const HomogenizationResult& first = homogenizer.homogenize(twill);
  const WeavePattern sameContent(twill.rows(), twill.cols(), twill.cellTensors(), "copy from another file");
  const HomogenizationResult& second = homogenizer.homogenize(sameContent);
  EXPECT_EQ(&first, &second);
  EXPECT_EQ(homogenizer.cacheHits(), 1);
  EXPECT_EQ(homogenizer.cacheMisses(), 1);
  // The same options are the same entry; a fixed K or another tolerance is not.
  HomogenizationOptions options;
  homogenizer.homogenize(twill, options);
  EXPECT_EQ(homogenizer.cacheHits(), 2);
  homogenizer.homogenize(twill, 2);
  options.tolerance = 1e-3;
  homogenizer.homogenize(twill, options);
  homogenizer.homogenize(presetWeavePattern("plain"));
  EXPECT_EQ(homogenizer.cacheMisses(), 4);
  EXPECT_EQ(homogenizer.cacheSize(), 4);
  EXPECT_EQ(first.effective, homogenize(twill).effective);  // cached == fresh, bit for bit
  homogenizer.clear();
  EXPECT_EQ(homogenizer.cacheSize(), 0);
}

TEST(Homogenization, EffectiveTensorReproducesFineScaleDiffusion) {
  // Paper Fig. 4 in small (the full study with images is
  // tests/studies/fig4_homogenization_test.cpp): a spot on 48 x 48 cells of
  // the 1/100 columns diffuses like the S_eff solution, not like the average.
  const WeavePattern columns(1, 2, {Matrix2::Identity(), 100.0 * Matrix2::Identity()}, "columns");
  test::TiledSpotSetup setup;
  setup.tilesX = 24;
  setup.tilesY = 48;
  setup.squaresPerCell = 2;
  setup.spotRadius = 4.0;
  setup.duration = 1.0;
  setup.steps = 10;
  const test::TiledSpotResult r = test::tiledSpotDiffusion(columns, setup);
  std::printf("columns, 48 x 48 cells: relative L2 from fine field: effective %.4f, average %.4f\n",
              r.effectiveError, r.averageError);
  EXPECT_LT(r.effectiveError, 0.1);
  EXPECT_LT(r.effectiveError, 0.2 * r.averageError);
  EXPECT_LT(r.massDrift, 1e-10);
}

TEST(Homogenization, DefaultSubdivisionsFollowTheUnknownBudget) {
  EXPECT_EQ(defaultSubdivisions(presetWeavePattern("plain")), 32);     // 4x4 cells
  EXPECT_EQ(defaultSubdivisions(presetWeavePattern("rib-knit")), 22);  // 4x8 cells
  EXPECT_EQ(defaultSubdivisions(presetWeavePattern("satin-5")), 12);   // 10x10 cells
  EXPECT_EQ(defaultSubdivisions(randomTile(32, 32, 1.0, 1u)), 4);
  EXPECT_EQ(defaultSubdivisions(randomTile(64, 64, 1.0, 1u)), 4);
  for (int n : {1, 3, 7, 16, 20, 31}) {
    const int K = defaultSubdivisions(randomTile(n, n, 1.0, 1u));
    EXPECT_EQ(K % 2, 0);
    EXPECT_LE(n * n * K * K, 16384) << n;
  }
  EXPECT_THROW(homogenize(presetWeavePattern("plain"), -1), std::invalid_argument);
  // Past the budget by any amount, however large: cells K^2 as a long wrapped
  // past 2^63 from K = 759250125 on a 4x4 tile, and such a K passed the check.
  for (const int K : {177, 759250124, 759250125, 1000000000, std::numeric_limits<int>::max()}) {
    try {
      homogenize(presetWeavePattern("plain"), K);
      ADD_FAILURE() << K << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("unknowns, more than the limit of 500000 (largest K for this tile: 176)"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace blot::stain
