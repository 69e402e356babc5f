// Tests for the Beer–Lambert stain colour mapping.
#include <blot/engine/stain_color.h>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace blot::engine {
namespace {

// Colours are computed in double; the closed form is the same arithmetic up
// to operation order.
constexpr double kTolerance = 1e-14;

TEST(StainColor, CleanDryClothShowsItsBaseColour) {
  const StainColorMapping mapping = stainColorMapping(PigmentPreset::Coffee, {0.9, 0.8, 0.7});
  const Eigen::Array3d color = stainColor(mapping, 0.0, 0.0, 0.0, 0.0);
  EXPECT_NEAR(color[0], 0.9, kTolerance);
  EXPECT_NEAR(color[1], 0.8, kTolerance);
  EXPECT_NEAR(color[2], 0.7, kTolerance);
}

TEST(StainColor, EqualsTheBeerLambertClosedForm) {
  std::mt19937 generator(42);
  std::uniform_real_distribution<double> density(0.0, 4.0);
  for (PigmentPreset preset : {PigmentPreset::Wine, PigmentPreset::Coffee, PigmentPreset::Ink}) {
    const StainColorMapping mapping = stainColorMapping(preset);
    for (int trial = 0; trial < 50; ++trial) {
      const double f = density(generator), s = density(generator), sp = density(generator),
                   sa = density(generator);
      const Eigen::Array3d color = stainColor(mapping, f, s, sp, sa);
      for (int c = 0; c < 3; ++c) {
        const double expected = mapping.clothColor[c] *
                                std::exp(-mapping.soluteAbsorbance[c] * (s + sp + sa)) *
                                std::exp(-mapping.solventAbsorbance[c] * f);
        EXPECT_NEAR(color[c], expected, kTolerance * (1.0 + expected));
      }
    }
  }
}

TEST(StainColor, LayersMultiplyAndOnlyTheTotalPigmentMatters) {
  const StainColorMapping mapping = stainColorMapping(PigmentPreset::Wine, {1.0, 1.0, 1.0});
  const Eigen::Array3d one = stainColor(mapping, 0.0, 0.7, 0.0, 0.0);
  const Eigen::Array3d two = stainColor(mapping, 0.0, 0.5, 0.0, 0.0);
  const Eigen::Array3d both = stainColor(mapping, 0.0, 0.7, 0.5, 0.0);
  EXPECT_LT((both - one * two).abs().maxCoeff(), kTolerance);
  // Free, absorbed and adsorbed solute colour the cloth alike.
  const Eigen::Array3d split = stainColor(mapping, 0.0, 0.2, 0.4, 0.6);
  const Eigen::Array3d lumped = stainColor(mapping, 0.0, 1.2, 0.0, 0.0);
  EXPECT_LT((split - lumped).abs().maxCoeff(), kTolerance);
}

TEST(StainColor, PresetsHaveTheirHue) {
  const double sigma = 1.5;
  const Eigen::Array3d wine = stainColor(stainColorMapping(PigmentPreset::Wine), 0, sigma, 0, 0);
  EXPECT_GT(wine[0], wine[2]);
  EXPECT_GT(wine[2], wine[1]);  // red-purple: green absorbed most
  const Eigen::Array3d coffee =
      stainColor(stainColorMapping(PigmentPreset::Coffee), 0, sigma, 0, 0);
  EXPECT_GT(coffee[0], coffee[1]);
  EXPECT_GT(coffee[1], coffee[2]);  // brown: red > green > blue
  const Eigen::Array3d ink = stainColor(stainColorMapping(PigmentPreset::Ink), 0, sigma, 0, 0);
  EXPECT_GT(ink[2], ink[1]);
  EXPECT_GT(ink[1], ink[0]);  // blue
  // Thicker wine is darker in every channel and redder (R/G grows).
  const Eigen::Array3d thicker =
      stainColor(stainColorMapping(PigmentPreset::Wine), 0, 2 * sigma, 0, 0);
  EXPECT_TRUE((thicker < wine).all());
  EXPECT_GT(thicker[0] / thicker[1], wine[0] / wine[1]);
}

TEST(StainColor, WaterDarkensALittleAndNegativeDensitiesAreClamped) {
  const StainColorMapping mapping = stainColorMapping(PigmentPreset::Ink, {0.95, 0.95, 0.95});
  const Eigen::Array3d dry = stainColor(mapping, 0.0, 0.0, 0.0, 0.0);
  const Eigen::Array3d wet = stainColor(mapping, 4.0, 0.0, 0.0, 0.0);
  EXPECT_TRUE((wet < dry).all());
  EXPECT_TRUE((wet > 0.5 * dry).all());  // wet cloth is darker, not black (linear reflectance)
  const Eigen::Array3d negative = stainColor(mapping, 0.0, -10.0, 0.0, 0.0);
  EXPECT_TRUE((negative <= 1.0).all());
  EXPECT_TRUE((negative >= 0.0).all());
}

TEST(StainColor, VertexColoursMatchTheScalarFunction) {
  const StainColorMapping mapping = stainColorMapping(PigmentPreset::Coffee);
  Eigen::VectorXd solvent(4), solute(4), absorbed(4);
  solvent << 0.0, 1.0, 2.0, 3.0;
  solute << 0.5, 0.0, 1.0, 2.0;
  absorbed << 0.1, 0.2, 0.3, 0.4;
  Eigen::MatrixX3d colors;
  stainColors(mapping, solvent, solute, absorbed, Eigen::VectorXd(), colors);
  ASSERT_EQ(colors.rows(), 4);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Array3d expected = stainColor(mapping, solvent[i], solute[i], absorbed[i], 0.0);
    EXPECT_LT((colors.row(i).transpose().array() - expected).abs().maxCoeff(), 1e-15) << i;
  }
  try {
    stainColors(mapping, solvent, Eigen::VectorXd(3), absorbed, Eigen::VectorXd(), colors);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("solute"), std::string::npos) << error.what();
  }
}

TEST(StainColor, PresetNamesRoundTrip) {
  for (PigmentPreset preset : {PigmentPreset::Wine, PigmentPreset::Coffee, PigmentPreset::Ink}) {
    EXPECT_EQ(pigmentPresetFromName(pigmentPresetName(preset)), preset);
  }
  try {
    pigmentPresetFromName("beer");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("beer"), std::string::npos);
    EXPECT_NE(message.find("wine"), std::string::npos);
  }
}

}  // namespace
}  // namespace blot::engine
