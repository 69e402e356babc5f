// blot-viewer: an interactive samples viewer (GLFW + OpenGL + Dear ImGui), in
// the manner of Box2D's samples app. Uses only the public engine API
// (engine/include/blot/engine/*.h). Controls and the command-line script are
// in docs/viewer.md.
#include <blot/engine/engine.h>
#include <blot/engine/image.h>
#include <blot/engine/scene.h>
#include <blot/engine/stain_color.h>

#define GL_GLEXT_PROTOTYPES 1  // glUseProgram (GL 2.0) from libGL
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using blot::engine::Engine;
using blot::engine::EngineDef;
using Eigen::Vector3d;

constexpr double kFrameDt = 1.0 / 60.0;  // simulated time per viewer frame (fixed, as Box2D's samples)
constexpr int kPanelWidth = 340;
constexpr int kWeftMarks = 250;           // weft segments drawn over the cloth         // the ImGui panel on the left; the 3D view is to its right

/// A drop a click throws: masses and radius of a liquid, and the pigment it is shown with.
struct LiquidPreset {
  const char* name;
  double solventMass, soluteMass;  // kg for radius 0.1 m, scaled by (r / 0.1)^2
  blot::engine::PigmentPreset pigment;
};
const LiquidPreset kLiquids[] = {
    {"wine", 0.04, 0.020, blot::engine::PigmentPreset::Wine},
    {"coffee", 0.04, 0.015, blot::engine::PigmentPreset::Coffee},
    {"ink", 0.03, 0.020, blot::engine::PigmentPreset::Ink},
};

/// The physics terms a user can switch, and the coupling mode.
struct Terms {
  bool inertia = true, coriolis = true, diffusion = true, absorption = true, adsorption = true,
       evaporation = true, twoWay = true;
  static Terms of(const EngineDef& def) {
    const auto& s = def.stain.switches;
    Terms t;
    t.inertia = s.linearInertia;
    t.coriolis = s.coriolis;
    t.diffusion = s.densityDiffusion && s.velocityDiffusion;
    t.absorption = s.absorption;
    t.adsorption = s.adsorption;
    t.evaporation = s.evaporation;
    t.twoWay = def.coupling == blot::coupling::CouplingMode::TwoWay;
    return t;
  }
  void applyTo(EngineDef& def) const {
    auto& s = def.stain.switches;
    s.linearInertia = inertia;
    s.coriolis = coriolis;
    s.densityDiffusion = s.velocityDiffusion = diffusion;
    s.absorption = absorption;
    s.adsorption = adsorption;
    s.evaporation = evaporation;
    def.coupling = twoWay ? blot::coupling::CouplingMode::TwoWay : blot::coupling::CouplingMode::OneWay;
  }
  static constexpr const char* kNames = "inertia, coriolis, diffusion, absorption, adsorption, evaporation, two-way";
  bool* find(const std::string& name) {
    if (name == "inertia") return &inertia;
    if (name == "coriolis") return &coriolis;
    if (name == "diffusion") return &diffusion;
    if (name == "absorption") return &absorption;
    if (name == "adsorption") return &adsorption;
    if (name == "evaporation") return &evaporation;
    if (name == "two-way") return &twoWay;
    return nullptr;
  }
  static bool knows(const std::string& name) { return Terms().find(name) != nullptr; }
  bool operator!=(const Terms& o) const {
    return inertia != o.inertia || coriolis != o.coriolis || diffusion != o.diffusion || absorption != o.absorption ||
           adsorption != o.adsorption || evaporation != o.evaporation || twoWay != o.twoWay;
  }
};

struct Options {
  std::string scene;
  bool noSceneDrops = false;
  struct ScriptDrop {
    double u = 0.5, v = 0.5;  // position in the 3D view, fractions of its width and height from the top left
    Vector3d velocity = Vector3d::Zero();
    int frame = 0;
  };
  std::vector<ScriptDrop> drops;
  struct ScriptToggle {
    std::string term;
    int frame = 0;
  };
  std::vector<ScriptToggle> toggles;  // flip a physics term before that frame, as its checkbox would
  int frames = -1;  // run this many frames then stop (with --exit: quit)
  std::string screenshot;
  bool exitAfter = false;
  int width = 1280, height = 800;
  int liquid = -1;  // index into kLiquids; -1: the scene's pigment
  double radius = 0.1;
};

constexpr const char* kUsage =
    "usage: blot-viewer [SCENE.json] [--no-scene-drops] [--liquid wine|coffee|ink] [--radius R]\n"
    "                   [--drop U,V[,VX,VY,VZ][@FRAME]]... [--frames N] [--screenshot OUT.png]\n"
    "                   [--toggle TERM[@FRAME]]... [--exit] [--size WxH]\n"
    "       TERM: %s\n";

/// Most frames a script names (--frames, @FRAME): an int, and days at 60 Hz.
constexpr double kMaxScriptFrames = 1e7;

[[noreturn]] void usage(const std::string& error) {
  std::fprintf(stderr, "blot-viewer: %s\n", error.c_str());
  std::fprintf(stderr, kUsage, Terms::kNames);
  std::exit(2);
}

/// A frame number of a script: a whole number in [0, kMaxScriptFrames]
/// (3e9 overflowed int and read as "--exit needs --frames N").
int scriptFrame(const std::vector<double>& f, const std::string& what) {
  if (f.size() != 1 || !(f[0] >= 0 && f[0] <= kMaxScriptFrames) || f[0] != std::floor(f[0]))
    usage(what + " must be a whole number in [0, 10000000]");
  return static_cast<int>(f[0]);
}

std::vector<double> parseNumbers(const std::string& text, const std::string& option) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      usage(option + ": '" + text + "' is not a comma-separated list of numbers");
    }
    if (!std::isfinite(out.back())) usage(option + ": '" + item + "' is not finite");
  }
  return out;
}

Options parseOptions(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--no-scene-drops") {
      o.noSceneDrops = true;
    } else if (a == "--drop") {
      std::string text = value();
      Options::ScriptDrop d;
      const auto at = text.find('@');
      if (at != std::string::npos) {
        d.frame = scriptFrame(parseNumbers(text.substr(at + 1), "--drop @FRAME"), "--drop: @FRAME");
        text = text.substr(0, at);
      }
      const std::vector<double> v = parseNumbers(text, "--drop");
      if (v.size() != 2 && v.size() != 5) usage("--drop: expected U,V or U,V,VX,VY,VZ, got '" + text + "'");
      if (v[0] < 0 || v[0] > 1 || v[1] < 0 || v[1] > 1) usage("--drop: U and V are fractions of the view, in [0, 1]");
      d.u = v[0];
      d.v = v[1];
      if (v.size() == 5) d.velocity = Vector3d(v[2], v[3], v[4]);
      o.drops.push_back(d);
    } else if (a == "--toggle") {
      const std::string text = value();
      const auto at = text.find('@');
      Options::ScriptToggle t;
      t.term = text.substr(0, at);
      if (!Terms::knows(t.term)) usage("--toggle: '" + t.term + "' is not one of " + Terms::kNames);
      if (at != std::string::npos) {
        t.frame = scriptFrame(parseNumbers(text.substr(at + 1), "--toggle @FRAME"), "--toggle: @FRAME");
      }
      o.toggles.push_back(t);
    } else if (a == "--frames") {
      o.frames = scriptFrame(parseNumbers(value(), "--frames"), "--frames");
    } else if (a == "--screenshot") {
      o.screenshot = value();
    } else if (a == "--exit") {
      o.exitAfter = true;
    } else if (a == "--radius") {
      const std::vector<double> v = parseNumbers(value(), "--radius");
      if (v.size() != 1 || !(v[0] > 0 && v[0] <= 1e6)) usage("--radius: expected a length in (0, 1e6] m");
      o.radius = v[0];
    } else if (a == "--liquid") {
      const std::string name = value();
      o.liquid = -1;
      for (int k = 0; k < 3; ++k)
        if (name == kLiquids[k].name) o.liquid = k;
      if (o.liquid < 0) usage("--liquid: '" + name + "' is not one of wine, coffee, ink");
    } else if (a == "--size") {
      const std::string s = value();
      int w = 0, h = 0;
      char x = 0;
      std::stringstream ss(s);
      if (!(ss >> w >> x >> h) || x != 'x' || w < 640 || h < 400 || w > 8192 || h > 8192)
        usage("--size: expected WxH with W >= 640, H >= 400, got '" + s + "'");
      o.width = w;
      o.height = h;
    } else if (a == "-h" || a == "--help") {
      std::printf(kUsage, Terms::kNames);
      std::exit(0);
    } else if (!a.empty() && a[0] == '-') {
      usage("unknown option '" + a + "'");
    } else if (o.scene.empty()) {
      o.scene = a;
    } else {
      usage("more than one scene given ('" + o.scene + "', '" + a + "')");
    }
  }
  if (o.exitAfter && o.frames < 0) usage("--exit needs --frames N");
  // A scripted drop or toggle after the last frame never happened, silently.
  if (o.exitAfter) {
    for (const auto& d : o.drops)
      if (d.frame > o.frames) usage("--drop @" + std::to_string(d.frame) + " is after the last frame (--frames " + std::to_string(o.frames) + ")");
    for (const auto& t : o.toggles)
      if (t.frame > o.frames) usage("--toggle " + t.term + "@" + std::to_string(t.frame) + " is after the last frame (--frames " + std::to_string(o.frames) + ")");
  }
  return o;
}

/// The rows of the panel's "last step (ms)" bars, in order.
enum class PanelRow { Hidden, Cloth, Geometry, Forces, Advection, Diffusion, Interaction, Coupling, Unplaced };
constexpr int kPanelRows = static_cast<int>(PanelRow::Unplaced);
constexpr const char* kPanelRowLabels[kPanelRows] = {"",          "cloth",     "geometry",    "forces",
                                                     "advection", "diffusion", "interaction", "coupling"};

/// The row a stage's time adds to (Hidden: not shown). Every Stage has its
/// case: a new stage is placed here or the static_assert below fails.
constexpr PanelRow panelRow(blot::stain::Stage stage) {
  using blot::stain::Stage;
  switch (stage) {
    case Stage::Guard:
    case Stage::Drops:
    case Stage::Sources:
    case Stage::LiquidBand:
    case Stage::Validate: return PanelRow::Hidden;
    case Stage::Cloth: return PanelRow::Cloth;
    case Stage::Geometry: return PanelRow::Geometry;
    case Stage::BodyForces:
    case Stage::FilmPressure:
    case Stage::FilmFriction:
    case Stage::Coriolis: return PanelRow::Forces;
    case Stage::AdvectVelocity:
    case Stage::AdvectDensity: return PanelRow::Advection;
    case Stage::Diffuse: return PanelRow::Diffusion;
    case Stage::Interact: return PanelRow::Interaction;
    case Stage::Coupling: return PanelRow::Coupling;
  }
  return PanelRow::Unplaced;
}
constexpr bool everyStageHasARow() {
  for (int k = 0; k < blot::stain::kStageCount; ++k)
    if (panelRow(static_cast<blot::stain::Stage>(k)) == PanelRow::Unplaced) return false;
  return true;
}
static_assert(everyStageHasARow(), "place the new Stage in panelRow (a row of the panel, or Hidden)");

/// The last internal step's time of a stage (ms): the coupled step times the
/// cloth and the coupling (EngineStatistics::lastTimes), the stain solver the
/// others (StepProfile).
double lastStageTime(const blot::engine::EngineStatistics& s, blot::stain::Stage stage) {
  if (stage == blot::stain::Stage::Cloth) return s.lastTimes.cloth;
  if (stage == blot::stain::Stage::Coupling) return s.lastTimes.coupling;
  return s.lastProfile.time(stage);
}

/// A field's label on a panel: its own, or its key with ' ' for '_'.
std::string panelLabel(const blot::stain::OutputField& f) {
  std::string text = *f.label != '\0' ? f.label : f.key;
  std::replace(text.begin(), text.end(), '_', ' ');
  return text;
}

/// The mass budget's values as MassBudget::fields lists them, for its panel.
struct MassBudgetEntries {
  struct Entry {
    blot::stain::OutputField field;
    double value;
  };
  std::vector<Entry> entries;
  void field(const blot::stain::OutputField& f, double value) { entries.push_back({f, value}); }
  template <class Get>
  void computed(const blot::stain::OutputField& f, Get&& get) {
    entries.push_back({f, get()});
  }
  /// The Total of `group` (kg), 0 if it has none.
  double total(const char* group) const {
    for (const Entry& e : entries)
      if (e.field.role == blot::stain::FieldRole::Total && std::strcmp(e.field.group, group) == 0) return e.value;
    return 0;
  }
};

/// Orbit camera around a target: yaw about world z, pitch above the horizon.
struct OrbitCamera {
  Vector3d target = Vector3d::Zero();
  double distance = 2, yaw = -1.5707963, pitch = 0.15, fovY = 0.8;
  Vector3d eye() const {
    return target + distance * Vector3d(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw), std::sin(pitch));
  }
  Eigen::Matrix4d view() const {
    const Vector3d e = eye(), f = (target - e).normalized();
    const Vector3d s = f.cross(Vector3d::UnitZ()).normalized(), u = s.cross(f);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.block<1, 3>(0, 0) = s.transpose();
    m.block<1, 3>(1, 0) = u.transpose();
    m.block<1, 3>(2, 0) = -f.transpose();
    m(0, 3) = -s.dot(e);
    m(1, 3) = -u.dot(e);
    m(2, 3) = f.dot(e);
    return m;
  }
  Eigen::Matrix4d projection(double aspect) const {
    const double n = 0.01 * distance, fa = 100 * distance, t = 1 / std::tan(fovY / 2);
    Eigen::Matrix4d p = Eigen::Matrix4d::Zero();
    p(0, 0) = t / aspect;
    p(1, 1) = t;
    p(2, 2) = (fa + n) / (n - fa);
    p(2, 3) = 2 * fa * n / (n - fa);
    p(3, 2) = -1;
    return p;
  }
  /// World ray through view pixel (x, y) (y down) of a w x h view.
  void ray(double x, double y, double w, double h, Vector3d& origin, Vector3d& dir) const {
    const Vector3d e = eye(), f = (target - e).normalized();
    const Vector3d s = f.cross(Vector3d::UnitZ()).normalized(), u = s.cross(f);
    const double t = std::tan(fovY / 2);
    const double px = (2 * (x + 0.5) / w - 1) * t * (w / h), py = (1 - 2 * (y + 0.5) / h) * t;
    origin = e;
    dir = (f + px * s + py * u).normalized();
  }
};

/// Nearest hit of a ray with the mesh (Möller–Trumbore); false when it misses.
bool pickSurface(const Eigen::MatrixX3d& p, const blot::stain::Triangles& faces, const Vector3d& o,
                 const Vector3d& d, Vector3d& hit) {
  double best = INFINITY;
  for (int f = 0; f < faces.rows(); ++f) {
    const Vector3d a = p.row(faces(f, 0)), b = p.row(faces(f, 1)), c = p.row(faces(f, 2));
    const Vector3d e1 = b - a, e2 = c - a, q = d.cross(e2);
    const double det = e1.dot(q);
    if (std::abs(det) < 1e-14) continue;
    const Vector3d s = o - a;
    const double u = s.dot(q) / det;
    if (u < 0 || u > 1) continue;
    const Vector3d r = s.cross(e1);
    const double v = d.dot(r) / det;
    if (v < 0 || u + v > 1) continue;
    const double t = e2.dot(r) / det;
    if (t > 0 && t < best) best = t;
  }
  if (!std::isfinite(best)) return false;
  hit = o + best * d;
  return true;
}

class Viewer {
 public:
  explicit Viewer(Options options) : opt_(std::move(options)) {
    for (const auto& entry : fs::directory_iterator(BLOT_SCENE_DIR))
      if (entry.path().extension() == ".json") scenes_.push_back(entry.path().string());
    std::sort(scenes_.begin(), scenes_.end());
    liquid_ = opt_.liquid < 0 ? 0 : opt_.liquid;
    radius_ = opt_.radius;
  }

  /// Loads a scene file into a fresh engine; on an error keeps the engine it had.
  bool loadScene(const std::string& path) {
    try {
      EngineDef def = blot::engine::engineDef(blot::engine::loadScene(path));
      if (opt_.noSceneDrops) def.drops.clear();
      auto engine = std::make_unique<Engine>(def);
      engine_ = std::move(engine);
      def_ = def;
      scenePath_ = path;
      terms_ = Terms::of(def_);
      mapping_ = def_.colors;
      if (opt_.liquid >= 0) mapping_ = blot::engine::stainColorMapping(kLiquids[opt_.liquid].pigment, def_.colors.clothColor);
      frames_ = 0;
      thrown_ = 0;
      error_.clear();
      frameCamera();
      computeRestWeftBasis();
      return true;
    } catch (const std::exception& e) {
      error_ = e.what();
      std::fprintf(stderr, "blot-viewer: %s\n", e.what());
      return false;
    }
  }

  /// Rebuilds the engine with the switched terms and carries the state over
  /// (Engine::save / load: the switches are not part of a state file).
  bool applyTerms() {
    bool ok = true;
    EngineDef def = def_;
    terms_.applyTo(def);
    const fs::path tmp = fs::temp_directory_path() / ("blot-viewer-" + std::to_string(::getpid()) + ".state");
    try {
      engine_->save(tmp.string());
      auto engine = std::make_unique<Engine>(def);
      engine->load(tmp.string());
      engine_ = std::move(engine);
      def_ = def;
      error_.clear();
    } catch (const std::exception& e) {
      error_ = e.what();
      std::fprintf(stderr, "blot-viewer: switching terms: %s\n", e.what());
      terms_ = Terms::of(def_);
      ok = false;
    }
    std::error_code ignored;
    fs::remove(tmp, ignored);
    return ok;
  }

  int run() {
    if (!glfwInit()) {
      std::fprintf(stderr, "blot-viewer: cannot initialise GLFW (no display? run under xvfb-run)\n");
      return 1;
    }
    GLFWwindow* window = glfwCreateWindow(opt_.width, opt_.height, "blot-viewer", nullptr, nullptr);
    if (!window) {
      std::fprintf(stderr, "blot-viewer: cannot create an OpenGL window\n");
      glfwTerminate();
      return 1;
    }
    glfwMakeContextCurrent(window);
    glfwSwapInterval(opt_.frames >= 0 ? 0 : 1);
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL3_Init("#version 130");

    const std::string first = opt_.scene.empty() ? std::string(BLOT_SCENE_DIR) + "/two_way_flag.json" : opt_.scene;
    if (!loadScene(first)) {
      shutdown(window);
      return 1;
    }
    playing_ = true;
    int rc = 0;
    while (!glfwWindowShouldClose(window)) {
      glfwPollEvents();
      int w = 0, h = 0;
      glfwGetFramebufferSize(window, &w, &h);
      viewW_ = std::max(1, w - kPanelWidth);
      viewH_ = std::max(1, h);

      // Scripted drops land before the frame's step, as a click would.
      for (const auto& d : opt_.drops) {
        if (d.frame != frames_) continue;
        error_.clear();
        if (!throwAtView(d.u * viewW_, d.v * viewH_, d.velocity)) {
          // A miss, or a drop the engine refused (its reason, not "misses").
          if (error_.empty()) {
            std::fprintf(stderr, "blot-viewer: --drop %g,%g misses the cloth in the view\n", d.u, d.v);
          } else {
            std::fprintf(stderr, "blot-viewer: --drop %g,%g: %s\n", d.u, d.v, error_.c_str());
          }
          rc = 1;
        }
      }
      for (const auto& t : opt_.toggles)
        if (t.frame == frames_) {
          bool* term = terms_.find(t.term);
          *term = !*term;
          if (!applyTerms()) rc = 1;
          std::printf("blot-viewer: frame %d: %s %s\n", frames_, t.term.c_str(), *terms_.find(t.term) ? "on" : "off");
        }
      const bool scripted = opt_.frames >= 0;
      if (scripted ? frames_ < opt_.frames : (playing_ || stepOnce_)) {
        stepFrame();
        stepOnce_ = false;
      }

      ImGui_ImplOpenGL3_NewFrame();
      ImGui_ImplGlfw_NewFrame();
      ImGui::NewFrame();
      drawPanel();
      handleMouse();
      ImGui::Render();

      glViewport(0, 0, w, h);
      glClearColor(0.18f, 0.18f, 0.18f, 1);  // neutral grey: no hue of its own
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      drawScene();
      glViewport(0, 0, w, h);
      ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

      if (scripted && frames_ >= opt_.frames && !shotTaken_) {
        shotTaken_ = true;
        if (!opt_.screenshot.empty() && !screenshot(w, h, opt_.screenshot)) rc = 1;
        const auto stats = engine_->statistics();
        // Drops thrown by this viewer (engine statistics restart when a term switch rebuilds it).
        std::printf("blot-viewer: scene %s frames %d steps %lld time %.4f s drops %d\n",
                    fs::path(scenePath_).filename().string().c_str(), frames_, static_cast<long long>(stats.steps),
                    stats.time, thrown_);
        std::fflush(stdout);
        if (opt_.exitAfter) glfwSetWindowShouldClose(window, 1);
      }
      glfwSwapBuffers(window);
    }
    shutdown(window);
    return rc;
  }

 private:
  void shutdown(GLFWwindow* window) {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(window);
    glfwTerminate();
  }

  void stepFrame() {
    const blot::stain::StepReport report = engine_->step(kFrameDt);
    if (!report.ok()) {
      error_ = report.message;
      playing_ = false;
    }
    ++frames_;
  }

  void frameCamera() {
    const Eigen::MatrixX3d& p = engine_->positions();
    const Vector3d lo = p.colwise().minCoeff(), hi = p.colwise().maxCoeff();
    camera_.target = 0.5 * (lo + hi);
    camera_.distance = std::max(0.1, 1.05 * (hi - lo).norm() / (2 * std::tan(camera_.fovY / 2)));
    // Face the cloth's broad side: look across its thinnest extent.
    const Vector3d extent = hi - lo;
    if (extent.z() <= extent.x() && extent.z() <= extent.y()) {
      camera_.yaw = -1.5707963;
      camera_.pitch = 1.0;  // a cloth lying flat: from above
    } else if (extent.x() < extent.y()) {
      camera_.yaw = 0;
      camera_.pitch = 0.15;
    } else {
      camera_.yaw = -1.5707963;  // looking along +y, the flags' xz plane face on
      camera_.pitch = 0.15;
    }
  }

  /// Throws the current liquid at view pixel (x, y), world velocity v. False on a miss.
  bool throwAtView(double x, double y, const Vector3d& v) {
    Vector3d o, d, hit;
    camera_.ray(x, y, viewW_, viewH_, o, d);
    if (!pickSurface(engine_->positions(), engine_->faces(), o, d, hit)) return false;
    const LiquidPreset& liquid = kLiquids[liquid_];
    blot::stain::DropDef drop;
    drop.radius = radius_;
    const double scale = (radius_ / 0.1) * (radius_ / 0.1);
    drop.solventMass = liquid.solventMass * scale;
    drop.soluteMass = liquid.soluteMass * scale;
    drop.velocity = v;
    try {
      engine_->addDropAtPoint(hit, drop);
      // One solute per engine: the view shows it in the pigment of the last liquid thrown.
      mapping_ = blot::engine::stainColorMapping(liquid.pigment, def_.colors.clothColor);
      ++thrown_;
    } catch (const std::exception& e) {
      error_ = e.what();
      return false;
    }
    return true;
  }

  void handleMouse() {
    ImGuiIO& io = ImGui::GetIO();
    if (io.WantCaptureMouse) return;
    const double x = io.MousePos.x - kPanelWidth, y = io.MousePos.y;
    if (ImGui::IsMouseDragging(ImGuiMouseButton_Right)) {
      camera_.yaw -= 0.005 * io.MouseDelta.x;
      camera_.pitch = std::clamp(camera_.pitch + 0.005 * io.MouseDelta.y, -1.5, 1.5);
    }
    if (io.MouseWheel != 0) camera_.distance *= std::pow(0.9, io.MouseWheel);
    if (ImGui::IsMouseClicked(ImGuiMouseButton_Left) && x >= 0) {
      pressX_ = x;
      pressY_ = y;
      pressing_ = true;
    }
    if (pressing_ && ImGui::IsMouseReleased(ImGuiMouseButton_Left)) {
      pressing_ = false;
      // The drag, in the view plane, sets the throw velocity: speedScale_ m/s per 100 pixels.
      const Vector3d e = camera_.eye(), f = (camera_.target - e).normalized();
      const Vector3d s = f.cross(Vector3d::UnitZ()).normalized(), u = s.cross(f);
      const Vector3d v = speedScale_ / 100.0 * ((x - pressX_) * s - (y - pressY_) * u) + throwInto_ * f;
      if (!throwAtView(pressX_, pressY_, v)) error_ = "the click missed the cloth";
    }
  }

  /// Each face's rest weft in the basis of two of its edges, so that it can be
  /// carried onto the deformed face: w = a e1 + b e2.
  void computeRestWeftBasis() {
    const auto& weft = engine_->fabric().weftDirections;
    const auto& faces = engine_->faces();
    const auto& rest = def_.mesh.vertexPositions;
    weftCoefficients_.assign(faces.rows(), Eigen::Vector2d::Zero());
    hasWeft_ = false;
    for (int f = 0; f < faces.rows(); ++f) {
      const Vector3d w = weft.row(f).transpose();
      if (w.squaredNorm() < 1e-20) continue;
      const Vector3d e1 = rest.row(faces(f, 1)) - rest.row(faces(f, 0)), e2 = rest.row(faces(f, 2)) - rest.row(faces(f, 0));
      Eigen::Matrix<double, 3, 2> E;
      E << e1, e2;
      weftCoefficients_[f] = E.colPivHouseholderQr().solve(w);
      hasWeft_ = true;
    }
    // About kWeftMarks marks spread over the faces, each a bit shorter than their spacing.
    double area = 0;
    for (int f = 0; f < faces.rows(); ++f)
      area += 0.5 * (rest.row(faces(f, 1)) - rest.row(faces(f, 0))).cross(rest.row(faces(f, 2)) - rest.row(faces(f, 0))).norm();
    weftStride_ = std::max(1, static_cast<int>(faces.rows() / kWeftMarks));
    weftLength_ = 0.6 * std::sqrt(area * weftStride_ / std::max<double>(1, faces.rows()));
  }

  void drawScene() {
    glViewport(kPanelWidth, 0, viewW_, viewH_);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_LIGHTING);
    glDisable(GL_TEXTURE_2D);
    glDisable(GL_BLEND);
    glUseProgram(0);
    glMatrixMode(GL_PROJECTION);
    const Eigen::Matrix4d proj = camera_.projection(double(viewW_) / viewH_), view = camera_.view();
    glLoadMatrixd(proj.data());
    glMatrixMode(GL_MODELVIEW);
    glLoadMatrixd(view.data());

    // Stain colour by the documented Beer–Lambert convention (stain_color.h),
    // then two-sided Lambert shading from a light at the eye.
    const Eigen::MatrixX3d& p = engine_->positions();
    const Eigen::MatrixX3d& n = engine_->normals();
    blot::engine::stainColors(mapping_, engine_->solvent(), engine_->solute(), engine_->absorbedSolute(),
                              engine_->adsorbedSolute(), colors_);
    const Vector3d light = (camera_.eye() - camera_.target).normalized();
    const auto& faces = engine_->faces();
    glBegin(GL_TRIANGLES);
    for (int f = 0; f < faces.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int i = faces(f, k);
        const double shade = 0.35 + 0.65 * std::abs(n.row(i).dot(light));
        glColor3d(colors_(i, 0) * shade, colors_(i, 1) * shade, colors_(i, 2) * shade);
        glVertex3d(p(i, 0), p(i, 1), p(i, 2));
      }
    glEnd();

    if (showWeft_ && hasWeft_) {
      // Short weft segments at every few faces' centroids, carried onto the
      // deformed face; drawn over the cloth (no depth test) so both sides show them.
      glDisable(GL_DEPTH_TEST);
      glColor3d(0.1, 0.55, 0.2);
      glBegin(GL_LINES);
      for (int f = 0; f < faces.rows(); f += weftStride_) {
        const Eigen::Vector2d& c = weftCoefficients_[f];
        if (c.squaredNorm() == 0) continue;
        const Vector3d a = p.row(faces(f, 0)), b = p.row(faces(f, 1)), d = p.row(faces(f, 2));
        const Vector3d centroid = (a + b + d) / 3.0;
        const Vector3d w = c(0) * (b - a) + c(1) * (d - a);
        const Vector3d half = 0.5 * weftLength_ * w.normalized();
        glVertex3dv((centroid - half).eval().data());
        glVertex3dv((centroid + half).eval().data());
      }
      glEnd();
    }
    glDisable(GL_DEPTH_TEST);
  }

  static void section(const char* title) {
    ImGui::Separator();
    ImGui::TextUnformatted(title);
  }

  static void bar(const char* label, double value, double max, const char* unit) {
    char text[64];
    std::snprintf(text, sizeof text, "%.3g %s", value, unit);
    ImGui::ProgressBar(max > 0 ? static_cast<float>(std::clamp(value / max, 0.0, 1.0)) : 0.f, ImVec2(170, 0), text);
    ImGui::SameLine();
    ImGui::TextUnformatted(label);
  }

  void drawPanel() {
    ImGui::SetNextWindowPos(ImVec2(0, 0));
    ImGui::SetNextWindowSize(ImVec2(kPanelWidth, static_cast<float>(viewH_)));
    ImGui::Begin("Blot", nullptr, ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
    const std::string current = fs::path(scenePath_).stem().string();
    if (ImGui::BeginCombo("scene", current.c_str())) {
      for (const std::string& s : scenes_) {
        const std::string stem = fs::path(s).stem().string();
        if (ImGui::Selectable(stem.c_str(), s == scenePath_)) loadScene(s);
      }
      ImGui::EndCombo();
    }
    if (ImGui::Button(playing_ ? "pause" : "play")) playing_ = !playing_;
    ImGui::SameLine();
    if (ImGui::Button("step")) {
      playing_ = false;
      stepOnce_ = true;
    }
    ImGui::SameLine();
    if (ImGui::Button("restart")) loadScene(scenePath_);
    const auto stats = engine_->statistics();
    ImGui::Text("frame %d  step %lld  t = %.3f s", frames_, static_cast<long long>(stats.steps), stats.time);

    section("drop (left click; drag to throw)");
    const char* names[] = {kLiquids[0].name, kLiquids[1].name, kLiquids[2].name};
    ImGui::Combo("liquid", &liquid_, names, 3);
    float r = static_cast<float>(radius_);
    if (ImGui::SliderFloat("radius (m)", &r, 0.02f, 0.25f)) radius_ = r;
    float sp = static_cast<float>(speedScale_), into = static_cast<float>(throwInto_);
    if (ImGui::SliderFloat("m/s per 100 px", &sp, 0.f, 5.f)) speedScale_ = sp;
    if (ImGui::SliderFloat("into (m/s)", &into, 0.f, 5.f)) throwInto_ = into;

    section("physics terms");
    Terms t = terms_;
    ImGui::Checkbox("inertia", &t.inertia);
    ImGui::SameLine(170);
    ImGui::Checkbox("Coriolis", &t.coriolis);
    ImGui::Checkbox("diffusion", &t.diffusion);
    ImGui::SameLine(170);
    ImGui::Checkbox("absorption", &t.absorption);
    ImGui::Checkbox("adsorption", &t.adsorption);
    ImGui::SameLine(170);
    ImGui::Checkbox("evaporation", &t.evaporation);
    ImGui::Checkbox("two-way coupling", &t.twoWay);
    if (t != terms_) {
      terms_ = t;
      applyTerms();
    }
    ImGui::Checkbox("show weft", &showWeft_);
    if (!hasWeft_) {
      ImGui::SameLine();
      ImGui::TextDisabled("(isotropic fabric)");
    }

    section("last step (ms)");
    double rows[kPanelRows] = {};  // each stage's time added to its row, in stage order
    for (int k = 0; k < blot::stain::kStageCount; ++k) {
      const auto stage = static_cast<blot::stain::Stage>(k);
      if (panelRow(stage) != PanelRow::Hidden) rows[static_cast<int>(panelRow(stage))] += lastStageTime(stats, stage);
    }
    const double maxMs = std::max(1e-3, *std::max_element(std::begin(rows) + 1, std::end(rows)));
    for (int k = 1; k < kPanelRows; ++k) bar(kPanelRowLabels[k], rows[k], maxMs, "ms");
    ImGui::Text("step total %.2f ms (%.1f steps/s)", stats.lastTimes.total, stats.stepsPerSecond);

    section("mass budget (g)");
    // MassBudget::fields: each part a bar against its group's total, then the
    // totals and the relative errors on a line each.
    MassBudgetEntries m;
    stats.massBudget.visit(m);
    for (const auto& e : m.entries)
      if (e.field.role == blot::stain::FieldRole::Part)
        bar(panelLabel(e.field).c_str(), 1e3 * e.value, 1e3 * std::max(m.total(e.field.group), 1e-30), "g");
    std::string added = "added", errors = "error";
    bool anyAdded = false, firstTotal = true;
    char text[64];
    for (const auto& e : m.entries) {
      if (e.field.role == blot::stain::FieldRole::Total) {
        std::snprintf(text, sizeof text, "%s %.3g g %s", firstTotal ? "" : ",", 1e3 * e.value, e.field.group);
        added += text;
        if (firstTotal) anyAdded = e.value > 0;  // the errors once the first group has some
        firstTotal = false;
      } else if (e.field.role == blot::stain::FieldRole::Error) {
        std::snprintf(text, sizeof text, "%s %.1e %s", errors.size() > 5 ? "," : "", e.value, e.field.group);
        errors += text;
      }
    }
    ImGui::TextUnformatted(added.c_str());
    if (anyAdded) ImGui::TextUnformatted(errors.c_str());

    section("camera");
    ImGui::TextWrapped("right drag: orbit, wheel: zoom");
    if (ImGui::Button("frame cloth")) frameCamera();
    if (!error_.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.3f, 1), "%s", error_.c_str());
    ImGui::End();
  }

  /// The framebuffer as an RGB PNG through the project's image writer.
  bool screenshot(int w, int h, const std::string& path) {
    std::vector<unsigned char> pixels(static_cast<std::size_t>(w) * h * 3);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
    blot::engine::Image image(w, h, 3);
    for (int y = 0; y < h; ++y)
      std::copy_n(&pixels[static_cast<std::size_t>(h - 1 - y) * w * 3], static_cast<std::size_t>(w) * 3, image.row(y));
    try {
      blot::engine::writePng(image, path);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "blot-viewer: %s\n", e.what());
      return false;
    }
    std::printf("blot-viewer: wrote %s (%dx%d, 3D view from x = %d)\n", path.c_str(), w, h, kPanelWidth);
    return true;
  }

  Options opt_;
  std::vector<std::string> scenes_;
  std::string scenePath_, error_;
  std::unique_ptr<Engine> engine_;
  EngineDef def_;
  Terms terms_;
  blot::engine::StainColorMapping mapping_;
  Eigen::MatrixX3d colors_;
  OrbitCamera camera_;
  std::vector<Eigen::Vector2d> weftCoefficients_;
  bool hasWeft_ = false, showWeft_ = true;
  int weftStride_ = 1;
  double weftLength_ = 0;
  bool playing_ = false, stepOnce_ = false, shotTaken_ = false, pressing_ = false;
  int frames_ = 0, viewW_ = 1, viewH_ = 1, liquid_ = 0, thrown_ = 0;
  double radius_ = 0.1, speedScale_ = 1.0, throwInto_ = 0.0, pressX_ = 0, pressY_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  Options options = parseOptions(argc, argv);
  Viewer viewer(std::move(options));
  return viewer.run();
}
