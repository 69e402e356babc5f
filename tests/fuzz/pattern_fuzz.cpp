// libFuzzer target for weave pattern files (JSON, docs/patterns.md).
//
// Design note: parseWeavePattern is the whole file loader minus the read, so
// the target fuzzes it directly. The oracle is the header's contract: a
// pattern, whose tensors are then all finite and SPD, or a PatternError whose
// message starts with the source name; any other exception is a finding.
#include <blot/stain/fabric/weave_pattern.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string source = "fuzz.json";
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const blot::stain::WeavePattern pattern = blot::stain::parseWeavePattern(text, source);
    for (const blot::stain::Matrix2& tensor : pattern.cellTensors()) {
      if (!tensor.allFinite() || !(tensor(0, 0) > 0.0) || !(tensor(1, 1) > 0.0)) std::abort();
    }
    (void)pattern.rotated90();  // exercised too: it re-validates every tensor
  } catch (const blot::stain::PatternError& error) {
    if (std::string(error.what()).rfind(source + ": ", 0) != 0) std::abort();
  }
  return 0;
}
