#pragma once
/// The engines fuzz_state loads its inputs into, shared with the corpus test
/// (tests/engine/engine_test.cpp, StateFuzzCorpus) that replays the seeds.
/// Small on purpose (a 3 x 3 vertex patch), so that a whole state file fits
/// in the fuzzer's input limit and one load costs well under a millisecond.
#include <blot/engine/engine.h>
#include <blot/stain/geometry/mesh_primitives.h>

#include <cstddef>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::engine::fuzz {

/// How many engines an input can pick from (its first byte, modulo this).
inline constexpr int kStateFuzzEngineCount = 3;

/// 0: a static patch with a drop; 1: the same patch moving rigidly;
/// 2: a two-way Bullet cloth pinned at two corners (every state block:
/// cloth nodes, liquid node masses, impulses).
inline EngineDef stateFuzzEngineDef(int which) {
  EngineDef def;
  def.mesh = stain::gridMesh(2, 2, 0.2, 0.2);
  def.timeStep = 0.01;
  def.maxStepsPerCall = 4;
  if (which == 1) {
    def.source = MotionSource::Rigid;
    def.rigid.angularVelocity = Eigen::Vector3d(0, 0, 0.5);
  } else if (which == 2) {
    def.mesh.vertexPositions.col(2) = def.mesh.vertexPositions.col(1);
    def.mesh.vertexPositions.col(1).setZero();
    def.source = MotionSource::Bullet;
    def.cloth.pins = {{6, {}}, {8, {}}};
    def.coupling = coupling::CouplingMode::TwoWay;
    def.stain.strainTolerance = 0.02;
  }
  TimedDrop drop;
  drop.drop.centerVertex = 4;
  drop.drop.radius = 0.08;
  drop.drop.solventMass = 0.01;
  drop.drop.soluteMass = 0.002;
  def.drops.push_back(drop);
  TimedDrop late = drop;  // still scheduled when the seeds are saved
  late.time = 10;
  def.drops.push_back(late);
  return def;
}

/// A fuzz_state input: the engine's index, then a state file's bytes.
inline std::string stateFuzzInput(int which, const std::string& stateFile) {
  std::ifstream in(stateFile, std::ios::binary);
  std::string bytes(1, static_cast<char>(which));
  bytes.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (!in.eof() && in.fail()) throw std::runtime_error(stateFile + ": cannot read");
  return bytes;
}

/// The seed corpus of fuzz_state, as {file name, bytes}: per engine, its state
/// before any step, after 3 steps (the first drop applied, the second still
/// scheduled), and after 3 steps with a runtime drop queued and half a step
/// of frame time carried. `scratch` is a file path the states go through.
inline std::vector<std::pair<std::string, std::string>> stateFuzzSeeds(const std::string& scratch) {
  std::vector<std::pair<std::string, std::string>> seeds;
  const char* names[kStateFuzzEngineCount] = {"static", "rigid", "bullet_two_way"};
  for (int which = 0; which < kStateFuzzEngineCount; ++which) {
    Engine engine(stateFuzzEngineDef(which));
    engine.save(scratch);
    seeds.emplace_back(std::string(names[which]) + "_start.bin", stateFuzzInput(which, scratch));
    engine.step(3 * engine.timeStep());
    engine.save(scratch);
    seeds.emplace_back(std::string(names[which]) + "_3_steps.bin", stateFuzzInput(which, scratch));
    stain::DropDef drop;
    drop.centerVertex = 1;
    drop.radius = 0.05;
    drop.solventMass = 0.004;
    drop.soluteMass = 0.001;
    drop.splashSpeed = 0.2;
    engine.addDrop(drop);
    engine.step(0.5 * engine.timeStep());
    engine.save(scratch);
    seeds.emplace_back(std::string(names[which]) + "_pending_drop.bin", stateFuzzInput(which, scratch));
  }
  return seeds;
}

}  // namespace blot::engine::fuzz
