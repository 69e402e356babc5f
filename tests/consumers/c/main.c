/* A C program on the installed C API (blot/blot.h): an engine from a scene
 * given as JSON text, a drop, half a second of 60 Hz frames, the solute read
 * back. Exits non-zero on any failure or if the solute mass changed. */
#include <blot/blot.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static const char* kScene =
    "{\"mesh\": {\"patch\": {\"size\": [0.5, 0.5], \"resolution\": [10, 10]}},"
    " \"cloth\": {\"source\": \"static\"}, \"time_step\": 0.01,"
    " \"liquid\": {\"absorption_rate\": 0, \"evaporation_rate\": 0}}";

int main(void) {
  blotEngine* engine = NULL;
  blotDropDef drop = blotDefaultDropDef();
  float* solute; /* reused for the solvent */
  double total = 0.0;
  int frame, i, n;

  if (blotCreateEngineFromSceneJson(kScene, NULL, &engine) != BLOT_OK) {
    fprintf(stderr, "create: %s\n", blotGetLastError());
    return 1;
  }
  drop.radius = 0.1;
  if (blotEngine_AddDropAtVertex(engine, 60, &drop) != BLOT_OK) return 1;
  for (frame = 0; frame < 30; ++frame)
    if (blotEngine_Step(engine, 1.0 / 60.0) != BLOT_OK) {
      fprintf(stderr, "step: %s\n", blotGetLastError());
      return 1;
    }
  n = blotEngine_GetVertexCount(engine);
  solute = (float*)malloc(sizeof(float) * (size_t)n);
  if (solute == NULL || blotEngine_CopyDensities(engine, BLOT_DENSITY_SOLVENT, solute, n) != BLOT_OK) return 1;
  for (i = 0; i < n; ++i) total += solute[i];
  free(solute);
  printf("blot C consumer: %d vertices, t = %.3f s, summed solvent density %.4f kg/m^2\n", n,
         blotEngine_GetTime(engine), total);
  blotDestroyEngine(engine);
  return total > 0.0 && isfinite(total) ? 0 : 1;
}
