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
#include <vector>

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

// Liquid presets at 20 °C. Sources (docs/rendering.md, "Liquid presets", has
// the full references; "choice" marks a value picked, not measured):
// - water: ρ, μ, γ from the CRC Handbook of Chemistry and Physics (998.2 kg/m³,
//   1.002 mPa s, 72.75 mN/m).
// - evaporation (all four, the water value): Carrier's equation as given in
//   the ASHRAE Handbook (HVAC Applications, "Natatoriums") for still air,
//   W = 0.089 (p_w − p_a) / Y: 20 °C water into 20 °C, 50 % RH air,
//   0.089 · (2.34 − 1.17) kPa / 2454 kJ/kg ≈ 4.2e-5 kg/(m² s). Wine's ethanol
//   evaporates faster at first; ignored (choice).
// - molecular diffusivity D_m of the solute in the liquid, the CRC Handbook's
//   values at infinite dilution, 25 °C: wine's dry extract (sugars, glycerol,
//   acids) as glucose, 6.7e-10 m²/s; coffee's dissolved solids as sucrose,
//   5.2e-10 (choices of the stand-in molecule); ink's dye 4.0e-10 (choice:
//   dye molecules are larger than sugars); water carries no solute: 1.0e-9,
//   a small molecule's (choice).
// - wine: a dry red, 13 % vol. Density 994 (dry reds 990–997, OIV); μ 1.6 mPa s
//   (10 wt% ethanol–water 1.5 mPa s, Khattab et al. 2012, plus the extract:
//   choice); γ 46 mN/m (10 wt% ethanol–water 48, Vázquez et al. 1995; red
//   wines measure a little lower); solute = dry extract 25 g/L (red wines
//   20–35 g/L, OIV) → 0.025; A(1 cm) at 620/520/420 nm = 1.2/5.0/3.5, a young
//   red within Glories' (1984) ranges (colour intensity ≈ 10, hue 0.7: choice).
// - coffee: filter brew at SCA's Golden Cup strength, 1.15–1.35 % TDS → 0.0125;
//   ρ 1003 (water plus the solids: estimate); μ 1.03 mPa s and γ 65 mN/m
//   (choices near water's: the brew is dilute, its melanoidins weakly
//   surface-active); A(1 cm) = 1.0/1.8/3.1 (choice: brown, blue absorbed most).
// - ink: blue-black fountain-pen ink, water with about 3 % dye (choice; inks
//   are 1–5 %), ρ 1010, μ 1.2 mPa s, γ 45 mN/m (choices: surfactant-bearing
//   water), A(1 cm) = 11/7.8/2.3 (choice: opaque in a cuvette, blue-black).
const std::vector<LiquidPreset>& liquidPresets() {
  static const std::vector<LiquidPreset> presets{
      {"water", 998.2, 1.002e-3, 0.07275, 0.0, 4.2e-5, 1.0e-9, {0.0, 0.0, 0.0}},
      {"wine", 994.0, 1.6e-3, 0.046, 0.025, 4.2e-5, 6.7e-10, {1.2, 5.0, 3.5}},
      {"coffee", 1003.0, 1.03e-3, 0.065, 0.0125, 4.2e-5, 5.2e-10, {1.0, 1.8, 3.1}},
      {"ink", 1010.0, 1.2e-3, 0.045, 0.03, 4.2e-5, 4.0e-10, {11.0, 7.8, 2.3}},
  };
  return presets;
}

std::string liquidPresetNames() {
  std::string names;
  for (const LiquidPreset& p : liquidPresets()) names += (names.empty() ? "" : ", ") + std::string(p.name);
  return names;
}

const LiquidPreset& liquidPresetFromName(const std::string& name) {
  for (const LiquidPreset& p : liquidPresets())
    if (name == p.name) return p;
  throw std::invalid_argument("unknown liquid \"" + name + "\" (expected one of " + liquidPresetNames() + ")");
}

Eigen::Array3d liquidSoluteAbsorbance(const LiquidPreset& liquid) {
  if (liquid.soluteFraction <= 0) return Eigen::Array3d::Zero();
  // A film of σ kg/m² of liquid is σ/ρ metres thick and holds f·σ of solute;
  // light crosses it twice: 2 ln10 · A/(0.01 m) · σ/ρ = ε · f σ.
  const double perPath = 2.0 * std::log(10.0) / (0.01 * liquid.density * liquid.soluteFraction);
  return liquid.absorbance1cm * perPath;
}

double liquidWickingFactor(const LiquidPreset& liquid) {
  const LiquidPreset& water = liquidPresets().front();
  return (liquid.surfaceTension / water.surfaceTension) * (water.viscosity / liquid.viscosity);
}

double liquidViscosityFactor(const LiquidPreset& liquid) {
  const LiquidPreset& water = liquidPresets().front();
  return (liquid.viscosity / liquid.density) / (water.viscosity / water.density);
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
