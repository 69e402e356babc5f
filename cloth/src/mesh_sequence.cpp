// Mesh-sequence playback (frames from files or from code, fixed connectivity).
//
// Design note: docs/design-notes.md, "cloth/src/mesh_sequence.cpp".
#include <blot/cloth/mesh_sequence.h>


#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace blot::cloth {
namespace {

struct PatternParts {
  std::string prefix, suffix;
  int width = 0;
  bool zeroPad = false;
};

PatternParts parsePattern(const std::string& pattern) {
  PatternParts parts;
  bool found = false;
  std::string* out = &parts.prefix;
  for (size_t i = 0; i < pattern.size(); ++i) {
    if (pattern[i] != '%') {
      *out += pattern[i];
      continue;
    }
    if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
      *out += '%';
      ++i;
      continue;
    }
    size_t j = i + 1;
    if (j < pattern.size() && pattern[j] == '0') {
      parts.zeroPad = true;
      ++j;
    }
    int width = 0;
    while (j < pattern.size() && pattern[j] >= '0' && pattern[j] <= '9' && width < 100)
      width = 10 * width + (pattern[j++] - '0');
    if (found || j >= pattern.size() || (pattern[j] != 'd' && pattern[j] != 'i')) {
      throw std::invalid_argument("MeshSequence: pattern \"" + pattern +
                                  "\" must contain exactly one integer field such as %d or %04d "
                                  "(write %% for a percent sign)");
    }
    parts.width = width;
    found = true;
    out = &parts.suffix;
    i = j;
  }
  if (!found) {
    throw std::invalid_argument("MeshSequence: pattern \"" + pattern +
                                "\" has no integer field such as %d or %04d");
  }
  return parts;
}

std::string framePath(const PatternParts& parts, int number) {
  std::ostringstream s;
  s << parts.prefix << std::setfill(parts.zeroPad ? '0' : ' ') << std::setw(parts.width) << number
    << parts.suffix;
  return s.str();
}

std::vector<std::string> resolvePaths(const MeshSequenceDef& def) {
  if (!def.paths.empty()) return def.paths;
  if (def.firstFrame < 0 || def.frameCount < 0)
    throw std::invalid_argument("MeshSequence: firstFrame and frameCount must not be negative");
  const PatternParts parts = parsePattern(def.pattern);
  std::vector<std::string> paths;
  if (def.frameCount > 0) {
    for (int k = 0; k < def.frameCount; ++k) paths.push_back(framePath(parts, def.firstFrame + k));
    return paths;
  }
  for (int number = def.firstFrame;; ++number) {
    std::string path = framePath(parts, number);
    if (!std::filesystem::exists(path)) break;
    paths.push_back(std::move(path));
  }
  if (paths.empty()) {
    throw SequenceError(framePath(parts, def.firstFrame) +
                           ": no such file (first frame of the sequence \"" + def.pattern + "\")");
  }
  return paths;
}

std::string faceText(const Eigen::MatrixX3i& faces, Eigen::Index f) {
  std::ostringstream s;
  s << "(" << faces(f, 0) << ", " << faces(f, 1) << ", " << faces(f, 2) << ")";
  return s.str();
}

// Positions and faces of one frame as the reader returned them.
struct FrameData {
  Eigen::MatrixX3d vertexPositions;
  Eigen::MatrixX3i faces;
};

FrameData readFrame(const FrameReader& read, const std::string& path) {
  FrameData frame;
  read(path, frame.vertexPositions, frame.faces);
  return frame;
}

// Throws SequenceError naming `path` if `mesh` does not have frame 0's vertices and faces.
void checkSameConnectivity(const FrameData& mesh, const std::string& path, const FrameData& first,
                           const std::string& firstPath) {
  const std::string rule = "; every frame of a mesh sequence needs frame 0's vertices and faces";
  if (mesh.vertexPositions.rows() != first.vertexPositions.rows()) {
    throw SequenceError(path + ": " + std::to_string(mesh.vertexPositions.rows()) +
                           " vertices, but frame 0 (" + firstPath + ") has " +
                           std::to_string(first.vertexPositions.rows()) + rule);
  }
  const Eigen::Index common = std::min(mesh.faces.rows(), first.faces.rows());
  for (Eigen::Index f = 0; f < common; ++f) {
    if (mesh.faces.row(f) != first.faces.row(f)) {
      throw SequenceError(path + ": face " + std::to_string(f) + " is " + faceText(mesh.faces, f) +
                             " but in frame 0 (" + firstPath + ") it is " + faceText(first.faces, f) +
                             rule);
    }
  }
  if (mesh.faces.rows() != first.faces.rows()) {
    throw SequenceError(path + ": face " + std::to_string(common) +
                           (mesh.faces.rows() > common ? " is extra" : " is missing") + " (" +
                           std::to_string(mesh.faces.rows()) + " faces, frame 0 (" + firstPath +
                           ") has " + std::to_string(first.faces.rows()) + ")" + rule);
  }
}

}  // namespace

MeshSequence::MeshSequence(const MeshSequenceDef& def, const FrameReader& read) : playback_(def.playback) {
  checkPlayback();
  if (!read) throw std::invalid_argument("MeshSequence: no frame reader given");
  paths_ = resolvePaths(def);
  FrameData first = readFrame(read, paths_.front());
  frames_.reserve(paths_.size());
  frames_.push_back(first.vertexPositions);
  for (size_t k = 1; k < paths_.size(); ++k) {
    FrameData mesh = readFrame(read, paths_[k]);
    checkSameConnectivity(mesh, paths_[k], first, paths_.front());
    frames_.push_back(std::move(mesh.vertexPositions));
  }
  faces_ = std::move(first.faces);
  evaluate(0.0, positions_, velocities_);
}

MeshSequence::MeshSequence(std::vector<Eigen::MatrixX3d> frames, Eigen::MatrixX3i faces,
                           const SequencePlayback& playback)
    : frames_(std::move(frames)), faces_(std::move(faces)), playback_(playback) {
  checkPlayback();
  if (frames_.empty()) throw std::invalid_argument("MeshSequence: no frames");
  const Eigen::Index n = frames_.front().rows();
  for (size_t k = 0; k < frames_.size(); ++k) {
    if (frames_[k].rows() != n) {
      throw std::invalid_argument("MeshSequence: frame " + std::to_string(k) + " has " +
                                  std::to_string(frames_[k].rows()) + " vertices, frame 0 has " +
                                  std::to_string(n));
    }
    if (!frames_[k].allFinite())
      throw std::invalid_argument("MeshSequence: frame " + std::to_string(k) + " has a non-finite position");
  }
  if (faces_.size() > 0 && (faces_.minCoeff() < 0 || faces_.maxCoeff() >= n))
    throw std::invalid_argument("MeshSequence: a face index is out of range");
  evaluate(0.0, positions_, velocities_);
}

void MeshSequence::checkPlayback() const {
  if (!(playback_.frameRate > 0) || !std::isfinite(playback_.frameRate))
    throw std::invalid_argument("MeshSequence: frameRate must be finite and positive");
}

void MeshSequence::advance(double h) {
  if (!(h > 0) || !std::isfinite(h))
    throw std::invalid_argument("MeshSequence::advance: time step must be finite and positive");
  time_ += h;
  evaluate(time_, positions_, velocities_);
}

void MeshSequence::rollBack() {
  time_ = rollbackTime_;
  evaluate(time_, positions_, velocities_);
}

void MeshSequence::evaluate(double t, Eigen::MatrixX3d& positions, Eigen::MatrixX3d& velocities) const {
  const int frameCount = static_cast<int>(frames_.size());
  const Eigen::Index n = frames_.front().rows();
  if (positions.rows() != n) positions.resize(n, 3);
  if (velocities.rows() != n) velocities.resize(n, 3);
  const bool loop = playback_.end == SequenceEnd::Loop;
  double u = std::max(t, 0.0) * playback_.frameRate;  // time in frames
  if (loop) u = std::fmod(u, static_cast<double>(frameCount));
  if (frameCount == 1 || (!loop && u >= frameCount - 1)) {
    positions = frames_.back();
    velocities.setZero();
    return;
  }
  int k = static_cast<int>(std::floor(u));
  k = std::min(k, loop ? frameCount - 1 : frameCount - 2);  // guards u rounding up to the end
  const double s = u - k;
  auto wrap = [frameCount](int i) { return (i % frameCount + frameCount) % frameCount; };
  const int b = k, c = loop ? wrap(k + 1) : k + 1;
  const double rate = playback_.frameRate;

  if (playback_.interpolation == FrameInterpolation::Linear) {
    positions.noalias() = (1.0 - s) * frames_[static_cast<size_t>(b)] + s * frames_[static_cast<size_t>(c)];
    velocities.noalias() = rate * (frames_[static_cast<size_t>(c)] - frames_[static_cast<size_t>(b)]);
    return;
  }

  // Hermite basis at s and its derivative, as weights on P_{k−1}, P_k, P_{k+1}, P_{k+2}.
  const double s2 = s * s, s3 = s2 * s;
  const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
  const double d00 = 6 * s2 - 6 * s, d10 = 3 * s2 - 4 * s + 1, d01 = -6 * s2 + 6 * s, d11 = 3 * s2 - 2 * s;
  double w[4] = {-0.5 * h10, h00 - 0.5 * h11, h01 + 0.5 * h10, 0.5 * h11};
  double dw[4] = {-0.5 * d10, d00 - 0.5 * d11, d01 + 0.5 * d10, 0.5 * d11};
  int index[4] = {k - 1, b, c, k + 2};
  if (loop) {
    index[0] = wrap(k - 1);
    index[3] = wrap(k + 2);
  } else {
    // Missing end frames are linear extrapolations: P_{−1} = 2P_0 − P_1 and
    // P_N = 2P_{N−1} − P_{N−2}; fold their weights onto the real frames.
    auto fold = [](double* weights, int ghost, int nearest, int other) {
      weights[nearest] += 2 * weights[ghost];
      weights[other] -= weights[ghost];
      weights[ghost] = 0;
    };
    if (index[0] < 0) {
      fold(w, 0, 1, 2);
      fold(dw, 0, 1, 2);
      index[0] = b;
    }
    if (index[3] > frameCount - 1) {
      fold(w, 3, 2, 1);
      fold(dw, 3, 2, 1);
      index[3] = c;
    }
  }
  const Eigen::MatrixX3d& p0 = frames_[static_cast<size_t>(index[0])];
  const Eigen::MatrixX3d& p1 = frames_[static_cast<size_t>(index[1])];
  const Eigen::MatrixX3d& p2 = frames_[static_cast<size_t>(index[2])];
  const Eigen::MatrixX3d& p3 = frames_[static_cast<size_t>(index[3])];
  positions.noalias() = w[0] * p0 + w[1] * p1 + w[2] * p2 + w[3] * p3;
  velocities.noalias() = rate * (dw[0] * p0 + dw[1] * p1 + dw[2] * p2 + dw[3] * p3);
}

}  // namespace blot::cloth
