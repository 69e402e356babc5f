// sRGB transfer function (IEC 61966-2-1), used by every 8-bit colour output.
#include <blot/engine/color_space.h>

#include <algorithm>
#include <cmath>

namespace blot::engine {
namespace {
double clamp01(double c) { return c > 0 ? std::min(c, 1.0) : 0.0; }  // NaN -> 0
}  // namespace

double srgbEncode(double linear) {
  const double c = clamp01(linear);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}

double srgbDecode(double encoded) {
  const double e = clamp01(encoded);
  return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}

std::uint8_t linearToSrgbByte(double linear) {
  return static_cast<std::uint8_t>(std::lround(255.0 * srgbEncode(linear)));
}

double srgbByteToLinear(std::uint8_t byte) { return srgbDecode(byte / 255.0); }

}  // namespace blot::engine
