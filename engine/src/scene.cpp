// Scene files: strict JSON → SceneDef (docs/scene-format.md is the reference).
//
// Design note: every object is read through an ObjectReader that records the
// keys it was asked for; when the object is done, any key nobody asked for is
// an error naming its path and listing the keys that object accepts. Values are
// checked where they are read, against a range that is also the text of the
// error ("expected a number in (0, 1], got 2"), so the message and the check
// cannot drift apart. The mesh is built during parsing, so vertex indices
// (pins, drops, held regions) are checked with their key path.
// Rejected: a JSON-Schema file and a validator library — it would add a
// dependency and still not know the mesh's vertex count.
#include <blot/engine/scene.h>

#include <blot/stain/content_hash.h>
#include <blot/stain/io/bounded_read.h>
#include <blot/stain/thread_limit.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/io/strict_json.h>
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/geometry/mesh_order.h>
#include <blot/stain/geometry/mesh_primitives.h>
#include <blot/stain/fabric/weave_pattern.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>

namespace blot::engine {
namespace {

using nlohmann::json;
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string formatNumber(double value) {
  std::ostringstream s;
  s << std::setprecision(12) << value;
  return s.str();
}

/// "a string \"abc\"", "an array", "2.5", ...: what the file actually holds.
std::string describe(const json& value) {
  const std::string text = stain::briefJson(value, 48);
  switch (value.type()) {
    case json::value_t::string: return "a string " + text;
    case json::value_t::array: return "an array " + text;
    case json::value_t::object: return "an object " + text;
    case json::value_t::boolean: return text;
    case json::value_t::null: return "null";
    default: return text;
  }
}

/// A numeric range that prints itself as the error text uses it.
struct Range {
  double lo = -kInf, hi = kInf;
  bool loOpen = false, hiOpen = false;
  bool contains(double v) const {
    return (loOpen ? v > lo : v >= lo) && (hiOpen ? v < hi : v <= hi);
  }
  std::string text() const {
    if (std::isinf(lo) && std::isinf(hi)) return "";
    if (std::isinf(hi)) return std::string(loOpen ? " > " : " >= ") + formatNumber(lo);
    if (std::isinf(lo)) return std::string(hiOpen ? " < " : " <= ") + formatNumber(hi);
    return std::string(" in ") + (loOpen ? "(" : "[") + formatNumber(lo) + ", " + formatNumber(hi) +
           (hiOpen ? ")" : "]");
  }
};
// Every number a scene gives is at most kMaxSceneMagnitude in size (metres,
// seconds, kilograms, m/s, m/s², rates): no key can then overflow a product
// downstream (a squared distance, a mass over an area, float32 in the PLY
// frames), and the error names the key instead of a later stage.
Range any() { return {-kMaxSceneMagnitude, kMaxSceneMagnitude, false, false}; }
Range positive() { return {0, kMaxSceneMagnitude, true, false}; }
Range nonNegative() { return {0, kMaxSceneMagnitude, false, false}; }
Range closed(double lo, double hi) { return {lo, hi, false, false}; }
Range leftOpen(double lo, double hi) { return {lo, hi, true, false}; }
/// Integers in [lo, hi).
Range indices(int lo, int hi) { return {double(lo), double(hi), false, true}; }

class Context {
 public:
  Context(std::string source, std::filesystem::path base, const SceneLoadOptions& options)
      : source_(std::move(source)), base_(std::move(base)), options_(options) {}
  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw SceneError(source_ + ": " + (path.empty() ? std::string("(top level)") : path) + ": " + what);
  }
  std::string resolve(const std::string& relative) const {
    const std::filesystem::path p(relative);
    return p.is_absolute() ? p.string() : (base_ / p).lexically_normal().string();
  }
  const std::string& source() const { return source_; }
  const SceneLoadOptions& options() const { return options_; }
  /// The mesh's renumbering (mesh.vertex_order "locality"; empty lists: the
  /// file's own numbering). Indices in the scene name the file's elements;
  /// these map them to the engine's, and back for messages.
  void setMeshOrder(const stain::MeshOrder& order) {
    order_ = order;
    vertexOf_ = order.vertices.empty() ? std::vector<int>() : stain::inversePermutation(order.vertices);
    faceOf_ = order.faces.empty() ? std::vector<int>() : stain::inversePermutation(order.faces);
  }
  int engineVertex(int fileVertex) const { return vertexOf_.empty() ? fileVertex : vertexOf_[size_t(fileVertex)]; }
  int engineFace(int fileFace) const { return faceOf_.empty() ? fileFace : faceOf_[size_t(fileFace)]; }
  int fileVertex(int engineVertex) const {
    return order_.vertices.empty() ? engineVertex : order_.vertices[size_t(engineVertex)];
  }
  bool renumbered() const { return !order_.vertices.empty(); }
  int fileFace(int engineFace) const { return order_.faces.empty() ? engineFace : order_.faces[size_t(engineFace)]; }
  /// Vertex and face indices name other elements on a re-meshed patch: refused.
  void refuseIndexUnderOverride(const std::string& path, const char* instead) const {
    if (options_.patchResolution > 0)
      fail(path, std::string("an index cannot be used with a patch resolution override (it would name another "
                             "element of the new grid); give ") + instead);
  }

 private:
  std::string source_;
  std::filesystem::path base_;
  SceneLoadOptions options_;
  stain::MeshOrder order_;
  std::vector<int> vertexOf_, faceOf_;
};

double numberValue(const Context& ctx, const json& v, const std::string& path, const Range& range) {
  if (!v.is_number()) ctx.fail(path, "expected a number" + range.text() + ", got " + describe(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || !range.contains(x))
    ctx.fail(path, "expected a number" + range.text() + ", got " + formatNumber(x));
  return x;
}

int integerValue(const Context& ctx, const json& v, const std::string& path, const Range& range) {
  const bool integral = v.is_number_integer() || (v.is_number_float() && std::isfinite(v.get<double>()) &&
                                                  std::floor(v.get<double>()) == v.get<double>());
  if (!integral) ctx.fail(path, "expected an integer" + range.text() + ", got " + describe(v));
  const double x = v.get<double>();
  if (!range.contains(x) || std::abs(x) > 2e9)
    ctx.fail(path, "expected an integer" + range.text() + ", got " + formatNumber(x));
  return static_cast<int>(x);
}

std::string indexPath(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

/// Reads one JSON object; finish() rejects keys nobody asked for.
class ObjectReader {
 public:
  ObjectReader(const Context& ctx, const json& object, std::string path)
      : ctx_(ctx), object_(object), path_(std::move(path)) {
    if (!object_.is_object()) ctx_.fail(path_, "expected an object, got " + describe(object_));
  }
  const Context& context() const { return ctx_; }
  std::string path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const std::string& path() const { return path_; }

  const json* find(const std::string& key) {
    if (std::find(known_.begin(), known_.end(), key) == known_.end()) known_.push_back(key);
    const auto it = object_.find(key);
    return it == object_.end() ? nullptr : &*it;
  }
  bool has(const std::string& key) { return find(key) != nullptr; }
  const json& require(const std::string& key) {
    const json* v = find(key);
    if (v == nullptr) ctx_.fail(path(key), "required key is missing");
    return *v;
  }
  double number(const std::string& key, double fallback, const Range& range = any()) {
    const json* v = find(key);
    return v == nullptr ? fallback : numberValue(ctx_, *v, path(key), range);
  }
  int integer(const std::string& key, int fallback, const Range& range = any()) {
    const json* v = find(key);
    return v == nullptr ? fallback : integerValue(ctx_, *v, path(key), range);
  }
  bool boolean(const std::string& key, bool fallback) {
    const json* v = find(key);
    if (v == nullptr) return fallback;
    if (!v->is_boolean()) ctx_.fail(path(key), "expected true or false, got " + describe(*v));
    return v->get<bool>();
  }
  std::string string(const std::string& key, const std::string& fallback) {
    const json* v = find(key);
    if (v == nullptr) return fallback;
    if (!v->is_string()) ctx_.fail(path(key), "expected a string, got " + describe(*v));
    // A \u0000 would cut the path (and the message naming it) short.
    const std::string& text = v->get_ref<const std::string&>();
    if (const auto nul = text.find('\0'); nul != std::string::npos)
      ctx_.fail(path(key), "expected a string without NUL characters, got one at byte " + std::to_string(nul));
    return text;
  }
  /// One of `choices`; returns its index.
  int choice(const std::string& key, int fallback, const std::vector<std::string>& choices) {
    const json* v = find(key);
    if (v == nullptr) return fallback;
    std::string list;
    for (const std::string& c : choices) list += (list.empty() ? "\"" : ", \"") + c + "\"";
    if (v->is_string()) {
      const auto it = std::find(choices.begin(), choices.end(), v->get<std::string>());
      if (it != choices.end()) return static_cast<int>(it - choices.begin());
    }
    ctx_.fail(path(key), "expected one of " + list + ", got " + describe(*v));
  }
  Eigen::Vector3d vector3(const std::string& key, const Eigen::Vector3d& fallback, const Range& range = any()) {
    const json* v = find(key);
    if (v == nullptr) return fallback;
    if (!v->is_array() || v->size() != 3)
      ctx_.fail(path(key), "expected an array of 3 numbers, got " + describe(*v));
    Eigen::Vector3d x;
    for (int c = 0; c < 3; ++c) x[c] = numberValue(ctx_, (*v)[size_t(c)], indexPath(path(key), size_t(c)), range);
    return x;
  }
  /// Array of exactly two numbers (e.g. a size).
  Eigen::Vector2d vector2(const std::string& key, const Eigen::Vector2d& fallback, const Range& range = any()) {
    const json* v = find(key);
    if (v == nullptr) return fallback;
    if (!v->is_array() || v->size() != 2)
      ctx_.fail(path(key), "expected an array of 2 numbers, got " + describe(*v));
    return {numberValue(ctx_, (*v)[0], indexPath(path(key), 0), range),
            numberValue(ctx_, (*v)[1], indexPath(path(key), 1), range)};
  }
  /// The value at `key`, which must be an array (empty when absent).
  const json& array(const std::string& key) {
    static const json empty = json::array();
    const json* v = find(key);
    if (v == nullptr) return empty;
    if (!v->is_array()) ctx_.fail(path(key), "expected an array, got " + describe(*v));
    return *v;
  }
  /// Refuses, before any value is read, a key not among `keys` (finish()'s
  /// message): a misspelt "liquid2" was reported as the error its missing
  /// "liquid" caused elsewhere (drops[0].mass: needs the liquid's solute fraction).
  void allowOnly(std::initializer_list<const char*> keys) {
    for (const char* key : keys) find(key);
    finish();
  }
  void finish() const {
    for (auto it = object_.begin(); it != object_.end(); ++it) {
      if (std::find(known_.begin(), known_.end(), it.key()) != known_.end()) continue;
      std::string list;
      for (const std::string& k : known_) list += (list.empty() ? "" : ", ") + k;
      ctx_.fail(path(it.key()), "unknown key (expected one of: " + list + ")");
    }
  }

 private:
  const Context& ctx_;
  const json& object_;
  std::string path_;
  std::vector<std::string> known_;
};

// ---------------------------------------------------------------- mesh

/// Maps the grid's (x, y, 0) into the requested plane by a rotation (keeps the
/// faces counter-clockwise): xy: normal +z; xz: (x, 0, y), normal −y; yz: (0, x, y), normal +x.
void placePatch(stain::TriangleMesh& mesh, int plane, const Eigen::Vector3d& center, double width,
                double height) {
  for (Eigen::Index i = 0; i < mesh.vertexPositions.rows(); ++i) {
    const double x = mesh.vertexPositions(i, 0) - 0.5 * width, y = mesh.vertexPositions(i, 1) - 0.5 * height;
    Eigen::Vector3d p(x, y, 0);
    if (plane == 1) p = Eigen::Vector3d(x, 0, y);
    if (plane == 2) p = Eigen::Vector3d(0, x, y);
    mesh.vertexPositions.row(i) = (p + center).transpose();
  }
}

stain::TriangleMesh parseMesh(ObjectReader& r, std::string& description, stain::MeshOrder& order) {
  const char* kinds[] = {"file", "patch", "icosphere", "disc"};
  int count = 0;
  for (const char* k : kinds) count += r.has(k) ? 1 : 0;
  if (count != 1)
    r.context().fail(r.path(), "expected exactly one of \"file\", \"patch\", \"icosphere\", \"disc\", got " +
                                   std::to_string(count));
  stain::TriangleMesh mesh;
  const Context& ctx = r.context();
  if (ctx.options().patchResolution > 0 && !r.has("patch"))
    ctx.fail(r.path(), "a patch resolution override needs a \"patch\" mesh");
  if (const json* file = r.find("file")) {
    if (!file->is_string()) ctx.fail(r.path("file"), "expected a path string, got " + describe(*file));
    const std::string path = ctx.resolve(r.string("file", ""));  // r.string refuses a NUL
    try {
      mesh = stain::loadMesh(path);
    } catch (const std::exception& e) {
      ctx.fail(r.path("file"), e.what());
    }
    description = path;
  } else if (const json* patch = r.find("patch")) {
    ObjectReader p(ctx, *patch, r.path("patch"));
    // At least 1 µm: a 1e-300 m patch's faces were refused as "zero area".
    const Eigen::Vector2d size = p.vector2("size", {1.0, 1.0}, closed(1e-6, kMaxSceneMagnitude));
    Eigen::Vector2d resolution(32, 32);
    if (const json* res = p.find("resolution")) {
      if (!res->is_array() || res->size() != 2)
        ctx.fail(p.path("resolution"), "expected an array of 2 integers, got " + describe(*res));
      for (int c = 0; c < 2; ++c)
        resolution[c] = integerValue(ctx, (*res)[size_t(c)], indexPath(p.path("resolution"), size_t(c)),
                                     closed(1, 2000));
    }
    const int plane = p.choice("plane", 0, {"xy", "xz", "yz"});
    const Eigen::Vector3d center = p.vector3("center", Eigen::Vector3d::Zero());
    p.finish();
    if (const int across = ctx.options().patchResolution; across > 0) {
      resolution[1] = std::max(1.0, std::round(resolution[1] * across / resolution[0]));
      resolution[0] = across;
    }
    const int nx = int(resolution[0]), ny = int(resolution[1]);
    mesh = stain::gridMesh(nx, ny, size[0], size[1]);
    placePatch(mesh, plane, center, size[0], size[1]);
    std::ostringstream s;
    s << "patch " << size[0] << " x " << size[1] << " m, " << nx << " x " << ny << " quads";
    description = s.str();
  } else if (const json* ico = r.find("icosphere")) {
    ObjectReader p(ctx, *ico, r.path("icosphere"));
    const int level = p.integer("level", 3, closed(0, 7));
    const double radius = p.number("radius", 0.5, positive());
    const Eigen::Vector3d center = p.vector3("center", Eigen::Vector3d::Zero());
    p.finish();
    mesh = stain::icosphereMesh(level, radius);
    mesh.vertexPositions.rowwise() += center.transpose();
    description = "icosphere level " + std::to_string(level) + ", radius " + formatNumber(radius) + " m";
  } else {
    ObjectReader p(ctx, *r.find("disc"), r.path("disc"));
    const int rings = p.integer("rings", 16, closed(1, 1000));
    const double radius = p.number("radius", 0.5, positive());
    const Eigen::Vector3d center = p.vector3("center", Eigen::Vector3d::Zero());
    p.finish();
    mesh = stain::discMesh(rings, radius);
    mesh.vertexPositions.rowwise() += center.transpose();
    description = "disc of " + std::to_string(rings) + " rings, radius " + formatNumber(radius) + " m";
  }
  const double scale = r.number("scale", 1.0, positive());
  const Eigen::Vector3d translate = r.vector3("translate", Eigen::Vector3d::Zero());
  const bool locality = r.choice("vertex_order", 0, {"file", "locality"}) == 1;
  r.finish();
  mesh.vertexPositions *= scale;
  mesh.vertexPositions.rowwise() += translate.transpose();
  // Finite keys can still overflow together ("scale": 1e308 on a 10 m patch),
  // and a mesh file may hold coordinates near 1e308 whose areas overflow.
  for (Eigen::Index i = 0; i < mesh.vertexPositions.rows(); ++i) {
    if (!mesh.vertexPositions.row(i).allFinite())
      ctx.fail(r.path(), "vertex " + std::to_string(i) +
                             " is not finite after size, scale and translate (the coordinates overflow a double)");
    if (mesh.vertexPositions.row(i).cwiseAbs().maxCoeff() > kMaxSceneMagnitude)
      ctx.fail(r.path(), "vertex " + std::to_string(i) + " has a coordinate of " +
                             formatNumber(mesh.vertexPositions.row(i).cwiseAbs().maxCoeff()) +
                             " m after scale and translate; expected at most " + formatNumber(kMaxSceneMagnitude) + " m");
  }
  description += " (" + std::to_string(mesh.vertexPositions.rows()) + " vertices, " +
                 std::to_string(mesh.faces.rows()) + " faces)";
  // Renumbered for memory locality (stain/geometry/mesh_order.h); the scene's
  // indices keep naming the file's elements (Context::engineVertex).
  if (locality) {
    order = stain::localityOrder(mesh);
    stain::reorderMesh(mesh, order);
    description += ", renumbered for locality";
  }
  return mesh;
}

/// A vertex given as "vertex": index or "point": [x, y, z] (nearest rest vertex).
int vertexOrPoint(ObjectReader& r, const stain::TriangleMesh& mesh, bool required) {
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const bool hasVertex = r.has("vertex"), hasPoint = r.has("point");
  if (hasVertex && hasPoint) r.context().fail(r.path("point"), "give either \"vertex\" or \"point\", not both");
  if (hasVertex) {
    r.context().refuseIndexUnderOverride(r.path("vertex"), "\"point\"");
    return r.context().engineVertex(r.integer("vertex", -1, indices(0, n)));
  }
  if (hasPoint) {
    // The nearest vertex; of equally near ones the file's first (whatever
    // the engine's numbering).
    const Eigen::Vector3d p = r.vector3("point", Eigen::Vector3d::Zero());
    const Eigen::VectorXd distances = (mesh.vertexPositions.rowwise() - p.transpose()).rowwise().squaredNorm();
    const double nearest = distances.minCoeff();
    int best = -1;
    for (int i = 0; i < n; ++i)
      if (distances[i] == nearest && (best < 0 || r.context().fileVertex(i) < r.context().fileVertex(best))) best = i;
    return best;
  }
  if (required) r.context().fail(r.path("vertex"), "required: give \"vertex\" (an index) or \"point\" ([x, y, z])");
  return -1;
}

// ---------------------------------------------------------------- cloth

void parsePin(ObjectReader& r, const stain::TriangleMesh& mesh, cloth::ClothPin& pin) {
  pin.vertex = vertexOrPoint(r, mesh, true);
  pin.motion.velocity = r.vector3("velocity", Eigen::Vector3d::Zero());
  pin.motion.amplitude = r.vector3("amplitude", Eigen::Vector3d::Zero());
  pin.motion.frequency = r.number("frequency", 0.0, nonNegative());
  pin.motion.phase = r.number("phase", 0.0);
  if (const json* release = r.find("release_time"); release != nullptr && !release->is_null())
    pin.motion.releaseTime = numberValue(r.context(), *release, r.path("release_time"), nonNegative());
  r.finish();
}

cloth::ClothCollider parseCollider(ObjectReader& r) {
  cloth::ClothCollider c;
  const int shape = r.choice("shape", -1, {"plane", "box", "sphere"});
  if (shape < 0) r.context().fail(r.path("shape"), "required key is missing (\"plane\", \"box\" or \"sphere\")");
  c.shape = static_cast<cloth::ClothCollider::Shape>(shape);
  c.center = r.vector3("center", Eigen::Vector3d::Zero());
  if (c.shape == cloth::ClothCollider::Shape::Plane) {
    c.normal = r.vector3("normal", Eigen::Vector3d::UnitZ());
    if (!(c.normal.norm() > 0)) r.context().fail(r.path("normal"), "expected a non-zero vector, got [0, 0, 0]");
  } else if (c.shape == cloth::ClothCollider::Shape::Box) {
    c.halfExtents = r.vector3("half_extents", Eigen::Vector3d::Constant(0.5), positive());
    const Eigen::Vector3d degrees = r.vector3("rotation_deg", Eigen::Vector3d::Zero());
    const double k = M_PI / 180.0;
    c.orientation = (Eigen::AngleAxisd(degrees.z() * k, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(degrees.y() * k, Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(degrees.x() * k, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
  } else {
    c.radius = r.number("radius", 0.5, positive());
  }
  c.friction = r.number("friction", 0.5, closed(0, 1));
  r.finish();
  return c;
}

void parseBullet(ObjectReader& r, const stain::TriangleMesh& mesh, cloth::ClothDef& d) {
  const Context& ctx = r.context();
  d.totalMass = r.number("total_mass", d.totalMass, positive());
  d.stretchStiffness = r.number("stretch_stiffness", d.stretchStiffness, leftOpen(0, 1));
  d.shearStiffness = r.number("shear_stiffness", d.shearStiffness, leftOpen(0, 1));
  d.bendStiffness = r.number("bend_stiffness", d.bendStiffness, closed(0, 1));
  d.dampingRate = r.number("damping_rate", d.dampingRate, nonNegative());
  d.solver = static_cast<cloth::ClothSolver>(r.choice("solver", int(d.solver), {"positions", "velocities"}));
  d.positionIterations = r.integer("position_iterations", d.positionIterations, closed(1, 1000));
  d.velocityIterations = r.integer("velocity_iterations", d.velocityIterations, closed(0, 1000));
  d.driftIterations = r.integer("drift_iterations", d.driftIterations, closed(0, 1000));
  d.substeps = r.integer("substeps", d.substeps, closed(1, 1000));
  const json& pins = r.array("pins");
  d.pins.clear();
  std::vector<int> pinOf(static_cast<size_t>(mesh.vertexPositions.rows()), -1);
  for (std::size_t i = 0; i < pins.size(); ++i) {
    ObjectReader p(ctx, pins[i], indexPath(r.path("pins"), i));
    cloth::ClothPin pin;
    parsePin(p, mesh, pin);
    int& owner = pinOf[static_cast<size_t>(pin.vertex)];
    if (owner >= 0)
      ctx.fail(p.path("vertex"), "vertex " + std::to_string(ctx.fileVertex(pin.vertex)) + " is already pinned by " +
                                     indexPath(r.path("pins"), size_t(owner)));
    owner = static_cast<int>(i);
    d.pins.push_back(pin);
  }
  d.tethers = r.boolean("tethers", d.tethers);
  d.tetherSlack = r.number("tether_slack", d.tetherSlack, nonNegative());
  if (const json* wind = r.find("wind")) {
    ObjectReader w(ctx, *wind, r.path("wind"));
    d.wind.velocity = w.vector3("velocity", d.wind.velocity);
    d.wind.dragCoefficient = w.number("drag_coefficient", d.wind.dragCoefficient, nonNegative());
    d.wind.liftCoefficient = w.number("lift_coefficient", d.wind.liftCoefficient, nonNegative());
    d.wind.airDensity = w.number("air_density", d.wind.airDensity, positive());
    d.wind.model = static_cast<cloth::AeroModel>(
        w.choice("model", int(d.wind.model),
                 {"vertex-point", "vertex-two-sided", "vertex-two-sided-lift-drag", "vertex-one-sided",
                  "face-two-sided", "face-two-sided-lift-drag", "face-one-sided"}));
    w.finish();
  }
  const json& colliders = r.array("colliders");
  d.colliders.clear();
  for (std::size_t i = 0; i < colliders.size(); ++i) {
    ObjectReader c(ctx, colliders[i], indexPath(r.path("colliders"), i));
    d.colliders.push_back(parseCollider(c));
  }
  d.collisionMargin = r.number("collision_margin", d.collisionMargin, nonNegative());
  d.contactHardness = r.number("contact_hardness", d.contactHardness, leftOpen(0, 1));
  d.collisionVoxelSize = r.number("collision_voxel_size", d.collisionVoxelSize, nonNegative());
  if (d.collisionVoxelSize != 0 && d.collisionVoxelSize < cloth::kMinCollisionVoxelSize)
    ctx.fail(r.path("collision_voxel_size"), "expected 0 (automatic) or a number >= " +
                                                 formatNumber(cloth::kMinCollisionVoxelSize) + " m, got " +
                                                 formatNumber(d.collisionVoxelSize));
}

void parseCloth(ObjectReader& r, const stain::TriangleMesh& mesh, EngineDef& def) {
  const int source = r.choice("source", -1, {"static", "rigid", "sequence", "bullet"});
  if (source < 0) r.context().fail(r.path("source"), "required key is missing (\"static\", \"rigid\", \"sequence\" or \"bullet\")");
  def.source = static_cast<MotionSource>(source);
  switch (def.source) {
    case MotionSource::Static: break;
    case MotionSource::Rigid:
      def.rigid.angularVelocity = r.vector3("angular_velocity", Eigen::Vector3d::Zero());
      def.rigid.pivot = r.vector3("pivot", Eigen::Vector3d::Zero());
      def.rigid.linearVelocity = r.vector3("linear_velocity", Eigen::Vector3d::Zero());
      def.rigid.linearAcceleration = r.vector3("linear_acceleration", Eigen::Vector3d::Zero());
      break;
    case MotionSource::Sequence: {
      const std::string pattern = r.string("pattern", "");
      if (pattern.empty()) r.context().fail(r.path("pattern"), "required: a printf-style frame path such as \"frames/f_%04d.obj\"");
      def.sequence.pattern = r.context().resolve(pattern);
      def.sequence.firstFrame = r.integer("first_frame", 0, nonNegative());
      def.sequence.frameCount = r.integer("frame_count", 0, closed(0, kMaxSequenceFrames));
      def.sequence.playback.frameRate = r.number("frame_rate", 30.0, positive());
      def.sequence.playback.interpolation =
          static_cast<cloth::FrameInterpolation>(r.choice("interpolation", 0, {"catmull-rom", "linear"}));
      def.sequence.playback.end = static_cast<cloth::SequenceEnd>(r.choice("end", 0, {"hold", "loop"}));
      break;
    }
    case MotionSource::Bullet: parseBullet(r, mesh, def.cloth); break;
    case MotionSource::Caller: break;  // not a scene choice: the positions come from code
  }
  r.finish();
}

// ---------------------------------------------------------------- fabric

stain::Matrix2 parseTensor(const Context& ctx, const json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 2 || !v[0].is_array() || !v[1].is_array() || v[0].size() != 2 ||
      v[1].size() != 2)
    ctx.fail(path, "expected a 2x2 array [[s_ww, s_wp], [s_wp, s_pp]] (m²/s), got " + describe(v));
  stain::Matrix2 t;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      t(i, j) = numberValue(ctx, v[size_t(i)][size_t(j)], indexPath(indexPath(path, size_t(i)), size_t(j)), any());
  if (t(0, 1) != t(1, 0)) ctx.fail(path, "expected a symmetric tensor, got off-diagonals " + formatNumber(t(0, 1)) +
                                             " and " + formatNumber(t(1, 0)));
  if (!(t(0, 0) > 0) || !(t.determinant() > 0))
    ctx.fail(path, "expected a positive definite tensor (s_ww > 0, determinant > 0)");
  return t;
}

void parseFabric(ObjectReader& r, const stain::TriangleMesh& mesh, EngineDef& def) {
  const Context& ctx = r.context();
  // Bounded below, as wicking_factor is, so that their product stays a normal
  // double: 5e-324 underflowed and was refused as "EngineDef.diffusivity".
  def.diffusivity = r.number("diffusivity", def.diffusivity, closed(1e-12, kMaxSceneMagnitude));
  def.viscosity = r.number("viscosity", def.viscosity, nonNegative());
  def.stain.liquid.slipLength = r.number("slip_length", def.stain.liquid.slipLength, closed(0, 1));
  def.homogenizationSubdivisions = r.integer("subdivisions", 0, closed(0, 64));
  const bool acceptUnconverged = r.boolean("accept_unconverged", false);
  const int faceCount = static_cast<int>(mesh.faces.rows());
  const json& patches = r.array("patches");
  // On a renumbered mesh, which patch holds each face so far: a face listed
  // twice, or in two patches, is named here by its index in the file (the
  // layout's own check, at Engine construction, names the engine's).
  std::vector<int> patchOfFace(static_cast<size_t>(faceCount), -1);
  std::vector<std::string> names;
  for (std::size_t i = 0; i < patches.size(); ++i) {
    ObjectReader p(ctx, patches[i], indexPath(r.path("patches"), i));
    stain::FabricPatch patch;
    patch.name = p.string("name", p.path());
    // Faces: "all", {"label": L} (OBJ groups / PLY labels), or a list of indices.
    const json* faces = p.find("faces");
    if (faces == nullptr || (faces->is_string() && faces->get<std::string>() == "all")) {
      patch.faces.resize(static_cast<size_t>(faceCount));
      for (int f = 0; f < faceCount; ++f) patch.faces[static_cast<size_t>(f)] = f;
    } else if (faces->is_object()) {
      ObjectReader l(ctx, *faces, p.path("faces"));
      const int label = l.integer("label", 0, any());
      l.finish();
      if (mesh.faceLabels.empty()) ctx.fail(l.path("label"), "the mesh has no face labels (OBJ groups or PLY label)");
      patch.faces = stain::facesWithLabel(mesh.faceLabels, label);
      if (patch.faces.empty()) ctx.fail(l.path("label"), "no face has label " + std::to_string(label));
    } else if (faces->is_array()) {
      ctx.refuseIndexUnderOverride(p.path("faces"), "\"all\"");
      for (std::size_t k = 0; k < faces->size(); ++k)
        patch.faces.push_back(
            ctx.engineFace(integerValue(ctx, (*faces)[k], indexPath(p.path("faces"), k), indices(0, faceCount))));
    } else {
      ctx.fail(p.path("faces"), "expected \"all\", {\"label\": L} or an array of face indices, got " + describe(*faces));
    }
    if (ctx.renumbered()) {
      for (const int f : patch.faces) {
        int& owner = patchOfFace[static_cast<size_t>(f)];
        if (owner == static_cast<int>(i))
          ctx.fail(p.path("faces"), "face " + std::to_string(ctx.fileFace(f)) + " listed twice");
        if (owner >= 0)
          ctx.fail(p.path("faces"), "face " + std::to_string(ctx.fileFace(f)) + " already belongs to patch \"" +
                                        names[static_cast<size_t>(owner)] + "\"");
        owner = static_cast<int>(i);
      }
    }
    names.push_back(patch.name);
    const int materials = (p.has("pattern") ? 1 : 0) + (p.has("preset") ? 1 : 0) + (p.has("tensor") ? 1 : 0);
    if (materials != 1)
      ctx.fail(p.path(), "expected exactly one of \"pattern\" (file), \"preset\" (name) or \"tensor\", got " +
                             std::to_string(materials));
    if (p.has("pattern")) {
      const std::string path = ctx.resolve(p.string("pattern", ""));
      try {
        patch.pattern = stain::loadWeavePattern(path);
      } catch (const std::exception& e) {
        ctx.fail(p.path("pattern"), e.what());
      }
    } else if (p.has("preset")) {
      const std::string name = p.string("preset", "");
      try {
        patch.pattern = stain::presetWeavePattern(name);
      } catch (const std::exception& e) {
        ctx.fail(p.path("preset"), e.what());
      }
    } else {
      patch.tensor = parseTensor(ctx, p.require("tensor"), p.path("tensor"));
    }
    // The engine gets the homogenized tensor only if its bounds met (or the
    // scene accepts a looser one), and takes it from here instead of solving
    // the cell problems again (docs/patterns.md).
    stain::Matrix2 effective = stain::Matrix2::Zero();
    if (patch.pattern) {
      const std::string key = p.path(p.has("pattern") ? "pattern" : "preset");
      stain::HomogenizationResult h;
      try {
        h = stain::homogenize(*patch.pattern, def.homogenizationSubdivisions);
      } catch (const std::invalid_argument& e) {
        ctx.fail(key, e.what());
      }
      if (!h.converged && !acceptUnconverged)
        ctx.fail(key, "homogenization did not converge: the bounds differ by " + formatNumber(h.gap) +
                          " of the largest eigenvalue (tolerance " + formatNumber(h.tolerance) + ") at " +
                          std::to_string(h.vertexCount) + " unknowns; set \"fabric.accept_unconverged\": true to use "
                          "the mean of the bounds anyway");
      effective = h.effective;
    }
    def.fabricPatchEffectiveTensors.push_back(effective);
    // Scale: the patch's tensor (S_eff for a pattern, after homogenization in
    // the engine) is scaled so its mean eigenvalue, trace / 2, is this (m²/s).
    double scale = 0;
    if (p.has("diffusivity")) {
      scale = p.number("diffusivity", 0.0, closed(1e-12, kMaxSceneMagnitude));
      if (!patch.pattern) patch.tensor *= 2.0 * scale / patch.tensor.trace();
    }
    def.fabricPatchDiffusivities.push_back(patch.pattern ? scale : 0.0);
    const bool hasWeft = p.has("weft"), hasConstraints = p.has("weft_constraints");
    if (hasWeft && hasConstraints) ctx.fail(p.path("weft_constraints"), "give either \"weft\" or \"weft_constraints\", not both");
    if (hasConstraints) {
      const json& list = p.array("weft_constraints");
      for (std::size_t k = 0; k < list.size(); ++k) {
        ObjectReader c(ctx, list[k], indexPath(p.path("weft_constraints"), k));
        stain::WeftConstraint w;
        ctx.refuseIndexUnderOverride(c.path("face"), "\"weft\"");
        w.face = c.has("face") ? ctx.engineFace(c.integer("face", -1, indices(0, faceCount))) : -1;
        if (!c.has("face")) ctx.fail(c.path("face"), "required key is missing");
        w.direction = c.vector3("direction", Eigen::Vector3d::UnitX());
        c.finish();
        patch.weftConstraints.push_back(w);
      }
    } else {
      // One direction held on every face of the patch (projected per face).
      const Eigen::Vector3d direction = p.vector3("weft", Eigen::Vector3d::UnitX());
      if (!(direction.norm() > 0)) ctx.fail(p.path("weft"), "expected a non-zero direction");
      for (int f : patch.faces) patch.weftConstraints.push_back({f, direction});
      patch.oneWeftDirection = true;
    }
    p.finish();
    def.fabricPatches.push_back(std::move(patch));
  }
  r.finish();
}

// ---------------------------------------------------------------- liquid, physics, drops

/// What a scene's liquid sets beyond stain::LiquidParameters: the drops'
/// solute fraction (for `mass`), the pigment (unless `display` names one) and
/// the factors on the fabric's diffusivities.
struct LiquidChoice {
  const LiquidPreset* preset = nullptr;
  double soluteFraction = -1;  ///< < 0: none given, a drop's `mass` is an error
  double wickingFactor = 1, viscosityFactor = 1;
};

const LiquidPreset& presetByName(const Context& ctx, const json& value, const std::string& key) {
  if (!value.is_string())
    ctx.fail(key, "expected a liquid name (one of " + liquidPresetNames() + "), got " + describe(value));
  try {
    return liquidPresetFromName(value.get<std::string>());
  } catch (const std::invalid_argument& e) {
    ctx.fail(key, e.what());
  }
}

void applyPreset(const LiquidPreset& preset, stain::LiquidParameters& l, LiquidChoice& choice) {
  choice.preset = &preset;
  choice.soluteFraction = preset.soluteFraction;
  choice.wickingFactor = liquidWickingFactor(preset);
  choice.viscosityFactor = liquidViscosityFactor(preset);
  l.liquidDensity = preset.density;
  l.kinematicViscosity = preset.viscosity / preset.density;
  l.evaporationRate = preset.evaporationRate;
  l.molecularDiffusivity = preset.molecularDiffusivity;
}

// A preset fills in its values first; every key given explicitly wins.
void parseLiquid(ObjectReader& r, stain::LiquidParameters& l, LiquidChoice& choice) {
  if (const json* preset = r.find("preset")) applyPreset(presetByName(r.context(), *preset, r.path("preset")), l, choice);
  choice.soluteFraction = r.number("solute_fraction", choice.soluteFraction < 0 ? 0.0 : choice.soluteFraction,
                                   closed(0, 1));
  if (!r.has("solute_fraction") && choice.preset == nullptr) choice.soluteFraction = -1;
  choice.wickingFactor = r.number("wicking_factor", choice.wickingFactor, closed(1e-6, kMaxSceneMagnitude));
  choice.viscosityFactor = r.number("viscosity_factor", choice.viscosityFactor, nonNegative());
  l.absorptionRate = r.number("absorption_rate", l.absorptionRate, nonNegative());
  l.saturationDensity = r.number("saturation_density", l.saturationDensity, positive());
  l.desorptionRate = r.number("desorption_rate", l.desorptionRate, nonNegative());
  l.adsorptionCapacity = r.number("adsorption_capacity", l.adsorptionCapacity, nonNegative());
  l.evaporationRate = r.number("evaporation_rate", l.evaporationRate, nonNegative());
  l.boundaryEvaporationFactor = r.number("boundary_evaporation_factor", l.boundaryEvaporationFactor, nonNegative());
  l.evaporationBoundary = static_cast<stain::EvaporationBoundary>(
      r.choice("evaporation_boundary", int(l.evaporationBoundary), {"mesh-boundary", "wet-front"}));
  l.wetThreshold = r.number("wet_threshold", l.wetThreshold, positive());
  l.liquidDensity = r.number("liquid_density", l.liquidDensity, positive());
  l.kinematicViscosity = r.number("kinematic_viscosity", l.kinematicViscosity, closed(1e-9, 1.0));
  l.molecularDiffusivity = r.number("molecular_diffusivity", l.molecularDiffusivity, closed(0.0, 1.0));
  r.finish();
}

const std::vector<std::string> kPhysicsModels = {"film", "paper"};

void parsePhysics(ObjectReader& r, stain::PhysicsSwitches& s) {
  r.choice("model", 0, kPhysicsModels);  // applied before the liquid (parseScene)
  s.gravity = r.boolean("gravity", s.gravity);
  s.linearInertia = r.boolean("linear_inertia", s.linearInertia);
  s.coriolis = r.boolean("coriolis", s.coriolis);
  s.velocityAdvection = r.boolean("velocity_advection", s.velocityAdvection);
  s.densityAdvection = r.boolean("density_advection", s.densityAdvection);
  s.densityDiffusion = r.boolean("density_diffusion", s.densityDiffusion);
  s.velocityDiffusion = r.boolean("velocity_diffusion", s.velocityDiffusion);
  s.absorption = r.boolean("absorption", s.absorption);
  s.adsorption = r.boolean("adsorption", s.adsorption);
  s.evaporation = r.boolean("evaporation", s.evaporation);
  s.sources = r.boolean("sources", s.sources);
  s.filmPressure = r.boolean("film_pressure", s.filmPressure);
  s.filmFriction = r.boolean("film_friction", s.filmFriction);
  s.soluteWithSolvent = r.boolean("solute_with_solvent", s.soluteWithSolvent);
  s.massWeightedViscosity = r.boolean("mass_weighted_viscosity", s.massWeightedViscosity);
  s.velocityOnFreeLiquid = r.boolean("velocity_on_free_liquid", s.velocityOnFreeLiquid);
  s.boundaryWall = r.boolean("boundary_wall", s.boundaryWall);
  s.diffusiveMomentum = r.boolean("diffusive_momentum", s.diffusiveMomentum);
  s.positivityLimiter = r.boolean("positivity_limiter", s.positivityLimiter);
  s.coriolisScheme =
      static_cast<stain::CoriolisScheme>(r.choice("coriolis_scheme", int(s.coriolisScheme), {"exact-rotation", "explicit"}));
  r.finish();
}

TimedDrop parseDrop(ObjectReader& r, const stain::TriangleMesh& mesh, double soluteFraction) {
  TimedDrop t;
  stain::DropDef& d = t.drop;
  d.centerVertex = vertexOrPoint(r, mesh, false);
  if (d.centerVertex < 0 && !r.has("point"))
    r.context().fail(r.path("vertex"), "required: give \"vertex\" (an index) or \"point\" ([x, y, z])");
  if (r.has("point")) {
    // A world point lands where it hits the cloth (the engine projects it).
    d.centerPoint = r.vector3("point", Eigen::Vector3d::Zero());
    d.centerVertex = -1;
  }
  d.radius = r.number("radius", d.radius, positive());
  if (r.has("mass")) {
    // The whole drop, split by the liquid's solute fraction.
    if (r.has("solvent_mass") || r.has("solute_mass"))
      r.context().fail(r.path("mass"), "give either \"mass\" or \"solvent_mass\" and \"solute_mass\", not both");
    if (soluteFraction < 0)
      r.context().fail(r.path("mass"), "needs the liquid's solute fraction: set \"liquid\" to a preset (" +
                                           liquidPresetNames() + ") or give liquid.solute_fraction");
    const double mass = r.number("mass", 0.0, nonNegative());
    d.soluteMass = soluteFraction * mass;
    d.solventMass = mass - d.soluteMass;
  }
  d.solventMass = r.number("solvent_mass", d.solventMass, nonNegative());
  d.soluteMass = r.number("solute_mass", d.soluteMass, nonNegative());
  // Without a world velocity the drop lands at rest on the cloth.
  d.velocityIsWorld = r.has("velocity");
  d.velocity = r.vector3("velocity", Eigen::Vector3d::Zero());
  d.relativeVelocity = r.vector3("relative_velocity", Eigen::Vector3d::Zero());
  d.splashSpeed = r.number("splash_speed", 0.0, nonNegative());
  d.splashSeed = static_cast<std::uint64_t>(r.integer("splash_seed", 0, closed(0, 2e9)));
  t.time = r.number("time", 0.0, nonNegative());
  r.finish();
  return t;
}

stain::HeldRegion parseHeldRegion(ObjectReader& r, const stain::TriangleMesh& mesh) {
  stain::HeldRegion h;
  const int n = static_cast<int>(mesh.vertexPositions.rows());
  const bool hasList = r.has("vertices"), hasBall = r.has("center");
  if (hasList == hasBall)
    r.context().fail(r.path("vertices"), "expected exactly one of \"vertices\" (indices) or \"center\" with \"radius\"");
  if (hasList) {
    r.context().refuseIndexUnderOverride(r.path("vertices"), "\"center\" and \"radius\"");
    const json& list = r.array("vertices");
    for (std::size_t k = 0; k < list.size(); ++k)
      h.vertices.push_back(r.context().engineVertex(
          integerValue(r.context(), list[k], indexPath(r.path("vertices"), k), indices(0, n))));
    if (h.vertices.empty()) r.context().fail(r.path("vertices"), "expected at least one vertex");
  } else {
    const Eigen::Vector3d c = r.vector3("center", Eigen::Vector3d::Zero());
    const double radius = r.number("radius", 0.02, positive());
    for (int i = 0; i < n; ++i)
      if ((mesh.vertexPositions.row(i).transpose() - c).norm() <= radius) h.vertices.push_back(i);
    if (h.vertices.empty())
      r.context().fail(r.path("radius"), "no rest-shape vertex lies within " + formatNumber(radius) + " m of the center");
  }
  h.solventDensity = r.number("solvent_density", 0.0, nonNegative());
  h.soluteDensity = r.number("solute_density", 0.0, nonNegative());
  r.finish();
  return h;
}

void parseOutputs(ObjectReader& r, SceneOutputs& o) {
  o.frames = r.integer("frames", o.frames, closed(1, 1000000));
  o.stepsPerFrame = r.integer("steps_per_frame", o.stepsPerFrame, closed(1, 1000000));
  o.plyEvery = r.integer("ply_every", o.plyEvery, closed(0, 1000000));
  o.plyFormat = static_cast<PlyFormat>(r.choice("ply_format", 0, {"binary", "ascii"}));
  o.directory = r.string("directory", o.directory);
  if (const json* preview = r.find("preview")) {
    ObjectReader p(r.context(), *preview, r.path("preview"));
    ScenePreview& s = o.preview;
    s.enabled = p.boolean("enabled", s.enabled);
    s.width = p.integer("width", s.width, closed(16, kMaxImageSide));
    s.height = p.integer("height", s.height, closed(16, kMaxImageSide));
    s.supersampling = p.integer("supersampling", s.supersampling, closed(1, kMaxSupersampling));
    if (double(s.width) * s.height * s.supersampling * s.supersampling > kMaxImageSamples)
      r.context().fail(p.path(), "width x height x supersampling^2 = " + std::to_string(s.width) + " x " +
                                     std::to_string(s.height) + " x " + std::to_string(s.supersampling) +
                                     "^2 is more than the renderer's " + formatNumber(kMaxImageSamples) + " samples");
    s.viewDirection = p.vector3("view_direction", s.viewDirection);
    if (!(s.viewDirection.norm() > 0)) r.context().fail(p.path("view_direction"), "expected a non-zero direction");
    s.projection = static_cast<Projection>(p.choice("projection", int(s.projection), {"perspective", "orthographic"}));
    s.restShape = p.boolean("rest_shape", s.restShape);
    s.up = p.vector3("up", s.up);
    if (p.find("up") != nullptr && !(s.up.cross(s.viewDirection).norm() > 1e-6 * s.up.norm() * s.viewDirection.norm()))
      r.context().fail(p.path("up"), "expected a non-zero direction not parallel to view_direction");
    p.finish();
  }
  if (const json* images = r.find("images")) {
    ObjectReader p(r.context(), *images, r.path("images"));
    SceneImages& s = o.images;
    s.enabled = p.boolean("enabled", true);
    s.every = p.integer("every", s.every, closed(1, 1000000));
    s.width = p.integer("width", s.width, closed(16, 8192));
    s.height = p.integer("height", s.height, closed(16, 8192));
    s.supersampling = p.integer("supersampling", s.supersampling, closed(1, 4));
    s.camera = static_cast<FrameCamera>(p.choice("camera", int(s.camera), {"follow", "rest"}));
    s.viewDirection = p.vector3("view_direction", s.viewDirection);
    if (!(s.viewDirection.norm() > 0)) r.context().fail(p.path("view_direction"), "expected a non-zero direction");
    s.projection = static_cast<Projection>(p.choice("projection", int(s.projection), {"perspective", "orthographic"}));
    s.up = p.vector3("up", s.up);
    if (p.find("up") != nullptr && !(s.up.cross(s.viewDirection).norm() > 1e-6 * s.up.norm() * s.viewDirection.norm()))
      r.context().fail(p.path("up"), "expected a non-zero direction not parallel to view_direction");
    p.finish();
  }
  if (const json* video = r.find("video")) {
    ObjectReader p(r.context(), *video, r.path("video"));
    o.video.mp4 = p.boolean("mp4", true);
    o.video.gif = p.boolean("gif", o.video.gif);
    o.video.fps = p.number("fps", o.video.fps, closed(1, 240));
    p.finish();
    if (o.video.mp4 || o.video.gif) o.images.enabled = true;  // the video is made of the frame images
  }
  if (const json* texture = r.find("texture")) {
    ObjectReader p(r.context(), *texture, r.path("texture"));
    SceneTexture& t = o.texture;
    t.enabled = p.boolean("enabled", true);
    t.everyFrame = p.boolean("every_frame", t.everyFrame);
    t.width = p.integer("width", t.width, closed(1, kMaxImageSide));
    t.height = p.integer("height", t.height, closed(1, kMaxImageSide));
    if (double(t.width) * double(t.height) > kMaxTextureTexels)
      r.context().fail(p.path("width"), "a " + std::to_string(t.width) + " x " + std::to_string(t.height) +
                                            " texture has more than 2^26 texels (8192 x 8192), the baking "
                                            "budget (about 38 bytes a texel)");
    t.padding = p.integer("padding", t.padding, closed(0, 256));
    t.densityScale = p.number("density_scale", t.densityScale, leftOpen(0, 1e6));
    if (const json* maps = p.find("maps")) {
      // The wetness, saturation and stain maps: a list of formats.
      const std::string at = p.path("maps");
      if (!maps->is_array()) r.context().fail(at, "expected a list of \"png8\", \"png16\", \"exr\", got " + describe(*maps));
      for (std::size_t k = 0; k < maps->size(); ++k) {
        const json& format = (*maps)[k];
        const std::string item = at + "[" + std::to_string(k) + "]";
        const std::string name = format.is_string() ? format.get<std::string>() : std::string();
        bool* chosen = name == "png8" ? &t.maps.png8 : name == "png16" ? &t.maps.png16 : name == "exr" ? &t.maps.exr : nullptr;
        if (chosen == nullptr)
          r.context().fail(item, "expected \"png8\", \"png16\" or \"exr\", got " + describe(format));
        if (*chosen) r.context().fail(item, "\"" + name + "\" is listed twice");
        *chosen = true;
      }
    }
    p.finish();
  }
  if (const json* gltf = r.find("gltf")) {
    ObjectReader p(r.context(), *gltf, r.path("gltf"));
    o.gltf.enabled = p.boolean("enabled", true);
    o.gltf.everyFrame = p.boolean("every_frame", o.gltf.everyFrame);
    o.gltf.glossWetness = p.number("gloss_wetness", o.gltf.glossWetness, leftOpen(0, 1e6));
    p.finish();
  }
  r.finish();
}

}  // namespace

const char* motionSourceName(MotionSource source) {
  switch (source) {
    case MotionSource::Static: return "static";
    case MotionSource::Rigid: return "rigid";
    case MotionSource::Sequence: return "sequence";
    case MotionSource::Bullet: return "bullet";
    case MotionSource::Caller: return "caller";
  }
  return "?";
}

SceneDef parseScene(const std::string& jsonText, const std::string& sourceName, const std::string& baseDirectory,
                    const SceneLoadOptions& options) {
  if (options.patchResolution < 0 || options.patchResolution > 2000)
    throw SceneError(sourceName + ": patch resolution override: expected an integer in [1, 2000] (or 0: none), got " +
                     std::to_string(options.patchResolution));
  Context ctx(sourceName, baseDirectory.empty() ? std::filesystem::path(".") : std::filesystem::path(baseDirectory),
                    options);
  json root;
  try {
    root = stain::parseStrictJson(jsonText);
  } catch (const stain::StrictJsonError& e) {
    throw SceneError(sourceName + ": " + e.what());
  }
  ObjectReader r(ctx, root, "");
  r.allowOnly({"name", "description", "mesh", "cloth", "fabric", "liquid", "physics", "gravity", "strain_tolerance",
               "strain_test", "intrinsic_refresh", "threads", "adaptive_threads", "coupling", "time_step",
               "max_steps_per_call", "drops", "held_regions", "display", "outputs"});
  SceneDef scene;
  scene.sourceName = sourceName;
  scene.sourceHash = stain::kContentHashBasis;
  stain::hashBytes(scene.sourceHash, jsonText.data(), jsonText.size());
  const std::int64_t resolution = options.patchResolution;
  stain::hashBytes(scene.sourceHash, &resolution, sizeof resolution);
  scene.name = r.string("name", std::filesystem::path(sourceName).stem().string());
  // The name becomes file names inside the output folder (<name>_0001.ply,
  // <name>.png): it may not name a path.
  if (scene.name.empty() || scene.name.size() > 200 || scene.name.front() == '.' ||
      scene.name.find_first_of("/\\") != std::string::npos ||
      std::any_of(scene.name.begin(), scene.name.end(), [](char c) { return static_cast<unsigned char>(c) < 32; }))
    ctx.fail("name", "expected a file name (1 to 200 bytes of UTF-8, no '/', '\\' or control characters, not starting "
                     "with '.'), got " + describe(json(scene.name)));
  scene.description = r.string("description", "");
  EngineDef& def = scene.engine;

  // The cloth source decides whether "mesh" may be omitted (a sequence's first frame).
  const json* clothJson = r.find("cloth");
  if (clothJson == nullptr) ctx.fail("cloth", "required key is missing (an object with \"source\")");
  if (const json* mesh = r.find("mesh")) {
    ObjectReader m(ctx, *mesh, "mesh");
    def.mesh = parseMesh(m, scene.meshDescription, scene.meshOrder);
    ctx.setMeshOrder(scene.meshOrder);
    def.meshOrder = scene.meshOrder;  // kept with the engine (Engine::fromSceneFile)
  } else {
    ctx.fail("mesh", "required key is missing (\"file\", \"patch\", \"icosphere\" or \"disc\")");
  }
  {
    ObjectReader c(ctx, *clothJson, "cloth");
    parseCloth(c, def.mesh, def);
  }
  // A sequence's frames are read in the file's numbering as the engine steps.
  if (!scene.meshOrder.vertices.empty() && def.source == MotionSource::Sequence)
    ctx.fail("mesh.vertex_order", "\"locality\" cannot be used with a \"sequence\" cloth (its frames number the "
                                  "vertices as the file does); use \"file\"");
  if (const json* fabric = r.find("fabric")) {
    ObjectReader f(ctx, *fabric, "fabric");
    parseFabric(f, def.mesh, def);
  }
  // The model first: it sets switches and the evaporation boundary, which
  // the liquid's and physics' own keys then override.
  if (const json* physics = r.find("physics"); physics != nullptr && physics->is_object() && physics->contains("model")) {
    ObjectReader p(ctx, *physics, "physics");
    const auto model = static_cast<stain::PhysicsModel>(p.choice("model", 0, kPhysicsModels));
    stain::applyPhysicsModel(model, def.stain.switches, def.stain.liquid);
  }
  LiquidChoice liquidChoice;
  if (const json* liquid = r.find("liquid")) {
    if (liquid->is_string()) {
      applyPreset(presetByName(ctx, *liquid, "liquid"), def.stain.liquid, liquidChoice);
    } else {
      ObjectReader l(ctx, *liquid, "liquid");
      parseLiquid(l, def.stain.liquid, liquidChoice);
    }
    // The fabric's diffusivities are its values with water; the liquid scales
    // them (Washburn: wicking ∝ γ/μ; the film's momentum diffusion ∝ μ/ρ).
    def.diffusivity *= liquidChoice.wickingFactor;
    def.viscosity *= liquidChoice.viscosityFactor;
    for (std::size_t i = 0; i < def.fabricPatches.size(); ++i) {
      stain::FabricPatch& patch = def.fabricPatches[i];
      if (!patch.pattern) {
        patch.tensor *= liquidChoice.wickingFactor;
      } else if (def.fabricPatchDiffusivities[i] > 0) {
        def.fabricPatchDiffusivities[i] *= liquidChoice.wickingFactor;
      } else if (liquidChoice.wickingFactor != 1) {
        def.fabricPatchDiffusivities[i] = liquidChoice.wickingFactor * 0.5 * def.fabricPatchEffectiveTensors[i].trace();
      }
    }
  }
  if (const json* physics = r.find("physics")) {
    ObjectReader p(ctx, *physics, "physics");
    parsePhysics(p, def.stain.switches);
  }
  def.stain.gravity = r.vector3("gravity", def.stain.gravity);
  def.cloth.gravity = def.stain.gravity;
  // A Bullet cloth's edges jitter by 1-4 % near the pins from step to step
  // (its Gauss-Seidel links never converge fully): with the solver's 1e-3 the
  // stain would refactorize on most steps (docs/coupling.md), so such scenes
  // default to 0.02 — the operators then carry at most a 2 % metric error.
  const double defaultStrainTolerance = def.source == MotionSource::Bullet ? kBulletStrainTolerance
                                                                          : def.stain.strainTolerance;
  def.stain.strainTolerance = r.number("strain_tolerance", defaultStrainTolerance, positive());
  def.stain.strainTest = static_cast<stain::StrainTest>(
      r.choice("strain_test", static_cast<int>(def.stain.strainTest), {"whole-mesh", "around-liquid"}));
  // "partial" (IntrinsicRefresh::Partial) stays API-only: measured less
  // accurate than either of these (docs/accuracy.md, "Strain tolerance").
  if (r.choice("intrinsic_refresh", 0, {"whole", "region"}) == 1) {
    if (def.stain.strainTest != stain::StrainTest::AroundLiquid)
      ctx.fail("intrinsic_refresh", "\"region\" needs strain_test \"around-liquid\", got \"whole-mesh\"");
    def.stain.intrinsicRefresh = stain::IntrinsicRefresh::Region;
  }
  def.stain.threads = r.integer("threads", def.stain.threads, closed(0, stain::kMaxThreads));
  def.stain.adaptiveThreads = r.boolean("adaptive_threads", def.stain.adaptiveThreads);
  def.coupling = static_cast<coupling::CouplingMode>(r.choice("coupling", 0, {"one-way", "two-way"}));
  if (def.coupling == coupling::CouplingMode::TwoWay && def.source != MotionSource::Bullet)
    ctx.fail("coupling", std::string("\"two-way\" needs cloth.source \"bullet\", got \"") +
                             motionSourceName(def.source) + "\"");
  def.timeStep = r.number("time_step", def.timeStep, closed(kMinTimeStep, 1));
  def.maxStepsPerCall = r.integer("max_steps_per_call", def.maxStepsPerCall, closed(1, 100000));
  const json& drops = r.array("drops");
  for (std::size_t i = 0; i < drops.size(); ++i) {
    ObjectReader d(ctx, drops[i], indexPath("drops", i));
    def.drops.push_back(parseDrop(d, def.mesh, liquidChoice.soluteFraction));
  }
  const json& held = r.array("held_regions");
  for (std::size_t i = 0; i < held.size(); ++i) {
    ObjectReader h(ctx, held[i], indexPath("held_regions", i));
    def.heldRegions.push_back(parseHeldRegion(h, def.mesh));
  }
  // A liquid preset's own pigment unless the display names another.
  if (liquidChoice.preset != nullptr) def.colors.soluteAbsorbance = liquidSoluteAbsorbance(*liquidChoice.preset);
  if (const json* display = r.find("display")) {
    ObjectReader d(ctx, *display, "display");
    const int pigment = d.choice("pigment", 0, {"wine", "coffee", "ink"});
    const Eigen::Vector3d cloth = d.vector3("cloth_color", kDefaultClothColor.matrix(), closed(0, 1));
    const Eigen::Array3d presetAbsorbance = def.colors.soluteAbsorbance;
    def.colors = stainColorMapping(static_cast<PigmentPreset>(pigment), cloth.array());
    if (liquidChoice.preset != nullptr && d.find("pigment") == nullptr) def.colors.soluteAbsorbance = presetAbsorbance;
    // A custom pigment: its absorbance directly, or the (linear) colour the
    // stain has on this cloth at pigment_color_density of solute.
    const bool byAbsorbance = d.find("pigment_absorbance") != nullptr, byColor = d.find("pigment_color") != nullptr;
    if (byAbsorbance && (byColor || d.find("pigment") != nullptr))
      ctx.fail("display.pigment_absorbance", "give one of pigment, pigment_absorbance, pigment_color");
    if (byColor && d.find("pigment") != nullptr)
      ctx.fail("display.pigment_color", "give one of pigment, pigment_absorbance, pigment_color");
    if (byAbsorbance)
      def.colors.soluteAbsorbance = d.vector3("pigment_absorbance", Eigen::Vector3d::Zero(), closed(0, 1e6)).array();
    const double density = d.number("pigment_color_density", 1.0, leftOpen(0, 1e6));
    if (byColor) {
      const Eigen::Vector3d color = d.vector3("pigment_color", Eigen::Vector3d::Zero(), leftOpen(0, 1));
      for (int c = 0; c < 3; ++c) {
        if (!(color[c] <= cloth[c]))
          ctx.fail("display.pigment_color", "channel " + std::to_string(c) + " is " + formatNumber(color[c]) +
                                                ", expected at most the cloth's " + formatNumber(cloth[c]) +
                                                " (a pigment only absorbs)");
        def.colors.soluteAbsorbance[c] = -std::log(color[c] / cloth[c]) / density;  // Beer–Lambert solved for ε
        // Held to pigment_absorbance's range: a density of 5e-324 gave an
        // infinite ε, and ∞ · 0 made every dry vertex's colour NaN.
        if (!(def.colors.soluteAbsorbance[c] <= 1e6))
          ctx.fail("display.pigment_color_density",
                   "with pigment_color channel " + std::to_string(c) + " at " + formatNumber(color[c]) +
                       " this gives an absorbance of " + formatNumber(def.colors.soluteAbsorbance[c]) +
                       " m²/kg, more than 1e6 (pigment_absorbance's range): expected a density of at least " +
                       formatNumber(-std::log(color[c] / cloth[c]) / 1e6) + " kg/m², got " + formatNumber(density));
      }
    } else if (d.find("pigment_color_density") != nullptr) {
      ctx.fail("display.pigment_color_density", "only meaningful with pigment_color");
    }
    d.finish();
  }
  if (const json* outputs = r.find("outputs")) {
    ObjectReader o(ctx, *outputs, "outputs");
    parseOutputs(o, scene.outputs);
    if ((scene.outputs.texture.enabled || scene.outputs.texture.maps.any()) && def.mesh.vertexUVs.rows() == 0)
      ctx.fail("outputs.texture", "the mesh has no UVs to bake into (use a mesh file with UVs or a \"patch\")");
  }
  r.finish();
  if (scene.outputs.directory.empty()) scene.outputs.directory = "out/" + scene.name;
  return scene;
}

SceneDef loadScene(const std::string& path, const SceneLoadOptions& options) {
  std::string text;
  try {
    text = stain::readFileBounded(path, stain::kJsonFileByteLimit, "the scene file");
  } catch (const stain::FileReadError& e) {
    throw SceneError(e.what());
  }
  return parseScene(text, path, std::filesystem::path(path).parent_path().string(), options);
}

EngineDef engineDef(const SceneDef& scene) { return scene.engine; }

}  // namespace blot::engine
