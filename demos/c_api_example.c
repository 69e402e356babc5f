/* The Blot C API end to end: create an engine from a scene file, add a drop,
 * step a second of 60 Hz frames, read the colours back and print a checksum.
 * Usage: blot_c_api_example SCENE.json
 * Exits non-zero (with blotGetLastError's message) on any failure, or if the
 * drop did not darken the cloth. Built and run by ctest (c_api_example). */
#include <blot/blot.h>

#include <stdio.h>
#include <stdlib.h>

static int check(blotStatus status, const char* what) {
  if (status != BLOT_OK) {
    fprintf(stderr, "c_api_example: %s failed (status %d): %s\n", what, (int)status, blotGetLastError());
    return 1;
  }
  return 0;
}

int main(int argc, char** argv) {
  blotEngine* engine = NULL;
  blotDropDef drop = blotDefaultDropDef();
  const double above[3] = {0.05, -0.02, 0.5};
  int face = -1, frame, vertexCount, i;
  float* colors;
  double checksum = 0.0, darkest = 1.0;

  if (argc != 2) {
    fprintf(stderr, "usage: %s SCENE.json\n", argv[0]);
    return 2;
  }
  if (check(blotCreateEngineFromSceneFile(argv[1], &engine), "blotCreateEngineFromSceneFile")) return 1;

  /* A drop falling from above the cloth lands where it hits the surface. */
  drop.radius = 0.06;
  drop.solventMass = 0.01;
  drop.soluteMass = 0.004;
  if (check(blotEngine_AddDropAtPoint(engine, above, &drop, &face), "blotEngine_AddDropAtPoint")) return 1;

  for (frame = 0; frame < 60; ++frame)
    if (check(blotEngine_Step(engine, 1.0 / 60.0), "blotEngine_Step")) return 1;

  vertexCount = blotEngine_GetVertexCount(engine);
  colors = (float*)malloc(sizeof(float) * 3 * (size_t)vertexCount);
  if (colors == NULL) return 1;
  if (check(blotEngine_CopyColors(engine, colors, 3 * vertexCount), "blotEngine_CopyColors")) return 1;
  for (i = 0; i < 3 * vertexCount; ++i) {
    checksum += colors[i];
    if (colors[i] < darkest) darkest = colors[i];
  }
  /* A too-small buffer is an error with a message, not a crash. */
  if (blotEngine_CopyColors(engine, colors, 2) != BLOT_ERROR_INVALID_ARGUMENT) return 1;

  printf("vertices %d, drop hit face %d, time %.3f s\n", vertexCount, face, blotEngine_GetTime(engine));
  printf("colour checksum %.6f, darkest channel %.4f\n", checksum, darkest);
  free(colors);
  blotDestroyEngine(engine);
  if (darkest > 0.8) {
    fprintf(stderr, "c_api_example: the drop left no visible stain (darkest channel %.3f)\n", darkest);
    return 1;
  }
  return 0;
}
