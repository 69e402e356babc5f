#pragma once
/// Float OpenEXR files of data maps (the stain maps of stain_maps.h), through
/// OpenEXR when Blot is built with it (CMake option BLOT_WITH_OPENEXR, used
/// when Debian's libopenexr-dev is found). Without it exrSupported() is false
/// and writeExr throws MissingFeatureError saying what to install.
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace blot::engine {

/// 32-bit float samples, row-major, top row first, channels interleaved.
struct FloatImage {
  int width = 0, height = 0;
  std::vector<std::string> channels;  ///< channel names, e.g. {"Y"} for one grey channel
  std::vector<float> samples;         ///< width * height * channels.size()
};

/// A requested output this build of Blot cannot write (it was built without
/// the library); the message names the library, the package and the option.
class MissingFeatureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Whether this build writes OpenEXR files.
bool exrSupported();

/// What to say when EXR is asked for in a build without OpenEXR: the CMake
/// option and the Debian package.
std::string exrMissingHelp();

/// Writes `image` as a scan-line OpenEXR file, FLOAT channels, lossless ZIP
/// compression, data window (0, 0)–(width − 1, height − 1), atomically
/// (encoded in memory, then a temporary file renamed over `path`).
/// `attributes` become string attributes of the header (name, value), e.g.
/// the quantity and its unit. Throws MissingFeatureError without OpenEXR,
/// std::invalid_argument naming the path on a malformed image, and
/// std::runtime_error naming the path on an encoding or write failure.
void writeExr(const FloatImage& image, const std::string& path,
              const std::vector<std::pair<std::string, std::string>>& attributes = {});

}  // namespace blot::engine
