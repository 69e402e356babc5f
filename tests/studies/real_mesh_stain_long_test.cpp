// Long study (label "study"): 1000 steps of the rotating bunny and camel with
// every term on at h = 0.01, 0.025 and 0.1 s.
#include <gtest/gtest.h>

#include "rotating_mesh_run.h"

namespace blot::test {
namespace {

TEST(RealMeshStainStudy, ThousandStepsOnBunnyAndCamel) {
  for (const char* mesh : {"camel.off", "bunny00.off"})
    for (const double h : {0.01, 0.025, 0.1}) expectHealthyRun(runRotatingRealMesh(mesh, h, 1000), 1000);
}

}  // namespace
}  // namespace blot::test
