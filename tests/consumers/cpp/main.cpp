// An embedding game's first program: an engine from an EngineDef (no file),
// a drop, a second of 60 Hz frames, the mass budget and a PLY frame written
// with Blot::outputs. Exits non-zero if the liquid's mass is not conserved.
// Usage: blot_cpp_consumer OUT.ply
#include <blot/engine/engine.h>
#include <blot/engine/ply_frame_writer.h>
#include <blot/engine/version.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <cmath>
#include <cstdio>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.ply\n", argv[0]);
    return 2;
  }
  blot::EngineDef def;
  def.mesh = blot::stain::gridMesh(12, 12, 0.4, 0.4);
  def.source = blot::engine::MotionSource::Rigid;
  def.rigid.angularVelocity = Eigen::Vector3d(0, 0, 2.0);  // rad/s: inertial and Coriolis forces act
  blot::Engine engine(def);

  blot::stain::DropDef drop;
  drop.radius = 0.06;
  drop.solventMass = 0.01;
  drop.soluteMass = 0.002;
  engine.addDropAtPoint(Eigen::Vector3d(0.05, -0.03, 0.2), drop);
  for (int frame = 0; frame < 60; ++frame) {
    const blot::stain::StepReport report = engine.step(1.0 / 60.0);
    if (report.status != blot::stain::StepStatus::Ok) {
      std::fprintf(stderr, "step failed in stage %s: %s\n", report.stageName(), report.message.c_str());
      return 1;
    }
  }
  const blot::engine::EngineStatistics stats = engine.statistics();
  const double solventError = stats.massBudget.solventError(), soluteError = stats.massBudget.soluteError();

  blot::engine::PlyFrame frame;
  frame.vertexPositions = engine.positions();
  frame.faces = engine.faces();
  frame.vertexAttributes.push_back({"solute", engine.solute(), blot::engine::PlyScalarType::Float32});
  blot::engine::writePlyFrame(argv[1], frame);

  std::printf("blot %s: %lld steps, t = %.3f s, solvent error %.2e, solute error %.2e\n",
              blot::engine::versionString(), static_cast<long long>(stats.steps), engine.time(), solventError,
              soluteError);
  // The engine conserves liquid mass to rounding (docs/transport.md).
  if (!(solventError < 1e-9) || !(soluteError < 1e-9) || stats.steps != 120) return 1;
  return 0;
}
