#include "rotating_mesh_run.h"

#include <blot/stain/io/mesh_io.h>
#include <blot/stain/stain_solver.h>

#include <gtest/gtest.h>

#include "mesh_fixture.h"

#include <cstdio>

namespace blot::test {

using namespace blot::stain;

RunResult runRotatingRealMesh(const std::string& name, double h, int steps) {
  const TriangleMesh mesh = loadMesh(externalMesh(name.c_str()));
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const SurfaceTopology topology(mesh.faces, n, name);
  const Vector3 center = mesh.vertexPositions.colwise().mean().transpose();
  const double size = (mesh.vertexPositions.rowwise() - center.transpose()).rowwise().norm().maxCoeff();

  // Anisotropic fabric (ratio 10) with the weft along each face's first edge:
  // a rough field on purpose, the operators must stay PSD whatever it is.
  FabricField fabric;
  fabric.densityTensors.resize(mesh.faces.rows(), 3);
  fabric.velocityTensors.resize(mesh.faces.rows(), 3);
  fabric.weftDirections.resize(mesh.faces.rows(), 3);
  const double d = 2e-4 * size * size;
  for (int f = 0; f < mesh.faces.rows(); ++f) {
    fabric.densityTensors.row(f) << 10 * d, 0, d;
    fabric.velocityTensors.row(f) << d, 0, d;
    fabric.weftDirections.row(f) = mesh.vertexPositions.row(mesh.faces(f, 1)) - mesh.vertexPositions.row(mesh.faces(f, 0));
  }
  StainSolverDef def;
  def.gravity = Vector3(0, -9.8, 0);  // both meshes stand with +y up
  StainSolver solver(topology, mesh.vertexPositions, fabric, def);

  // Rigid rotation about the vertical axis through the centroid, 1.5 rad/s.
  const double omega = 1.5;
  const auto positionsAt = [&](double t) {
    const Matrix3 R = Eigen::AngleAxisd(omega * t, Vector3::UnitY()).toRotationMatrix();
    RowVectors3 p = (mesh.vertexPositions.rowwise() - center.transpose()) * R.transpose();
    p.rowwise() += center.transpose();
    return p;
  };
  RowVectors3 velocities(n, 3);
  for (int i = 0; i < n; ++i)
    velocities.row(i) = Vector3(0, omega, 0).cross(Vector3(mesh.vertexPositions.row(i).transpose() - center)).transpose();
  solver.setInitialMotion(mesh.vertexPositions, velocities);

  // Two drops near the top, one with a splash, and a held source region.
  int top = 0;
  for (int i = 1; i < n; ++i)
    if (mesh.vertexPositions(i, 1) > mesh.vertexPositions(top, 1)) top = i;
  DropDef drop;
  drop.centerVertex = top;
  drop.radius = 0.08 * size;
  drop.solventMass = 1e-3;
  drop.soluteMass = 1e-4;
  solver.addDrop(drop);
  drop.centerVertex = n / 2;
  drop.splashSpeed = 0.2 * size;
  drop.splashSeed = 11;
  solver.addDrop(drop);
  HeldRegion source;
  for (int i = 0; i < n && source.vertices.size() < 12; i += n / 12) source.vertices.push_back(i);
  source.solventDensity = 0.5;
  source.soluteDensity = 0.05;
  solver.addHeldRegion(source);

  RunResult result;
  result.worstNegative = 0;
  for (int k = 1; k <= steps; ++k) {
    const StepReport r = solver.step(h, positionsAt(k * h));
    if (r.status != StepStatus::Ok) {
      ADD_FAILURE() << name << " h=" << h << " step " << k << " stage " << r.stageName() << ": " << r.message;
      return result;
    }
    const StainState& s = solver.state();
    const double scale = std::max(s.solvent.maxCoeff(), 1e-300);
    for (const Vector* f : {&s.solvent, &s.solute, &s.absorbedSolvent, &s.absorbedSolute, &s.adsorbedSolute})
      result.worstNegative = std::min(result.worstNegative, f->minCoeff() / scale);
    result.steps = k;
  }
  const MassBudget b = solver.massBudget();
  result.soluteError = b.soluteError();
  result.solventError = b.solventError();
  std::printf("%s h=%.3f: %d steps, solute error %.2e, solvent error %.2e, worst negative %.2e x max, "
              "%d intrinsic rebuilds\n",
              name.c_str(), h, result.steps, result.soluteError, result.solventError, result.worstNegative,
              solver.geometry().intrinsic().rebuildCount - 1);
  return result;
}

void expectHealthyRun(const RunResult& r, int steps) {
  EXPECT_EQ(r.steps, steps);
  EXPECT_LT(r.soluteError, 1e-12);
  EXPECT_LT(r.solventError, 1e-12);
  EXPECT_GE(r.worstNegative, -1e-12);
}

}  // namespace blot::test
