// The full stain step on real scanned meshes (Debian's CGAL data): the
// Stanford bunny (37,706 vertices) and the camel (9,770 vertices, 3,485
// negative cotan weights), rotating rigidly with gravity, drops and a held
// source region, every physics term on: no solver failure, no negative
// density, mass conserved to 1e-12. CI runs 1000 camel steps at the paper's
// time step and at 0.1 s and 200 bunny steps (under the sanitizers, whose
// build runs a step 10 to 20 times slower, 40 and 20: the same code on the
// same meshes, every stage many times over; tests/support/sanitized_build.h); the study
// tests/studies/real_mesh_stain_long_test.cpp runs 1000 steps of each at
// h = 0.01, 0.025 and 0.1.
#include <gtest/gtest.h>

#include "rotating_mesh_run.h"
#include "sanitized_build.h"

namespace blot::test {
namespace {

TEST(RealMeshStain, CamelThousandStepsAtPaperAndLargeTimeSteps) {
  const int steps = stepsForThisBuild(1000, 40);
  for (const double h : {0.025, 0.1}) expectHealthyRun(runRotatingRealMesh("camel.off", h, steps), steps);
}

TEST(RealMeshStain, BunnyAtThePapersTimeStep) {
  const int steps = stepsForThisBuild(200, 20);
  expectHealthyRun(runRotatingRealMesh("bunny00.off", 0.01, steps), steps);
}

}  // namespace
}  // namespace blot::test
