#pragma once
/// The maps engines and compositors consume, baked into the mesh's UV layout:
/// wetness (the free film: gloss), saturation (liquid held in the fibres:
/// darkening) and stain (solute deposited in the fibres: colour). Houdini's
/// wet maps, Blender Dynamic Paint's wet and paint maps and game wetness decals
/// split a liquid on a surface this way; docs/rendering.md gives formats,
/// units and colour space.
///
/// | map | per vertex (kg/m²) | what it drives |
/// |---|---|---|
/// | wetness | σ_f + σ_s (free solvent + free solute) | gloss: roughness down |
/// | saturation | σ_p + σ_s,p (absorbed solvent + absorbed solute) | darkening |
/// | stain | σ_s,p + σ_s,a (absorbed + adsorbed solute) | colour |
///
/// All three are linear data (no transfer function), baked like every other
/// per-vertex field (uv_texture.h: P1 interpolation at texel centres, gutter).
#include <blot/engine/exr_image.h>
#include <blot/engine/image.h>
#include <blot/engine/uv_texture.h>

#include <Eigen/Core>

#include <string>

namespace blot::engine {

/// The maps, in this order: columns of stainMapValues, channels of its bake.
enum class StainMap { Wetness = 0, Saturation = 1, Stain = 2 };
inline constexpr int kStainMapCount = 3;

/// "wetness", "saturation", "stain": the file name part.
const char* stainMapName(StainMap map);
/// What the map sums, in the PLY attribute names, e.g. "solvent + solute".
const char* stainMapDefinition(StainMap map);

/// #V by 3 (kg/m²): wetness σ_f + σ_s, saturation σ_p + σ_s,p, stain
/// σ_s,p + σ_s,a, from the engine's per-vertex densities (each #V, kg/m²).
/// Throws std::invalid_argument when the lengths differ.
Eigen::MatrixX3d stainMapValues(const Eigen::VectorXd& solvent, const Eigen::VectorXd& solute,
                                const Eigen::VectorXd& absorbedSolvent, const Eigen::VectorXd& absorbedSolute,
                                const Eigen::VectorXd& adsorbedSolute);

/// Channel `channel` of `baked` as a one-channel (grey) data map of `bitDepth`
/// 8 or 16: sample = round(M · clamp(value / fullScale, 0, 1)), M = 255 or
/// 65535; texels outside the charts and their gutter are 0. Write it with
/// writeDataPng (linear: gAMA 1.0, no sRGB chunk). Throws
/// std::invalid_argument naming the argument.
Image16 dataMapChannel(const UvBake& baked, int channel, int bitDepth, double fullScale);

/// Channel `channel` of `baked` as a one-channel float image named
/// `channelName`, the baked value as is (kg/m² for the stain maps), 0 outside
/// the charts and their gutter. Throws std::invalid_argument naming the argument.
FloatImage floatMapChannel(const UvBake& baked, int channel, const std::string& channelName = "Y");

/// How wetness turns into the glTF material's roughness: linear from
/// dryRoughness at wetness 0 to wetRoughness at glossWetness and above.
/// Defaults: dry cloth fully rough (1, the material's value without liquid),
/// a free film of 0.1 kg/m² (0.1 mm of water) smooth as wet cloth (0.2).
struct GlossSettings {
  double dryRoughness = 1.0;
  double wetRoughness = 0.2;
  double glossWetness = 0.1;  ///< kg/m² (> 0)
};
double roughnessOfWetness(double wetness, const GlossSettings& gloss);

/// The glTF metallicRoughness texture of a wetness bake (channel
/// `wetnessChannel`): 8-bit RGB samples, R 255 (unused by glTF's metallic-
/// roughness model), G = round(255 · roughnessOfWetness), B 0 (metallic 0);
/// dry roughness outside the charts. Linear data, as glTF requires: encode
/// it with encodeDataPng. Throws std::invalid_argument naming the argument.
Image16 metallicRoughnessMap(const UvBake& baked, int wetnessChannel, const GlossSettings& gloss);

}  // namespace blot::engine
