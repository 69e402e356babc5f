#pragma once
/// The engine tests' Bullet flag: 17 x 17 vertices, 0.6 m, hanging in the xz
/// plane from its two top corners, with a heavy drop in the middle.
#include <blot/engine/engine.h>
#include <blot/stain/geometry/mesh_primitives.h>

namespace blot::engine {

/// The drop's centre vertex.
inline constexpr int kBulletFlagDropVertex = 8 * 17 + 8;

inline EngineDef bulletFlag(coupling::CouplingMode mode) {
  EngineDef def;
  def.mesh = stain::gridMesh(16, 16, 0.6, 0.6);
  def.mesh.vertexPositions.col(2) = def.mesh.vertexPositions.col(1);
  def.mesh.vertexPositions.col(1).setZero();
  def.source = MotionSource::Bullet;
  def.cloth.pins = {{16 * 17, {}}, {16 * 17 + 16, {}}};
  def.coupling = mode;
  def.timeStep = 0.01;
  TimedDrop drop;
  drop.drop.centerVertex = kBulletFlagDropVertex;
  drop.drop.radius = 0.15;
  drop.drop.solventMass = 0.05;
  drop.drop.soluteMass = 0.01;
  def.drops.push_back(drop);
  return def;
}

}  // namespace blot::engine
