// The full stain step on real scanned meshes (Debian's CGAL data): the
// Stanford bunny (37,706 vertices) and the camel (9,770 vertices, 3,485
// negative cotan weights), rotating rigidly with gravity, drops and a held
// source region, every physics term on: no solver failure, no negative
// density, mass conserved to 1e-12. CI runs 1000 camel steps at the paper's
// time step and at 0.1 s and 200 bunny steps; the study
// tests/studies/real_mesh_stain_long_test.cpp runs 1000 steps of each at
// h = 0.01, 0.025 and 0.1.
#include <gtest/gtest.h>

#include "rotating_mesh_run.h"

namespace blot::test {
namespace {

TEST(RealMeshStain, CamelThousandStepsAtPaperAndLargeTimeSteps) {
  for (const double h : {0.025, 0.1}) expectHealthyRun(runRotatingRealMesh("camel.off", h, 1000), 1000);
}

TEST(RealMeshStain, BunnyAtThePapersTimeStep) {
  expectHealthyRun(runRotatingRealMesh("bunny00.off", 0.01, 200), 200);
}

}  // namespace
}  // namespace blot::test
