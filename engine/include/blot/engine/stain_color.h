#pragma once
/// Colour of stained cloth from the stain densities (Beer–Lambert), linear RGB:
/// the outputs sRGB-encode it when they write bytes (color_space.h).
///
/// Per RGB channel c, with surface densities in kg/m² (the paper's σ):
///   colour_c = clamp( base_c · exp(−ε_solute,c · (σ_s + σ_s,p + σ_s,a))
///                            · exp(−ε_water,c  · σ_f), 0, 1 )
/// σ_s free solute, σ_s,p absorbed solute, σ_s,a adsorbed solute, σ_f solvent
/// (free; pass σ_f + σ_p to let absorbed water darken the cloth as well).
/// ε are absorbances in m²/kg: a layer of density 1/ε_c dims channel c to 1/e.
/// See docs/rendering.md for the presets and why.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace blot::engine {

/// Built-in pigments; absorbances chosen so that σ ≈ 1 kg/m² (the paper's
/// densities, σ_sat 2–8) gives a clearly visible stain.
enum class PigmentPreset { Wine, Coffee, Ink };

/// Linear reflectance of the default off-white cloth.
inline const Eigen::Array3d kDefaultClothColor{0.848, 0.807, 0.729};

struct StainColorMapping {
  /// Reflectance of the dry, clean cloth per channel, linear [0, 1] (the
  /// default is sRGB (0.93, 0.91, 0.87), bytes (237, 232, 222), decoded).
  Eigen::Array3d clothColor{kDefaultClothColor};
  /// ε_solute per channel, m²/kg (>= 0).
  Eigen::Array3d soluteAbsorbance{0.77, 3.5, 2.4};
  /// ε_water per channel, m²/kg (>= 0): wet cloth looks darker.
  Eigen::Array3d solventAbsorbance{0.13, 0.11, 0.10};
};

/// ε_solute per channel (m²/kg) of a preset.
Eigen::Array3d pigmentAbsorbance(PigmentPreset preset);

/// Mapping with the preset's pigment, the default wetness and `clothColor`.
StainColorMapping stainColorMapping(PigmentPreset preset,
                                    const Eigen::Array3d& clothColor = kDefaultClothColor);

/// "wine", "coffee" or "ink" (exact, lower case). Throws std::invalid_argument
/// listing the valid names otherwise.
PigmentPreset pigmentPresetFromName(const std::string& name);
const char* pigmentPresetName(PigmentPreset preset);

/// A liquid by its measured properties (docs/rendering.md, "Liquid presets",
/// gives each value's source and says which are choices). A scene's
/// `liquid.preset` sets the density, the evaporation rate, the drops' solute
/// fraction (a drop's `mass`), the pigment absorbance and the factors on the
/// fabric's diffusivities; explicit keys override each.
struct LiquidPreset {
  const char* name;
  double density;           ///< ρ at 20 °C (kg/m³)
  double viscosity;         ///< dynamic viscosity μ at 20 °C (Pa s)
  double surfaceTension;    ///< γ at 20 °C (N/m)
  double soluteFraction;    ///< solute (dissolved and suspended solids) per kg of liquid
  double evaporationRate;   ///< K_evap of a wet surface in still room air (kg/(m² s))
  double molecularDiffusivity;  ///< D_m of the dissolved solute in the liquid (m²/s)
  /// Base-10 absorbance of a 1 cm path of the liquid per linear RGB channel,
  /// read at about 620, 520 and 420 nm.
  Eigen::Array3d absorbance1cm;
};

/// The built-in liquids: water, wine (red), coffee (brewed), ink (blue-black).
const std::vector<LiquidPreset>& liquidPresets();
/// The preset called `name` (exact, lower case); throws std::invalid_argument
/// naming the value and the accepted names otherwise.
const LiquidPreset& liquidPresetFromName(const std::string& name);
/// "water, wine, coffee, ink".
std::string liquidPresetNames();
/// ε_solute (m²/kg of solute) of the liquid: Beer–Lambert through the film
/// twice (in and out), ε_c = 2 ln10 · A_c / (0.01 m · ρ · soluteFraction);
/// zero for a liquid without solute.
Eigen::Array3d liquidSoluteAbsorbance(const LiquidPreset& liquid);
/// Washburn's law (L² = γ r cosθ t / (2μ)): the wicking diffusivity scales with
/// γ/μ; relative to water, at an equal contact angle.
double liquidWickingFactor(const LiquidPreset& liquid);
/// Kinematic viscosity μ/ρ relative to water's: the film's velocity diffusivity.
double liquidViscosityFactor(const LiquidPreset& liquid);

/// Colour of one vertex. Densities in kg/m². A negative density (a limiter
/// not yet applied) can brighten a channel, which the clamp bounds at 1;
/// non-finite input gives non-finite output (the renderer shows it magenta).
Eigen::Array3d stainColor(const StainColorMapping& mapping, double solvent, double solute,
                          double absorbedSolute, double adsorbedSolute);

/// Colours of all vertices into `vertexColors` (#V by 3, resized only if the
/// row count differs). All density vectors have #V entries (kg/m²); an empty
/// vector counts as zero everywhere. Throws std::invalid_argument on a length
/// mismatch.
void stainColors(const StainColorMapping& mapping, const Eigen::VectorXd& solvent,
                 const Eigen::VectorXd& solute, const Eigen::VectorXd& absorbedSolute,
                 const Eigen::VectorXd& adsorbedSolute, Eigen::MatrixX3d& vertexColors);

}  // namespace blot::engine
