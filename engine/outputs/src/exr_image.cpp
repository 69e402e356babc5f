// Float OpenEXR files through OpenEXR (Debian's libopenexr-dev), optional.
//
// Design note: the file is encoded into memory through an Imf::OStream and
// written whole with stain::writeFileAtomically, like every other output, so
// a reader or a kill never sees half a file. FLOAT channels (not HALF): the
// maps hold kg/m² with no normalisation, and half's 11-bit mantissa would
// round a thin film next to a thick rim. Rejected: tinyexr (not packaged in
// Debian 12) and OpenEXR's file constructor (it writes in place, no rename).
// Built without OpenEXR (BLOT_HAVE_OPENEXR unset), the same functions refuse
// with what to install, so callers need no #if of their own.
#include <blot/engine/exr_image.h>

#include <blot/stain/io/atomic_file.h>

#if BLOT_HAVE_OPENEXR
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#endif

#include <cmath>
#include <cstdint>
#include <cstring>

namespace blot::engine {

std::string exrMissingHelp() {
  return "this blot was built without OpenEXR; install it (Debian: apt-get install libopenexr-dev) and "
         "rebuild (the CMake option BLOT_WITH_OPENEXR, on by default, uses it when found), or ask for "
         "png8/png16 maps";
}

#if BLOT_HAVE_OPENEXR
namespace {

// An Imf::OStream into a byte string (OpenEXR seeks back to write the line
// offset table, so writes may land inside what is already there).
class MemoryStream : public Imf::OStream {
 public:
  MemoryStream() : Imf::OStream("memory") {}
  void write(const char c[], int n) override {
    const std::size_t end = position_ + static_cast<std::size_t>(n);
    if (end > bytes_.size()) bytes_.resize(end);
    std::memcpy(bytes_.data() + position_, c, static_cast<std::size_t>(n));
    position_ = end;
  }
  std::uint64_t tellp() override { return position_; }
  void seekp(std::uint64_t position) override { position_ = static_cast<std::size_t>(position); }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
  std::size_t position_ = 0;
};

}  // namespace

bool exrSupported() { return true; }
#else
bool exrSupported() { return false; }
#endif

void writeExr(const FloatImage& image, const std::string& path,
              const std::vector<std::pair<std::string, std::string>>& attributes) {
  if (!exrSupported()) throw MissingFeatureError(path + ": cannot write OpenEXR: " + exrMissingHelp());
  const std::size_t channels = image.channels.size();
  if (image.width < 1 || image.height < 1 || channels < 1 ||
      image.samples.size() != static_cast<std::size_t>(image.width) * image.height * channels)
    throw std::invalid_argument(path + ": EXR image must be at least 1x1 with at least one channel and "
                                "width*height*channels samples");
  for (std::size_t c = 0; c < channels; ++c)
    for (std::size_t d = 0; d < c; ++d)
      if (image.channels[c].empty() || image.channels[c] == image.channels[d])
        throw std::invalid_argument(path + ": EXR channel names must be non-empty and distinct");
#if BLOT_HAVE_OPENEXR
  MemoryStream stream;
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const std::string& name : image.channels) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    for (const auto& [name, value] : attributes) header.insert(name, Imf::StringAttribute(value));
    Imf::FrameBuffer frame;
    const std::size_t pixel = sizeof(float) * channels;
    for (std::size_t c = 0; c < channels; ++c)
      frame.insert(image.channels[c],
                   Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(image.samples.data() + c)),
                              pixel, pixel * static_cast<std::size_t>(image.width)));
    Imf::OutputFile file(stream, header, 0);  // 0: no worker threads, encoded in this one
    file.setFrameBuffer(frame);
    file.writePixels(image.height);
  } catch (const std::exception& error) {  // Iex::BaseExc is a std::exception
    throw std::runtime_error(path + ": OpenEXR encoding failed: " + error.what());
  }
  stain::writeFileAtomically(path, stream.bytes().data(), stream.bytes().size());
#else
  (void)attributes;
#endif
}

}  // namespace blot::engine
