/* A C program on the installed C API (blot/blot.h): an engine from
 * definitions (a rotating 9 x 9 grid, no file), a drop, half a second of
 * 60 Hz frames, the statistics and the mass budget read back. Exits non-zero
 * on any failure or if the liquid's mass is not conserved. */
#include <blot/blot.h>

#include <stdio.h>

#define N 9

int main(void) {
  double positions[3 * N * N];
  int32_t faces[6 * (N - 1) * (N - 1)];
  blotEngineDef def = blotDefaultEngineDef();
  blotEngine* engine = NULL;
  blotDropDef drop = blotDefaultDropDef();
  blotStatistics stats;
  int i, j, f = 0, frame;

  for (j = 0; j < N; ++j)
    for (i = 0; i < N; ++i) {
      positions[3 * (j * N + i) + 0] = 0.4 * i / (N - 1) - 0.2;
      positions[3 * (j * N + i) + 1] = 0.4 * j / (N - 1) - 0.2;
      positions[3 * (j * N + i) + 2] = 0.0;
    }
  for (j = 0; j + 1 < N; ++j)
    for (i = 0; i + 1 < N; ++i) {
      const int32_t a = j * N + i;
      faces[f++] = a; faces[f++] = a + 1; faces[f++] = a + N + 1;
      faces[f++] = a; faces[f++] = a + N + 1; faces[f++] = a + N;
    }
  def.positions = positions;
  def.vertexCount = N * N;
  def.faces = faces;
  def.faceCount = 2 * (N - 1) * (N - 1);
  def.source = BLOT_MOTION_RIGID;
  def.rigidAngularVelocity[2] = 2.0; /* rad/s about z */

  if (blotCreateEngine(&def, &engine) != BLOT_OK) {
    fprintf(stderr, "blotCreateEngine: %s\n", blotGetLastError());
    return 1;
  }
  drop.radius = 0.08;
  if (blotEngine_AddDropAtVertex(engine, N * N / 2 + 2, &drop) != BLOT_OK) return 1;
  for (frame = 0; frame < 30; ++frame)
    if (blotEngine_Step(engine, 1.0 / 60.0) != BLOT_OK) {
      fprintf(stderr, "blotEngine_Step: %s\n", blotGetLastError());
      return 1;
    }
  if (blotEngine_GetStatistics(engine, &stats) != BLOT_OK) return 1;
  printf("blot C consumer: %d vertices, %lld steps, t = %.3f s, solvent error %.1e, solute error %.1e\n",
         blotEngine_GetVertexCount(engine), (long long)stats.steps, stats.time, stats.massBudget.solventError,
         stats.massBudget.soluteError);
  blotDestroyEngine(engine);
  return stats.steps == 60 && stats.massBudget.solventError < 1e-9 && stats.massBudget.soluteError < 1e-9 ? 0 : 1;
}
