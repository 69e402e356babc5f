/* Calls with enum arguments holding any int, as a C caller may pass them.
 * Compiled as C (capi_enum_shim.c): in C++ even forming such a value and
 * passing it would load an enum outside its enumerators' range, which is
 * undefined (and which UBSan reports in the caller rather than in the API). */
#ifndef BLOT_CAPI_ENUM_SHIM_H
#define BLOT_CAPI_ENUM_SHIM_H

#include <blot/blot.h>

#ifdef __cplusplus
extern "C" {
#endif

blotStatus blotTestCopyDensitiesOfKind(const blotEngine* engine, int kind, float* out, int capacity);
void blotTestSetMotionSource(blotEngineDef* def, int source);

#ifdef __cplusplus
}
#endif

#endif
