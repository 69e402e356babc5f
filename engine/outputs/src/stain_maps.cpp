// Wetness, saturation and stain maps from one three-channel UV bake.
//
// Design note: the three per-vertex sums are baked together by
// bakeVertexValuesToUv (one rasterization for all three, the same coverage
// and gutter as the colour texture and density map), then each channel is
// quantized on its own for PNG or copied to float for EXR. The maps are
// separate files, one grey channel each, because that is how engines and
// compositors load a wet mask or a paint mask; the density map already packs
// channels for shaders that want one texture. Rejected: one RGB map (a
// material would need a channel split node in every tool).
#include <blot/engine/stain_maps.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace blot::engine {
namespace {

void checkChannel(const UvBake& baked, int channel, const char* who) {
  if (baked.width < 1 || baked.height < 1 || baked.channels < 1 ||
      baked.values.size() != static_cast<std::size_t>(baked.width) * baked.height * baked.channels ||
      baked.coverage.size() != static_cast<std::size_t>(baked.width) * baked.height)
    throw std::invalid_argument(std::string(who) + ": baked is empty or its arrays do not match its size");
  if (channel < 0 || channel >= baked.channels)
    throw std::invalid_argument(std::string(who) + ": channel " + std::to_string(channel) + ", expected 0 to " +
                                std::to_string(baked.channels - 1));
}

}  // namespace

const char* stainMapName(StainMap map) {
  switch (map) {
    case StainMap::Wetness: return "wetness";
    case StainMap::Saturation: return "saturation";
    case StainMap::Stain: return "stain";
  }
  return "?";
}

const char* stainMapDefinition(StainMap map) {
  switch (map) {
    case StainMap::Wetness: return "solvent + solute";
    case StainMap::Saturation: return "absorbed_solvent + absorbed_solute";
    case StainMap::Stain: return "absorbed_solute + adsorbed_solute";
  }
  return "?";
}

Eigen::MatrixX3d stainMapValues(const Eigen::VectorXd& solvent, const Eigen::VectorXd& solute,
                                const Eigen::VectorXd& absorbedSolvent, const Eigen::VectorXd& absorbedSolute,
                                const Eigen::VectorXd& adsorbedSolute) {
  const Eigen::Index n = solvent.size();
  if (solute.size() != n || absorbedSolvent.size() != n || absorbedSolute.size() != n || adsorbedSolute.size() != n)
    throw std::invalid_argument("stainMapValues: the five densities must have one value per vertex each (solvent has " +
                                std::to_string(n) + ")");
  Eigen::MatrixX3d values(n, kStainMapCount);
  values.col(static_cast<int>(StainMap::Wetness)) = solvent + solute;
  values.col(static_cast<int>(StainMap::Saturation)) = absorbedSolvent + absorbedSolute;
  values.col(static_cast<int>(StainMap::Stain)) = absorbedSolute + adsorbedSolute;
  return values;
}

Image16 dataMapChannel(const UvBake& baked, int channel, int bitDepth, double fullScale) {
  checkChannel(baked, channel, "dataMapChannel");
  if (bitDepth != 8 && bitDepth != 16)
    throw std::invalid_argument("dataMapChannel: bit depth " + std::to_string(bitDepth) + ", expected 8 or 16");
  if (!(fullScale > 0) || !std::isfinite(fullScale))
    throw std::invalid_argument("dataMapChannel: full scale " + std::to_string(fullScale) + ", expected > 0");
  const double top = bitDepth == 8 ? 255.0 : 65535.0;
  Image16 map;
  map.width = baked.width;
  map.height = baked.height;
  map.channels = 1;
  map.samples.assign(baked.coverage.size(), 0);
  for (std::size_t t = 0; t < baked.coverage.size(); ++t) {
    if (!baked.coverage[t]) continue;
    const double q = baked.values[t * baked.channels + channel] / fullScale;
    map.samples[t] = static_cast<std::uint16_t>(std::lround(top * std::min(1.0, std::max(0.0, q))));
  }
  return map;
}

FloatImage floatMapChannel(const UvBake& baked, int channel, const std::string& channelName) {
  checkChannel(baked, channel, "floatMapChannel");
  FloatImage image;
  image.width = baked.width;
  image.height = baked.height;
  image.channels = {channelName};
  image.samples.assign(baked.coverage.size(), 0.0f);
  for (std::size_t t = 0; t < baked.coverage.size(); ++t)
    if (baked.coverage[t]) image.samples[t] = static_cast<float>(baked.values[t * baked.channels + channel]);
  return image;
}

double roughnessOfWetness(double wetness, const GlossSettings& gloss) {
  const double w = std::min(1.0, std::max(0.0, wetness / gloss.glossWetness));
  return (1.0 - w) * gloss.dryRoughness + w * gloss.wetRoughness;  // exactly each end at w = 0 and 1
}

Image16 metallicRoughnessMap(const UvBake& baked, int wetnessChannel, const GlossSettings& gloss) {
  checkChannel(baked, wetnessChannel, "metallicRoughnessMap");
  const auto unit = [](double r) { return r >= 0 && r <= 1; };
  if (!(gloss.glossWetness > 0) || !std::isfinite(gloss.glossWetness) || !unit(gloss.dryRoughness) ||
      !unit(gloss.wetRoughness))
    throw std::invalid_argument("metallicRoughnessMap: gloss wetness " + std::to_string(gloss.glossWetness) +
                                " (expected > 0), roughness dry " + std::to_string(gloss.dryRoughness) + " and wet " +
                                std::to_string(gloss.wetRoughness) + " (expected in [0, 1])");
  const auto byte = [](double r) { return static_cast<std::uint16_t>(std::lround(255.0 * r)); };
  Image16 map;
  map.width = baked.width;
  map.height = baked.height;
  map.channels = 3;
  map.samples.resize(baked.coverage.size() * 3);
  for (std::size_t t = 0; t < baked.coverage.size(); ++t) {
    const double wetness = baked.coverage[t] ? baked.values[t * baked.channels + wetnessChannel] : 0.0;
    map.samples[3 * t] = 255;
    map.samples[3 * t + 1] = byte(roughnessOfWetness(wetness, gloss));
    map.samples[3 * t + 2] = 0;
  }
  return map;
}

}  // namespace blot::engine
