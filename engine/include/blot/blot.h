/* Blot C API: embed the stain engine in any engine or language with a C FFI.
 *
 * A thin wrapper over blot::Engine (engine/include/blot/engine/engine.h):
 * an opaque handle, plain-old-data arguments, status codes and a last-error
 * string. Units: metres, kilograms, seconds. Naming follows Box2D's C API:
 * blotCreateX / blotDestroyX, blotX_Verb.
 *
 * Errors: every call that can fail returns a blotStatus; on failure the
 * message (naming the file, key, field or stage) is available from
 * blotGetLastError() on the same thread until the next failing call there.
 * Nothing throws across this boundary.
 *
 * Threads: one engine must not be used from two threads at once; different
 * engines are independent.
 */
#ifndef BLOT_BLOT_H
#define BLOT_BLOT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Opaque engine handle. */
typedef struct blotEngine blotEngine;

typedef enum blotStatus {
  BLOT_OK = 0,
  BLOT_ERROR_INVALID_ARGUMENT = 1, /**< null pointer, bad index, buffer too small, bad value */
  BLOT_ERROR_SCENE = 2,            /**< scene file or JSON rejected (message names the key) */
  BLOT_ERROR_NUMERICAL = 3,        /**< a step failed (stage, vertex, step in the message); state kept */
  BLOT_ERROR_IO = 4,               /**< file could not be read or written */
  BLOT_ERROR_INTERNAL = 5          /**< anything else */
} blotStatus;

/** Which per-vertex surface density to copy (kg/m²). */
typedef enum blotDensity {
  BLOT_DENSITY_SOLVENT = 0,          /**< free solvent */
  BLOT_DENSITY_SOLUTE = 1,           /**< free (dissolved) solute */
  BLOT_DENSITY_ABSORBED_SOLVENT = 2, /**< solvent held in the fibres */
  BLOT_DENSITY_ABSORBED_SOLUTE = 3,  /**< solute absorbed with it */
  BLOT_DENSITY_ADSORBED_SOLUTE = 4   /**< solute deposited on the fibres */
} blotDensity;

/** A drop (see blot::stain::DropDef). Start from blotDefaultDropDef(). */
typedef struct blotDropDef {
  double radius;      /**< m, > 0 */
  double solventMass; /**< kg, >= 0 */
  double soluteMass;  /**< kg, >= 0 */
  double velocity[3]; /**< m/s, world frame */
  double splashSpeed; /**< m/s outward, >= 0 */
  uint64_t splashSeed;
} blotDropDef;

/** radius 0.05 m, 1 g solvent, 0.1 g solute, at rest, no splash. */
blotDropDef blotDefaultDropDef(void);

/** Message of the last failing call on this thread ("" if none). Valid until the next failing call. */
const char* blotGetLastError(void);

/** Creates an engine from a scene file (docs/scene-format.md). *outEngine is set on success. */
blotStatus blotCreateEngineFromSceneFile(const char* path, blotEngine** outEngine);
/** The same from JSON text; relative paths resolve against baseDirectory (NULL: "."). */
blotStatus blotCreateEngineFromSceneJson(const char* json, const char* baseDirectory, blotEngine** outEngine);
/** Destroys an engine (NULL is ignored). */
void blotDestroyEngine(blotEngine* engine);

/** Advances by frameDt seconds of frame time (fixed internal steps, accumulator; see Engine::step). */
blotStatus blotEngine_Step(blotEngine* engine, double frameDt);
/** Queues a drop centred at a vertex, applied at the next internal step. */
blotStatus blotEngine_AddDropAtVertex(blotEngine* engine, int vertex, const blotDropDef* drop);
/** Queues a drop where the world point point[3] (m) lands on the cloth (nearest surface point).
 *  outFace (may be NULL) receives the face hit. */
blotStatus blotEngine_AddDropAtPoint(blotEngine* engine, const double point[3], const blotDropDef* drop, int* outFace);

/** Number of vertices (0 for NULL). */
int blotEngine_GetVertexCount(const blotEngine* engine);
/** Number of triangles (0 for NULL). */
int blotEngine_GetFaceCount(const blotEngine* engine);
/** Simulated time (s). */
double blotEngine_GetTime(const blotEngine* engine);

/** Copies #V x 3 positions (m), interleaved xyz, into out (capacity: floats available, >= 3 #V). */
blotStatus blotEngine_CopyPositions(const blotEngine* engine, float* out, int capacity);
/** Copies #V x 3 unit vertex normals, interleaved. */
blotStatus blotEngine_CopyNormals(const blotEngine* engine, float* out, int capacity);
/** Copies #V x 3 stain colours, interleaved: linear RGB in [0, 1] (Beer–Lambert
    reflectance, not sRGB-encoded). Upload them to a linear (float or UNORM,
    not _SRGB) vertex attribute; a renderer that writes to an sRGB target
    encodes them, one that does not must apply the sRGB transfer function
    (docs/rendering.md "Colour"). */
blotStatus blotEngine_CopyColors(const blotEngine* engine, float* out, int capacity);
/** Copies #V densities (kg/m²) of one kind (capacity >= #V). */
blotStatus blotEngine_CopyDensities(const blotEngine* engine, blotDensity which, float* out, int capacity);
/** Copies #F x 3 vertex indices of the triangles (capacity >= 3 #F). */
blotStatus blotEngine_CopyFaces(const blotEngine* engine, int32_t* out, int capacity);

/** Saves / loads the whole state (binary; see Engine::save and Engine::load). */
blotStatus blotEngine_Save(const blotEngine* engine, const char* path);
blotStatus blotEngine_Load(blotEngine* engine, const char* path);

#ifdef __cplusplus
}
#endif

#endif /* BLOT_BLOT_H */
