/* The Blot C API end to end, as a C game uses it.
 *
 * Without arguments the engine is built from definitions, no file involved:
 * an 11 x 11 Bullet cloth flag hanging from two pinned corners, two-way
 * coupled with a wine drop, twill fabric. With SCENE.json it is built from
 * that scene file instead. Either way: a drop lands where a world point hits
 * the cloth, a second of 60 Hz frames runs, and the example reads back the
 * colours, the liquid's world and relative velocities, the statistics and the
 * mass budget, then checks that a missing file is BLOT_ERROR_IO.
 * Usage: blot_c_api_example [SCENE.json]
 * Exits non-zero (with blotGetLastError's message) on any failure, if the
 * drop left no visible stain or if the liquid's mass is not conserved.
 * Built and run by ctest (c_api_example, c_api_example_scene). */
#include <blot/blot.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define N 11 /* vertices per side */

static int check(blotStatus status, const char* what) {
  if (status != BLOT_OK) {
    fprintf(stderr, "c_api_example: %s failed (status %d): %s\n", what, (int)status, blotGetLastError());
    return 1;
  }
  return 0;
}

/* A 0.5 m square flag in the xz plane (normal -y), top edge at z = 0.5. */
static blotStatus createFlag(blotEngine** engine) {
  static double positions[3 * N * N];
  static int32_t faces[6 * (N - 1) * (N - 1)];
  static const int32_t pins[2] = {N * (N - 1), N * N - 1}; /* the two top corners */
  blotEngineDef def = blotDefaultEngineDef();
  int i, j, f = 0;
  for (j = 0; j < N; ++j)
    for (i = 0; i < N; ++i) {
      double* p = positions + 3 * (j * N + i);
      p[0] = 0.5 * i / (N - 1) - 0.25;
      p[1] = 0.0;
      p[2] = 0.5 * j / (N - 1);
    }
  for (j = 0; j + 1 < N; ++j)
    for (i = 0; i + 1 < N; ++i) {
      const int32_t a = j * N + i, b = a + 1, c = a + N, d = c + 1;
      /* counter-clockwise seen from -y: the normal points at the viewer */
      faces[f++] = a; faces[f++] = c; faces[f++] = b;
      faces[f++] = b; faces[f++] = c; faces[f++] = d;
    }
  def.positions = positions;
  def.vertexCount = N * N;
  def.faces = faces;
  def.faceCount = 2 * (N - 1) * (N - 1);
  def.source = BLOT_MOTION_BULLET;
  def.cloth.pinnedVertices = pins;
  def.cloth.pinnedVertexCount = 2;
  def.cloth.twoWay = 1;
  def.fabric.weavePreset = "twill-2-1";
  def.fabric.diffusivity = 0.004;
  def.liquid.evaporationRate = 0.002;
  return blotCreateEngine(&def, engine);
}

int main(int argc, char** argv) {
  blotEngine* engine = NULL;
  blotEngine* missing = NULL;
  blotDropDef drop = blotDefaultDropDef();
  blotStatistics stats;
  blotMassBudget budget;
  const double above[3] = {0.05, -0.02, 0.5};
  int face = -1, frame, vertexCount, i;
  float* colors;
  float* velocities;
  float* solvent;
  double checksum = 0.0, darkest = 1.0, fastest = 0.0;

  if (argc > 2) {
    fprintf(stderr, "usage: %s [SCENE.json]\n", argv[0]);
    return 2;
  }
  if (argc == 2) {
    if (check(blotCreateEngineFromSceneFile(argv[1], &engine), "blotCreateEngineFromSceneFile")) return 1;
  } else if (check(createFlag(&engine), "blotCreateEngine")) {
    return 1;
  }

  /* A drop falling from in front of / above the cloth lands where it hits the surface. */
  drop.radius = 0.06;
  drop.solventMass = 0.01;
  drop.soluteMass = 0.004;
  if (argc == 1) {
    const double front[3] = {0.0, -0.2, 0.3};
    if (check(blotEngine_AddDropAtPoint(engine, front, &drop, &face), "blotEngine_AddDropAtPoint")) return 1;
  } else if (check(blotEngine_AddDropAtPoint(engine, above, &drop, &face), "blotEngine_AddDropAtPoint")) {
    return 1;
  }

  for (frame = 0; frame < 60; ++frame)
    if (check(blotEngine_Step(engine, 1.0 / 60.0), "blotEngine_Step")) return 1;

  vertexCount = blotEngine_GetVertexCount(engine);
  colors = (float*)malloc(sizeof(float) * 3 * (size_t)vertexCount);
  velocities = (float*)malloc(sizeof(float) * 3 * (size_t)vertexCount);
  solvent = (float*)malloc(sizeof(float) * (size_t)vertexCount);
  if (colors == NULL || velocities == NULL || solvent == NULL) return 1;
  if (check(blotEngine_CopyColors(engine, colors, 3 * vertexCount), "blotEngine_CopyColors")) return 1;
  for (i = 0; i < 3 * vertexCount; ++i) {
    checksum += colors[i];
    if (colors[i] < darkest) darkest = colors[i];
  }
  if (check(blotEngine_CopyLiquidWorldVelocities(engine, velocities, 3 * vertexCount), "world velocities")) return 1;
  if (check(blotEngine_CopyLiquidRelativeVelocities(engine, velocities, 3 * vertexCount), "relative velocities"))
    return 1;
  if (check(blotEngine_CopyDensities(engine, BLOT_DENSITY_SOLVENT, solvent, vertexCount), "solvent")) return 1;
  for (i = 0; i < vertexCount; ++i) { /* where there is free liquid (1 g/m² or more) */
    const float* v = velocities + 3 * i;
    if (solvent[i] < 1e-3f) continue;
    const double speed = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (speed > fastest) fastest = speed;
  }
  if (check(blotEngine_GetStatistics(engine, &stats), "blotEngine_GetStatistics")) return 1;
  if (check(blotEngine_GetMassBudget(engine, &budget), "blotEngine_GetMassBudget")) return 1;

  /* A too-small buffer is an error with a message, not a crash; a missing file is an I/O error. */
  if (blotEngine_CopyColors(engine, colors, 2) != BLOT_ERROR_INVALID_ARGUMENT) return 1;
  if (blotCreateEngineFromSceneFile("/nonexistent/scene.json", &missing) != BLOT_ERROR_IO || missing != NULL) return 1;

  printf("vertices %d, drop hit face %d, time %.3f s, %lld steps (%.0f steps/s)\n", vertexCount, face,
         blotEngine_GetTime(engine), (long long)stats.steps, stats.stepsPerSecond);
  printf("mass budget: solvent added %.4g kg (free %.4g, absorbed %.4g, evaporated %.4g), error %.1e; "
         "solute error %.1e\n",
         budget.addedSolvent, budget.freeSolvent, budget.absorbedSolvent, budget.evaporatedSolvent,
         budget.solventError, budget.soluteError);
  printf("fastest wet liquid relative to the cloth %.4f m/s\n", fastest);
  printf("colour checksum %.6f, darkest channel %.4f\n", checksum, darkest);
  free(colors);
  free(velocities);
  free(solvent);
  blotDestroyEngine(engine);
  if (darkest > 0.8) {
    fprintf(stderr, "c_api_example: the drop left no visible stain (darkest channel %.3f)\n", darkest);
    return 1;
  }
  if (!(budget.solventError < 1e-9) || !(budget.soluteError < 1e-9) || stats.massBudget.addedSolvent != budget.addedSolvent) {
    fprintf(stderr, "c_api_example: liquid mass not conserved (solvent %.2e, solute %.2e)\n", budget.solventError,
            budget.soluteError);
    return 1;
  }
  return 0;
}
