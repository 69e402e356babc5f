#pragma once
/// 8-bit RGB / RGBA images: PNG files (written atomically), contact sheets and
/// side-by-side comparisons with small text labels. Pixels are stored row-major,
/// top row first, channels interleaved; values are sRGB-encoded bytes
/// (color_space.h), and writePng marks them so with the sRGB chunk.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::engine {

/// A colour as bytes; alpha is ignored when drawn into an RGB image.
struct Rgba8 {
  std::uint8_t r = 0, g = 0, b = 0, a = 255;
  friend bool operator==(const Rgba8& p, const Rgba8& q) {
    return p.r == q.r && p.g == q.g && p.b == q.b && p.a == q.a;
  }
  friend bool operator!=(const Rgba8& p, const Rgba8& q) { return !(p == q); }
};

/// The most bytes readPng, readPng16 and readPngInfo read from one file
/// (512 MiB): a larger file is refused by its size before a byte is read, an
/// endless one (a pipe, /dev/zero) after this many. Decoded images are also
/// limited to kMaxImageSide (output_options.h) along each side.
inline constexpr std::size_t kPngFileByteLimit = std::size_t(512) << 20;

/// PNG read/write failures (file names the path and libpng's message).
class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Image {
 public:
  Image() = default;
  /// width x height pixels (>= 0) with 3 (RGB) or 4 (RGBA) channels, filled with `fill`.
  Image(int width, int height, int channels = 3, Rgba8 fill = {0, 0, 0, 255});

  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  bool empty() const { return width_ == 0 || height_ == 0; }

  /// Pixel (x, y), x to the right, y down; alpha is 255 for RGB images. Unchecked.
  Rgba8 pixel(int x, int y) const;
  /// Sets pixel (x, y) (alpha dropped for RGB images). Unchecked.
  void setPixel(int x, int y, Rgba8 color);
  /// Like setPixel but ignores coordinates outside the image.
  void setPixelClipped(int x, int y, Rgba8 color);
  void fill(Rgba8 color);

  /// First byte of row y (width * channels bytes).
  std::uint8_t* row(int y) { return bytes_.data() + rowOffset(y); }
  const std::uint8_t* row(int y) const { return bytes_.data() + rowOffset(y); }
  /// All bytes, height * width * channels.
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

  friend bool operator==(const Image& p, const Image& q) {
    return p.width_ == q.width_ && p.height_ == q.height_ && p.channels_ == q.channels_ &&
           p.bytes_ == q.bytes_;
  }
  friend bool operator!=(const Image& p, const Image& q) { return !(p == q); }

 private:
  std::size_t rowOffset(int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) *
           static_cast<std::size_t>(channels_);
  }
  int width_ = 0;
  int height_ = 0;
  int channels_ = 3;
  std::vector<std::uint8_t> bytes_;
};

/// Writes `image` as an 8-bit RGB or RGBA PNG, atomically (temporary file +
/// rename), with the sRGB chunk (rendering intent perceptual) and the gAMA
/// (1/2.2) and cHRM chunks libpng pairs with it. Output bytes depend only on
/// the pixels (no timestamp). Throws ImageError on an empty image or a write failure.
void writePng(const Image& image, const std::string& path);
/// The bytes writePng would write (e.g. to embed in a glTF file).
std::vector<std::uint8_t> encodePng(const Image& image);

/// 16-bit samples, 1 (grey), 2 (grey + alpha), 3 (RGB) or 4 (RGBA) channels,
/// row-major, top row first: data maps (e.g. stain densities), not colours.
/// Also holds 8-bit data maps (samples 0-255, written by writeDataPng at depth 8).
struct Image16 {
  int width = 0, height = 0, channels = 4;
  std::vector<std::uint16_t> samples;  ///< width * height * channels
};

/// Writes a 16-bit PNG atomically, marked linear (gAMA 1.0, no sRGB chunk),
/// with `text` as tEXt key/value pairs (even count: key, value, key, value…).
/// Throws ImageError naming the path on a malformed image or a write failure.
void writePng16(const Image16& image, const std::string& path, const std::vector<std::string>& text = {});
/// The same at `bitDepth` 8 (every sample 0-255) or 16: a data PNG, marked
/// linear (gAMA 1.0, no sRGB chunk), 1-4 channels (grey, grey + alpha, RGB,
/// RGBA). Throws ImageError naming the path on a bad depth, a sample above
/// 255 at depth 8, a malformed image or a write failure.
void writeDataPng(const Image16& image, int bitDepth, const std::string& path,
                  const std::vector<std::string>& text = {});
/// The bytes writeDataPng would write (e.g. to embed in a glTF file).
std::vector<std::uint8_t> encodeDataPng(const Image16& image, int bitDepth, const std::vector<std::string>& text = {});

/// Reads a 16-bit, non-interlaced PNG (grey, grey+alpha, RGB, RGBA) exactly;
/// throws ImageError naming the path for any other file.
Image16 readPng16(const std::string& path);

/// What a PNG file says about itself (header and colour-space chunks).
struct PngFileInfo {
  int width = 0, height = 0, bitDepth = 0, channels = 0;
  int srgbIntent = -1;  ///< the sRGB chunk's rendering intent (0-3), -1 when the file has none
  double gamma = 0;     ///< the gAMA chunk's file gamma (0.45455 for sRGB, 1 for linear), 0 when none
};
/// Reads the header and colour chunks of a PNG; throws ImageError naming the path.
PngFileInfo readPngInfo(const std::string& path);

/// Reads a PNG of any colour type and depth into 8-bit RGB (or RGBA when the
/// file has alpha or transparency): palette and grey expanded, 16-bit reduced.
/// Throws ImageError naming the path on a missing or malformed file.
Image readPng(const std::string& path);

/// Copies `source` into `target` with its top-left corner at (x, y), clipped;
/// RGBA sources are alpha-blended over the target ("over", straight alpha).
void blit(Image& target, const Image& source, int x, int y);

/// Draws ASCII `text` with the built-in 5x7 bitmap font, each font pixel a
/// `scale` x `scale` block, top-left corner at (x, y), clipped. Characters
/// outside 32..126 are drawn as '?'. '\n' is not interpreted.
void drawText(Image& image, int x, int y, const std::string& text, Rgba8 color, int scale = 1);

/// Width and height in pixels that drawText uses for `text` (6 * scale per
/// character minus the trailing gap; 7 * scale high, 0 x 0 for empty text).
int textWidth(const std::string& text, int scale = 1);
int textHeight(int scale = 1);

struct ContactSheetOptions {
  /// Images per row; 0 picks ceil(sqrt(count)).
  int columns = 0;
  /// Pixels around the sheet and between cells.
  int margin = 8;
  Rgba8 background = {255, 255, 255, 255};
  Rgba8 labelColor = {0, 0, 0, 255};
  /// Font pixel size of the labels (>= 1).
  int labelScale = 1;
};

/// Arranges `images` in a grid, row by row. Every cell is as wide as the widest
/// image or label and as tall as the tallest image; images are centred in their
/// cell. When `labels` is non-empty it must have one entry per image, drawn
/// centred below each image. The result has 4 channels if any input does,
/// otherwise 3. Throws std::invalid_argument on no images or a label count mismatch.
Image contactSheet(const std::vector<Image>& images, const std::vector<std::string>& labels = {},
                   const ContactSheetOptions& options = {});

/// One row of images, left to right (a contact sheet with one row).
Image sideBySide(const std::vector<Image>& images, const std::vector<std::string>& labels = {},
                 int margin = 8, Rgba8 background = {255, 255, 255, 255});

}  // namespace blot::engine
