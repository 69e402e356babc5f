#pragma once
/// The one colour convention of Blot's outputs (docs/rendering.md "Colour"):
///
/// - Every colour the engine computes (Engine::colors(), stainColors(), the
///   renderer's shading, RenderSettings colours) is *linear* RGB in [0, 1]:
///   proportional to light, so shading and mixing are plain multiplications.
/// - Every 8-bit colour written to a file (PNG images and colour textures, PLY
///   red/green/blue) is *sRGB-encoded* with the IEC 61966-2-1 transfer
///   function, byte = round(255 · srgbEncode(clamp(c, 0, 1))), and PNGs carry
///   the sRGB chunk (plus the gAMA/cHRM fallback libpng writes with it).
/// - Data textures (the density maps) and glTF COLOR_0 stay linear: the
///   density PNG has gAMA 1.0 and no sRGB chunk; glTF requires linear vertex
///   colours and declares base-colour textures sRGB.
#include <cstdint>

namespace blot::engine {

/// sRGB transfer function (encode): linear c in [0, 1] -> non-linear value in
/// [0, 1]; 12.92 c below 0.0031308, 1.055 c^(1/2.4) − 0.055 above. Input is
/// clamped to [0, 1]; NaN gives 0.
double srgbEncode(double linear);
/// Its inverse (decode): sRGB value in [0, 1] -> linear; clamped, NaN gives 0.
double srgbDecode(double encoded);
/// round(255 · srgbEncode(linear)): the byte every 8-bit colour output writes.
std::uint8_t linearToSrgbByte(double linear);
/// srgbDecode(byte / 255).
double srgbByteToLinear(std::uint8_t byte);

}  // namespace blot::engine
