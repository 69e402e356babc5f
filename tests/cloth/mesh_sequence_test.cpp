// MeshSequence: exact reproduction of linear (and, for Catmull–Rom, quadratic)
// motion, velocities consistent with positions, hold/loop ends, file loading,
// and rejection of frames whose connectivity differs from frame 0.
#include <blot/cloth/mesh_sequence.h>

#include <blot/stain/io/mesh_io.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/geometry/triangle_mesh.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

namespace blot::cloth {
namespace {

namespace fs = std::filesystem;

// What the engine passes: frames read with stain::loadMesh.
void readWithLoadMesh(const std::string& path, Eigen::MatrixX3d& positions, Eigen::MatrixX3i& faces) {
  stain::TriangleMesh mesh = stain::loadMesh(path);
  positions = std::move(mesh.vertexPositions);
  faces = std::move(mesh.faces);
}

stain::TriangleMesh smallGrid() { return stain::gridMesh(4, 3, 1.0, 0.75); }

Eigen::MatrixX3d randomField(Eigen::Index rows, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::MatrixX3d field(rows, 3);
  for (Eigen::Index i = 0; i < field.size(); ++i) field.data()[i] = unit(rng);
  return field;
}

// Frames of p(t) = p0 + v t + ½ a t², sampled at k / rate.
std::vector<Eigen::MatrixX3d> polynomialFrames(const Eigen::MatrixX3d& p0, const Eigen::MatrixX3d& v,
                                               const Eigen::MatrixX3d& a, int count, double rate) {
  std::vector<Eigen::MatrixX3d> frames;
  for (int k = 0; k < count; ++k) {
    const double t = k / rate;
    frames.push_back(p0 + t * v + 0.5 * t * t * a);
  }
  return frames;
}

TEST(MeshSequence, LinearMotionIsReproducedExactlyByBothInterpolants) {
  const stain::TriangleMesh grid = smallGrid();
  const Eigen::MatrixX3d p0 = grid.vertexPositions, v = randomField(p0.rows(), 1);
  const Eigen::MatrixX3d zero = Eigen::MatrixX3d::Zero(p0.rows(), 3);
  const double rate = 24.0;
  for (FrameInterpolation interpolation : {FrameInterpolation::CatmullRom, FrameInterpolation::Linear}) {
    SequencePlayback playback;
    playback.frameRate = rate;
    playback.interpolation = interpolation;
    const MeshSequence sequence(polynomialFrames(p0, v, zero, 6, rate), grid.faces, playback);
    Eigen::MatrixX3d positions, velocities;
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> time(0.0, 5.0 / rate);
    for (int sample = 0; sample < 200; ++sample) {
      const double t = sample == 0 ? 0.0 : (sample == 1 ? 5.0 / rate - 1e-12 : time(rng));
      sequence.evaluate(t, positions, velocities);
      EXPECT_LT((positions - (p0 + t * v)).cwiseAbs().maxCoeff(), 1e-13) << "t = " << t;
      EXPECT_LT((velocities - v).cwiseAbs().maxCoeff(), 1e-11) << "t = " << t;
    }
  }
}

// Catmull–Rom tangents are exact for quadratics, so inside the sequence
// (segments 1 .. N−3, away from the extrapolated ends) uniform acceleration is
// reproduced exactly: no spurious acceleration impulses at frame boundaries.
TEST(MeshSequence, CatmullRomReproducesUniformAccelerationInside) {
  const stain::TriangleMesh grid = smallGrid();
  const Eigen::MatrixX3d p0 = grid.vertexPositions, v = randomField(p0.rows(), 3),
                         a = randomField(p0.rows(), 4);
  const double rate = 30.0;
  SequencePlayback playback;
  playback.frameRate = rate;
  const MeshSequence sequence(polynomialFrames(p0, v, a, 8, rate), grid.faces, playback);
  Eigen::MatrixX3d positions, velocities;
  for (int sample = 0; sample <= 100; ++sample) {
    const double t = (1.0 + 4.0 * sample / 100.0) / rate;  // segments 1..4 of 0..6
    sequence.evaluate(t, positions, velocities);
    EXPECT_LT((positions - (p0 + t * v + 0.5 * t * t * a)).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_LT((velocities - (v + t * a)).cwiseAbs().maxCoeff(), 1e-11);
  }
}

// d/dt of the interpolated positions equals the reported velocity, for a
// random (non-polynomial) sequence; Catmull–Rom velocity is continuous across
// frames, piecewise-linear velocity is not.
TEST(MeshSequence, VelocityIsTheDerivativeOfThePositions) {
  const stain::TriangleMesh grid = smallGrid();
  std::vector<Eigen::MatrixX3d> frames;
  for (int k = 0; k < 7; ++k) frames.push_back(grid.vertexPositions + 0.1 * randomField(grid.vertexPositions.rows(), 10 + k));
  const double rate = 25.0, delta = 1e-6 / rate;
  for (FrameInterpolation interpolation : {FrameInterpolation::CatmullRom, FrameInterpolation::Linear}) {
    SequencePlayback playback;
    playback.frameRate = rate;
    playback.interpolation = interpolation;
    const MeshSequence sequence(frames, grid.faces, playback);
    Eigen::MatrixX3d ahead, behind, positions, velocities, scratch;
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> time(0.0, 6.0 / rate);
    for (int sample = 0; sample < 100; ++sample) {
      const double t = time(rng);
      const double phase = t * rate - std::floor(t * rate);
      if (phase < 1e-3 || phase > 1 - 1e-3) continue;  // keep t ± δ in one segment
      sequence.evaluate(t, positions, velocities);
      sequence.evaluate(t + delta, ahead, scratch);
      sequence.evaluate(t - delta, behind, scratch);
      // Central difference: truncation ~ δ² |p'''| ≈ 1e-9, rounding ~ ε/δ ≈ 1e-8.
      EXPECT_LT(((ahead - behind) / (2 * delta) - velocities).cwiseAbs().maxCoeff(), 1e-6);
    }
    // Across frame 3: continuous for Catmull–Rom, a jump for linear.
    Eigen::MatrixX3d before, after;
    sequence.evaluate(3.0 / rate - 1e-9, positions, before);
    sequence.evaluate(3.0 / rate + 1e-9, positions, after);
    const double jump = (after - before).cwiseAbs().maxCoeff();
    if (interpolation == FrameInterpolation::CatmullRom) {
      EXPECT_LT(jump, 1e-5);
    } else {
      EXPECT_GT(jump, 0.1);
    }
  }
}

// The reason Catmull–Rom is the default: between frames of a rotating sheet
// the linear interpolant shrinks edges by ≈ φ²/8 (φ = rotation per frame),
// close to the stain's 1e-3 rebuild tolerance; the cubic keeps them to O(φ⁴).
TEST(MeshSequence, CatmullRomKeepsEdgeLengthsOfARotatingSheet) {
  const stain::TriangleMesh grid = smallGrid();
  const double rate = 30.0, omega = 2.0, phi = omega / rate;
  std::vector<Eigen::MatrixX3d> frames;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(omega * k / rate, Eigen::Vector3d::UnitY()).toRotationMatrix();
    frames.push_back(grid.vertexPositions * R.transpose());
  }
  auto maxStrainAtMidFrame = [&](FrameInterpolation interpolation) {
    SequencePlayback playback;
    playback.frameRate = rate;
    playback.interpolation = interpolation;
    const MeshSequence sequence(frames, grid.faces, playback);
    Eigen::MatrixX3d p, v;
    sequence.evaluate(2.5 / rate, p, v);
    double strain = 0;
    for (Eigen::Index f = 0; f < grid.faces.rows(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const int i = grid.faces(f, c), j = grid.faces(f, (c + 1) % 3);
        const double rest = (grid.vertexPositions.row(i) - grid.vertexPositions.row(j)).norm();
        strain = std::max(strain, std::abs((p.row(i) - p.row(j)).norm() / rest - 1.0));
      }
    }
    return strain;
  };
  const double linear = maxStrainAtMidFrame(FrameInterpolation::Linear);
  const double cubic = maxStrainAtMidFrame(FrameInterpolation::CatmullRom);
  EXPECT_NEAR(linear, 1.0 - std::cos(phi / 2), 1e-12);  // chord: φ²/8 = 5.6e-4
  EXPECT_LT(cubic, 1e-5);
  std::printf("mid-frame edge strain at 2 rad/s, 30 fps: linear %.3g, Catmull-Rom %.3g\n", linear, cubic);
}

TEST(MeshSequence, HoldsOrLoopsPastTheLastFrame) {
  const stain::TriangleMesh grid = smallGrid();
  std::vector<Eigen::MatrixX3d> frames;
  for (int k = 0; k < 4; ++k) frames.push_back(grid.vertexPositions + 0.05 * randomField(grid.vertexPositions.rows(), 20 + k));
  SequencePlayback playback;
  playback.frameRate = 10.0;
  MeshSequence held(frames, grid.faces, playback);
  for (int step = 0; step < 50; ++step) held.advance(0.01);  // t = 0.5 s, past frame 3 (0.3 s)
  EXPECT_EQ(held.positions(), frames.back());
  EXPECT_EQ(held.velocities().cwiseAbs().maxCoeff(), 0.0);

  playback.end = SequenceEnd::Loop;
  const MeshSequence looped(frames, grid.faces, playback);
  Eigen::MatrixX3d p1, v1, p2, v2;
  for (double t : {0.0, 0.013, 0.15, 0.37}) {
    looped.evaluate(t, p1, v1);
    looped.evaluate(t + 0.4, p2, v2);  // period N / rate = 0.4 s
    EXPECT_LT((p1 - p2).cwiseAbs().maxCoeff(), 1e-13) << "t = " << t;
    EXPECT_LT((v1 - v2).cwiseAbs().maxCoeff(), 1e-10) << "t = " << t;
  }
  looped.evaluate(0.4, p2, v2);
  EXPECT_LT((p2 - frames[0]).cwiseAbs().maxCoeff(), 1e-13);
}

// ---- Files -----------------------------------------------------------------

class MeshSequenceFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() / ("blot_mesh_sequence_" + std::string(info->name()));
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }

  std::string writeObj(const std::string& name, const Eigen::MatrixX3d& positions,
                       const Eigen::MatrixX3i& faces) const {
    const std::string path = (directory_ / name).string();
    std::ofstream out(path);
    char line[128];
    for (Eigen::Index i = 0; i < positions.rows(); ++i) {
      std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", positions(i, 0), positions(i, 1), positions(i, 2));
      out << line;
    }
    for (Eigen::Index f = 0; f < faces.rows(); ++f)
      out << "f " << faces(f, 0) + 1 << " " << faces(f, 1) + 1 << " " << faces(f, 2) + 1 << "\n";
    return path;
  }
  std::string pattern() const { return (directory_ / "flag_%04d.obj").string(); }
  std::string frameName(int k) const {
    char name[32];
    std::snprintf(name, sizeof name, "flag_%04d.obj", k);
    return name;
  }

  fs::path directory_;
};

TEST_F(MeshSequenceFiles, LoadsNumberedFramesAndPlaysThemAtTheFrameRate) {
  const stain::TriangleMesh grid = smallGrid();
  std::vector<Eigen::MatrixX3d> frames;
  for (int k = 0; k < 4; ++k) {
    frames.push_back(grid.vertexPositions + 0.1 * randomField(grid.vertexPositions.rows(), 40 + k));
    writeObj(frameName(k + 1), frames.back(), grid.faces);  // numbered from 1
  }
  MeshSequenceDef def;
  def.pattern = pattern();
  def.firstFrame = 1;  // frameCount 0: read until the first missing number
  def.playback.frameRate = 20.0;
  const MeshSequence sequence(def, readWithLoadMesh);
  ASSERT_EQ(sequence.frameCount(), 4);
  EXPECT_EQ(sequence.faces(), grid.faces);
  EXPECT_EQ(sequence.framePaths()[3], (directory_ / "flag_0004.obj").string());
  Eigen::MatrixX3d p, v;
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(sequence.frame(k), frames[static_cast<size_t>(k)]);  // %.17g round-trips exactly
    sequence.evaluate(k / 20.0, p, v);
    EXPECT_LT((p - frames[static_cast<size_t>(k)]).cwiseAbs().maxCoeff(), 1e-14);
  }
  // The same frames through an explicit path list and a fixed count.
  MeshSequenceDef listed;
  for (int k = 1; k <= 4; ++k) listed.paths.push_back((directory_ / frameName(k)).string());
  EXPECT_EQ(MeshSequence(listed, readWithLoadMesh).frame(2), frames[2]);
  MeshSequenceDef counted;
  counted.pattern = pattern();
  counted.firstFrame = 2;
  counted.frameCount = 2;
  EXPECT_EQ(MeshSequence(counted, readWithLoadMesh).frameCount(), 2);
}

// Flips the diagonal of a quad in a flat (z = 0) mesh: faces (u, v, w) and
// (v, u, x) become (w, u, x) and (x, v, w), when both new triangles keep a
// positive area (a valid re-triangulation). Searches from face `start`;
// returns the lower index of the two faces changed.
int flipAnEdge(Eigen::MatrixX3i& faces, const Eigen::MatrixX3d& positions, int start) {
  auto area = [&](int a, int b, int c) {
    const Eigen::Vector3d ab = (positions.row(b) - positions.row(a)).transpose();
    const Eigen::Vector3d ac = (positions.row(c) - positions.row(a)).transpose();
    return ab.cross(ac).z();
  };
  for (int f = start; f < faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int u = faces(f, k), v = faces(f, (k + 1) % 3), w = faces(f, (k + 2) % 3);
      for (int g = 0; g < faces.rows(); ++g) {
        for (int c = 0; c < 3; ++c) {
          if (faces(g, c) != v || faces(g, (c + 1) % 3) != u) continue;
          const int x = faces(g, (c + 2) % 3);
          if (!(area(w, u, x) > 1e-9 && area(x, v, w) > 1e-9)) continue;
          faces.row(f) = Eigen::RowVector3i(w, u, x);
          faces.row(g) = Eigen::RowVector3i(x, v, w);
          return std::min(f, g);
        }
      }
    }
  }
  throw std::logic_error("flipAnEdge: no flippable edge");
}

TEST_F(MeshSequenceFiles, RejectsAFrameWithDifferentFacesNamingFileAndFace) {
  const stain::TriangleMesh grid = smallGrid();
  Eigen::MatrixX3i flipped = grid.faces;
  const int firstDifferent = flipAnEdge(flipped, grid.vertexPositions, 7);  // a face inside the list
  for (int k = 0; k < 3; ++k) writeObj(frameName(k), grid.vertexPositions, k == 2 ? flipped : grid.faces);
  MeshSequenceDef def;
  def.pattern = pattern();
  try {
    const MeshSequence sequence(def, readWithLoadMesh);
    FAIL() << "a connectivity change was accepted";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    const std::string expected = "flag_0002.obj: face " + std::to_string(firstDifferent) + " is";
    EXPECT_NE(message.find(expected), std::string::npos) << message;
    EXPECT_NE(message.find("flag_0000.obj"), std::string::npos) << message;
    std::printf("%s\n", message.c_str());
  }
}

TEST_F(MeshSequenceFiles, RejectsAFrameWithADifferentVertexCount) {
  const stain::TriangleMesh grid = smallGrid(), other = stain::gridMesh(5, 3, 1.0, 0.75);
  writeObj(frameName(0), grid.vertexPositions, grid.faces);
  writeObj(frameName(1), other.vertexPositions, other.faces);
  MeshSequenceDef def;
  def.pattern = pattern();
  try {
    const MeshSequence sequence(def, readWithLoadMesh);
    FAIL() << "a vertex-count change was accepted";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("flag_0001.obj: 24 vertices, but frame 0"), std::string::npos) << message;
  }
}

TEST_F(MeshSequenceFiles, RejectsMissingFilesAndBadPatterns) {
  MeshSequenceDef def;
  def.pattern = pattern();
  EXPECT_THROW(MeshSequence(def, readWithLoadMesh), SequenceError);  // no frame 0
  def.pattern = (directory_ / "flag.obj").string();
  EXPECT_THROW(MeshSequence(def, readWithLoadMesh), std::invalid_argument);  // no number field
  def.pattern = (directory_ / "flag_%d_%d.obj").string();
  EXPECT_THROW(MeshSequence(def, readWithLoadMesh), std::invalid_argument);  // two fields
  def.pattern = (directory_ / "flag_%s.obj").string();
  EXPECT_THROW(MeshSequence(def, readWithLoadMesh), std::invalid_argument);  // not an integer field
  const stain::TriangleMesh grid = smallGrid();
  SequencePlayback bad;
  bad.frameRate = 0.0;
  EXPECT_THROW(MeshSequence({grid.vertexPositions}, grid.faces, bad), std::invalid_argument);
  EXPECT_THROW(MeshSequence({grid.vertexPositions, grid.vertexPositions.topRows(3)}, grid.faces),
               std::invalid_argument);
}

}  // namespace
}  // namespace blot::cloth
