// Engine::save / Engine::load: the whole simulation state in one binary file.
//
// Design note: docs/design-notes.md, "engine/src/engine_state.cpp".
#include <blot/engine/engine.h>

#include <blot/cloth/surface_motion.h>
#include <blot/stain/io/atomic_file.h>
#include <blot/stain/io/bounded_read.h>
#include <blot/stain/content_hash.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <fstream>
#include <iterator>
#include <sstream>
#include <type_traits>

namespace blot::engine {
namespace {

constexpr char kMagic[8] = {'B', 'L', 'O', 'T', 'S', 'T', 'A', 'T'};
constexpr std::uint32_t kVersion = 7;  // 2: field lists; 3: drops carry relativeVelocity and velocityIsWorld;
                                       // 4: the run counters (drops applied, refreshes, term steps);
                                       // 5: geometry without previousRotations, with nextSlotKind,
                                       //    Bullet pins moved at runtime (movedPins, pinTargets);
                                       // 6: the stain's writtenOutside (a write through mutableState);
                                       // 7: a trailing checksum (kChecksumBytes)

/// The file ends with the 64-bit FNV-1a (stain/content_hash.h) of every byte
/// before it: a file changed or damaged after it was written is refused as
/// such, not read as a different, finite state.
constexpr std::size_t kChecksumBytes = sizeof(std::uint64_t);

std::uint64_t checksumOf(const char* data, std::size_t bytes) {
  std::uint64_t hash = stain::kContentHashBasis;
  stain::hashBytes(hash, data, bytes);
  return hash;
}

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
    // Real and complex entries alike (u is stored complex: a NaN there
    // loaded and failed every step after it).
    if constexpr (!std::is_integral_v<typename Derived::Scalar>) {
      for (Eigen::Index k = 0; k < m.size(); ++k)
        if (!finite(m.data()[k]))
          fail(std::string(what) + ": entry " + std::to_string(k) + " of " + std::to_string(m.size()) + " is not finite");
    }
  }
  template <typename Scalar>
  void sparse(Eigen::SparseMatrix<Scalar>& m, const char* what) {
    const auto rows = pod<std::int64_t>(what), cols = pod<std::int64_t>(what), nnz = pod<std::int64_t>(what);
    const auto limit = static_cast<std::int64_t>(bytes_.size());
    if (rows < 0 || cols < 0 || nnz < 0 || rows >= limit || cols >= limit || nnz > limit ||
        rows > std::numeric_limits<int>::max() || (rows > 0 && cols > 0 && nnz / rows > cols))
      fail(std::string("bad shape of ") + what + " (" + std::to_string(rows) + " x " + std::to_string(cols) + ", " +
           std::to_string(nnz) + " non-zeros)");
    check(static_cast<std::size_t>(cols + 1) * sizeof(int), what);
    std::vector<int> outer(static_cast<std::size_t>(cols + 1));
    take(outer.data(), outer.size() * sizeof(int), what);
    check(static_cast<std::size_t>(nnz) * (sizeof(int) + sizeof(Scalar)), what);
    std::vector<int> inner(static_cast<std::size_t>(nnz));
    std::vector<Scalar> values(static_cast<std::size_t>(nnz));
    take(inner.data(), inner.size() * sizeof(int), what);
    take(values.data(), values.size() * sizeof(Scalar), what);
    // The compressed-column structure CHOLMOD and Eigen assume without
    // checking: column pointers from 0 to nnz, never decreasing; row indices
    // inside the matrix and strictly increasing within a column.
    if (outer.front() != 0 || outer.back() != nnz)
      fail(std::string("corrupt sparse matrix ") + what + ": column pointers run from " + std::to_string(outer.front()) +
           " to " + std::to_string(outer.back()) + ", expected 0 to " + std::to_string(nnz));
    for (std::int64_t c = 0; c < cols; ++c) {
      const int begin = outer[static_cast<std::size_t>(c)], end = outer[static_cast<std::size_t>(c + 1)];
      // Checked before the column's entries are read: the last pointer being
      // nnz does not bound the ones before it until all are non-decreasing.
      if (end < begin)
        fail(std::string("corrupt sparse matrix ") + what + ": column pointer " + std::to_string(c + 1) + " (" +
             std::to_string(end) + ") is below column pointer " + std::to_string(c) + " (" + std::to_string(begin) + ")");
      if (end > nnz)
        fail(std::string("corrupt sparse matrix ") + what + ": column pointer " + std::to_string(c + 1) + " (" +
             std::to_string(end) + ") is beyond the " + std::to_string(nnz) + " non-zeros");
      for (int k = begin; k < end; ++k) {
        const int row = inner[static_cast<std::size_t>(k)];
        if (row < 0 || row >= rows || (k > begin && row <= inner[static_cast<std::size_t>(k - 1)]))
          fail(std::string("corrupt sparse matrix ") + what + ": column " + std::to_string(c) + " has row index " +
               std::to_string(row) + " (entry " + std::to_string(k) + "); expected increasing indices in [0, " +
               std::to_string(rows) + ")");
      }
    }
    for (std::int64_t k = 0; k < nnz; ++k)
      if (!finite(values[static_cast<std::size_t>(k)]))
        fail(std::string(what) + ": entry " + std::to_string(k) + " is not finite");
    m = Eigen::Map<const Eigen::SparseMatrix<Scalar>>(rows, cols, nnz, outer.data(), inner.data(), values.data());
  }
  template <typename T>
  void vector(std::vector<T>& v, const char* what) {
    const auto n = pod<std::uint64_t>(what);
    if (n > bytes_.size()) fail(std::string("corrupt length of ") + what);
    check(n * sizeof(T), what);
    v.resize(n);
    take(v.data(), n * sizeof(T), what);
    if constexpr (std::is_floating_point_v<T>) {
      for (std::size_t k = 0; k < v.size(); ++k)
        if (!std::isfinite(v[k])) fail(std::string(what) + ": entry " + std::to_string(k) + " is not finite");
    } else if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) {
      for (std::size_t k = 0; k < v.size(); ++k)
        if (!v[k].allFinite()) fail(std::string(what) + ": entry " + std::to_string(k) + " is not finite");
    } else if constexpr (std::is_base_of_v<Eigen::QuaternionBase<T>, T>) {
      for (std::size_t k = 0; k < v.size(); ++k)
        if (!v[k].coeffs().allFinite()) fail(std::string(what) + ": entry " + std::to_string(k) + " is not finite");
    }
  }
  template <typename Scalar>
  static bool finite(const Scalar& x) {
    if constexpr (std::is_floating_point_v<Scalar>) return std::isfinite(x);
    else return std::isfinite(x.real()) && std::isfinite(x.imag());
  }
  bool atEnd() const { return offset_ == bytes_.size(); }
  /// Checks the trailing checksum against every byte before it and drops it,
  /// so that the fields end where it began.
  void verifyChecksum() {
    if (bytes_.size() < offset_ + kChecksumBytes) fail("truncated: no checksum at the end");
    const std::size_t body = bytes_.size() - kChecksumBytes;
    std::uint64_t stored;
    std::memcpy(&stored, bytes_.data() + body, kChecksumBytes);
    const std::uint64_t computed = checksumOf(bytes_.data(), body);
    if (stored != computed) {
      std::ostringstream s;
      s << "checksum mismatch (stored " << std::hex << stored << ", computed " << computed
        << "): the file was cut short, changed or damaged after it was written";
      fail(s.str());
    }
    bytes_.resize(body);
  }
  std::size_t remaining() const { return bytes_.size() - offset_; }
  /// A double that must be finite (the engine's own fields).
  double finiteValue(const char* what) {
    const double v = pod<double>(what);
    if (!std::isfinite(v)) fail(std::string(what) + " is not finite");
    return v;
  }

  /// A state struct's field, read in place (errors name it).
  template <typename T>
  void field(const char* name, T& value) {
    read(value, name);
  }

 private:
  void read(double& v, const char* name) {
    v = pod<double>(name);
    if (!std::isfinite(v)) fail(std::string(name) + " is not finite");
  }
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
  for (int c = 0; c < 3; ++c) d.centerPoint[c] = r.finiteValue("drop.centerPoint");
  d.radius = r.finiteValue("drop.radius");
  d.solventMass = r.finiteValue("drop.solventMass");
  d.soluteMass = r.finiteValue("drop.soluteMass");
  for (int c = 0; c < 3; ++c) d.velocity[c] = r.finiteValue("drop.velocity");
  d.splashSpeed = r.finiteValue("drop.splashSpeed");
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

/// The most bytes a state file of this mesh can take: 1 MiB plus 16 KiB per
/// vertex and face (a saved two-way Bullet flag takes about 1.4 KiB per
/// vertex), never more than stain::kStateFileByteLimit.
std::size_t stateFileByteBudget(Eigen::Index vertices, Eigen::Index faces) {
  const double budget = double(1 << 20) + double(16 << 10) * double(vertices + faces);
  return static_cast<std::size_t>(std::min(budget, double(stain::kStateFileByteLimit)));
}

/// What the stain snapshot must satisfy before it reaches the solver (and
/// CHOLMOD): its step count and clock agree with the engine's, the stiffness
/// matrices are #V by #V, and no density is negative beyond the solver's own
/// tolerance (−1e-12 of the largest, as the stage checks).
void checkSnapshot(const Reader& r, const stain::StainSolverSnapshot& s, std::int64_t engineSteps, double h,
                   Eigen::Index vertices) {
  if (s.steps < 0 || s.steps != engineSteps)
    r.fail("stain step count " + std::to_string(s.steps) + " differs from the engine's " + std::to_string(engineSteps));
  const double expected = static_cast<double>(engineSteps) * h;
  if (!(std::abs(s.time - expected) <= 0.5 * h))
    r.fail("stain time " + std::to_string(s.time) + " s does not match " + std::to_string(engineSteps) +
           " steps of " + std::to_string(h) + " s");
  const auto square = [&](const char* name, Eigen::Index rows, Eigen::Index cols) {
    if ((rows != 0 || cols != 0) && (rows != vertices || cols != vertices))
      r.fail(std::string(name) + " is " + std::to_string(rows) + " x " + std::to_string(cols) + ", expected " +
             std::to_string(vertices) + " x " + std::to_string(vertices));
  };
  square("geometry.intrinsic.densityStiffness", s.geometry.intrinsic.densityStiffness.rows(),
         s.geometry.intrinsic.densityStiffness.cols());
  square("geometry.intrinsic.velocityStiffness", s.geometry.intrinsic.velocityStiffness.rows(),
         s.geometry.intrinsic.velocityStiffness.cols());
  if (!(s.factorizedStep >= 0)) r.fail("factorizedStep " + std::to_string(s.factorizedStep) + " is negative");
  const std::pair<const char*, const Eigen::VectorXd*> fields[] = {
      {"solvent", &s.state.solvent},
      {"solute", &s.state.solute},
      {"absorbedSolvent", &s.state.absorbedSolvent},
      {"absorbedSolute", &s.state.absorbedSolute},
      {"adsorbedSolute", &s.state.adsorbedSolute}};
  for (const auto& [name, field] : fields) {
    if (field->size() == 0) continue;
    const double floor = -1e-12 * std::max(0.0, field->maxCoeff());
    for (Eigen::Index i = 0; i < field->size(); ++i)
      if ((*field)[i] < floor)
        r.fail(std::string("state.") + name + "[" + std::to_string(i) + "] = " + std::to_string((*field)[i]) +
               " is negative");
  }
  // The metric's lengths and areas divide and weigh everything downstream
  // (a negative dual area makes a negative liquid mass for the cloth).
  const stain::IntrinsicGeometry& in = s.geometry.intrinsic;
  const std::pair<const char*, const Eigen::VectorXd*> positive[] = {
      {"geometry.intrinsic.edgeLengths", &in.edgeLengths},
      {"geometry.intrinsic.faceAreas", &in.faceAreas},
      {"geometry.intrinsic.vertexDualAreas", &in.vertexDualAreas},
      {"geometry.inverseBuiltSquaredLengths", &s.geometry.inverseBuiltSquaredLengths}};
  for (const auto& [name, field] : positive)
    for (Eigen::Index i = 0; i < field->size(); ++i)
      if (!((*field)[i] > 0))
        r.fail(std::string(name) + "[" + std::to_string(i) + "] = " + std::to_string((*field)[i]) +
               ", expected > 0");
  // The liquid a vertex holds (its pools times its dual area) is what the
  // coupling hands the cloth: at most what a node takes, or the load is
  // refused here rather than the next step.
  bool sized = in.vertexDualAreas.size() == vertices;
  for (const auto& [name, field] : fields) sized = sized && field->size() == vertices;
  if (sized)  // (otherwise StainSolver::restore refuses the sizes)
    for (int i = 0; i < s.state.vertexCount(); ++i)
      if (!(in.vertexDualAreas[i] * s.state.liquidDensity(i) <= cloth::kMaxLiquidLoad))
        r.fail("the liquid at vertex " + std::to_string(i) + " (dual area " + std::to_string(in.vertexDualAreas[i]) +
               " m^2 times its pools) is more than 1e30 kg, the most a vertex may hold");
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
  // The counters a run reports (blot run's summary.json), so that a resumed
  // run reports the whole run; wall-clock timings are not state.
  w.pod(droppedTime_);
  w.pod<std::int32_t>(dropsApplied_);
  w.pod<std::int32_t>(intrinsicRefreshes_);
  w.pod<std::uint32_t>(static_cast<std::uint32_t>(totals_.termSteps.size()));
  for (const std::int64_t n : totals_.termSteps) w.pod(n);

  w.pod<std::uint64_t>(checksumOf(w.bytes().data(), w.bytes().size()));

  // Atomic: a reader never sees a half-written state.
  try {
    stain::writeFileAtomically(path, w.bytes().data(), w.bytes().size());
  } catch (const std::runtime_error& e) {
    throw StateFileError(e.what());
  }
}

void Engine::load(const std::string& path) {
  if (def_.source == MotionSource::Bullet && def_.cloth.world)
    throw StateFileError(path + ": the cloth lives in the caller's Bullet world, which Blot cannot restore; load "
                                "is for an engine that owns its world");
  std::string text;
  try {
    text = stain::readFileBounded(path, stateFileByteBudget(def_.mesh.vertexPositions.rows(), def_.mesh.faces.rows()),
                                  "the state file");
  } catch (const stain::FileReadError& e) {
    throw StateFileError(e.what());
  }
  Reader r(std::vector<char>(text.begin(), text.end()), path);
  text = std::string();
  char magic[8];
  for (char& c : magic) c = r.pod<char>("magic");
  if (std::memcmp(magic, kMagic, sizeof kMagic) != 0) r.fail("not a Blot state file (bad magic)");
  const auto version = r.pod<std::uint32_t>("version");
  if (version != kVersion)
    r.fail("state file version " + std::to_string(version) + ", this build reads version " + std::to_string(kVersion));
  r.verifyChecksum();
  const auto source = r.pod<std::uint32_t>("motion source");
  if (source != static_cast<std::uint32_t>(def_.source))
    r.fail(std::string("saved from a \"") + (source <= 4 ? motionSourceName(static_cast<MotionSource>(source)) : "?") +
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
  // The engine's step count decides time(), the frame a resumed run starts
  // at and the drop schedule: it must agree with the stain's own count and
  // clock below, so an edited count is refused instead of resumed from.
  if (steps < 0 || steps > (std::int64_t(1) << 52))
    r.fail("step count " + std::to_string(steps) + " is outside [0, 2^52]");
  const double accumulator = r.finiteValue("engine.accumulator");
  if (!(accumulator >= 0 && accumulator <= 1 + 1e-9))
    r.fail("carried frame time " + std::to_string(accumulator) + " steps is outside [0, 1]");
  const auto nextScheduled = r.pod<std::uint64_t>("engine");
  if (nextScheduled > schedule_.size())
    r.fail("saved after " + std::to_string(nextScheduled) + " scheduled drops, this engine has only " +
           std::to_string(schedule_.size()));
  const auto pendingCount = r.pod<std::uint64_t>("engine");
  constexpr std::uint64_t kDropBytes = 4 + 8 * 11;  // what writeDrop writes
  if (pendingCount > r.remaining() / kDropBytes)
    r.fail("pending-drop count " + std::to_string(pendingCount) + " does not fit in the file's " +
           std::to_string(r.remaining()) + " remaining bytes");
  std::vector<stain::DropDef> pending;
  const auto vertexCount = static_cast<std::int32_t>(def_.mesh.vertexPositions.rows());
  for (std::uint64_t k = 0; k < pendingCount; ++k) {
    pending.push_back(readDrop(r));
    const stain::DropDef& d = pending.back();
    if (d.centerVertex < -1 || d.centerVertex >= vertexCount || !(d.radius > 0) || d.solventMass < 0 ||
        d.soluteMass < 0 || d.splashSpeed < 0)
      r.fail("pending drop " + std::to_string(k) + ": vertex " + std::to_string(d.centerVertex) + " of " +
             std::to_string(vertexCount) + ", radius " + std::to_string(d.radius) +
             " m, masses and splash speed must be >= 0");
  }
  const double motionTime = r.finiteValue("motion time");

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
  const double droppedTime = r.finiteValue("counters.droppedTime");
  const auto dropsApplied = r.pod<std::int32_t>("counters.dropsApplied");
  const auto intrinsicRefreshes = r.pod<std::int32_t>("counters.intrinsicRefreshes");
  if (droppedTime < 0 || dropsApplied < 0 || intrinsicRefreshes < 0 || intrinsicRefreshes > steps)
    r.fail("run counters out of range (dropped time " + std::to_string(droppedTime) + " s, " +
           std::to_string(dropsApplied) + " drops, " + std::to_string(intrinsicRefreshes) + " refreshes in " +
           std::to_string(steps) + " steps)");
  if (r.pod<std::uint32_t>("counters.termSteps") != totals_.termSteps.size())
    r.fail("counters.termSteps: saved for another list of step terms");
  decltype(totals_.termSteps) termSteps{};
  for (std::size_t k = 0; k < termSteps.size(); ++k) {
    termSteps[k] = r.pod<std::int64_t>("counters.termSteps");
    if (termSteps[k] < 0 || termSteps[k] > steps)
      r.fail("counters.termSteps[" + std::to_string(k) + "] = " + std::to_string(termSteps[k]) + " is outside [0, " +
             std::to_string(steps) + "]");
  }
  if (!r.atEnd()) r.fail("unexpected bytes after the state");
  checkSnapshot(r, snapshot, steps, def_.timeStep, def_.mesh.vertexPositions.rows());
  try {
    surface->stain().restore(snapshot);
  } catch (const std::exception& e) {
    r.fail(e.what());
  }
  surface_ = std::move(surface);
  steps_ = steps;
  accumulator_ = accumulator;
  droppedTime_ = droppedTime;
  dropsApplied_ = dropsApplied;
  intrinsicRefreshes_ = intrinsicRefreshes;
  totals_.termSteps = termSteps;
  nextScheduled_ = nextScheduled;
  pending_.clear();
  for (const stain::DropDef& d : pending) pending_.push_back(d);
  invalidateViews();
}

}  // namespace blot::engine
