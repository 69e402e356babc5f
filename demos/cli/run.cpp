// `blot run SCENE.json`: runs a scene file headless and writes what a
// technical artist takes elsewhere.
//
// Design note: the scene decides everything (docs/scene-format.md); the
// command line only overrides the frame count, output folder and thread
// count. Frames are whole internal steps (Engine::advanceSteps), so a frame's
// time is exact. Outputs: PLY frames with the per-vertex attributes DESIGN.md
// names (solvent, solute, absorbed_solvent, absorbed_solute, adsorbed_solute,
// vx/vy/vz, colours), a PNG of the last frame, summary.json, and the same
// summary on stdout. Progress goes to stderr: a bar redrawn in place on a
// terminal, one line per frame otherwise (logs stay readable). A numerical
// failure stops the run with exit code 3 naming the stage, step and vertex and
// the last good frame written; a bad scene exits 1 with the key path.
// Rejected: writing frames from a second thread (ordering and error handling
// for little gain at these sizes).
#include "assets.h"
#include "commands.h"

#include <blot/engine/engine.h>
#include <blot/engine/frame_writer.h>
#include <blot/engine/frame_exports.h>
#include <blot/engine/scene.h>
#include <blot/stain/content_hash.h>
#include <blot/stain/io/atomic_file.h>
#include <blot/stain/io/bounded_read.h>
#include <blot/stain/thread_limit.h>
#include <blot/stain/io/strict_json.h>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace blot::cli {
namespace {

struct RunOptions {
  std::string scenePath;
  int frames = 0;          // 0: the scene's
  std::string outputDirectory;  // empty: the scene's
  int threads = 0;         // 0: OpenMP's default
  bool fixedThreads = false;  // every step on `threads` (scene: adaptive_threads false)
  bool quiet = false;
  int checkpointEvery = 0;  // frames between checkpoints; 0: none
  bool resume = false;      // continue from <out>/checkpoint.json
  int killAfterFrame = 0;   // testing only: SIGKILL this process after that frame
  int killInWrite = 0;      // testing only: SIGKILL this process half-way through its n-th file write
  std::string injectFault;  // testing only: STAGE:STEP:VERTEX (Engine::injectFaultForTesting)
  // Artist outputs (override the scene's outputs; docs/rendering.md "blot run outputs").
  bool images = false;
  std::string camera;         // "follow" | "rest"; empty: the scene's
  std::string video;          // "mp4", "gif" or "mp4,gif"
  int textureSize = 0;        // > 0: bake the stain texture at this size (square)
  bool textureEveryFrame = false;
  std::string maps;           // "png8", "png16", "exr", comma-separated: wetness, saturation and stain maps
  bool gltf = false;
  bool gltfEveryFrame = false;
};

/// "STAGE:STEP:VERTEX" (e.g. "diffuse:12:140") into an InjectedFault; throws
/// std::invalid_argument naming the malformed part.
stain::InjectedFault parseInjectedFault(const std::string& text) {
  const size_t a = text.find(':'), b = text.find(':', a == std::string::npos ? a : a + 1);
  if (a == std::string::npos || b == std::string::npos)
    throw std::invalid_argument("--testing-inject-fault: expected STAGE:STEP:VERTEX, got '" + text + "'");
  stain::InjectedFault fault;
  if (!stain::parseStage(text.substr(0, a), fault.stage))
    throw std::invalid_argument("injected fault: unknown stain stage '" + text.substr(0, a) + "'");
  try {
    size_t used = 0;
    fault.step = std::stoi(text.substr(a + 1, b - a - 1), &used);
    if (used != b - a - 1) throw std::invalid_argument("trailing characters");
    fault.vertex = std::stoi(text.substr(b + 1), &used);
    if (used != text.size() - b - 1) throw std::invalid_argument("trailing characters");
  } catch (const std::exception&) {
    throw std::invalid_argument("--testing-inject-fault: STEP and VERTEX must be integers, got '" + text + "'");
  }
  return fault;
}

// Checkpoints: every `checkpointEvery` frames the whole engine state
// goes to <out>/checkpoint_<frame>.state (Engine::save writes a temporary and
// renames it), then <out>/checkpoint.json — frame, state file, state hash — is
// replaced the same way, and only then is the previous state file removed. A
// kill at any point leaves a checkpoint.json that names a complete state file;
// --resume loads it, checks the state hash, and reruns the frames after it,
// rewriting their PLY files with identical bytes (the run is deterministic for
// a given scene and thread count). Rejected: one fixed state file name (a kill
// between the state's rename and the JSON's would pair a new state with an old
// frame number).
struct Checkpoint {
  int frame = 0;
  std::string stateFile;  // file name inside the output folder
  std::uint64_t stateHash = 0;
  std::uint64_t fileHash = 0;  // of the state file's bytes, checked before Engine::load parses them
  std::uint64_t sceneHash = 0;  // SceneDef::sourceHash of the scene that wrote it (--resume refuses another)
};

using stain::kMaxThreads;  // --threads

/// The hash over checkpoint.json's own fields ("record_hash"): an edited
/// frame number or file name is refused, not resumed from.
std::uint64_t recordHash(int frame, const std::string& stateFile, std::uint64_t stateHash, std::uint64_t fileHash,
                         std::uint64_t sceneHash) {
  std::uint64_t h = stain::kContentHashBasis;
  const std::int64_t f = frame;
  stain::hashBytes(h, &f, sizeof f);
  stain::hashBytes(h, stateFile.data(), stateFile.size());
  stain::hashBytes(h, &stateHash, sizeof stateHash);
  stain::hashBytes(h, &fileHash, sizeof fileHash);
  stain::hashBytes(h, &sceneHash, sizeof sceneHash);
  return h;
}

std::uint64_t bytesHash(const std::string& bytes) {
  std::uint64_t h = stain::kContentHashBasis;
  stain::hashBytes(h, bytes.data(), bytes.size());
  return h;
}

/// Exactly 16 lower- or upper-case hex digits; throws naming the key.
std::uint64_t parseHexHash(const std::string& file, const char* key, const nlohmann::json& record) {
  const auto it = record.find(key);
  const std::string text = it != record.end() && it->is_string() ? it->get<std::string>() : std::string();
  if (text.size() != 16 || text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
    throw std::runtime_error(file + ": " + key + ": expected 16 hex digits, got " +
                             (it == record.end() ? std::string("nothing") : stain::briefJson(*it)));
  return std::stoull(text, nullptr, 16);
}

std::string hexHash(std::uint64_t hash) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
  return hex;
}

void writeCheckpoint(const engine::Engine& engine, const std::filesystem::path& directory, int frame,
                     const std::string& previousStateFile, std::uint64_t sceneHash) {
  const std::string stateFile = "checkpoint_" + std::to_string(frame) + ".state";
  const std::string statePath = (directory / stateFile).string();
  engine.save(statePath);
  const std::uint64_t fileHash = bytesHash(stain::readFileBounded(statePath, stain::kStateFileByteLimit, "the state file"));
  const std::uint64_t stateHash = engine.stateHash();
  const nlohmann::json record = {{"frame", frame},
                                 {"state", stateFile},
                                 {"state_hash", hexHash(stateHash)},
                                 {"file_hash", hexHash(fileHash)},
                                 {"scene_hash", hexHash(sceneHash)},
                                 {"record_hash", hexHash(recordHash(frame, stateFile, stateHash, fileHash, sceneHash))}};
  const std::string text = stain::dumpJson(record, 2) + "\n";
  stain::writeFileAtomically((directory / "checkpoint.json").string(), text.data(), text.size());
  if (!previousStateFile.empty() && previousStateFile != stateFile) {
    std::error_code ignored;
    std::filesystem::remove(directory / previousStateFile, ignored);
  }
}

/// Reads <directory>/checkpoint.json; throws naming the file and the key.
Checkpoint readCheckpoint(const std::filesystem::path& directory) {
  const std::filesystem::path json = directory / "checkpoint.json";
  std::error_code missing;
  if (!std::filesystem::exists(json, missing))
    throw std::runtime_error(json.string() + ": no checkpoint to resume from (run with --checkpoint-every N first)");
  nlohmann::json record;
  try {
    record = stain::parseStrictJson(stain::readFileBounded(json.string(), stain::kRecordFileByteLimit, "checkpoint record"));
  } catch (const std::exception& e) {
    throw std::runtime_error(json.string() + ": not a checkpoint record: " + e.what());
  }
  if (!record.is_object()) throw std::runtime_error(json.string() + ": not a checkpoint record: expected an object");
  Checkpoint c;
  const auto frame = record.find("frame");
  if (frame == record.end() || !frame->is_number_integer() || frame->get<long long>() < 0 ||
      frame->get<long long>() > 1000000)
    throw std::runtime_error(json.string() + ": frame: expected an integer in [0, 1000000]");
  const auto state = record.find("state");
  // Only the name the writer gives (no folder, no "..": the file must be in the output folder).
  const std::string name = state != record.end() && state->is_string() ? state->get<std::string>() : std::string();
  if (name.rfind("checkpoint_", 0) != 0 || name.size() < 18 || name.substr(name.size() - 6) != ".state" ||
      name.substr(11, name.size() - 17).find_first_not_of("0123456789") != std::string::npos)
    throw std::runtime_error(json.string() + ": state: expected a file name checkpoint_<frame>.state, got " +
                             (state == record.end() ? std::string("nothing") : stain::briefJson(*state)));
  c.frame = static_cast<int>(frame->get<long long>());
  c.stateFile = name;
  c.stateHash = parseHexHash(json.string(), "state_hash", record);
  c.fileHash = parseHexHash(json.string(), "file_hash", record);
  c.sceneHash = parseHexHash(json.string(), "scene_hash", record);
  const std::uint64_t expected = recordHash(c.frame, c.stateFile, c.stateHash, c.fileHash, c.sceneHash);
  if (parseHexHash(json.string(), "record_hash", record) != expected)
    throw std::runtime_error(json.string() + ": record_hash does not match the record's frame, state and hashes "
                             "(the file was edited or is damaged)");
  return c;
}

class Progress {
 public:
  Progress(int total, bool quiet) : total_(total), quiet_(quiet), terminal_(isatty(fileno(stderr)) != 0) {}
  void update(int frame, double time, double stepsPerSecond) {
    if (quiet_) return;
    // ETA from the mean wall time per frame so far (frames run in this process).
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (first_ < 0) first_ = frame - 1;
    const double perFrame = frame > first_ ? elapsed / (frame - first_) : 0.0;
    const double eta = perFrame * (total_ - frame) + perFrame * encodeFrameCost_ * encodeFrames_;
    char text[200];
    if (terminal_) {
      const int width = 30, filled = total_ > 0 ? width * frame / total_ : width;
      std::string bar(static_cast<size_t>(filled), '#');
      bar.resize(static_cast<size_t>(width), '.');
      std::snprintf(text, sizeof text, "\r[%s] frame %d/%d  t = %.3f s  %.0f steps/s  ETA %.0f s ", bar.c_str(), frame,
                    total_, time, stepsPerSecond, eta);
      std::cerr << text << std::flush;
      if (frame == total_) std::cerr << "\n";
    } else {
      std::snprintf(text, sizeof text, "frame %d/%d t=%.4f s steps/s=%.1f eta=%.1f s", frame, total_, time,
                    stepsPerSecond, eta);
      std::cerr << text << "\n";
    }
  }
  /// Frames the videos will encode, counted in the ETA at `cost` frames of simulation each.
  void expectEncoding(int frames, double cost) {
    encodeFrames_ = frames;
    encodeFrameCost_ = cost;
  }
  void encoding(const std::string& video, int done, int total) {
    if (quiet_) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - encodeStart_).count();
    if (done == 1) encodeStart_ = std::chrono::steady_clock::now();
    const double eta = done > 1 ? elapsed / (done - 1) * (total - done) : 0.0;
    char text[160];
    std::snprintf(text, sizeof text, "%sencoding %s frame %d/%d  ETA %.0f s%s", terminal_ ? "\r" : "", video.c_str(), done,
                  total, eta, terminal_ ? " " : "\n");
    std::cerr << text << std::flush;
    if (terminal_ && done == total) std::cerr << "\n";
  }
  void interrupt() {
    if (terminal_ && !quiet_) std::cerr << "\n";
  }

 private:
  int total_;
  bool quiet_, terminal_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), encodeStart_ = start_;
  int first_ = -1;
  int encodeFrames_ = 0;
  double encodeFrameCost_ = 0;
};

/// Which physics terms the run had on and could use (a static surface has no
/// inertia; two-way coupling only with a Bullet cloth).
nlohmann::json termsJson(const engine::EngineDef& d) {
  const stain::PhysicsSwitches& s = d.stain.switches;
  const bool moves = d.source != engine::MotionSource::Static;
  return {{"model", s.model == stain::PhysicsModel::Film ? "film" : "paper"},
          {"gravity", s.gravity},
          {"linear_inertia", s.linearInertia && moves},
          {"coriolis", s.coriolis && moves},
          {"velocity_advection", s.velocityAdvection},
          {"density_advection", s.densityAdvection},
          {"density_diffusion", s.densityDiffusion},
          {"velocity_diffusion", s.velocityDiffusion},
          {"absorption", s.absorption},
          {"adsorption", s.adsorption},
          {"evaporation", s.evaporation},
          {"sources", s.sources && !d.heldRegions.empty()},
          {"film_pressure", s.filmPressure},
          {"film_friction", s.filmFriction},
          {"solute_with_solvent", s.soluteWithSolvent},
          {"mass_weighted_viscosity", s.massWeightedViscosity},
          {"velocity_on_free_liquid", s.velocityOnFreeLiquid},
          {"boundary_wall", s.boundaryWall},
          {"diffusive_momentum", s.diffusiveMomentum},
          {"positivity_limiter", s.positivityLimiter},
          {"two_way_coupling", d.coupling == coupling::CouplingMode::TwoWay}};
}

}  // namespace

nlohmann::json meanTimesJson(const engine::EngineStatistics& s) {
  return engine::statisticsJson(s)["mean_ms_per_step"];
}

namespace {

/// Removes the temporaries (<name>.<pid>.tmp, stain::writeFileAtomically)
/// that a killed run left in the output folder.
void removeStaleTemporaries(const std::string& directory) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(directory, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() < 5 || name.compare(name.size() - 4, 4, ".tmp") != 0) continue;
    const std::string stem = name.substr(0, name.size() - 4);
    const size_t dot = stem.rfind('.');
    if (dot == std::string::npos || dot + 1 == stem.size() ||
        stem.find_first_not_of("0123456789", dot + 1) != std::string::npos || !entry.is_regular_file(ec))
      continue;
    std::filesystem::remove(entry.path(), ec);
  }
}

/// Command-line output options over the scene's; throws std::invalid_argument naming the option.
void applyExportOptions(const RunOptions& o, engine::FrameExportSettings& s) {
  if (o.images) s.images.enabled = true;
  if (!o.camera.empty()) {
    if (o.camera != "follow" && o.camera != "rest")
      throw std::invalid_argument("--camera: expected follow or rest, got '" + o.camera + "'");
    s.images.camera = o.camera == "rest" ? engine::FrameCamera::Rest : engine::FrameCamera::Follow;
    s.images.enabled = true;
  }
  if (!o.video.empty()) {
    std::stringstream list(o.video);
    bool mp4 = false, gif = false;
    for (std::string format; std::getline(list, format, ',');) {
      bool& chosen = format == "mp4" ? mp4 : gif;
      if ((format != "mp4" && format != "gif") || chosen)  // unknown, or named twice
        throw std::invalid_argument("--video: expected mp4, gif or mp4,gif, got '" + o.video + "'");
      chosen = true;
    }
    s.video.mp4 = s.video.mp4 || mp4;
    s.video.gif = s.video.gif || gif;
    if (o.video.back() == ',') throw std::invalid_argument("--video: expected mp4, gif or mp4,gif, got '" + o.video + "'");
    s.images.enabled = true;
  }
  if (o.textureSize < 0 || o.textureSize > 8192)
    throw std::invalid_argument("--texture: expected a size in [1, 8192] (at most 2^26 texels, the baking budget), got " +
                                std::to_string(o.textureSize));
  if (o.textureSize > 0) {
    s.texture.enabled = true;
    s.texture.width = s.texture.height = o.textureSize;
  }
  if (o.textureEveryFrame) s.texture.enabled = s.texture.everyFrame = true;
  if (!o.maps.empty()) {
    const std::string expected = "--maps: expected a comma-separated list of png8, png16 and exr, got '" + o.maps + "'";
    std::stringstream list(o.maps);
    engine::StainMapFormats formats;
    for (std::string format; std::getline(list, format, ',');) {
      bool* chosen = format == "png8" ? &formats.png8 : format == "png16" ? &formats.png16
                     : format == "exr" ? &formats.exr : nullptr;
      if (chosen == nullptr || *chosen) throw std::invalid_argument(expected);  // unknown, or named twice
      *chosen = true;
    }
    if (o.maps.back() == ',') throw std::invalid_argument(expected);
    s.texture.maps.png8 = s.texture.maps.png8 || formats.png8;
    s.texture.maps.png16 = s.texture.maps.png16 || formats.png16;
    s.texture.maps.exr = s.texture.maps.exr || formats.exr;
  }
  if (o.gltf) s.gltf.enabled = true;
  if (o.gltfEveryFrame) s.gltf.enabled = s.gltf.everyFrame = true;
}

int runScene(const RunOptions& options) {
  engine::SceneDef scene;
  try {
    scene = engine::loadScene(options.scenePath);
  } catch (const std::exception& e) {
    std::cerr << "blot run: error: " << e.what() << "\n";
    return 1;
  }
  if (options.frames < 0 || options.frames > 1000000) {
    std::cerr << "blot run: error: --frames " << options.frames << ": expected 0 (the scene's) to 1000000\n";
    return 1;
  }
  if (options.threads < 0 || options.threads > kMaxThreads) {
    std::cerr << "blot run: error: --threads " << options.threads << ": expected 0 (all cores) to " << kMaxThreads
              << "\n";
    return 1;
  }
  if (options.checkpointEvery < 0) {
    std::cerr << "blot run: error: --checkpoint-every " << options.checkpointEvery
              << ": expected 0 (never) or a positive number of frames\n";
    return 1;
  }
  if (options.killAfterFrame < 0) {
    std::cerr << "blot run: error: --kill-after-frame " << options.killAfterFrame << ": expected >= 0\n";
    return 1;
  }
  if (options.killInWrite < 0) {
    std::cerr << "blot run: error: --testing-kill-in-write " << options.killInWrite << ": expected >= 0\n";
    return 1;
  }
  stain::killInWriteForTesting(options.killInWrite);
  if (options.threads > 0) scene.engine.stain.threads = options.threads;  // this engine's, not process-wide
  if (options.fixedThreads) scene.engine.stain.adaptiveThreads = false;
  const int frames = options.frames > 0 ? options.frames : scene.outputs.frames;
  const std::string directory = options.outputDirectory.empty() ? scene.outputs.directory : options.outputDirectory;

  std::unique_ptr<engine::Engine> engine;
  try {
    engine = std::make_unique<engine::Engine>(scene.engine);
  } catch (const std::exception& e) {
    std::cerr << "blot run: error: " << options.scenePath << ": " << e.what() << "\n";
    return 1;
  }
  if (!options.injectFault.empty()) {
    try {
      engine->injectFaultForTesting(parseInjectedFault(options.injectFault));
    } catch (const std::exception& e) {
      std::cerr << "blot run: error: " << e.what() << "\n";
      return 1;
    }
  }
  engine::FrameExportSettings exportSettings{scene.outputs.images, scene.outputs.video, scene.outputs.texture,
                                             scene.outputs.gltf};
  try {
    applyExportOptions(options, exportSettings);  // refused options create no folder
  } catch (const std::exception& e) {
    std::cerr << "blot run: error: " << e.what() << "\n";
    return 1;
  }
  // Named as the folder it is (--out or outputs.directory), not as a raw
  // filesystem_error ("cannot create directories: Not a directory [x]").
  if (std::error_code error; !std::filesystem::create_directories(directory, error) && error) {
    std::cerr << "blot run: error: output folder " << directory << ": cannot create it: " << error.message()
              << (options.outputDirectory.empty() ? " (the scene's outputs.directory)" : " (--out)") << "\n";
    return 1;
  }
  engine::FrameWriterOptions outputs;
  outputs.directory = directory;
  outputs.name = scene.name;
  outputs.ply.format = scene.outputs.plyFormat;
  outputs.ply.comment = "blot run " + options.scenePath;
  outputs.preview = scene.outputs.preview;
  const engine::FrameWriter writer(*engine, outputs);
  std::unique_ptr<engine::FrameExporter> exporter;
  try {
    exporter = std::make_unique<engine::FrameExporter>(exportSettings, directory, scene.name, *engine);
  } catch (const std::exception& e) {
    std::cerr << "blot run: error: " << e.what() << "\n";
    return 1;
  }

  nlohmann::json plyPaths = nlohmann::json::array();
  std::string lastGood = "(none)";
  const auto writeFrame = [&](int frame) {
    lastGood = writer.writePly(frame);
    plyPaths.push_back(lastGood);
  };
  const int every = scene.outputs.plyEvery;
  int firstFrame = 1;
  std::string checkpointState;
  if (options.resume) {
    try {
      removeStaleTemporaries(directory);
      const Checkpoint c = readCheckpoint(directory);
      // The rest of the run would follow the new scene's physics from the old
      // one's state: a hybrid no single run gives. Only the same text resumes.
      if (c.sceneHash != scene.sourceHash)
        throw std::runtime_error("the scene file " + options.scenePath + " is not the one the checkpoint was written "
                                 "with (scene hash " + hexHash(scene.sourceHash) + ", checkpoint.json's " +
                                 hexHash(c.sceneHash) + "); run without --resume to start over");
      const std::string statePath = (std::filesystem::path(directory) / c.stateFile).string();
      // The bytes are checked against the record before Engine::load parses them.
      const std::uint64_t fileHash =
          bytesHash(stain::readFileBounded(statePath, stain::kStateFileByteLimit, "the state file"));
      if (fileHash != c.fileHash)
        throw std::runtime_error(c.stateFile + ": file hash " + hexHash(fileHash) + " does not match checkpoint.json's " +
                                 hexHash(c.fileHash) + " (the state file was changed after the checkpoint)");
      engine->load(statePath);
      if (engine->stateHash() != c.stateHash)
        throw std::runtime_error(c.stateFile + ": state hash " + hexHash(engine->stateHash()) +
                                 " does not match checkpoint.json's " + hexHash(c.stateHash));
      if (c.frame > frames)
        throw std::runtime_error("checkpoint.json: frame " + std::to_string(c.frame) + " is past --frames " +
                                 std::to_string(frames));
      if (engine->stepCount() != static_cast<std::int64_t>(c.frame) * scene.outputs.stepsPerFrame)
        throw std::runtime_error("checkpoint.json: frame " + std::to_string(c.frame) + " of " +
                                 std::to_string(scene.outputs.stepsPerFrame) + " steps does not match the state's " +
                                 std::to_string(engine->stepCount()) + " internal steps");
      firstFrame = c.frame + 1;
      checkpointState = c.stateFile;
      for (int frame = 0; frame <= c.frame; ++frame) {  // frames already on disk
        if (every > 0 && (frame % every == 0)) plyPaths.push_back(lastGood = writer.plyPath(frame));
        exporter->adoptFrame(frame, frame == frames);
      }
      std::cerr << "blot run: resuming after frame " << c.frame << " from " << c.stateFile << "\n";
    } catch (const std::exception& e) {
      std::cerr << "blot run: error: cannot resume in " << directory << ": " << e.what() << "\n";
      return 1;
    }
  } else {
    if (every > 0) writeFrame(0);
    exporter->writeFrame(0, *engine, frames == 0);
  }

  // A failed run still writes summary.json, with "status": "failed": the
  // folder may hold an earlier run's summary and frames, and without it that
  // summary told of a success while this run's first frames had replaced its
  // own (files written by this run are listed; each PLY names its scene).
  const std::string summaryPath = (std::filesystem::path(directory) / "summary.json").string();
  const auto writeFailedSummary = [&](const std::string& error, int frame, const std::string& statePath) {
    const nlohmann::json failed = {{"scene", options.scenePath},
                                   {"name", scene.name},
                                   {"status", "failed"},
                                   {"error", error},
                                   {"failed_frame", frame},
                                   {"steps", engine->stepCount()},
                                   {"state_hash", hexHash(engine->stateHash())},
                                   {"last_good_state", statePath},
                                   {"outputs", {{"directory", directory}, {"ply", plyPaths}, {"summary", summaryPath}}}};
    const std::string text = stain::dumpJson(failed, 2) + "\n";
    try {
      stain::writeFileAtomically(summaryPath, text.data(), text.size());
    } catch (const std::exception& e) {
      std::cerr << "blot run: could not write the failed run's summary: " << e.what() << "\n";
    }
  };

  Progress progress(frames, options.quiet);
  progress.expectEncoding(exporter->encodeFrames() + (frames - firstFrame + 1) / std::max(1, exportSettings.images.every) *
                                                         ((exportSettings.video.mp4 ? 1 : 0) + (exportSettings.video.gif ? 1 : 0)),
                          0.05);
  const auto start = std::chrono::steady_clock::now();
  for (int frame = firstFrame; frame <= frames; ++frame) {
    const stain::StepReport report = engine->advanceSteps(scene.outputs.stepsPerFrame);
    std::string failure;
    if (report.status != stain::StepStatus::Ok) {
      failure = std::string("stage '") + report.stageName() + "'" +
                (report.vertex >= 0 ? ", vertex " + std::to_string(report.vertex) : std::string()) + ": " +
                report.message;
    }
    if (!failure.empty()) {
      // The engine undid the failed step: it holds the last good state, which
      // goes to a state file beside the frames (Engine::load reads it).
      progress.interrupt();
      std::cerr << "blot run: numerical failure in frame " << frame << ": " << failure
                << "\nblot run: last good frame written: " << lastGood << "\n";
      std::string statePath = (std::filesystem::path(directory) / "last_good.state").string();
      try {
        engine->save(statePath);
        std::cerr << "blot run: state at the last good internal step " << engine->stepCount() << " (t = "
                  << engine->time() << " s) saved to " << statePath << "\n";
      } catch (const std::exception& e) {
        std::cerr << "blot run: could not save the last good state: " << e.what() << "\n";
        statePath.clear();
      }
      writeFailedSummary("numerical failure in frame " + std::to_string(frame) + ": " + failure, frame, statePath);
      return 3;
    }
    if (every > 0 && (frame % every == 0 || frame == frames)) writeFrame(frame);
    try {
      exporter->writeFrame(frame, *engine, frame == frames);
    } catch (const std::exception& e) {
      progress.interrupt();
      std::cerr << "blot run: error: frame " << frame << " outputs: " << e.what() << "\n";
      writeFailedSummary(std::string("frame ") + std::to_string(frame) + " outputs: " + e.what(), frame, "");
      return 1;
    }
    if (options.checkpointEvery > 0 && frame % options.checkpointEvery == 0 && frame < frames) {
      try {
        writeCheckpoint(*engine, directory, frame, checkpointState, scene.sourceHash);
        checkpointState = "checkpoint_" + std::to_string(frame) + ".state";
      } catch (const std::exception& e) {
        progress.interrupt();
        std::cerr << "blot run: error: checkpoint after frame " << frame << ": " << e.what() << "\n";
        writeFailedSummary(std::string("checkpoint after frame ") + std::to_string(frame) + ": " + e.what(), frame, "");
        return 1;
      }
    }
    progress.update(frame, engine->time(), engine->statistics().stepsPerSecond);
    if (options.killAfterFrame > 0 && frame == options.killAfterFrame) ::kill(::getpid(), SIGKILL);
  }
  try {
    exporter->finish([&](const std::string& video, int done, int total) { progress.encoding(video, done, total); });
  } catch (const std::exception& e) {
    std::cerr << "blot run: error: video: " << e.what() << "\n";
    writeFailedSummary(std::string("video: ") + e.what(), frames, "");
    return 1;
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  std::string previewPath, restPreviewPath;
  if (scene.outputs.preview.enabled) {
    previewPath = writer.writePreview(engine::PreviewShape::Current);
    if (scene.outputs.preview.restShape) restPreviewPath = writer.writePreview(engine::PreviewShape::Rest);
  }

  const engine::EngineStatistics s = engine->statistics();
  const engine::EngineDef& d = scene.engine;
  nlohmann::json summary = {
      {"scene", options.scenePath},
      {"name", scene.name},
      {"status", "ok"},
      {"mesh", scene.meshDescription},
      {"vertices", engine->vertexCount()},
      {"faces", engine->faces().rows()},
      {"cloth_source", engine::motionSourceName(d.source)},
      {"coupling", d.coupling == coupling::CouplingMode::TwoWay ? "two-way" : "one-way"},
      {"threads", engine->threadCount()},
      {"adaptive_threads", engine->adaptiveThreads()},
      {"time_step_s", d.timeStep},
      {"frames", frames},
      {"wall_time_s", wall},
      {"state_hash", hexHash(engine->stateHash())},
      {"terms", termsJson(d)},
      {"terms_ran_steps", engine::termCountsJson(s.totals.termSteps)},  // the internal steps each term ran in
      {"last_step_terms", stain::describeTerms(s.lastProfile)},
      {"outputs", {{"directory", directory}, {"ply", plyPaths}, {"preview", previewPath}, {"preview_rest_shape", restPreviewPath}, {"summary", summaryPath},
                   {"images", exporter->files().images}, {"videos", exporter->files().videos},
                   {"textures", exporter->files().colorTextures}, {"density_maps", exporter->files().densityMaps},
                   {"stain_maps", exporter->files().stainMaps}, {"gltf", exporter->files().gltf}}}};
  summary.update(engine::statisticsJson(s));  // steps, simulated_time_s, mean_ms_per_step, mass_budget_kg, ...
  const std::string summaryText = stain::dumpJson(summary, 2) + "\n";
  stain::writeFileAtomically(summaryPath, summaryText.data(), summaryText.size());  // every write checked
  std::cout << summaryText;
  return 0;
}

}  // namespace

void registerRunCommand(CLI::App& app, int& exitCode) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* command = app.add_subcommand(
      "run", "Run a scene file (docs/scene-format.md): PLY frames, a PNG of the last frame, JSON summary");
  command->add_option("scene", options->scenePath, "Scene file (JSON)")->required()->transform(assetPath());
  command->add_option("--frames", options->frames, "Frames to run (default: the scene's outputs.frames)");
  command
      ->add_option("--out", options->outputDirectory, "Output folder (default: the scene's outputs.directory)")
      ->check(outputFolder());
  command->add_option("--threads", options->threads, "threads of the engine's steps (default: the scene's \"threads\", else OpenMP's default)");
  command->add_flag("--fixed-threads", options->fixedThreads,
                    "every step on all the threads (default: all or one per step, whichever measured faster; scene: adaptive_threads)");
  command->add_flag("--quiet", options->quiet, "No progress output");
  command->add_flag("--images", options->images, "A PNG per frame, <out>/<name>_frame_<k>.png (scene: outputs.images)");
  command->add_option("--camera", options->camera, "Frame images: follow (world view following the cloth) or rest");
  command->add_option("--video", options->video, "mp4, gif or mp4,gif: videos of the frame images (needs ffmpeg on PATH)")
      ->check([](const std::string& value) {
        return value.empty() ? std::string("expected mp4, gif or mp4,gif, got an empty string") : std::string();
      });
  command->add_option("--texture", options->textureSize,
                      "Bake the final stain into the mesh's UVs at NxN texels: <name>_color.png, <name>_density.png");
  command->add_flag("--texture-every-frame", options->textureEveryFrame, "Bake the texture for every written frame");
  command
      ->add_option("--maps", options->maps,
                   "png8, png16, exr (comma-separated): wetness, saturation and stain maps in the mesh's UVs at the "
                   "--texture size (default 1024), <name>_wetness.png, <name>_wetness16.png, <name>_wetness.exr, ... "
                   "(exr needs a build with OpenEXR)")
      ->check([](const std::string& value) {
        return value.empty() ? std::string("expected png8, png16 and/or exr, got an empty string") : std::string();
      });
  command->add_flag("--gltf", options->gltf, "glTF 2.0 binary of the final frame, <out>/<name>.glb");
  command->add_flag("--gltf-every-frame", options->gltfEveryFrame, "A .glb per frame, <out>/<name>_<k>.glb");
  command->add_option("--checkpoint-every", options->checkpointEvery,
                      "Save the whole state every N frames to <out>/checkpoint_<frame>.state (0: never)");
  command->add_flag("--resume", options->resume,
                    "Continue from <out>/checkpoint.json; frames and results equal an uninterrupted run's");
  // Testing-only options: hidden from --help (an empty group).
  command->add_option("--kill-after-frame", options->killAfterFrame,
                      "Testing only: the process kills itself with SIGKILL after this frame")
      ->group("");
  command->add_option("--testing-kill-in-write", options->killInWrite,
                      "Testing only: the process kills itself with SIGKILL half-way through its N-th file write")
      ->group("");
  command->add_option("--testing-inject-fault", options->injectFault,
                      "Testing only: STAGE:STEP:VERTEX puts a NaN after that stage of that internal step "
                      "(docs/reliability.md)")
      ->group("");
  command->callback([options, &exitCode]() { exitCode = runScene(*options); });
}

}  // namespace blot::cli
