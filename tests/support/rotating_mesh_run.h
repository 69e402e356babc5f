#pragma once
// A rigidly rotating real mesh with drops, a held source and every stain
// term on: shared by the CI test (tests/stain/real_mesh_stain_test.cpp) and
// the long study (tests/studies/real_mesh_stain_long_test.cpp).
#include <string>

namespace blot::test {

struct RunResult {
  double soluteError = 1, solventError = 1, worstNegative = -1;
  int steps = 0;
};

/// Runs `steps` steps of size h on the CGAL sample mesh `name` (e.g.
/// "camel.off"), rotating at 1.5 rad/s about its vertical (+y) axis under
/// gravity −y; records a test failure naming the step and stage if a step fails.
RunResult runRotatingRealMesh(const std::string& name, double h, int steps);

/// Expects all steps done, mass conserved to 1e-12 and no density below −1e-12 × max.
void expectHealthyRun(const RunResult& result, int steps);

}  // namespace blot::test
