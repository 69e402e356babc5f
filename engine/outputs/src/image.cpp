// 8-bit images, PNG input/output through libpng, contact sheets and labels.
//
// Design note: PNG encoding goes to a memory buffer (png_set_write_fn) and the
// buffer is written with an atomic rename, so a preview is never seen half
// written. libpng reports errors by longjmp; the libpng calls therefore sit in
// small functions that own no C++ objects across setjmp (the image and buffers
// live in the caller), and the error text is carried out in a plain struct.
// Rejected: throwing C++ exceptions from the libpng error callback (unwinding
// through C frames built without -fexceptions is undefined) and stb_image_write
// (not packaged in Debian, and libpng is already required).
// The label font is the classic 5x7 dot-matrix set (the shapes of the HD44780
// LCD character generator), stored as five column bytes per glyph, bit 0 = top.
#include <blot/engine/image.h>

#include <blot/engine/output_options.h>
#include <blot/stain/io/atomic_file.h>
#include <blot/stain/io/bounded_read.h>

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace blot::engine {
namespace {

// ASCII 32..126, five columns each, least significant bit = top row.
constexpr std::uint8_t kFont5x7[95][5] = {
    {0x00, 0x00, 0x00, 0x00, 0x00}, {0x00, 0x00, 0x5F, 0x00, 0x00},  // space !
    {0x00, 0x07, 0x00, 0x07, 0x00}, {0x14, 0x7F, 0x14, 0x7F, 0x14},  // " #
    {0x24, 0x2A, 0x7F, 0x2A, 0x12}, {0x23, 0x13, 0x08, 0x64, 0x62},  // $ %
    {0x36, 0x49, 0x55, 0x22, 0x50}, {0x00, 0x05, 0x03, 0x00, 0x00},  // & '
    {0x00, 0x1C, 0x22, 0x41, 0x00}, {0x00, 0x41, 0x22, 0x1C, 0x00},  // ( )
    {0x14, 0x08, 0x3E, 0x08, 0x14}, {0x08, 0x08, 0x3E, 0x08, 0x08},  // * +
    {0x00, 0x50, 0x30, 0x00, 0x00}, {0x08, 0x08, 0x08, 0x08, 0x08},  // , -
    {0x00, 0x60, 0x60, 0x00, 0x00}, {0x20, 0x10, 0x08, 0x04, 0x02},  // . /
    {0x3E, 0x51, 0x49, 0x45, 0x3E}, {0x00, 0x42, 0x7F, 0x40, 0x00},  // 0 1
    {0x42, 0x61, 0x51, 0x49, 0x46}, {0x21, 0x41, 0x45, 0x4B, 0x31},  // 2 3
    {0x18, 0x14, 0x12, 0x7F, 0x10}, {0x27, 0x45, 0x45, 0x45, 0x39},  // 4 5
    {0x3C, 0x4A, 0x49, 0x49, 0x30}, {0x01, 0x71, 0x09, 0x05, 0x03},  // 6 7
    {0x36, 0x49, 0x49, 0x49, 0x36}, {0x06, 0x49, 0x49, 0x29, 0x1E},  // 8 9
    {0x00, 0x36, 0x36, 0x00, 0x00}, {0x00, 0x56, 0x36, 0x00, 0x00},  // : ;
    {0x08, 0x14, 0x22, 0x41, 0x00}, {0x14, 0x14, 0x14, 0x14, 0x14},  // < =
    {0x00, 0x41, 0x22, 0x14, 0x08}, {0x02, 0x01, 0x51, 0x09, 0x06},  // > ?
    {0x32, 0x49, 0x79, 0x41, 0x3E}, {0x7E, 0x11, 0x11, 0x11, 0x7E},  // @ A
    {0x7F, 0x49, 0x49, 0x49, 0x36}, {0x3E, 0x41, 0x41, 0x41, 0x22},  // B C
    {0x7F, 0x41, 0x41, 0x22, 0x1C}, {0x7F, 0x49, 0x49, 0x49, 0x41},  // D E
    {0x7F, 0x09, 0x09, 0x09, 0x01}, {0x3E, 0x41, 0x49, 0x49, 0x7A},  // F G
    {0x7F, 0x08, 0x08, 0x08, 0x7F}, {0x00, 0x41, 0x7F, 0x41, 0x00},  // H I
    {0x20, 0x40, 0x41, 0x3F, 0x01}, {0x7F, 0x08, 0x14, 0x22, 0x41},  // J K
    {0x7F, 0x40, 0x40, 0x40, 0x40}, {0x7F, 0x02, 0x0C, 0x02, 0x7F},  // L M
    {0x7F, 0x04, 0x08, 0x10, 0x7F}, {0x3E, 0x41, 0x41, 0x41, 0x3E},  // N O
    {0x7F, 0x09, 0x09, 0x09, 0x06}, {0x3E, 0x41, 0x51, 0x21, 0x5E},  // P Q
    {0x7F, 0x09, 0x19, 0x29, 0x46}, {0x46, 0x49, 0x49, 0x49, 0x31},  // R S
    {0x01, 0x01, 0x7F, 0x01, 0x01}, {0x3F, 0x40, 0x40, 0x40, 0x3F},  // T U
    {0x1F, 0x20, 0x40, 0x20, 0x1F}, {0x3F, 0x40, 0x38, 0x40, 0x3F},  // V W
    {0x63, 0x14, 0x08, 0x14, 0x63}, {0x07, 0x08, 0x70, 0x08, 0x07},  // X Y
    {0x61, 0x51, 0x49, 0x45, 0x43}, {0x00, 0x7F, 0x41, 0x41, 0x00},  // Z [
    {0x02, 0x04, 0x08, 0x10, 0x20}, {0x00, 0x41, 0x41, 0x7F, 0x00},  // backslash ]
    {0x04, 0x02, 0x01, 0x02, 0x04}, {0x40, 0x40, 0x40, 0x40, 0x40},  // ^ _
    {0x00, 0x01, 0x02, 0x04, 0x00}, {0x20, 0x54, 0x54, 0x54, 0x78},  // ` a
    {0x7F, 0x48, 0x44, 0x44, 0x38}, {0x38, 0x44, 0x44, 0x44, 0x20},  // b c
    {0x38, 0x44, 0x44, 0x48, 0x7F}, {0x38, 0x54, 0x54, 0x54, 0x18},  // d e
    {0x08, 0x7E, 0x09, 0x01, 0x02}, {0x08, 0x54, 0x54, 0x54, 0x3C},  // f g
    {0x7F, 0x08, 0x04, 0x04, 0x78}, {0x00, 0x44, 0x7D, 0x40, 0x00},  // h i
    {0x20, 0x40, 0x44, 0x3D, 0x00}, {0x7F, 0x10, 0x28, 0x44, 0x00},  // j k
    {0x00, 0x41, 0x7F, 0x40, 0x00}, {0x7C, 0x04, 0x18, 0x04, 0x78},  // l m
    {0x7C, 0x08, 0x04, 0x04, 0x78}, {0x38, 0x44, 0x44, 0x44, 0x38},  // n o
    {0x7C, 0x14, 0x14, 0x14, 0x08}, {0x08, 0x14, 0x14, 0x14, 0x7C},  // p q
    {0x7C, 0x08, 0x04, 0x04, 0x08}, {0x48, 0x54, 0x54, 0x54, 0x20},  // r s
    {0x04, 0x3F, 0x44, 0x40, 0x20}, {0x3C, 0x40, 0x40, 0x20, 0x7C},  // t u
    {0x1C, 0x20, 0x40, 0x20, 0x1C}, {0x3C, 0x40, 0x30, 0x40, 0x3C},  // v w
    {0x44, 0x28, 0x10, 0x28, 0x44}, {0x0C, 0x50, 0x50, 0x50, 0x3C},  // x y
    {0x44, 0x64, 0x54, 0x4C, 0x44}, {0x00, 0x08, 0x36, 0x41, 0x00},  // z {
    {0x00, 0x00, 0x7F, 0x00, 0x00}, {0x00, 0x41, 0x36, 0x08, 0x00},  // | }
    {0x10, 0x08, 0x08, 0x10, 0x08},                                  // ~
};

constexpr int kGlyphWidth = 5;
constexpr int kGlyphHeight = 7;
constexpr int kGlyphAdvance = 6;

// ---- libpng glue. No C++ object with a destructor lives across setjmp. ----

struct PngStatus {
  char message[256] = {0};
  char warning[256] = {0};  // the first warning: libpng explains a refused header there
};

void pngError(png_structp png, png_const_charp message) {
  auto* status = static_cast<PngStatus*>(png_get_error_ptr(png));
  std::snprintf(status->message, sizeof status->message, "%s", message);
  png_longjmp(png, 1);
}

void pngWarning(png_structp png, png_const_charp message) {
  auto* status = static_cast<PngStatus*>(png_get_error_ptr(png));
  if (status->warning[0] == '\0') std::snprintf(status->warning, sizeof status->warning, "%s", message);
}

struct PngWriteBuffer {
  std::vector<std::uint8_t>* bytes;
};

void pngWriteToBuffer(png_structp png, png_bytep data, png_size_t length) {
  auto* buffer = static_cast<PngWriteBuffer*>(png_get_io_ptr(png));
  try {
    buffer->bytes->insert(buffer->bytes->end(), data, data + length);
  } catch (...) {
    png_error(png, "out of memory while encoding");
  }
}

void pngFlush(png_structp) {}

bool encodePng(const Image& image, std::vector<std::uint8_t>& out, PngStatus& status) {
  PngWriteBuffer buffer{&out};
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &status, pngError, pngWarning);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, &buffer, pngWriteToBuffer, pngFlush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width()),
               static_cast<png_uint_32>(image.height()), 8,
               image.channels() == 4 ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // The bytes are sRGB-encoded (color_space.h): the sRGB chunk says so, with
  // the gAMA 1/2.2 and cHRM (BT.709 primaries) that readers without sRGB support use.
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  for (int y = 0; y < image.height(); ++y) {
    png_write_row(png, image.row(y));
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

struct PngReadBuffer {
  const std::string* bytes;
  std::size_t offset;
};

/// A read struct that refuses images wider or taller than kMaxImageSide
/// (libpng: "Image width exceeds user limit in IHDR") before allocating rows,
/// so a small file cannot declare a gigapixel image.
png_structp createPngReader(PngStatus& status) {
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &status, pngError, pngWarning);
  if (png != nullptr) png_set_user_limits(png, kMaxImageSide, kMaxImageSide);
  return png;
}

void pngReadFromBuffer(png_structp png, png_bytep data, png_size_t length) {
  auto* buffer = static_cast<PngReadBuffer*>(png_get_io_ptr(png));
  if (length > buffer->bytes->size() - buffer->offset) png_error(png, "file is truncated");
  std::memcpy(data, buffer->bytes->data() + buffer->offset, length);
  buffer->offset += length;
}

// Decodes into `image`, which the caller owns (so no destructor is skipped by longjmp).
bool decodePng(const std::string& bytes, Image& image, PngStatus& status) {
  PngReadBuffer buffer{&bytes, 0};
  png_structp png = createPngReader(status);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_set_read_fn(png, &buffer, pngReadFromBuffer);
  png_read_info(png, info);
  const png_byte colorType = png_get_color_type(png, info);
  const png_byte bitDepth = png_get_bit_depth(png, info);
  if (colorType == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (colorType == PNG_COLOR_TYPE_GRAY || colorType == PNG_COLOR_TYPE_GRAY_ALPHA) {
    if (bitDepth < 8) png_set_expand_gray_1_2_4_to_8(png);
    png_set_gray_to_rgb(png);
  }
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (bitDepth == 16) png_set_strip_16(png);
  const int passes = png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const int channels = png_get_channels(png, info);
  if (channels != 3 && channels != 4) png_error(png, "unsupported channel layout");
  const auto width = static_cast<int>(png_get_image_width(png, info));
  const auto height = static_cast<int>(png_get_image_height(png, info));
  image = Image(width, height, channels);
  // Interlaced images need every row present in each pass.
  for (int pass = 0; pass < passes; ++pass) {
    for (int y = 0; y < height; ++y) png_read_row(png, image.row(y), nullptr);
  }
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

// A data PNG of `bitDepth` 8 or 16 (samples then 0-255 or 0-65535).
// `rowBytes` (2 * width * channels bytes) and `texts` are the caller's, so no
// destructor is skipped by libpng's longjmp.
bool encodeDataPng(const Image16& image, int bitDepth, std::vector<std::uint8_t>& out, PngStatus& status,
                   const std::vector<std::string>* textPairs, std::uint8_t* rowBytes, std::vector<png_text>& texts) {
  PngWriteBuffer buffer{&out};
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &status, pngError, pngWarning);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, &buffer, pngWriteToBuffer, pngFlush);
  static const int kColorTypes[5] = {0, PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                                     PNG_COLOR_TYPE_RGB_ALPHA};
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), bitDepth,
               kColorTypes[image.channels], PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  // Data, not colour: gamma 1.0 (linear), no sRGB chunk.
  png_set_gAMA_fixed(png, info, PNG_GAMMA_LINEAR);
  if (textPairs != nullptr) {
    for (std::size_t k = 0; k + 1 < textPairs->size(); k += 2) {
      png_text t{};
      t.compression = PNG_TEXT_COMPRESSION_NONE;
      t.key = const_cast<char*>((*textPairs)[k].c_str());
      t.text = const_cast<char*>((*textPairs)[k + 1].c_str());
      texts.push_back(t);
    }
    if (!texts.empty()) png_set_text(png, info, texts.data(), static_cast<int>(texts.size()));
  }
  png_write_info(png, info);
  // PNG stores 16-bit samples big-endian, whatever the host's byte order.
  const std::size_t rowLength = static_cast<std::size_t>(image.width) * image.channels;
  std::uint8_t* row = rowBytes;
  for (int y = 0; y < image.height; ++y) {
    const std::uint16_t* in = image.samples.data() + rowLength * y;
    if (bitDepth == 8) {
      for (std::size_t k = 0; k < rowLength; ++k) row[k] = static_cast<std::uint8_t>(in[k]);
    } else {
      for (std::size_t k = 0; k < rowLength; ++k) {
        row[2 * k] = static_cast<std::uint8_t>(in[k] >> 8);
        row[2 * k + 1] = static_cast<std::uint8_t>(in[k] & 0xFF);
      }
    }
    png_write_row(png, row);
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

bool readPngInfoFrom(const std::string& bytes, PngFileInfo& result, PngStatus& status) {
  PngReadBuffer buffer{&bytes, 0};
  png_structp png = createPngReader(status);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_set_read_fn(png, &buffer, pngReadFromBuffer);
  png_read_info(png, info);
  result.width = static_cast<int>(png_get_image_width(png, info));
  result.height = static_cast<int>(png_get_image_height(png, info));
  result.bitDepth = png_get_bit_depth(png, info);
  result.channels = png_get_channels(png, info);
  int intent = 0;
  result.srgbIntent = png_get_sRGB(png, info, &intent) != 0 ? intent : -1;
  double gamma = 0;
  result.gamma = png_get_gAMA(png, info, &gamma) != 0 ? gamma : 0.0;
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

// 16-bit files only; `image` and `row` belong to the caller (longjmp).
bool decodePng16(const std::string& bytes, Image16& image, std::vector<std::uint8_t>& row,
                 PngStatus& status) {
  PngReadBuffer buffer{&bytes, 0};
  png_structp png = createPngReader(status);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_set_read_fn(png, &buffer, pngReadFromBuffer);
  png_read_info(png, info);
  if (png_get_bit_depth(png, info) != 16) png_error(png, "not a 16-bit PNG");
  if (png_get_color_type(png, info) == PNG_COLOR_TYPE_PALETTE) png_error(png, "16-bit palette PNG");
  if (png_get_interlace_type(png, info) != PNG_INTERLACE_NONE) png_error(png, "interlaced 16-bit PNG");
  image.width = static_cast<int>(png_get_image_width(png, info));
  image.height = static_cast<int>(png_get_image_height(png, info));
  image.channels = png_get_channels(png, info);
  const std::size_t rowLength = static_cast<std::size_t>(image.width) * image.channels;
  image.samples.resize(rowLength * image.height);
  row.resize(2 * rowLength);
  for (int y = 0; y < image.height; ++y) {
    png_read_row(png, row.data(), nullptr);
    for (std::size_t k = 0; k < rowLength; ++k)
      image.samples[rowLength * y + k] = static_cast<std::uint16_t>(row[2 * k] << 8 | row[2 * k + 1]);
  }
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

/// The one read of a PNG file: at most kPngFileByteLimit bytes (stain::
/// readFileBounded: a larger file by its size, an endless one such as
/// /dev/zero after the budget), and the 8-byte PNG signature checked.
std::string readPngFile(const std::string& path) {
  std::string bytes;
  try {
    bytes = stain::readFileBounded(path, kPngFileByteLimit, "the PNG file");
  } catch (const stain::FileReadError& error) {
    throw ImageError(error.what());
  }
  if (bytes.size() < 8 || png_sig_cmp(reinterpret_cast<png_const_bytep>(bytes.data()), 0, 8) != 0)
    throw ImageError(path + ": not a PNG file (bad signature)");
  return bytes;
}

/// "<path>: PNG decoding failed: <libpng's error> (<its first warning>)".
ImageError decodingFailed(const std::string& path, const PngStatus& status) {
  std::string message = path + ": PNG decoding failed: " + status.message;
  if (status.warning[0] != '\0') message += std::string(" (") + status.warning + ")";
  return ImageError(message);
}

/// The one write of an encoded PNG: whole, to a temporary renamed over `path`.
void writePngFile(const std::vector<std::uint8_t>& encoded, const std::string& path) {
  try {
    stain::writeFileAtomically(path, encoded.data(), encoded.size());
  } catch (const std::runtime_error& error) {
    throw ImageError(error.what());
  }
}

std::uint8_t blendChannel(std::uint8_t source, std::uint8_t target, std::uint8_t alpha) {
  const int value = source * alpha + target * (255 - alpha);
  return static_cast<std::uint8_t>((value + 127) / 255);
}

}  // namespace

Image::Image(int width, int height, int channels, Rgba8 fillColor)
    : width_(width), height_(height), channels_(channels) {
  if (width < 0 || height < 0) {
    throw std::invalid_argument("Image: negative size " + std::to_string(width) + " x " +
                                std::to_string(height));
  }
  if (channels != 3 && channels != 4) {
    throw std::invalid_argument("Image: channels must be 3 or 4, got " + std::to_string(channels));
  }
  bytes_.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
                static_cast<std::size_t>(channels));
  fill(fillColor);
}

Rgba8 Image::pixel(int x, int y) const {
  const std::uint8_t* p = row(y) + static_cast<std::size_t>(x) * channels_;
  return Rgba8{p[0], p[1], p[2], channels_ == 4 ? p[3] : std::uint8_t{255}};
}

void Image::setPixel(int x, int y, Rgba8 color) {
  std::uint8_t* p = row(y) + static_cast<std::size_t>(x) * channels_;
  p[0] = color.r;
  p[1] = color.g;
  p[2] = color.b;
  if (channels_ == 4) p[3] = color.a;
}

void Image::setPixelClipped(int x, int y, Rgba8 color) {
  if (x >= 0 && y >= 0 && x < width_ && y < height_) setPixel(x, y, color);
}

void Image::fill(Rgba8 color) {
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) setPixel(x, y, color);
  }
}

std::vector<std::uint8_t> encodePng(const Image& image) {
  if (image.empty()) throw ImageError("encodePng: cannot encode an empty image");
  std::vector<std::uint8_t> encoded;
  PngStatus status;
  if (!encodePng(image, encoded, status)) throw ImageError(std::string("encodePng: ") + status.message);
  return encoded;
}

void writePng(const Image& image, const std::string& path) {
  if (image.empty()) throw ImageError(path + ": cannot write an empty image as PNG");
  std::vector<std::uint8_t> encoded;
  PngStatus status;
  if (!encodePng(image, encoded, status)) {
    throw ImageError(path + ": PNG encoding failed: " + status.message);
  }
  writePngFile(encoded, path);
}

Image readPng(const std::string& path) {
  const std::string bytes = readPngFile(path);
  Image image;
  PngStatus status;
  if (!decodePng(bytes, image, status)) {
    throw decodingFailed(path, status);
  }
  return image;
}

namespace {

// Checks `image` and encodes it; errors name `who` (the path, or the function).
std::vector<std::uint8_t> checkedDataPng(const Image16& image, int bitDepth, const std::vector<std::string>& text,
                                         const std::string& who) {
  if (bitDepth != 8 && bitDepth != 16)
    throw ImageError(who + ": data PNG bit depth " + std::to_string(bitDepth) + ", expected 8 or 16");
  if (image.width < 1 || image.height < 1 || image.channels < 1 || image.channels > 4 ||
      image.samples.size() != static_cast<std::size_t>(image.width) * image.height * image.channels)
    throw ImageError(who + ": " + std::to_string(bitDepth) +
                     "-bit image must be at least 1x1 with 1-4 channels and width*height*channels samples");
  if (bitDepth == 8)
    for (std::size_t k = 0; k < image.samples.size(); ++k)
      if (image.samples[k] > 255)
        throw ImageError(who + ": sample " + std::to_string(k) + " is " + std::to_string(image.samples[k]) +
                         ", expected 0-255 in an 8-bit PNG");
  if (text.size() % 2 != 0) throw ImageError(who + ": PNG text must come as key, value pairs");
  std::vector<std::uint8_t> encoded;
  PngStatus status;
  std::vector<std::uint8_t> rowBytes(static_cast<std::size_t>(image.width) * image.channels * 2);
  std::vector<png_text> texts;
  texts.reserve(text.size() / 2);
  if (!encodeDataPng(image, bitDepth, encoded, status, &text, rowBytes.data(), texts))
    throw ImageError(who + ": PNG encoding failed: " + status.message);
  return encoded;
}

}  // namespace

std::vector<std::uint8_t> encodeDataPng(const Image16& image, int bitDepth, const std::vector<std::string>& text) {
  return checkedDataPng(image, bitDepth, text, "encodeDataPng");
}

void writeDataPng(const Image16& image, int bitDepth, const std::string& path, const std::vector<std::string>& text) {
  writePngFile(checkedDataPng(image, bitDepth, text, path), path);
}

void writePng16(const Image16& image, const std::string& path, const std::vector<std::string>& text) {
  writeDataPng(image, 16, path, text);
}

Image16 readPng16(const std::string& path) {
  const std::string bytes = readPngFile(path);
  Image16 image;
  std::vector<std::uint8_t> row;
  PngStatus status;
  if (!decodePng16(bytes, image, row, status)) throw decodingFailed(path, status);
  return image;
}

PngFileInfo readPngInfo(const std::string& path) {
  const std::string bytes = readPngFile(path);
  PngFileInfo info;
  PngStatus status;
  if (!readPngInfoFrom(bytes, info, status)) throw decodingFailed(path, status);
  return info;
}

void blit(Image& target, const Image& source, int x, int y) {
  const int x0 = std::max(0, x);
  const int y0 = std::max(0, y);
  const int x1 = std::min(target.width(), x + source.width());
  const int y1 = std::min(target.height(), y + source.height());
  for (int ty = y0; ty < y1; ++ty) {
    for (int tx = x0; tx < x1; ++tx) {
      const Rgba8 s = source.pixel(tx - x, ty - y);
      if (source.channels() == 3 || s.a == 255) {
        target.setPixel(tx, ty, s);
        continue;
      }
      const Rgba8 t = target.pixel(tx, ty);
      const auto alpha = static_cast<std::uint8_t>(s.a + (t.a * (255 - s.a) + 127) / 255);
      target.setPixel(tx, ty, Rgba8{blendChannel(s.r, t.r, s.a), blendChannel(s.g, t.g, s.a),
                                    blendChannel(s.b, t.b, s.a), alpha});
    }
  }
}

int textWidth(const std::string& text, int scale) {
  if (text.empty()) return 0;
  return (static_cast<int>(text.size()) * kGlyphAdvance - 1) * scale;
}

int textHeight(int scale) { return kGlyphHeight * scale; }

void drawText(Image& image, int x, int y, const std::string& text, Rgba8 color, int scale) {
  if (scale < 1) throw std::invalid_argument("drawText: scale must be >= 1");
  int penX = x;
  for (char character : text) {
    const auto code = static_cast<unsigned char>(character);
    const int glyph = (code >= 32 && code <= 126) ? code - 32 : '?' - 32;
    for (int column = 0; column < kGlyphWidth; ++column) {
      const std::uint8_t bits = kFont5x7[glyph][column];
      for (int rowIndex = 0; rowIndex < kGlyphHeight; ++rowIndex) {
        if ((bits >> rowIndex & 1u) == 0) continue;
        for (int dy = 0; dy < scale; ++dy) {
          for (int dx = 0; dx < scale; ++dx) {
            image.setPixelClipped(penX + column * scale + dx, y + rowIndex * scale + dy, color);
          }
        }
      }
    }
    penX += kGlyphAdvance * scale;
  }
}

Image contactSheet(const std::vector<Image>& images, const std::vector<std::string>& labels,
                   const ContactSheetOptions& options) {
  if (images.empty()) throw std::invalid_argument("contactSheet: no images");
  if (!labels.empty() && labels.size() != images.size()) {
    throw std::invalid_argument("contactSheet: " + std::to_string(labels.size()) +
                                " labels for " + std::to_string(images.size()) + " images");
  }
  if (options.margin < 0 || options.labelScale < 1 || options.columns < 0) {
    throw std::invalid_argument("contactSheet: margin and columns must be >= 0, labelScale >= 1");
  }
  const int count = static_cast<int>(images.size());
  const int columns =
      options.columns > 0 ? std::min(options.columns, count)
                          : static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
  const int rows = (count + columns - 1) / columns;
  int cellWidth = 0;
  int imageHeight = 0;
  int channels = 3;
  for (int k = 0; k < count; ++k) {
    cellWidth = std::max(cellWidth, images[k].width());
    imageHeight = std::max(imageHeight, images[k].height());
    if (images[k].channels() == 4) channels = 4;
    if (!labels.empty()) cellWidth = std::max(cellWidth, textWidth(labels[k], options.labelScale));
  }
  const int labelGap = std::max(2, options.margin / 2);
  const int labelBand = labels.empty() ? 0 : labelGap + textHeight(options.labelScale);
  const int cellHeight = imageHeight + labelBand;
  const int margin = options.margin;
  Image sheet(margin + columns * (cellWidth + margin), margin + rows * (cellHeight + margin),
              channels, options.background);
  for (int k = 0; k < count; ++k) {
    const int cellX = margin + (k % columns) * (cellWidth + margin);
    const int cellY = margin + (k / columns) * (cellHeight + margin);
    const Image& image = images[k];
    blit(sheet, image, cellX + (cellWidth - image.width()) / 2,
         cellY + (imageHeight - image.height()) / 2);
    if (!labels.empty()) {
      drawText(sheet, cellX + (cellWidth - textWidth(labels[k], options.labelScale)) / 2,
               cellY + imageHeight + labelGap, labels[k], options.labelColor, options.labelScale);
    }
  }
  return sheet;
}

Image sideBySide(const std::vector<Image>& images, const std::vector<std::string>& labels,
                 int margin, Rgba8 background) {
  ContactSheetOptions options;
  options.columns = static_cast<int>(images.size());
  options.margin = margin;
  options.background = background;
  return contactSheet(images, labels, options);
}

}  // namespace blot::engine
