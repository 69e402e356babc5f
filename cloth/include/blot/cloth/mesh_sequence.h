#pragma once
/// Mesh-sequence playback: numbered OBJ/PLY frames (or frames built in code)
/// with fixed connectivity, played back in time as a SurfaceMotion.
///
/// Between frames the positions follow a Catmull–Rom spline by default (C¹:
/// velocity continuous, so the stain's centred accelerations see no impulse at
/// frame boundaries) or a piecewise-linear interpolant; velocities are the time
/// derivative of the same interpolant. Frame k is at time k / frameRate.
#include <blot/cloth/surface_motion.h>

#include <Eigen/Core>

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::cloth {

/// How positions between two frames are computed.
enum class FrameInterpolation {
  CatmullRom,  ///< default: uniform Catmull–Rom cubic through the frames (C¹)
  Linear       ///< piecewise linear (C⁰: the velocity jumps at every frame)
};

/// What happens after the last frame.
enum class SequenceEnd {
  Hold,  ///< default: stay at the last frame with zero velocity
  Loop   ///< wrap around: the last frame is followed by frame 0 one frame later
};

/// Playback settings shared by file-based and in-memory sequences.
struct SequencePlayback {
  double frameRate = 30.0;  ///< frames per second (> 0)
  FrameInterpolation interpolation = FrameInterpolation::CatmullRom;
  SequenceEnd end = SequenceEnd::Hold;
};

/// A sequence stored as files.
struct MeshSequenceDef {
  /// printf-style path with exactly one integer field (%d, %4d or %04d; %% for
  /// a literal percent sign), e.g. "frames/flag_%04d.obj".
  std::string pattern;
  int firstFrame = 0;  ///< number substituted for frame 0
  int frameCount = 0;  ///< files to read; 0 = every consecutive number until one is missing
  /// Alternatively the files in playback order; when non-empty, pattern,
  /// firstFrame and frameCount are ignored.
  std::vector<std::string> paths;
  SequencePlayback playback;
};

/// Reads one frame file into positions (#V by 3, m) and faces (#F by 3), or
/// throws naming the file. cloth/ does no mesh I/O of its own (it never sees
/// stain/): the engine passes a reader built on blot::stain::loadMesh.
using FrameReader =
    std::function<void(const std::string& path, Eigen::MatrixX3d& positions, Eigen::MatrixX3i& faces)>;

/// A frame whose vertex count or faces differ from frame 0's.
class SequenceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class MeshSequence final : public SurfaceMotion {
 public:
  /// Reads every frame with `read`. Throws SequenceError naming the file when
  /// a frame's vertex count or faces differ from frame 0's (naming the first
  /// differing face), whatever `read` throws for a missing or unreadable file,
  /// and std::invalid_argument for a malformed pattern or playback setting.
  MeshSequence(const MeshSequenceDef& def, const FrameReader& read);
  /// Frames built in code: each #V by 3 (m), all sharing `faces` (#F by 3).
  /// Throws std::invalid_argument when sizes differ or a value is not finite.
  MeshSequence(std::vector<Eigen::MatrixX3d> frames, Eigen::MatrixX3i faces,
               const SequencePlayback& playback = SequencePlayback());

  /// Static for a single frame, Deforming otherwise.
  int vertexCount() const override { return static_cast<int>(frames_.front().rows()); }
  double time() const override { return time_; }
  const Eigen::MatrixX3d& positions() const override { return positions_; }
  const Eigen::MatrixX3d& velocities() const override { return velocities_; }
  /// Moves to time() + h (h > 0, s); allocates nothing.
  void advance(double h) override;
  void keepRollbackPoint() override { rollbackTime_ = time_; }
  /// Evaluates the sequence at the kept time (a pure function of time).
  void rollBack() override;

  /// Positions (m) and velocities (m/s) at any time t ≥ 0 (s), written into
  /// caller-owned #V by 3 arrays (resized only if their size differs).
  void evaluate(double t, Eigen::MatrixX3d& positions, Eigen::MatrixX3d& velocities) const;

  const Eigen::MatrixX3i& faces() const { return faces_; }
  int frameCount() const { return static_cast<int>(frames_.size()); }
  /// Frame k as loaded, #V by 3 (m).
  const Eigen::MatrixX3d& frame(int k) const { return frames_.at(static_cast<size_t>(k)); }
  /// File each frame came from (empty for in-memory frames).
  const std::vector<std::string>& framePaths() const { return paths_; }
  const SequencePlayback& playback() const { return playback_; }

 private:
  void checkPlayback() const;
  std::vector<Eigen::MatrixX3d> frames_;
  Eigen::MatrixX3i faces_;
  std::vector<std::string> paths_;
  SequencePlayback playback_;
  Eigen::MatrixX3d positions_, velocities_;
  double time_ = 0, rollbackTime_ = 0;
};

}  // namespace blot::cloth
