// Blot's cloth in the game's own Bullet world (docs/embedding.md).
//
// The game owns a btSoftRigidDynamicsWorld and steps it; Blot's two-way
// coupled flag lives in it (EngineDef::cloth.world), so a rigid sphere the
// game moves (kinematic) pushes into the cloth while a stain is on it. Per
// internal step the game steps its world by h, then the engine reads the
// nodes, advances the stain and writes the liquid's node masses and impulses
// into the body for the next world step.
//
// Run by ctest (shared_world_example, about 1 s). It checks, and exits 1 if
// any check fails:
//   * contact: the flag's centre is pushed along +y by the sphere, against the
//     same run without the sphere;
//   * the stain moves with the cloth: its solvent-weighted centroid (free and
//     absorbed) moves
//     like the cloth under it;
//   * the stain's mass is conserved;
//   * a body the game builds itself (appendNode/appendLink/appendFace) can be
//     handed to Blot too (EngineDef::cloth.body), and the liquid's mass
//     reaches its nodes without touching its links' rest lengths.
#include <blot/engine/engine.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionShapes/btSphereShape.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <cmath>
#include <cstdio>
#include <memory>

namespace {

constexpr int kCells = 16;                         // 17 x 17 vertices, 0.6 m
constexpr int kCentre = 8 * 17 + 8;                // the flag's centre vertex
constexpr double kStep = 0.01;                     // the engine's internal step (s)
constexpr int kSteps = 60;

// The game's world, as any Bullet game sets one up.
struct GameWorld {
  btSoftBodyRigidBodyCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher{&configuration};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btSoftRigidDynamicsWorld world{&dispatcher, &broadphase, &solver, &configuration};
  GameWorld() {
    world.setGravity(btVector3(0, 0, -9.8f));
    world.getWorldInfo().m_gravity = btVector3(0, 0, -9.8f);
  }
};

// A kinematic sphere the game moves along +y through the flag's middle.
struct MovingSphere {
  btSphereShape shape{0.08f};
  std::unique_ptr<btRigidBody> body;
  explicit MovingSphere(btSoftRigidDynamicsWorld& world) {
    btRigidBody::btRigidBodyConstructionInfo info(0, nullptr, &shape);
    body = std::make_unique<btRigidBody>(info);
    body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    body->setActivationState(DISABLE_DEACTIVATION);
    moveTo(0);
    world.addRigidBody(body.get());
  }
  // From y = -0.2 m (behind the flag) at 0.5 m/s, level with the flag's centre.
  void moveTo(double t) {
    body->setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0.3f, float(-0.2 + 0.5 * t), 0.3f)));
  }
};

// The two-way flag hanging in the xz plane from its top corners, a drop in the middle.
blot::EngineDef flag(btSoftRigidDynamicsWorld& world) {
  blot::EngineDef def;
  def.mesh = blot::stain::gridMesh(kCells, kCells, 0.6, 0.6);
  def.mesh.vertexPositions.col(2) = def.mesh.vertexPositions.col(1);
  def.mesh.vertexPositions.col(1).setZero();
  def.source = blot::engine::MotionSource::Bullet;
  def.cloth.pins = {{16 * 17, {}}, {16 * 17 + 16, {}}};
  def.cloth.world = &world;  // the game's world: Blot builds its body into it
  def.coupling = blot::coupling::CouplingMode::TwoWay;
  def.timeStep = kStep;
  blot::engine::TimedDrop drop;
  drop.drop.centerVertex = kCentre;
  drop.drop.radius = 0.12;
  drop.drop.solventMass = 0.02;
  drop.drop.soluteMass = 0.005;
  def.drops.push_back(drop);
  return def;
}

// Weighted by the solvent, free and absorbed: the film's friction holds the
// drop where it lands while the fibres soak it up.
Eigen::Vector3d stainCentroid(const blot::Engine& engine) {
  const Eigen::VectorXd w = engine.solvent() + engine.absorbedSolvent();
  return (engine.positions().transpose() * w) / w.sum();
}

struct Run {
  Eigen::Vector3d centre, centroid, centroidStart, centreStart;
  double solventError = 0;
};

// The game loop: step the world by h (in the cloth's substeps), then the engine by one internal step.
Run play(bool withSphere) {
  GameWorld game;
  std::unique_ptr<MovingSphere> sphere;
  if (withSphere) sphere = std::make_unique<MovingSphere>(game.world);
  blot::Engine engine(flag(game.world));
  const int substeps = engine.definition().cloth.substeps;
  Run run;
  run.centreStart = engine.positions().row(kCentre).transpose();
  run.centroidStart = stainCentroid(engine);
  for (int k = 0; k < kSteps; ++k) {
    if (sphere) sphere->moveTo((k + 1) * kStep);
    game.world.stepSimulation(float(kStep), substeps, float(kStep / substeps));
    const blot::stain::StepReport report = engine.advanceSteps(1);
    if (!report.ok()) {
      std::printf("step %d failed: %s\n", k, report.message.c_str());
      std::exit(1);
    }
  }
  run.centre = engine.positions().row(kCentre).transpose();
  run.centroid = stainCentroid(engine);
  run.solventError = engine.statistics().massBudget.solventError();
  return run;
}

// The game builds the body itself (node i = vertex i, one link per mesh edge)
// and hands it to Blot; returns whether the liquid reached the node masses
// with every link's rest length unchanged (the setMass trap avoided).
bool gameBuiltBody() {
  GameWorld game;
  blot::EngineDef def = flag(game.world);
  const Eigen::MatrixX3d& x = def.mesh.vertexPositions;
  btSoftBody body(&game.world.getWorldInfo(), 0, nullptr, nullptr);
  for (Eigen::Index i = 0; i < x.rows(); ++i)
    body.appendNode(btVector3(float(x(i, 0)), float(x(i, 1)), float(x(i, 2))), 0.15f / float(x.rows()));
  for (Eigen::Index f = 0; f < def.mesh.faces.rows(); ++f) {
    const int a = def.mesh.faces(f, 0), b = def.mesh.faces(f, 1), c = def.mesh.faces(f, 2);
    body.appendLink(a, b, nullptr, true);  // bCheckExist: each edge once
    body.appendLink(b, c, nullptr, true);
    body.appendLink(c, a, nullptr, true);
    body.appendFace(a, b, c);
  }
  body.m_cfg.piterations = 4;
  body.updateConstants();
  game.world.addSoftBody(&body);
  def.cloth.body = &body;
  btAlignedObjectArray<btScalar> rest;
  for (int l = 0; l < body.m_links.size(); ++l) rest.push_back(body.m_links[l].m_rl);
  bool ok = true;
  {
    blot::Engine engine(def);
    for (int k = 0; k < 30; ++k) {
      game.world.stepSimulation(float(kStep), 4, float(kStep / 4));
      ok = ok && engine.advanceSteps(1).ok();
    }
    const double liquid = 1.0 / body.m_nodes[kCentre].m_im - 0.15 / double(x.rows());
    for (int l = 0; l < body.m_links.size(); ++l) ok = ok && body.m_links[l].m_rl == rest[l];
    std::printf("game-built body: liquid on the centre node %.3g kg, rest lengths %s\n", liquid,
                ok ? "unchanged" : "CHANGED");
    ok = ok && liquid > 1e-6;
  }
  game.world.removeSoftBody(&body);
  return ok;
}

// A pin the game drags 1 km away in one step tears the cloth: the engine's
// step fails and puts the cloth's nodes in the game's world back where the
// last good step left them (it used to keep the torn cloth there, so every
// later step failed too); with the pin set back, the game steps on. Returns
// whether that held.
bool failedStepRollsBackTheWorldsCloth() {
  GameWorld game;
  blot::Engine engine(flag(game.world));
  const int substeps = engine.definition().cloth.substeps;
  const auto worldStep = [&] { game.world.stepSimulation(float(kStep), substeps, float(kStep / substeps)); };
  bool ok = true;
  for (int k = 0; k < 10; ++k) {
    worldStep();
    ok = ok && engine.advanceSteps(1).ok();
  }
  const int pin = 16 * 17;
  const Eigen::MatrixX3d before = engine.positions();
  const Eigen::Vector3d held = before.row(pin).transpose();
  engine.setPinTarget(pin, Eigen::Vector3d(1000.0, 0.0, 0.5));
  worldStep();
  const bool failed = !engine.advanceSteps(1).ok();
  const btSoftBody::Node& node = game.world.getSoftBodyArray()[0]->m_nodes[kCentre];  // Blot's body in the game's world
  const Eigen::Vector3d inWorld(node.m_x.x(), node.m_x.y(), node.m_x.z());
  const double back = (inWorld - before.row(kCentre).transpose()).norm();
  engine.setPinTarget(pin, held);
  int stepped = 0;
  for (int k = 0; k < 10; ++k) {
    worldStep();
    stepped += engine.advanceSteps(1).ok() ? 1 : 0;
  }
  std::printf("torn by a 1 km pin: step failed %s, centre node back within %.2g m in the game's world, %d of 10 "
              "steps after\n",
              failed ? "yes" : "NO", back, stepped);
  return ok && failed && back < 1e-6 && stepped == 10;
}

}  // namespace

int main() {
  const Run free = play(false), pushed = play(true);
  // Contact: how far the sphere pushed the centre along +y beyond the free flag.
  const double push = pushed.centre.y() - free.centre.y();
  const double stainMoved = (pushed.centroid - pushed.centroidStart).y() - (free.centroid - free.centroidStart).y();
  const double error = std::max(pushed.solventError, free.solventError);
  std::printf("centre pushed %.4f m along +y by the sphere (free flag: %.4f m)\n", push, free.centre.y());
  std::printf("stain centroid moved %.4f m along +y with it\n", stainMoved);
  std::printf("solvent mass error %.3g\n", error);
  bool ok = push > 0.05 && stainMoved > 0.5 * push && error < 1e-9;
  ok = gameBuiltBody() && ok;
  ok = failedStepRollsBackTheWorldsCloth() && ok;
  std::printf("%s\n", ok ? "shared world OK" : "shared world FAILED");
  return ok ? 0 : 1;
}
