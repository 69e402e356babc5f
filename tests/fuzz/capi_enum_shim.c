/* See capi_enum_shim.h. */
#include "capi_enum_shim.h"

blotStatus blotTestCopyDensitiesOfKind(const blotEngine* engine, int kind, float* out, int capacity) {
  return blotEngine_CopyDensities(engine, (blotDensity)kind, out, capacity);
}

void blotTestSetMotionSource(blotEngineDef* def, int source) { def->source = (blotMotionSource)source; }
