// Tests for blot::engine images: PNG round trips, atomic writes, the label
// font, contact sheets and side-by-side composition.
#include <blot/engine/image.h>
#include <blot/engine/output_options.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <unistd.h>

namespace blot::engine {
namespace {

namespace fs = std::filesystem;

class ImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() /
                 ("blot_image_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }
  std::string path(const std::string& name) const { return (directory_ / name).string(); }
  fs::path directory_;
};

Image randomImage(int width, int height, int channels, unsigned seed) {
  std::mt19937 generator(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  Image image(width, height, channels);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.setPixel(x, y,
                     Rgba8{static_cast<std::uint8_t>(byte(generator)),
                           static_cast<std::uint8_t>(byte(generator)),
                           static_cast<std::uint8_t>(byte(generator)),
                           static_cast<std::uint8_t>(byte(generator))});
    }
  }
  return image;
}

std::string fileBytes(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

TEST_F(ImageTest, PngRoundTripIsExactForRgbAndRgba) {
  for (int channels : {3, 4}) {
    const Image original = randomImage(37, 23, channels, 7u + static_cast<unsigned>(channels));
    const std::string file = path("round_trip_" + std::to_string(channels) + ".png");
    writePng(original, file);
    const Image read = readPng(file);
    EXPECT_EQ(read.width(), 37);
    EXPECT_EQ(read.height(), 23);
    EXPECT_EQ(read.channels(), channels);
    EXPECT_TRUE(read == original) << "channels " << channels;
  }
}

TEST_F(ImageTest, PngBytesDependOnlyOnPixels) {
  const Image image = randomImage(16, 16, 3, 3u);
  writePng(image, path("a.png"));
  writePng(image, path("b.png"));
  EXPECT_EQ(fileBytes(path("a.png")), fileBytes(path("b.png")));
}

TEST_F(ImageTest, PngWriteReplacesAtomicallyAndLeavesNoTemporary) {
  writePng(Image(4, 4, 3, {255, 0, 0, 255}), path("frame.png"));
  writePng(Image(5, 3, 3, {0, 0, 255, 255}), path("frame.png"));
  const Image read = readPng(path("frame.png"));
  EXPECT_EQ(read.width(), 5);
  EXPECT_EQ(read.pixel(2, 1), (Rgba8{0, 0, 255, 255}));
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(directory_)) {
    ++entries;
    EXPECT_EQ(entry.path().filename(), "frame.png");
  }
  EXPECT_EQ(entries, 1);
}

TEST_F(ImageTest, PngErrorsNameThePath) {
  const std::string missing = path("missing.png");
  try {
    readPng(missing);
    FAIL() << "expected ImageError";
  } catch (const ImageError& error) {
    EXPECT_NE(std::string(error.what()).find(missing), std::string::npos) << error.what();
  }
  std::ofstream(path("text.png")) << "not a png at all";
  EXPECT_THROW(readPng(path("text.png")), ImageError);
  // A truncated PNG: keep the signature and header, cut the data.
  writePng(randomImage(20, 20, 3, 11u), path("full.png"));
  const std::string bytes = fileBytes(path("full.png"));
  std::ofstream(path("cut.png"), std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  EXPECT_THROW(readPng(path("cut.png")), ImageError);
  // Writing into a folder that does not exist fails and creates nothing.
  EXPECT_THROW(writePng(Image(2, 2), path("no_such_dir/x.png")), ImageError);
  EXPECT_FALSE(fs::exists(path("no_such_dir")));
  EXPECT_THROW(writePng(Image(), path("empty.png")), ImageError);
}

/// The message of the ImageError `read` throws, or "" when it throws none.
template <typename Read>
std::string imageError(Read read) {
  try {
    read();
  } catch (const ImageError& error) {
    return error.what();
  }
  return "";
}

// Every PNG reader reads at most kPngFileByteLimit bytes: an endless file
// (/dev/zero, about 5 s) after that many, a larger regular file (sparse: no disk used)
// by its size before a byte; a folder by name. Each message names the path
// and the limit.
TEST_F(ImageTest, PngReadersRefuseEndlessAndOversizeFilesNamingTheLimit) {
  const std::string limit = std::to_string(kPngFileByteLimit);
  const std::string huge = path("huge.png");
  {
    std::ofstream file(huge, std::ios::binary);
    file << "\x89PNG\r\n\x1a\n";
  }
  fs::resize_file(huge, kPngFileByteLimit + 1);
  const std::string tooLarge = huge + ": the PNG file is " + std::to_string(kPngFileByteLimit + 1) +
                               " bytes, more than the limit of " + limit + " bytes";
  EXPECT_EQ(imageError([&] { readPng(huge); }), tooLarge);
  EXPECT_EQ(imageError([&] { readPng16(huge); }), tooLarge);
  EXPECT_EQ(imageError([&] { readPngInfo(huge); }), tooLarge);
  // One endless read (the three share their reader; each costs a 512 MiB read).
  const std::string endless = imageError([] { readPng16("/dev/zero"); });
  EXPECT_EQ(endless.rfind("/dev/zero: the PNG file has more than the limit of " + limit + " bytes", 0), 0u) << endless;
  EXPECT_EQ(imageError([&] { readPng(directory_.string()); }), directory_.string() + ": the PNG file is a directory");
  EXPECT_EQ(imageError([&] { readPng16(path("missing.png")); }),
            path("missing.png") + ": cannot open the PNG file: No such file or directory");
}

// A small file cannot declare a gigapixel image: wider or taller than
// kMaxImageSide is refused by libpng's user limit before rows are allocated.
TEST_F(ImageTest, PngReadersRefuseImagesWiderThanTheImageSideLimit) {
  Image16 wide;
  wide.width = kMaxImageSide + 1;
  wide.height = 1;
  wide.channels = 1;
  wide.samples.assign(static_cast<std::size_t>(wide.width), 7);
  writePng16(wide, path("wide.png"));
  for (const std::string& message : {imageError([&] { readPng(path("wide.png")); }),
                                     imageError([&] { readPng16(path("wide.png")); })})
    EXPECT_EQ(message, path("wide.png") +
                           ": PNG decoding failed: Invalid IHDR data (Image width exceeds user limit in IHDR)");
  wide.width = kMaxImageSide;
  wide.samples.resize(static_cast<std::size_t>(wide.width));
  writePng16(wide, path("wide.png"));
  EXPECT_EQ(readPng16(path("wide.png")).width, kMaxImageSide);
}

TEST(ImageBasics, ConstructorValidatesAndFills) {
  EXPECT_THROW(Image(2, 2, 2), std::invalid_argument);
  EXPECT_THROW(Image(-1, 2), std::invalid_argument);
  const Image image(3, 2, 4, {1, 2, 3, 4});
  EXPECT_EQ(image.bytes().size(), 3u * 2u * 4u);
  EXPECT_EQ(image.pixel(2, 1), (Rgba8{1, 2, 3, 4}));
  const Image rgb(3, 2, 3, {1, 2, 3, 4});
  EXPECT_EQ(rgb.pixel(0, 0), (Rgba8{1, 2, 3, 255}));  // RGB reports opaque
}

TEST(ImageText, GlyphBitsAreDrawnAtScale) {
  // 'I' is columns {0x00, 0x41, 0x7F, 0x41, 0x00}: a full vertical bar in
  // column 2 with serifs at rows 0 and 6 in columns 1 and 3.
  Image image(20, 20, 3, {255, 255, 255, 255});
  const Rgba8 black{0, 0, 0, 255};
  drawText(image, 2, 3, "I", black, 2);
  for (int row = 0; row < 7; ++row) {
    for (int column = 0; column < 5; ++column) {
      const bool expected = column == 2 || ((column == 1 || column == 3) && (row == 0 || row == 6));
      for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
          EXPECT_EQ(image.pixel(2 + 2 * column + dx, 3 + 2 * row + dy) == black, expected)
              << "row " << row << " column " << column;
        }
      }
    }
  }
  EXPECT_EQ(textWidth("AB", 1), 11);
  EXPECT_EQ(textWidth("AB", 3), 33);
  EXPECT_EQ(textWidth("", 2), 0);
  EXPECT_EQ(textHeight(2), 14);
  // Clipped at the border without crashing; unknown characters draw '?'.
  drawText(image, 17, 17, "\x01", black, 1);
  EXPECT_EQ(image.pixel(17 + 1, 17 + 0), black);  // '?' column 1 = 0x01: top pixel set
}

TEST(ImageCompose, ContactSheetLayout) {
  const Rgba8 red{255, 0, 0, 255}, green{0, 255, 0, 255}, blue{0, 0, 255, 255};
  const std::vector<Image> images = {Image(10, 8, 3, red), Image(10, 8, 3, green),
                                     Image(6, 4, 3, blue)};
  ContactSheetOptions options;
  options.columns = 2;
  options.margin = 4;
  options.background = {200, 200, 200, 255};
  const Image sheet = contactSheet(images, {}, options);
  ASSERT_EQ(sheet.width(), 4 + 2 * (10 + 4));
  ASSERT_EQ(sheet.height(), 4 + 2 * (8 + 4));
  EXPECT_EQ(sheet.channels(), 3);
  EXPECT_EQ(sheet.pixel(0, 0), options.background);
  EXPECT_EQ(sheet.pixel(4, 4), red);
  EXPECT_EQ(sheet.pixel(13, 11), red);
  EXPECT_EQ(sheet.pixel(14, 4), options.background);  // gap between cells
  EXPECT_EQ(sheet.pixel(18, 4), green);
  // The small blue image is centred in the 10 x 8 cell at (4, 16): offset (2, 2).
  EXPECT_EQ(sheet.pixel(4 + 2, 16 + 2), blue);
  EXPECT_EQ(sheet.pixel(4 + 1, 16 + 2), options.background);
  EXPECT_EQ(sheet.pixel(4 + 7, 16 + 5), blue);
  EXPECT_EQ(sheet.pixel(4 + 8, 16 + 5), options.background);
  EXPECT_THROW(contactSheet({}, {}, options), std::invalid_argument);
  EXPECT_THROW(contactSheet(images, {"one"}, options), std::invalid_argument);
}

TEST(ImageCompose, LabelsGoBelowTheirImageAndWidenCells) {
  const Rgba8 white{255, 255, 255, 255}, grey{128, 128, 128, 255}, black{0, 0, 0, 255};
  const std::vector<Image> images = {Image(4, 4, 3, grey), Image(4, 4, 3, grey)};
  ContactSheetOptions options;
  options.margin = 6;
  options.columns = 2;
  const Image sheet = contactSheet(images, {"WIDE LABEL", "x"}, options);
  const int cellWidth = textWidth("WIDE LABEL");
  EXPECT_EQ(sheet.width(), 6 + 2 * (cellWidth + 6));
  // Label band starts margin/2 = 3 pixels below the 4-pixel image.
  const int bandTop = 6 + 4 + 3;
  EXPECT_EQ(sheet.height(), 6 + (4 + 3 + textHeight() + 6));
  int blackInBand[2] = {0, 0};
  int blackElsewhere = 0;
  for (int y = 0; y < sheet.height(); ++y) {
    for (int x = 0; x < sheet.width(); ++x) {
      if (sheet.pixel(x, y) != black) continue;
      const bool inBand = y >= bandTop && y < bandTop + textHeight();
      if (inBand) {
        ++blackInBand[x < 6 + cellWidth + 3 ? 0 : 1];
      } else {
        ++blackElsewhere;
      }
    }
  }
  EXPECT_GT(blackInBand[0], 30);  // ten glyphs
  EXPECT_GT(blackInBand[1], 3);   // 'x'
  EXPECT_EQ(blackElsewhere, 0);
  // Images are centred horizontally in the widened cell.
  EXPECT_EQ(sheet.pixel(6 + (cellWidth - 4) / 2, 6), grey);
  EXPECT_EQ(sheet.pixel(6 + (cellWidth - 4) / 2 - 1, 6), white);
}

TEST(ImageCompose, SideBySideIsOneRowAndKeepsAlpha) {
  const Image left(3, 5, 3, {10, 20, 30, 255});
  const Image right(3, 5, 4, {40, 50, 60, 255});
  const Image row = sideBySide({left, right}, {}, 2, {0, 0, 0, 255});
  EXPECT_EQ(row.width(), 2 + 2 * (3 + 2));
  EXPECT_EQ(row.height(), 2 + 5 + 2);
  EXPECT_EQ(row.channels(), 4);
  EXPECT_EQ(row.pixel(2, 2), (Rgba8{10, 20, 30, 255}));
  EXPECT_EQ(row.pixel(7, 2), (Rgba8{40, 50, 60, 255}));
}

TEST(ImageCompose, BlitBlendsStraightAlpha) {
  Image target(2, 1, 3, {0, 0, 200, 255});
  const Image source(1, 1, 4, {255, 100, 0, 128});
  blit(target, source, 1, 0);
  // out = (s a + t (255 - a)) / 255, rounded.
  EXPECT_EQ(target.pixel(1, 0), (Rgba8{128, 50, 100, 255}));
  EXPECT_EQ(target.pixel(0, 0), (Rgba8{0, 0, 200, 255}));
  blit(target, Image(3, 3, 3, {1, 1, 1, 255}), -2, -1);  // clipped to pixel (0, 0)
  EXPECT_EQ(target.pixel(0, 0), (Rgba8{1, 1, 1, 255}));
  EXPECT_EQ(target.pixel(1, 0), (Rgba8{128, 50, 100, 255}));
}

}  // namespace
}  // namespace blot::engine
