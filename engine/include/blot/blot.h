/* Blot C API: embed the stain engine in any engine or language with a C FFI.
 *
 * A thin wrapper over blot::Engine (engine/include/blot/engine/engine.h):
 * an opaque handle, plain-old-data arguments, status codes and a last-error
 * string. Units: metres, kilograms, seconds. Naming follows Box2D's C API:
 * blotCreateX / blotDestroyX, blotX_Verb.
 *
 * Errors: every call that can fail returns a blotStatus; on failure the
 * message (naming the file, key, field or stage) is available from
 * blotGetLastError() on the same thread. The string belongs to the library:
 * do not free it; it stays valid and unchanged until the next call that fails
 * on that thread (successful calls leave it alone), so copy it to keep it.
 * Nothing throws across this boundary.
 *
 * Creation without files: fill a blotEngineDef (start from
 * blotDefaultEngineDef(), which holds blotDefaultClothDef(),
 * blotDefaultFabricDef() and blotDefaultLiquidDef()), point it at your mesh
 * arrays and call blotCreateEngine. The arrays are copied; they need to live
 * only during the call.
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
  BLOT_ERROR_NUMERICAL = 3,        /**< a step failed (stage, vertex, step in the message), state kept; or a
                                        value to copy out is beyond float range (entry and value named),
                                        nothing written */
  BLOT_ERROR_IO = 4,               /**< a file given to the call is missing, unreadable or unwritable */
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
  double solventMass; /**< kg, in [0, 1e6] (a scene's limit on any number) */
  double soluteMass;  /**< kg, in [0, 1e6] */
  double velocity[3]; /**< m/s, world frame */
  double splashSpeed; /**< m/s outward, >= 0 */
  uint64_t splashSeed;
} blotDropDef;

/** radius 0.05 m, 1 g solvent, 0.1 g solute, at rest, no splash. */
blotDropDef blotDefaultDropDef(void);

/** Where the moving mesh comes from. */
typedef enum blotMotionSource {
  BLOT_MOTION_STATIC = 0, /**< the mesh stays at its rest shape */
  BLOT_MOTION_RIGID = 1,  /**< a rigid motion (blotEngineDef.rigid*) */
  BLOT_MOTION_BULLET = 2, /**< Bullet soft-body cloth (blotEngineDef.cloth) */
  BLOT_MOTION_CALLER = 3  /**< positions the caller gives before every step (blotEngine_SetSurfaceFrame) */
} blotMotionSource;

/** Which equations the liquid follows (docs/scene-format.md, "physics.model"). */
typedef enum blotPhysicsModel {
  BLOT_PHYSICS_FILM = 0, /**< a thin viscous film: friction with the fabric, hydrostatic pressure (the default) */
  BLOT_PHYSICS_PAPER = 1 /**< the paper's equations as written, for comparison */
} blotPhysicsModel;

/** Bullet soft-body cloth (see blot::cloth::ClothDef, docs/cloth.md). */
typedef struct blotClothDef {
  double totalMass;         /**< kg, > 0, spread by lumped area */
  double stretchStiffness;  /**< Bullet kLST in (0, 1] */
  double bendStiffness;     /**< kLST in [0, 1]; 0 builds no bending links */
  double dampingRate;       /**< 1/s, >= 0 */
  int positionIterations;   /**< >= 1 */
  int substeps;             /**< Bullet steps per internal step, >= 1 */
  int tethers;              /**< nonzero: long-range attachments to the pins */
  double tetherSlack;       /**< fraction, >= 0 */
  const int32_t* pinnedVertices; /**< vertices held at their rest position (may be NULL if the count is 0) */
  int pinnedVertexCount;
  int twoWay;               /**< nonzero: the liquid's mass and momentum act on the cloth (coupling two-way) */
} blotClothDef;

/** Fabric: isotropic diffusion, or a homogenized weave preset. */
typedef struct blotFabricDef {
  double diffusivity;   /**< m²/s, > 0: isotropic diffusivity, or the preset's trace / 2 */
  double viscosity;     /**< m²/s, >= 0: velocity diffusivity of the film */
  /** NULL or "": isotropic. Otherwise a preset of `blot homogenize --list-presets`
   *  (e.g. "twill-2-1"), homogenized once, on every face, weft along `weft`. */
  const char* weavePreset;
  double weft[3];       /**< weft direction (projected into each face), used with weavePreset */
  double slipLength;    /**< m, >= 0: the liquid's slip over the fibres (film model's friction) */
} blotFabricDef;

/** The liquid's interaction with the fabric (see blot::stain::LiquidParameters). */
typedef struct blotLiquidDef {
  double absorptionRate;     /**< K_p, 1/s */
  double saturationDensity;  /**< sigma_sat, kg/m² */
  double desorptionRate;     /**< K_d, 1/s */
  double adsorptionCapacity; /**< A_d, kg/m² */
  double evaporationRate;    /**< K_evap, kg/(m² s) */
  double liquidDensity;      /**< rho, kg/m³, > 0: the film's thickness is (solvent + solute) / rho */
  double kinematicViscosity; /**< nu = mu / rho, m²/s, > 0: the film's friction with the fabric */
  double molecularDiffusivity; /**< D_m, m²/s, in [0, 1]: the dissolved solute's diffusion in the liquid (film model) */
} blotLiquidDef;

/** Everything an engine is built from. Only the mesh has no default. */
typedef struct blotEngineDef {
  const double* positions;  /**< rest shape, vertexCount x 3 interleaved xyz (m) */
  int vertexCount;
  const int32_t* faces;     /**< faceCount x 3 vertex indices, counter-clockwise */
  int faceCount;
  blotMotionSource source;
  double rigidAngularVelocity[3]; /**< rad/s, BLOT_MOTION_RIGID */
  double rigidPivot[3];           /**< m */
  double rigidLinearVelocity[3];  /**< m/s of the pivot */
  blotClothDef cloth;             /**< BLOT_MOTION_BULLET */
  blotFabricDef fabric;
  blotLiquidDef liquid;
  double gravity[3];        /**< m/s², also given to the Bullet cloth */
  double timeStep;          /**< the fixed internal step h (s, in [1e-6, 1], as a scene's time_step) */
  int maxStepsPerCall;      /**< >= 1 */
  blotPhysicsModel model;   /**< the film (default) or the paper's equations */
} blotEngineDef;

/** Bullet's stable cloth settings: 0.15 kg, kLST 1, bending 0.2, 4 iterations, 4 substeps, tethers. No pins, one-way. */
blotClothDef blotDefaultClothDef(void);
/** Isotropic, diffusivity 0.01 m²/s, viscosity 2e-3 m²/s, weft +x, slip length 1e-5 m. */
blotFabricDef blotDefaultFabricDef(void);
/** The engine's liquid defaults (docs/scene-format.md, "liquid"). */
blotLiquidDef blotDefaultLiquidDef(void);
/** No mesh, static, the default cloth, fabric and liquid, gravity (0, 0, -9.8), h = 1/120 s, 8 steps per call,
 *  the film model. */
blotEngineDef blotDefaultEngineDef(void);

/** Liquid mass totals (kg) and the relative conservation errors. */
typedef struct blotMassBudget {
  double freeSolvent, absorbedSolvent, evaporatedSolvent, addedSolvent;
  double freeSolute, absorbedSolute, adsorbedSolute, addedSolute;
  double solventError; /**< |free + absorbed + evaporated - added| / added */
  double soluteError;  /**< |free + absorbed + adsorbed - added| / added */
} blotMassBudget;

/** The free liquid's energy (J): kinetic relative to the cloth, gravitational, hydrostatic. */
typedef struct blotLiquidEnergy {
  double kinetic, gravitational, pressure;
} blotLiquidEnergy;

/** Counters and timings since creation (see blot::engine::EngineStatistics). */
typedef struct blotStatistics {
  int64_t steps;            /**< internal steps taken */
  double time;              /**< simulated time (s) */
  double droppedTime;       /**< frame time discarded by maxStepsPerCall (s) */
  int dropsApplied;
  int intrinsicRefreshes;   /**< internal steps that rebuilt the metric */
  double wallSeconds;       /**< wall-clock time inside internal steps (s) */
  double stepsPerSecond;
  double lastStepMilliseconds;     /**< the last internal step: total */
  double lastClothMilliseconds;    /**< its cloth part */
  double lastStainMilliseconds;    /**< its stain part */
  double lastCouplingMilliseconds; /**< its coupling part */
  blotMassBudget massBudget;       /**< now */
  blotLiquidEnergy liquidEnergy;   /**< now */
} blotStatistics;

/** Message of the last failing call on this thread ("" if none). Owned by the
 *  library; valid and unchanged until the next failing call on this thread. */
const char* blotGetLastError(void);

/** Creates an engine from a definition, no file involved. *outEngine is set on success;
 *  a NULL array or a bad field (out of range, invalid mesh, unknown preset) is
 *  BLOT_ERROR_INVALID_ARGUMENT with a message naming the field and the value. */
blotStatus blotCreateEngine(const blotEngineDef* def, blotEngine** outEngine);

/** Creates an engine from a scene file (docs/scene-format.md). *outEngine is set on success.
 *  BLOT_ERROR_IO if the file cannot be opened; BLOT_ERROR_SCENE if its content is rejected
 *  (also for a mesh or pattern file it names that cannot be read: the message names it). */
blotStatus blotCreateEngineFromSceneFile(const char* path, blotEngine** outEngine);
/** The same from JSON text; relative paths resolve against baseDirectory (NULL: "."). */
blotStatus blotCreateEngineFromSceneJson(const char* json, const char* baseDirectory, blotEngine** outEngine);
/** Destroys an engine (NULL is ignored). */
void blotDestroyEngine(blotEngine* engine);

/** Advances by frameDt seconds of frame time, frameDt in [0, 1] (fixed internal steps, accumulator; see
 *  Engine::step). BLOT_ERROR_INVALID_ARGUMENT for a frameDt outside that range, BLOT_ERROR_NUMERICAL for a
 *  step the engine undid; the message names the stage (and vertex) as blotEngine_AdvanceSteps's does. */
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

/* The copies below convert the engine's doubles to float. One whose entry is beyond float range
 * (|value| > 3.4e38, e.g. a liquid velocity under an absurd gravity) returns BLOT_ERROR_NUMERICAL,
 * naming the vertex and the value, and writes nothing. */

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
/** Copies, per engine vertex k, the index that vertex has in the scene's mesh file (capacity >= #V).
 *  The identity, except for an engine made from a scene whose mesh sets "vertex_order": "locality"
 *  (docs/scene-format.md): that engine renumbers the mesh, and every array copied from it, every face
 *  and blotEngine_AddDropAtVertex use its own numbering; out[k] names the file's vertex. */
blotStatus blotEngine_CopyFileVertexIndices(const blotEngine* engine, int32_t* out, int capacity);
/** Copies #V x 3 liquid velocities in the world (inertial) frame (m/s): the cloth's velocity plus the relative one. */
blotStatus blotEngine_CopyLiquidWorldVelocities(const blotEngine* engine, float* out, int capacity);
/** Copies #V x 3 liquid velocities relative to the cloth, tangential, in world axes (m/s); 0 at vertices
 *  without free liquid. */
blotStatus blotEngine_CopyLiquidRelativeVelocities(const blotEngine* engine, float* out, int capacity);

/** Counters, timings and the mass budget. */
blotStatus blotEngine_GetStatistics(const blotEngine* engine, blotStatistics* out);
/** The mass budget alone (cheaper than the statistics). */
blotStatus blotEngine_GetMassBudget(const blotEngine* engine, blotMassBudget* out);

/** OpenMP threads of this engine's steps (>= 0; 0: the calling thread's OpenMP default), from the next
 *  step on; per engine, not process-wide. Results are bit-identical for any count. */
blotStatus blotEngine_SetThreadCount(blotEngine* engine, int threads);

/** 1 (the default): with two or more threads, each step uses all of them or one, whichever recent steps
 *  measured faster, so threads that do not pay (a busy machine) are dropped; 0: every step uses the
 *  thread count. Any other value is an invalid argument. Only the time of a step depends on it. */
blotStatus blotEngine_SetAdaptiveThreads(blotEngine* engine, int adaptive);

/** Runs exactly `count` (>= 0) internal steps, bypassing the frame-time accumulator (one step per
 *  call when the caller feeds a BLOT_MOTION_CALLER surface or steps its own Bullet world). */
blotStatus blotEngine_AdvanceSteps(blotEngine* engine, int count);

/** Bullet cloth: moves the pin at `vertex` (one of blotClothDef.pinnedVertices) to `position` (m) in a
 *  straight line during the next internal step and holds it there. BLOT_ERROR_INVALID_ARGUMENT for
 *  another source, a vertex that is no pin, a position that is not finite or has a coordinate beyond
 *  1e6 m. */
blotStatus blotEngine_SetPinTarget(blotEngine* engine, int vertex, const double position[3]);

/** BLOT_MOTION_CALLER: the surface at the end of the next internal step: `positions` and (or NULL for
 *  the finite difference) `velocities`, vertexCount x 3 interleaved xyz (m, m/s), copied. A step
 *  without a new frame holds the surface still. BLOT_ERROR_INVALID_ARGUMENT for another source, a
 *  vertexCount other than the engine's, a non-finite value. */
blotStatus blotEngine_SetSurfaceFrame(blotEngine* engine, const double* positions, const double* velocities,
                                      int vertexCount);

/** Saves / loads the whole state (binary; see Engine::save and Engine::load).
 *  BLOT_ERROR_IO for a file that cannot be written, opened or does not match the engine. */
blotStatus blotEngine_Save(const blotEngine* engine, const char* path);
blotStatus blotEngine_Load(blotEngine* engine, const char* path);

#ifdef __cplusplus
}
#endif

#endif /* BLOT_BLOT_H */
