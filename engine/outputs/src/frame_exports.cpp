// Frame images, videos (ffmpeg), UV texture bakes and glTF files of a run.
//
// Design note: ffmpeg is run as a separate program (Debian's `ffmpeg`),
// spawned with posix_spawn (no shell, so no quoting of paths) and fed raw
// rgb24 frames on its standard input, decoded from the PNGs already written:
// the video has exactly the frames the images show, whatever their numbering,
// and its colours are those sRGB bytes (tagged BT.709 / sRGB transfer).
// Rejected: linking libavcodec (a large API for one encode) and an image2
// file pattern (frames written every k-th frame are not contiguous).
#include <blot/engine/frame_exports.h>

#include <blot/engine/exr_image.h>
#include <blot/engine/gltf_writer.h>
#include <blot/engine/image.h>
#include <blot/engine/stain_maps.h>
#include <blot/engine/uv_texture.h>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace blot::engine {
namespace {

Eigen::Vector3d upFor(const SceneImages& s) {
  const Eigen::Vector3d view = s.viewDirection.normalized();
  if (s.up.norm() > 0) return s.up.normalized();
  return std::abs(view.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
}

// Writes all of `bytes` to `fd`; false on a closed pipe or another error.
bool writeAll(int fd, const std::uint8_t* bytes, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, bytes, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    bytes += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

std::string findOnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return {};
  std::stringstream entries(path);
  for (std::string dir; std::getline(entries, dir, ':');) {
    if (dir.empty()) dir = ".";
    const std::string candidate = dir + "/" + program;
    if (::access(candidate.c_str(), X_OK) == 0 && !std::filesystem::is_directory(candidate)) return candidate;
  }
  return {};
}

FrameExporter::FrameExporter(const FrameExportSettings& settings, std::string directory, std::string name,
                             const Engine& engine)
    : settings_(settings), directory_(std::move(directory)), name_(std::move(name)) {
  const bool hasUvs = engine.definition().mesh.vertexUVs.rows() == engine.vertexCount();
  if (settings_.texture.enabled && !hasUvs)
    throw std::invalid_argument("outputs.texture: the mesh has no UVs to bake into");
  if (settings_.texture.maps.any() && !hasUvs)
    throw std::invalid_argument("outputs.texture.maps (--maps): the mesh has no UVs to bake the maps into");
  if (settings_.texture.maps.exr && !exrSupported())
    throw MissingFeatureError("outputs.texture.maps (--maps): exr: " + exrMissingHelp());
  if (settings_.video.mp4 || settings_.video.gif) {
    settings_.images.enabled = true;
    ffmpeg_ = findOnPath("ffmpeg");
    if (ffmpeg_.empty())
      throw MissingToolError("outputs.video: ffmpeg was not found on PATH; install it (Debian: apt-get install ffmpeg) "
                             "or drop the video outputs");
  }
}

std::string FrameExporter::numbered(const std::string& kind, int frame, const std::string& extension) const {
  char digits[32];
  std::snprintf(digits, sizeof digits, "%04d", frame);
  return (std::filesystem::path(directory_) / (name_ + "_" + kind + digits + extension)).string();
}

std::string FrameExporter::texturePath(const std::string& kind, int frame, const std::string& extension) const {
  if (settings_.texture.everyFrame) return numbered(kind + "_", frame, extension);
  return (std::filesystem::path(directory_) / (name_ + "_" + kind + extension)).string();
}

std::string FrameExporter::imagePath(int frame) const { return numbered("frame_", frame, ".png"); }

bool FrameExporter::imageDue(int frame, bool last) const {
  return settings_.images.enabled && (frame % settings_.images.every == 0 || last);
}

Camera FrameExporter::camera(const Engine& engine) {
  const SceneImages& s = settings_.images;
  const double aspect = double(s.width) / s.height;
  const Eigen::Vector3d view = s.viewDirection.normalized();
  if (s.camera == FrameCamera::Rest) {
    if (!baseCamera_) baseCamera_ = framePoints(engine.definition().mesh.vertexPositions, view, aspect, s.projection, upFor(s));
    return *baseCamera_;
  }
  const Eigen::Vector3d centroid = engine.positions().colwise().mean().transpose();
  if (!baseCamera_) {
    // Framed on the first frame with extra margin, so the cloth's swing stays in view.
    baseCamera_ = framePoints(engine.positions(), view, aspect, s.projection, upFor(s), 30.0, 1.35);
    baseCentroid_ = centroid;
  }
  Camera c = *baseCamera_;
  c.eye += centroid - baseCentroid_;
  c.target += centroid - baseCentroid_;
  return c;
}

void FrameExporter::writeFrame(int frame, const Engine& engine, bool last) {
  if (imageDue(frame, last)) {
    const SceneImages& s = settings_.images;
    RenderSettings render;
    render.width = s.width;
    render.height = s.height;
    render.supersampling = s.supersampling;
    render.background = {0.8, 0.82, 0.87};  // linear; sRGB bytes (231, 233, 240)
    const Camera cam = camera(engine);
    const auto& positions = s.camera == FrameCamera::Rest ? engine.definition().mesh.vertexPositions : engine.positions();
    const std::string path = imagePath(frame);
    writePng(renderMesh(positions, engine.faces(), engine.colors(), cam, render), path);
    files_.images.push_back(path);
  }
  const Eigen::MatrixX2d& uvs = engine.definition().mesh.vertexUVs;
  const bool hasUvs = uvs.rows() == engine.vertexCount() && uvs.rows() > 0;
  const bool textureDue = settings_.texture.enabled && (settings_.texture.everyFrame || last);
  const bool mapsDue = settings_.texture.maps.any() && (settings_.texture.everyFrame || last);
  const bool gltfDue = settings_.gltf.enabled && (settings_.gltf.everyFrame || last);
  if (!textureDue && !mapsDue && !gltfDue) return;
  UvBakeOptions bake;
  bake.width = settings_.texture.width;
  bake.height = settings_.texture.height;
  bake.padding = settings_.texture.padding;
  Image color;
  if (hasUvs && (textureDue || gltfDue)) color = bakeVertexColorsToUv(uvs, engine.faces(), engine.colors(), bake);
  // Wetness, saturation and stain in one bake: the maps and the glTF's roughness.
  UvBake stainMaps;
  if (hasUvs && (mapsDue || gltfDue))
    stainMaps = bakeVertexValuesToUv(uvs, engine.faces(),
                                     stainMapValues(engine.solvent(), engine.solute(), engine.absorbedSolvent(),
                                                    engine.absorbedSolute(), engine.adsorbedSolute()),
                                     bake);
  if (textureDue) {
    const std::string colorPath = texturePath("color", frame, ".png");
    const std::string densityPath = texturePath("density", frame, ".png");
    writePng(color, colorPath);
    // R: all solute (free + absorbed + adsorbed), G: all solvent (free +
    // absorbed), B: adsorbed solute (the rim), A: coverage; kg/m² / density_scale.
    Eigen::MatrixXd densities(engine.vertexCount(), 3);
    densities.col(0) = engine.solute() + engine.absorbedSolute() + engine.adsorbedSolute();
    densities.col(1) = engine.solvent() + engine.absorbedSolvent();
    densities.col(2) = engine.adsorbedSolute();
    const UvBake baked = bakeVertexValuesToUv(uvs, engine.faces(), densities, bake);
    char scale[64];
    std::snprintf(scale, sizeof scale, "%.17g", settings_.texture.densityScale);
    writePng16(densityMap(baked, settings_.texture.densityScale), densityPath,
               {"blot:channels", "R=solute+absorbed_solute+adsorbed_solute G=solvent+absorbed_solvent "
                                 "B=adsorbed_solute A=coverage",
                "blot:density_scale_kg_per_m2", scale});
    files_.colorTextures.push_back(colorPath);
    files_.densityMaps.push_back(densityPath);
  }
  if (mapsDue) writeStainMaps(frame, stainMaps);
  if (gltfDue) {
    GltfFrame g;
    g.positions = engine.positions();
    g.normals = engine.normals();
    if (hasUvs) {
      g.uvs = uvs;
      g.texturePng = encodePng(color);
      GlossSettings gloss;
      gloss.glossWetness = settings_.gltf.glossWetness;
      g.metallicRoughnessPng =
          encodeDataPng(metallicRoughnessMap(stainMaps, static_cast<int>(StainMap::Wetness), gloss), 8);
    }
    g.faces = engine.faces();
    g.colors = engine.colors();
    g.name = name_;
    const std::string path = settings_.gltf.everyFrame ? numbered("", frame, ".glb")
                                                       : (std::filesystem::path(directory_) / (name_ + ".glb")).string();
    writeGlb(path, g);
    files_.gltf.push_back(path);
  }
}

void FrameExporter::writeStainMaps(int frame, const UvBake& baked) {
  const StainMapFormats& formats = settings_.texture.maps;
  const double scale = settings_.texture.densityScale;
  char scaleText[64];
  std::snprintf(scaleText, sizeof scaleText, "%.17g", scale);
  for (int m = 0; m < kStainMapCount; ++m) {
    const std::string map = stainMapName(static_cast<StainMap>(m));
    const std::string definition = stainMapDefinition(static_cast<StainMap>(m));
    // PNG: grey = value / density_scale at full scale, both named in tEXt chunks.
    const std::vector<std::string> text = {"blot:map", map + " = " + definition + " (kg/m2)",
                                           "blot:density_scale_kg_per_m2", scaleText};
    if (formats.png8) {
      const std::string path = texturePath(map, frame, ".png");
      writeDataPng(dataMapChannel(baked, m, 8, scale), 8, path, text);
      files_.stainMaps.push_back(path);
    }
    if (formats.png16) {
      const std::string path = texturePath(map + "16", frame, ".png");
      writeDataPng(dataMapChannel(baked, m, 16, scale), 16, path, text);
      files_.stainMaps.push_back(path);
    }
    // EXR: kg/m² as they are, the quantity and unit in header attributes.
    if (formats.exr) {
      const std::string path = texturePath(map, frame, ".exr");
      writeExr(floatMapChannel(baked, m), path,
               {{"blot:map", map}, {"blot:definition", definition}, {"blot:units", "kg/m^2"}});
      files_.stainMaps.push_back(path);
    }
  }
}

void FrameExporter::adoptFrame(int frame, bool last) {
  if (imageDue(frame, last)) files_.images.push_back(imagePath(frame));
}

int FrameExporter::encodeFrames() const {
  return static_cast<int>(files_.images.size()) * ((settings_.video.mp4 ? 1 : 0) + (settings_.video.gif ? 1 : 0));
}

void FrameExporter::finish(const std::function<void(const std::string&, int, int)>& progress) {
  std::vector<std::string> formats;
  if (settings_.video.mp4) formats.push_back("mp4");
  if (settings_.video.gif) formats.push_back("gif");
  if (formats.empty() || files_.images.empty()) return;
  const SceneImages& s = settings_.images;
  char fps[32];
  std::snprintf(fps, sizeof fps, "%g", settings_.video.fps);
  const std::string size = std::to_string(s.width) + "x" + std::to_string(s.height);
  for (const std::string& format : formats) {
    const std::string path = (std::filesystem::path(directory_) / (name_ + "." + format)).string();
    const std::string temporary = path + "." + std::to_string(::getpid()) + ".tmp";
    std::vector<std::string> args = {ffmpeg_, "-hide_banner", "-loglevel", "error", "-nostdin", "-y",
                                     "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", size, "-r", fps, "-i", "pipe:0"};
    if (format == "mp4") {
      for (const char* a : {"-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2,scale=out_color_matrix=bt709", "-c:v", "libx264",
                            "-pix_fmt", "yuv420p", "-colorspace", "bt709", "-color_primaries", "bt709",
                            "-color_trc", "iec61966-2-1", "-movflags", "+faststart", "-f", "mp4"})
        args.emplace_back(a);
    } else {
      for (const char* a : {"-vf", "split[a][b];[a]palettegen[p];[b][p]paletteuse", "-f", "gif"}) args.emplace_back(a);
    }
    args.push_back(temporary);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);

    int pipeFds[2];
    if (::pipe(pipeFds) != 0) throw std::runtime_error(path + ": cannot create a pipe for ffmpeg");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, pipeFds[0], 0);
    posix_spawn_file_actions_addclose(&actions, pipeFds[0]);
    posix_spawn_file_actions_addclose(&actions, pipeFds[1]);
    pid_t pid = 0;
    const int spawned = posix_spawn(&pid, ffmpeg_.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(pipeFds[0]);
    if (spawned != 0) {
      ::close(pipeFds[1]);
      throw std::runtime_error(path + ": cannot start " + ffmpeg_ + ": " + std::strerror(spawned));
    }
    // A dying ffmpeg closes the pipe: report its status instead of dying of SIGPIPE.
    struct sigaction ignore {}, previous {};
    ignore.sa_handler = SIG_IGN;
    ::sigaction(SIGPIPE, &ignore, &previous);
    bool fed = true;
    std::string badImage;
    int done = 0;
    for (const std::string& image : files_.images) {
      Image frame;
      try {
        frame = readPng(image);
      } catch (const ImageError& e) {
        badImage = e.what();
        break;
      }
      if (frame.width() != s.width || frame.height() != s.height || frame.channels() != 3) {
        badImage = image + ": expected a " + size + " RGB frame";
        break;
      }
      if (!(fed = writeAll(pipeFds[1], frame.bytes().data(), frame.bytes().size()))) break;
      if (progress) progress(format, ++done, static_cast<int>(files_.images.size()));
    }
    ::close(pipeFds[1]);
    ::sigaction(SIGPIPE, &previous, nullptr);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    const bool ok = fed && badImage.empty() && WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!ok) {
      std::error_code ignored;
      std::filesystem::remove(temporary, ignored);
      if (!badImage.empty()) throw std::runtime_error(path + ": " + badImage);
      throw std::runtime_error(path + ": ffmpeg failed (" +
                               (WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                                  : std::string("killed by a signal")) +
                               "); its messages are above");
    }
    std::filesystem::rename(temporary, path);
    files_.videos.push_back(path);
  }
}

}  // namespace blot::engine
