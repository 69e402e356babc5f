// libFuzzer target for one mesh format (BLOT_FUZZ_FORMAT: obj, ply or off).
//
// Design note: the loaders take paths, so the target goes through parseMesh,
// the in-memory entry that loadMesh itself uses after reading the file: the
// fuzzed code is exactly the shipped parsing and validation. The oracle is the
// loader's contract (mesh_io.h): an input either gives a mesh that validates
// again, or throws MeshError whose message starts with the source name. Any
// other exception escapes and libFuzzer reports it as a crash.
#include <blot/stain/io/mesh_io.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string source = std::string("fuzz.") + BLOT_FUZZ_FORMAT;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const blot::stain::TriangleMesh mesh = blot::stain::parseMesh(text, BLOT_FUZZ_FORMAT, source);
    blot::stain::validateMesh(mesh, source);  // what loads must be valid
  } catch (const blot::stain::MeshError& error) {
    if (std::string(error.what()).rfind(source + ": ", 0) != 0) std::abort();
  }
  return 0;
}
