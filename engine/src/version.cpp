#include <blot/engine/version.h>

namespace blot::engine {
const char* versionString() { return BLOT_VERSION_STRING; }
}  // namespace blot::engine
