// Stain display colour by Beer–Lambert attenuation.
//
// Design note: light crosses the pigment layer, reflects off the fibres and
// crosses it again; each channel is attenuated by exp(−ε·σ) with σ the total
// pigment per unit area (free + absorbed + adsorbed solute: all of it sits in
// or on the cloth and colours it the same way). The two passes are folded into
// ε. Water darkens cloth because a wet fibre scatters less (its refractive
// index contrast drops); we model that as a weak, nearly neutral attenuation
// by the solvent density. Channels are independent, so a pigment absorbing
// green and blue (wine) reddens as it thickens, which a linear blend between
// "clean" and "stained" colours cannot do: that was the rejected alternative,
// along with colour maps of one density (no physical meaning, no mixing of
// free and absorbed solute). The clamp only matters for negative densities.
// Colours are linear (reflectance); the writers sRGB-encode them. The presets
// were first tuned on display values; in linear light the same pictures need
// about 2.2 times the absorbance (x^2.2 ≈ the sRGB decode), hence the numbers.
#include <blot/engine/stain_color.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace blot::engine {
namespace {

double densityAt(const Eigen::VectorXd& density, Eigen::Index i) {
  return density.size() == 0 ? 0.0 : density[i];
}

}  // namespace

Eigen::Array3d pigmentAbsorbance(PigmentPreset preset) {
  switch (preset) {
    case PigmentPreset::Wine:
      return {0.77, 3.5, 2.4};  // absorbs green strongly, blue less: red-purple
    case PigmentPreset::Coffee:
      return {1.0, 1.8, 3.1};  // absorbs blue most, red least: brown
    case PigmentPreset::Ink:
      return {3.7, 2.6, 0.77};  // absorbs red and green: blue-black
  }
  throw std::invalid_argument("pigmentAbsorbance: unknown preset");
}

StainColorMapping stainColorMapping(PigmentPreset preset, const Eigen::Array3d& clothColor) {
  StainColorMapping mapping;
  mapping.clothColor = clothColor;
  mapping.soluteAbsorbance = pigmentAbsorbance(preset);
  return mapping;
}

PigmentPreset pigmentPresetFromName(const std::string& name) {
  if (name == "wine") return PigmentPreset::Wine;
  if (name == "coffee") return PigmentPreset::Coffee;
  if (name == "ink") return PigmentPreset::Ink;
  throw std::invalid_argument("unknown pigment '" + name + "' (expected wine, coffee or ink)");
}

const char* pigmentPresetName(PigmentPreset preset) {
  switch (preset) {
    case PigmentPreset::Wine:
      return "wine";
    case PigmentPreset::Coffee:
      return "coffee";
    case PigmentPreset::Ink:
      return "ink";
  }
  return "unknown";
}

Eigen::Array3d stainColor(const StainColorMapping& mapping, double solvent, double solute,
                          double absorbedSolute, double adsorbedSolute) {
  const double pigment = solute + absorbedSolute + adsorbedSolute;
  const Eigen::Array3d transmitted = (-mapping.soluteAbsorbance * pigment).exp() *
                                     (-mapping.solventAbsorbance * solvent).exp();
  const Eigen::Array3d color = mapping.clothColor * transmitted;
  if (!color.allFinite()) return color;
  return color.min(1.0).max(0.0);
}

void stainColors(const StainColorMapping& mapping, const Eigen::VectorXd& solvent,
                 const Eigen::VectorXd& solute, const Eigen::VectorXd& absorbedSolute,
                 const Eigen::VectorXd& adsorbedSolute, Eigen::MatrixX3d& vertexColors) {
  Eigen::Index count = 0;
  for (const Eigen::VectorXd* density : {&solvent, &solute, &absorbedSolute, &adsorbedSolute}) {
    count = std::max(count, density->size());
  }
  const char* names[4] = {"solvent", "solute", "absorbedSolute", "adsorbedSolute"};
  const Eigen::VectorXd* densities[4] = {&solvent, &solute, &absorbedSolute, &adsorbedSolute};
  for (int k = 0; k < 4; ++k) {
    if (densities[k]->size() != 0 && densities[k]->size() != count) {
      throw std::invalid_argument(std::string("stainColors: ") + names[k] + " has " +
                                  std::to_string(densities[k]->size()) + " entries, expected " +
                                  std::to_string(count));
    }
  }
  if (vertexColors.rows() != count) vertexColors.resize(count, 3);
  for (Eigen::Index i = 0; i < count; ++i) {
    vertexColors.row(i) = stainColor(mapping, densityAt(solvent, i), densityAt(solute, i),
                                     densityAt(absorbedSolute, i), densityAt(adsorbedSolute, i))
                              .matrix()
                              .transpose();
  }
}

}  // namespace blot::engine
