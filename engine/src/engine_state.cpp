// Engine::save / Engine::load: the whole simulation state in one binary file.
//
// Design note: docs/design-notes.md, "engine/src/engine_state.cpp".
#include <blot/engine/engine.h>

#include <blot/stain/io/atomic_file.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <type_traits>

namespace blot::engine {
namespace {

constexpr char kMagic[8] = {'B', 'L', 'O', 'T', 'S', 'T', 'A', 'T'};
constexpr std::uint32_t kVersion = 3;  // 2: field lists; 3: drops carry relativeVelocity and velocityIsWorld

/// True for a type with a field list (a visit member).
template <typename T, typename = void>
constexpr bool kVisitable = false;
struct AnyVisitor;
template <typename T>
constexpr bool kVisitable<T, std::void_t<decltype(&T::template fields<T, AnyVisitor>)>> = true;

class Writer {
 public:
  template <typename T>
  void pod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>, "pod");
    const auto* p = reinterpret_cast<const char*>(&value);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  template <typename Derived>
  void dense(const Eigen::PlainObjectBase<Derived>& m) {
    pod<std::int64_t>(m.rows());
    pod<std::int64_t>(m.cols());
    const auto* p = reinterpret_cast<const char*>(m.data());
    bytes_.insert(bytes_.end(), p, p + sizeof(typename Derived::Scalar) * static_cast<std::size_t>(m.size()));
  }
  template <typename Scalar>
  void sparse(const Eigen::SparseMatrix<Scalar>& input) {
    Eigen::SparseMatrix<Scalar> m = input;
    m.makeCompressed();
    pod<std::int64_t>(m.rows());
    pod<std::int64_t>(m.cols());
    pod<std::int64_t>(m.nonZeros());
    raw(m.outerIndexPtr(), static_cast<std::size_t>(m.outerSize() + 1));
    raw(m.innerIndexPtr(), static_cast<std::size_t>(m.nonZeros()));
    raw(m.valuePtr(), static_cast<std::size_t>(m.nonZeros()));
  }
  template <typename T>
  void vector(const std::vector<T>& v) {
    pod<std::uint64_t>(v.size());
    raw(v.data(), v.size());
  }
  template <typename T>
  void raw(const T* data, std::size_t count) {
    const auto* p = reinterpret_cast<const char*>(data);
    bytes_.insert(bytes_.end(), p, p + sizeof(T) * count);
  }
  const std::vector<char>& bytes() const { return bytes_; }

  /// A state struct's field (its visit member calls this for each field).
  template <typename T>
  void field(const char* /*name*/, const T& value) {
    write(value);
  }

 private:
  void write(double v) { pod(v); }
  void write(int v) { pod<std::int32_t>(v); }
  void write(bool v) { pod<std::uint8_t>(v ? 1 : 0); }
  template <typename Derived>
  void write(const Eigen::PlainObjectBase<Derived>& m) { dense(m); }
  template <typename Scalar>
  void write(const Eigen::SparseMatrix<Scalar>& m) { sparse(m); }
  template <typename T>
  void write(const std::vector<T>& v) {
    if constexpr (kVisitable<T>) {
      pod<std::uint64_t>(v.size());
      for (const T& element : v) element.visit(*this);
    } else {
      vector(v);
    }
  }
  std::vector<char> bytes_;
};

class Reader {
 public:
  Reader(std::vector<char> bytes, std::string path) : bytes_(std::move(bytes)), path_(std::move(path)) {}
  [[noreturn]] void fail(const std::string& what) const { throw StateFileError(path_ + ": " + what); }
  template <typename T>
  T pod(const char* what) {
    T value;
    take(&value, sizeof(T), what);
    return value;
  }
  template <typename Derived>
  void dense(Eigen::PlainObjectBase<Derived>& m, const char* what) {
    const auto rows = pod<std::int64_t>(what), cols = pod<std::int64_t>(what);
    if (rows < 0 || cols < 0 || double(rows) * double(cols) > double(bytes_.size()) ||
        (Derived::ColsAtCompileTime != Eigen::Dynamic && cols != Derived::ColsAtCompileTime))
      fail(std::string("bad shape of ") + what);
    check(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * sizeof(typename Derived::Scalar), what);
    m.resize(rows, cols);
    take(m.data(), sizeof(typename Derived::Scalar) * static_cast<std::size_t>(m.size()), what);
  }
  template <typename Scalar>
  void sparse(Eigen::SparseMatrix<Scalar>& m, const char* what) {
    const auto rows = pod<std::int64_t>(what), cols = pod<std::int64_t>(what), nnz = pod<std::int64_t>(what);
    if (rows < 0 || cols < 0 || nnz < 0 || cols >= std::int64_t(bytes_.size()) || nnz > std::int64_t(bytes_.size())) fail(std::string("bad shape of ") + what);
    std::vector<int> outer(static_cast<std::size_t>(cols + 1)), inner(static_cast<std::size_t>(nnz));
    std::vector<Scalar> values(static_cast<std::size_t>(nnz));
    check(outer.size() * sizeof(int), what);
    take(outer.data(), outer.size() * sizeof(int), what);
    check(inner.size() * sizeof(int) + values.size() * sizeof(Scalar), what);
    take(inner.data(), inner.size() * sizeof(int), what);
    take(values.data(), values.size() * sizeof(Scalar), what);
    if (outer.front() != 0 || outer.back() != nnz) fail(std::string("corrupt sparse matrix ") + what);
    m = Eigen::Map<const Eigen::SparseMatrix<Scalar>>(rows, cols, nnz, outer.data(), inner.data(), values.data());
  }
  template <typename T>
  void vector(std::vector<T>& v, const char* what) {
    const auto n = pod<std::uint64_t>(what);
    if (n > bytes_.size()) fail(std::string("corrupt length of ") + what);
    check(n * sizeof(T), what);
    v.resize(n);
    take(v.data(), n * sizeof(T), what);
  }
  bool atEnd() const { return offset_ == bytes_.size(); }

  /// A state struct's field, read in place (errors name it).
  template <typename T>
  void field(const char* name, T& value) {
    read(value, name);
  }

 private:
  void read(double& v, const char* name) { v = pod<double>(name); }
  void read(int& v, const char* name) { v = pod<std::int32_t>(name); }
  void read(bool& v, const char* name) { v = pod<std::uint8_t>(name) != 0; }
  template <typename Derived>
  void read(Eigen::PlainObjectBase<Derived>& m, const char* name) { dense(m, name); }
  template <typename Scalar>
  void read(Eigen::SparseMatrix<Scalar>& m, const char* name) { sparse(m, name); }
  template <typename T>
  void read(std::vector<T>& v, const char* name) {
    if constexpr (kVisitable<T>) {
      const auto n = pod<std::uint64_t>(name);
      if (n > bytes_.size() - offset_) fail(std::string("corrupt length of ") + name);
      v.resize(n);
      for (T& element : v) element.visit(*this);
    } else {
      vector(v, name);
    }
  }
  void check(std::size_t count, const char* what) const {
    if (count > bytes_.size() - offset_)
      fail("truncated at byte " + std::to_string(offset_) + " while reading " + what);
  }
  void take(void* out, std::size_t count, const char* what) {
    check(count, what);
    if (count > 0) std::memcpy(out, bytes_.data() + offset_, count);
    offset_ += count;
  }
  std::vector<char> bytes_;
  std::string path_;
  std::size_t offset_ = 0;
};

void writeDrop(Writer& w, const stain::DropDef& d) {
  w.pod<std::int32_t>(d.centerVertex);
  w.raw(d.centerPoint.data(), 3);
  w.pod(d.radius);
  w.pod(d.solventMass);
  w.pod(d.soluteMass);
  w.raw(d.velocity.data(), 3);
  w.pod(d.splashSpeed);
  w.pod(d.splashSeed);
}

stain::DropDef readDrop(Reader& r) {
  stain::DropDef d;
  d.centerVertex = r.pod<std::int32_t>("drop");
  for (int c = 0; c < 3; ++c) d.centerPoint[c] = r.pod<double>("drop");
  d.radius = r.pod<double>("drop");
  d.solventMass = r.pod<double>("drop");
  d.soluteMass = r.pod<double>("drop");
  for (int c = 0; c < 3; ++c) d.velocity[c] = r.pod<double>("drop");
  d.splashSpeed = r.pod<double>("drop");
  d.splashSeed = r.pod<std::uint64_t>("drop");
  return d;
}

/// The motion's dynamic state through the Writer and Reader.
class MotionWriter final : public cloth::MotionStateVisitor {
 public:
  explicit MotionWriter(Writer& w) : w_(w) {}
  void field(const char* name, double& v) override { w_.field(name, v); }
  void field(const char* name, bool& v) override { w_.field(name, v); }
  void field(const char* name, Eigen::MatrixX3d& v) override { w_.field(name, v); }
  void field(const char* name, Eigen::VectorXd& v) override { w_.field(name, v); }
  void field(const char* name, std::vector<char>& v) override { w_.field(name, v); }

 private:
  Writer& w_;
};

class MotionReader final : public cloth::MotionStateVisitor {
 public:
  explicit MotionReader(Reader& r) : r_(r) {}
  void field(const char* name, double& v) override { r_.field(name, v); }
  void field(const char* name, bool& v) override { r_.field(name, v); }
  void field(const char* name, Eigen::MatrixX3d& v) override { r_.field(name, v); }
  void field(const char* name, Eigen::VectorXd& v) override { r_.field(name, v); }
  void field(const char* name, std::vector<char>& v) override { r_.field(name, v); }

 private:
  Reader& r_;
};

/// The motion's dynamic state (a simulated cloth's nodes, pins, pending
/// loads) after a marker, or the 0 marker alone.
void writeMotionState(Writer& w, const cloth::SurfaceMotion& motion) {
  w.pod<std::uint8_t>(motion.hasDynamicState() ? 1 : 0);
  if (!motion.hasDynamicState()) return;
  MotionWriter visitor(w);
  motion.saveDynamicState(visitor);
}

void readMotionState(Reader& r, cloth::SurfaceMotion& motion) {
  const bool has = r.pod<std::uint8_t>("cloth marker") != 0;
  if (has != motion.hasDynamicState()) r.fail("cloth state marker does not match the motion source");
  if (!has) return;
  MotionReader visitor(r);
  try {
    motion.loadDynamicState(visitor);
  } catch (const std::invalid_argument& e) {
    r.fail(e.what());
  }
}

}  // namespace

void Engine::save(const std::string& path) const {
  Writer w;
  w.raw(kMagic, sizeof kMagic);
  w.pod<std::uint32_t>(kVersion);
  w.pod<std::uint32_t>(static_cast<std::uint32_t>(def_.source));
  w.pod<std::int64_t>(def_.mesh.vertexPositions.rows());
  w.pod<std::int64_t>(def_.mesh.faces.rows());
  w.pod<std::uint64_t>(meshFingerprint_);
  w.pod(def_.timeStep);
  w.pod<std::int64_t>(steps_);
  w.pod(accumulator_);
  w.pod<std::uint64_t>(nextScheduled_);
  w.pod<std::uint64_t>(pending_.size());
  for (const stain::DropDef& d : pending_) writeDrop(w, d);
  w.pod(surface_->motion().time());
  writeMotionState(w, surface_->motion());
  w.dense(surface_->liquidNodeMasses());
  w.dense(surface_->pendingImpulses());
  w.raw(surface_->evaporatedMomentum().data(), 3);
  surface_->stain().snapshot().visit(w);

  // Atomic: a reader never sees a half-written state.
  try {
    stain::writeFileAtomically(path, w.bytes().data(), w.bytes().size());
  } catch (const std::runtime_error& e) {
    throw StateFileError(e.what());
  }
}

void Engine::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateFileError(path + ": cannot open the state file");
  Reader r(std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()), path);
  char magic[8];
  for (char& c : magic) c = r.pod<char>("magic");
  if (std::memcmp(magic, kMagic, sizeof kMagic) != 0) r.fail("not a Blot state file (bad magic)");
  const auto version = r.pod<std::uint32_t>("version");
  if (version != kVersion)
    r.fail("state file version " + std::to_string(version) + ", this build reads version " + std::to_string(kVersion));
  const auto source = r.pod<std::uint32_t>("motion source");
  if (source != static_cast<std::uint32_t>(def_.source))
    r.fail(std::string("saved from a \"") + (source <= 3 ? motionSourceName(static_cast<MotionSource>(source)) : "?") +
           "\" cloth source, this engine uses \"" + motionSourceName(def_.source) + "\"");
  const auto vertices = r.pod<std::int64_t>("mesh size"), faces = r.pod<std::int64_t>("mesh size");
  if (vertices != def_.mesh.vertexPositions.rows() || faces != def_.mesh.faces.rows())
    r.fail("saved for a mesh of " + std::to_string(vertices) + " vertices and " + std::to_string(faces) +
           " faces, this engine has " + std::to_string(def_.mesh.vertexPositions.rows()) + " vertices and " +
           std::to_string(def_.mesh.faces.rows()) + " faces");
  if (r.pod<std::uint64_t>("mesh fingerprint") != meshFingerprint_)
    r.fail("mesh fingerprint differs: same vertex and face counts, but other rest positions or faces");
  const double h = r.pod<double>("time step");
  if (h != def_.timeStep)
    r.fail("saved with time step " + std::to_string(h) + " s, this engine uses " + std::to_string(def_.timeStep) + " s");
  const auto steps = r.pod<std::int64_t>("engine");
  const double accumulator = r.pod<double>("engine");
  const auto nextScheduled = r.pod<std::uint64_t>("engine");
  if (nextScheduled > schedule_.size())
    r.fail("saved after " + std::to_string(nextScheduled) + " scheduled drops, this engine has only " +
           std::to_string(schedule_.size()));
  const auto pendingCount = r.pod<std::uint64_t>("engine");
  if (pendingCount > 1000000) r.fail("corrupt pending-drop count");
  std::vector<stain::DropDef> pending;
  for (std::uint64_t k = 0; k < pendingCount; ++k) pending.push_back(readDrop(r));
  const double motionTime = r.pod<double>("motion time");

  // Everything into a fresh surface; the engine changes only when all succeeded.
  std::unique_ptr<coupling::CoupledSurface> surface = buildSurface();
  surface->stain().setThreadCount(surface_->stain().threadCount());  // a setting, not saved state
  if (def_.source != MotionSource::Bullet && motionTime > 0) surface->motion().advance(motionTime);
  readMotionState(r, surface->motion());
  Eigen::VectorXd liquidMasses;
  Eigen::MatrixX3d impulses;
  Eigen::Vector3d vapour;
  r.dense(liquidMasses, "coupling.liquidMasses");
  r.dense(impulses, "coupling.impulses");
  for (int c = 0; c < 3; ++c) vapour[c] = r.pod<double>("coupling.evaporatedMomentum");
  try {
    surface->restoreCarriedState(liquidMasses, impulses, vapour);
  } catch (const std::invalid_argument& e) {
    r.fail(e.what());
  }
  stain::StainSolverSnapshot snapshot;
  snapshot.visit(r);
  if (!r.atEnd()) r.fail("unexpected bytes after the state");
  try {
    surface->stain().restore(snapshot);
  } catch (const std::exception& e) {
    r.fail(e.what());
  }
  surface_ = std::move(surface);
  steps_ = steps;
  accumulator_ = accumulator;
  nextScheduled_ = nextScheduled;
  pending_.clear();
  for (const stain::DropDef& d : pending) pending_.push_back(d);
  publishViews();
}

}  // namespace blot::engine
