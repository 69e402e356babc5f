// Failed output writes: a PNG or PLY frame that cannot be written completely
// leaves no partial file (neither the target nor a temporary), keeps the
// previous version of the file intact, and the error names the path. The
// failures are real: a target that is a directory (rename fails after the
// temporary was written), a parent that is a file (the temporary cannot be
// created), a file-size limit (RLIMIT_FSIZE) that makes write() fail half
// way, and a genuinely full filesystem (a 64 KiB tmpfs, ENOSPC) where the test
// may mount one. Root ignores permission bits, so chmod is no portable way to
// make a folder unwritable in CI.
#include <blot/engine/engine.h>
#include <blot/engine/frame_writer.h>
#include <blot/engine/image.h>
#include <blot/engine/ply_frame_writer.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/io/atomic_file.h>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <cerrno>
#include <cstring>
#include <sys/mount.h>
#include <sys/resource.h>
#include <unistd.h>
#include <vector>

namespace blot::engine {
namespace {

namespace fs = std::filesystem;

class OutputFailureTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() /
                 ("blot_output_failure_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }
  std::string path(const std::string& name) const { return (directory_ / name).string(); }
  /// Names in the test folder, sorted.
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(directory_))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path directory_;
};

std::string fileBytes(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

/// Runs `write`, expecting an exception of type E whose message names `target`.
template <class E>
void expectFailureNaming(const std::function<void()>& write, const std::string& target) {
  try {
    write();
    ADD_FAILURE() << "the write to " << target << " succeeded";
  } catch (const E& error) {
    EXPECT_NE(std::string(error.what()).find(target), std::string::npos) << error.what();
  }
}

/// Lowers the file-size limit of this process for its lifetime; writes past it
/// fail with EFBIG (SIGXFSZ is ignored meanwhile instead of killing us).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    previousHandler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    active_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    std::signal(SIGXFSZ, previousHandler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;
  bool active() const { return active_; }

 private:
  rlimit saved_{};
  void (*previousHandler_)(int) = SIG_DFL;
  bool active_ = false;
};

Image noiseImage(int size) {
  Image image(size, size, 3);
  unsigned state = 12345u;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      state = state * 1664525u + 1013904223u;  // incompressible pixels: a large PNG
      image.setPixel(x, y, Rgba8{static_cast<std::uint8_t>(state >> 24),
                                 static_cast<std::uint8_t>(state >> 16),
                                 static_cast<std::uint8_t>(state >> 8), 255});
    }
  }
  return image;
}

PlyFrame squareFrame(double z) {
  PlyFrame frame;
  frame.vertexPositions.resize(4, 3);
  frame.vertexPositions << 0, 0, z, 1, 0, z, 1, 1, z, 0, 1, z;
  frame.faces.resize(2, 3);
  frame.faces << 0, 1, 2, 0, 2, 3;
  Eigen::VectorXd solute(4);
  solute << 0.1, 0.2, 0.3, 0.4;
  frame.vertexAttributes.push_back({"solute", solute, PlyScalarType::Float64});
  return frame;
}

TEST_F(OutputFailureTest, TargetThatIsADirectoryLeavesNoTemporary) {
  fs::create_directories(path("frame.png/inside"));
  fs::create_directories(path("frame_0001.ply/inside"));
  expectFailureNaming<ImageError>([&] { writePng(noiseImage(8), path("frame.png")); },
                                  path("frame.png"));
  expectFailureNaming<std::runtime_error>(
      [&] { writePlyFrame(path("frame_0001.ply"), squareFrame(0)); }, path("frame_0001.ply"));
  EXPECT_EQ(entries(), (std::vector<std::string>{"frame.png", "frame_0001.ply"}));
  EXPECT_TRUE(fs::is_directory(path("frame.png/inside")));
}

// A link is written through: its target gets the new bytes and the link
// stays (the rename replaced the link with a file). Something there that is
// no regular file is refused, not replaced (as root a write to /dev/full
// turned the device into a file); a named pipe stands in for a device here.
TEST_F(OutputFailureTest, ALinkIsWrittenThroughAndANonRegularTargetIsRefused) {
  std::ofstream(path("real.ply")) << "old";
  fs::create_symlink("real.ply", path("link.ply"));
  writePlyFrame(path("link.ply"), squareFrame(0));
  EXPECT_TRUE(fs::is_symlink(path("link.ply")));
  EXPECT_NE(fileBytes(path("real.ply")), "old");
  EXPECT_EQ(fileBytes(path("link.ply")), fileBytes(path("real.ply")));
  ASSERT_EQ(::mkfifo(path("pipe.ply").c_str(), 0600), 0);
  expectFailureNaming<std::runtime_error>([&] { writePlyFrame(path("pipe.ply"), squareFrame(0)); },
                                          path("pipe.ply"));
  try {
    writePlyFrame(path("pipe.ply"), squareFrame(0));
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("it exists and is not a regular file (a named pipe); refusing to replace it"),
              std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(fs::is_fifo(path("pipe.ply")));
  EXPECT_EQ(entries(), (std::vector<std::string>{"link.ply", "pipe.ply", "real.ply"}));
}

TEST_F(OutputFailureTest, ParentThatIsAFileNamesThePath) {
  std::ofstream(path("not_a_folder")) << "x";
  const std::string png = path("not_a_folder/frame.png");
  const std::string ply = path("not_a_folder/frame.ply");
  expectFailureNaming<ImageError>([&] { writePng(noiseImage(4), png); }, png);
  expectFailureNaming<std::runtime_error>([&] { writePlyFrame(ply, squareFrame(0)); }, ply);
  EXPECT_EQ(entries(), std::vector<std::string>{"not_a_folder"});
  EXPECT_EQ(fileBytes(path("not_a_folder")), "x");
}

TEST_F(OutputFailureTest, WriteCutShortKeepsThePreviousFileAndRemovesThePartialOne) {
  // A good small version of each file first.
  const Image small = noiseImage(4);
  writePng(small, path("preview.png"));
  PlyWriteOptions ascii;
  ascii.format = PlyFormat::Ascii;
  writePlyFrame(path("frame_0007.ply"), squareFrame(0), ascii);
  const std::string goodPng = fileBytes(path("preview.png"));
  const std::string goodPly = fileBytes(path("frame_0007.ply"));
  ASSERT_LT(goodPng.size(), 2000u);
  ASSERT_LT(goodPly.size(), 2000u);

  // The replacement is far larger than the limit: the write stops part way.
  PlyFrame big = squareFrame(1);
  big.vertexAttributes.clear();
  for (int k = 0; k < 400; ++k) {
    Eigen::VectorXd values = Eigen::VectorXd::Constant(4, 0.123456789 * k);
    big.vertexAttributes.push_back({"a" + std::to_string(k), values, PlyScalarType::Float64});
  }
  {
    const FileSizeLimit limit(4096);
    ASSERT_TRUE(limit.active()) << "cannot lower RLIMIT_FSIZE here";
    expectFailureNaming<ImageError>([&] { writePng(noiseImage(64), path("preview.png")); },
                                    path("preview.png"));
    expectFailureNaming<std::runtime_error>(
        [&] { writePlyFrame(path("frame_0007.ply"), big, ascii); }, path("frame_0007.ply"));
  }
  EXPECT_EQ(fileBytes(path("preview.png")), goodPng);
  EXPECT_EQ(fileBytes(path("frame_0007.ply")), goodPly);
  EXPECT_TRUE(readPng(path("preview.png")) == small);
  EXPECT_EQ(entries(), (std::vector<std::string>{"frame_0007.ply", "preview.png"}));
}

TEST_F(OutputFailureTest, RefusedFrameLeavesThePreviousFrameUntouched) {
  writePlyFrame(path("frame_0002.ply"), squareFrame(0));
  const std::string good = fileBytes(path("frame_0002.ply"));
  PlyFrame bad = squareFrame(1);
  bad.vertexAttributes[0].values[2] = std::nan("");
  try {
    writePlyFrame(path("frame_0002.ply"), bad);
    FAIL() << "a NaN attribute was written";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("'solute' vertex 2"), std::string::npos) << error.what();
  }
  EXPECT_EQ(fileBytes(path("frame_0002.ply")), good);
  EXPECT_EQ(entries(), std::vector<std::string>{"frame_0002.ply"});
}

/// A real full disk: a 64 KiB tmpfs mounted over a folder for the test's
/// lifetime (needs root with CAP_SYS_ADMIN, as in CI's container; elsewhere
/// the tests using it skip, saying why).
class TinyFilesystem {
 public:
  explicit TinyFilesystem(const fs::path& folder) : folder_(folder) {
    fs::create_directories(folder);
    if (::mount("tmpfs", folder.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, "size=64k,mode=0700") == 0)
      mounted_ = true;
    else
      why_ = std::string("cannot mount a 64 KiB tmpfs on ") + folder.string() + ": " + std::strerror(errno);
  }
  ~TinyFilesystem() {
    if (mounted_) ::umount2(folder_.c_str(), MNT_DETACH);
  }
  TinyFilesystem(const TinyFilesystem&) = delete;
  TinyFilesystem& operator=(const TinyFilesystem&) = delete;
  bool mounted() const { return mounted_; }
  const std::string& why() const { return why_; }

 private:
  fs::path folder_;
  bool mounted_ = false;
  std::string why_;
};

std::vector<std::string> namesIn(const fs::path& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// ENOSPC for real: on a 64 KiB filesystem, earlier outputs written while it
// had room, then writes that do not fit. Each fails with "No space left on
// device" naming its file, leaves no temporary and no partial file, and every
// earlier file is byte-identical and still reads back; once space is freed
// the same write succeeds.
TEST_F(OutputFailureTest, FullFilesystemFailsClearlyAndKeepsEarlierOutputs) {
  const fs::path disk = directory_ / "disk";
  TinyFilesystem tiny(disk);
  if (!tiny.mounted()) GTEST_SKIP() << tiny.why();
  const std::string png = (disk / "preview.png").string(), ply = (disk / "frame_0001.ply").string();
  const std::string state = (disk / "checkpoint.json").string();
  const Image small = noiseImage(16);
  writePng(small, png);
  writePlyFrame(ply, squareFrame(0));
  const std::string record = "{\"frame\": 3}\n";
  stain::writeFileAtomically(state, record.data(), record.size());
  const std::string goodPng = fileBytes(png), goodPly = fileBytes(ply);
  // A filler that leaves less room than any of the next writes needs.
  const std::string filler(40 * 1024, 'x');
  stain::writeFileAtomically((disk / "filler").string(), filler.data(), filler.size());

  const auto expectNoSpace = [&](const std::function<void()>& write, const std::string& target) {
    try {
      write();
      ADD_FAILURE() << "the write to " << target << " succeeded on a full filesystem";
    } catch (const std::runtime_error& error) {
      const std::string message = error.what();
      EXPECT_EQ(message.rfind(target + ": cannot write", 0), 0u) << message;
      EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
    }
  };
  expectNoSpace([&] { writePng(noiseImage(100), png); }, png);  // 30 KiB of incompressible pixels
  PlyFrame big = squareFrame(1);
  for (int k = 0; k < 2000; ++k)
    big.vertexAttributes.push_back({"a" + std::to_string(k), Eigen::VectorXd::Constant(4, k), PlyScalarType::Float64});
  expectNoSpace([&] { writePlyFrame(ply, big); }, ply);
  const std::string summary(30 * 1024, ' ');
  expectNoSpace([&] { stain::writeFileAtomically(state, summary.data(), summary.size()); }, state);

  EXPECT_EQ(namesIn(disk), (std::vector<std::string>{"checkpoint.json", "filler", "frame_0001.ply", "preview.png"}));
  EXPECT_EQ(fileBytes(png), goodPng);
  EXPECT_TRUE(readPng(png) == small);
  EXPECT_EQ(fileBytes(ply), goodPly);
  EXPECT_EQ(fileBytes(state), record);
  // Room again: the same write goes through.
  fs::remove(disk / "filler");
  writePng(noiseImage(100), png);
  EXPECT_EQ(readPng(png).width(), 100);
}

// FrameWriter's name becomes file names in its directory, as a scene's name
// does: a folder in it ("../../escape" wrote outside the directory) or a
// leading dot is refused before anything is made.
TEST_F(OutputFailureTest, AFrameWriterNameWithAFolderIsRefused) {
  EngineDef def;
  def.mesh = stain::gridMesh(3, 3, 1.0, 1.0);
  const Engine engine(def);
  for (const char* name : {"../../escape", "a/b", ".hidden"}) {
    FrameWriterOptions options;
    options.directory = path("frames");
    options.name = name;
    try {
      const FrameWriter writer(engine, options);
      ADD_FAILURE() << name << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("must be a file name"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(entries().empty());
}

}  // namespace
}  // namespace blot::engine
