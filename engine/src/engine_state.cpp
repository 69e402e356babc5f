// Engine::save / Engine::load: the whole simulation state in one binary file.
//
// Design note. Layout (little-endian, as the host writes it; files are not
// meant to move between architectures):
//   "BLOTSTAT" | u32 version | u32 motion source | i64 #V | i64 #F |
//   u64 mesh fingerprint (FNV-1a of rest positions and faces) | f64 h |
//   engine: i64 steps, f64 accumulator, u64 next scheduled drop, pending drops |
//   motion: f64 time (+ the Bullet cloth's state) | coupling: liquid masses,
//   impulses owed, vapour momentum | stain: StainSolverSnapshot.
// Arrays are written as (rows, cols, raw column-major doubles), sparse
// matrices in compressed form. Everything step() reads is in the file — the
// stain's geometry tiers, its rotation history (it warm-starts the next fit,
// so leaving it out changes the last bits) — which is what makes a loaded run
// bit-identical to the original. Prescribed motions (static, rigid, sequence)
// are pure functions of their time, so their time is enough: a fresh motion
// is advanced to it in one call, landing on the same double.
// Rejected: text/JSON (3-5x larger, slow, and %.17g round-trips need care for
// every array) and memory dumps of the objects (pointers, Bullet internals).
#include <blot/engine/engine.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <type_traits>

namespace blot::engine {
namespace {

constexpr char kMagic[8] = {'B', 'L', 'O', 'T', 'S', 'T', 'A', 'T'};
constexpr std::uint32_t kVersion = 2;  // 2: drops carry relativeVelocity and velocityIsWorld

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

 private:
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

 private:
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
  w.raw(d.relativeVelocity.data(), 3);
  w.pod<std::uint8_t>(d.velocityIsWorld ? 1 : 0);
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
  for (int c = 0; c < 3; ++c) d.relativeVelocity[c] = r.pod<double>("drop");
  d.velocityIsWorld = r.pod<std::uint8_t>("drop") != 0;
  return d;
}

// A field added to these structs must be added to the file too (or loaded runs
// stop being bit-identical, as EngineTest.*SaveThenLoad* would show): these
// sizes break the build here first. Update writeSnapshot/readSnapshot, bump
// kVersion, then the sizes.
static_assert(sizeof(stain::ExtrinsicGeometry) == 6 * sizeof(stain::RowVectors3) + 4 * sizeof(std::vector<stain::Matrix3>) + 8,
              "ExtrinsicGeometry changed: update the state file");
static_assert(sizeof(stain::IntrinsicGeometry) ==
                  7 * sizeof(stain::Vector) + 2 * sizeof(Eigen::MatrixX3d) + sizeof(stain::SparseMatrix) +
                      sizeof(stain::ComplexSparseMatrix) + 8,
              "IntrinsicGeometry changed: update the state file");
static_assert(sizeof(stain::StainState) == 5 * sizeof(stain::Vector) + sizeof(stain::ComplexVector) + 3 * sizeof(double),
              "StainState changed: update the state file");

void writeSnapshot(Writer& w, const stain::StainSolverSnapshot& s) {
  const stain::StainState& st = s.state;
  w.dense(st.velocities);
  w.dense(st.solvent);
  w.dense(st.solute);
  w.dense(st.absorbedSolvent);
  w.dense(st.absorbedSolute);
  w.dense(st.adsorbedSolute);
  w.pod(st.evaporatedSolvent);
  w.pod(st.addedSolvent);
  w.pod(st.addedSolute);
  const stain::IntrinsicGeometry& in = s.geometry.intrinsic;
  w.dense(in.edgeLengths);
  w.dense(in.faceCornerAngles);
  w.dense(in.faceAreas);
  w.dense(in.edgeCotanWeights);
  w.dense(in.vertexDualAreas);
  w.dense(in.polarMap.ringAngles);
  w.dense(in.polarMap.vertexAngleScales);
  w.dense(in.edgeTransportAngles);
  w.dense(in.faceTransportAngles);
  w.sparse(in.densityStiffness);
  w.sparse(in.velocityStiffness);
  w.pod<std::int32_t>(in.rebuildCount);
  const stain::ExtrinsicGeometry& ex = s.geometry.extrinsic;
  w.dense(ex.previousPositions);
  w.dense(ex.positions);
  w.dense(ex.nextPositions);
  w.dense(ex.vertexNormals);
  w.vector(ex.restFrames);
  w.vector(ex.frames);
  w.vector(ex.nextFrames);
  w.vector(ex.kabschRotations);
  w.dense(ex.vertexAccelerations);
  w.dense(ex.vertexAngularVelocities);
  w.pod<std::uint8_t>(ex.rigid ? 1 : 0);
  w.pod<std::uint8_t>(ex.nextRigid ? 1 : 0);
  w.dense(s.geometry.nextNormals);
  w.vector(s.geometry.previousRotations);
  w.vector(s.geometry.rotations);
  w.vector(s.geometry.nextRotations);
  w.dense(s.geometry.inverseBuiltSquaredLengths);
  w.pod(s.geometry.maxEdgeStrain);
  w.pod(s.geometry.lastH);
  w.pod<std::int32_t>(s.geometry.unchangedRefreshes);
  w.pod<std::uint64_t>(s.heldRegions.size());
  for (const stain::HeldRegion& region : s.heldRegions) {
    w.vector(region.vertices);
    w.pod(region.solventDensity);
    w.pod(region.soluteDensity);
  }
  w.dense(s.initialVelocities);
  w.pod(s.factorizedStep);
  w.pod(s.time);
  w.pod<std::int32_t>(s.steps);
  w.pod<std::uint8_t>(s.started ? 1 : 0);
}

void readSnapshot(Reader& r, stain::StainSolverSnapshot& s) {
  stain::StainState& st = s.state;
  r.dense(st.velocities, "state.velocities");
  r.dense(st.solvent, "state.solvent");
  r.dense(st.solute, "state.solute");
  r.dense(st.absorbedSolvent, "state.absorbedSolvent");
  r.dense(st.absorbedSolute, "state.absorbedSolute");
  r.dense(st.adsorbedSolute, "state.adsorbedSolute");
  st.evaporatedSolvent = r.pod<double>("state");
  st.addedSolvent = r.pod<double>("state");
  st.addedSolute = r.pod<double>("state");
  stain::IntrinsicGeometry& in = s.geometry.intrinsic;
  r.dense(in.edgeLengths, "intrinsic");
  r.dense(in.faceCornerAngles, "intrinsic");
  r.dense(in.faceAreas, "intrinsic");
  r.dense(in.edgeCotanWeights, "intrinsic");
  r.dense(in.vertexDualAreas, "intrinsic");
  r.dense(in.polarMap.ringAngles, "intrinsic");
  r.dense(in.polarMap.vertexAngleScales, "intrinsic");
  r.dense(in.edgeTransportAngles, "intrinsic");
  r.dense(in.faceTransportAngles, "intrinsic");
  r.sparse(in.densityStiffness, "intrinsic.densityStiffness");
  r.sparse(in.velocityStiffness, "intrinsic.velocityStiffness");
  in.rebuildCount = r.pod<std::int32_t>("intrinsic");
  stain::ExtrinsicGeometry& ex = s.geometry.extrinsic;
  r.dense(ex.previousPositions, "extrinsic");
  r.dense(ex.positions, "extrinsic");
  r.dense(ex.nextPositions, "extrinsic");
  r.dense(ex.vertexNormals, "extrinsic");
  r.vector(ex.restFrames, "extrinsic");
  r.vector(ex.frames, "extrinsic");
  r.vector(ex.nextFrames, "extrinsic");
  r.vector(ex.kabschRotations, "extrinsic");
  r.dense(ex.vertexAccelerations, "extrinsic");
  r.dense(ex.vertexAngularVelocities, "extrinsic");
  ex.rigid = r.pod<std::uint8_t>("extrinsic") != 0;
  ex.nextRigid = r.pod<std::uint8_t>("extrinsic") != 0;
  r.dense(s.geometry.nextNormals, "geometry");
  r.vector(s.geometry.previousRotations, "geometry");
  r.vector(s.geometry.rotations, "geometry");
  r.vector(s.geometry.nextRotations, "geometry");
  r.dense(s.geometry.inverseBuiltSquaredLengths, "geometry");
  s.geometry.maxEdgeStrain = r.pod<double>("geometry");
  s.geometry.lastH = r.pod<double>("geometry");
  s.geometry.unchangedRefreshes = r.pod<std::int32_t>("geometry");
  const auto regions = r.pod<std::uint64_t>("held regions");
  if (regions > 1000000) r.fail("corrupt held-region count");
  s.heldRegions.resize(regions);
  for (stain::HeldRegion& region : s.heldRegions) {
    r.vector(region.vertices, "held region");
    region.solventDensity = r.pod<double>("held region");
    region.soluteDensity = r.pod<double>("held region");
  }
  r.dense(s.initialVelocities, "initial velocities");
  s.factorizedStep = r.pod<double>("solver");
  s.time = r.pod<double>("solver");
  s.steps = r.pod<std::int32_t>("solver");
  s.started = r.pod<std::uint8_t>("solver") != 0;
}

/// The Bullet cloth's state (nodes, pins, pending liquid loads), or a 0 marker.
void writeClothState(Writer& w, const cloth::BulletCloth* cloth) {
  w.pod<std::uint8_t>(cloth != nullptr ? 1 : 0);
  if (cloth == nullptr) return;
  const cloth::BulletClothState s = cloth->captureState();
  w.pod(s.time);
  w.dense(s.positions);
  w.dense(s.previousPositions);
  w.dense(s.velocities);
  w.dense(s.previousVelocities);
  w.dense(s.forces);
  w.dense(s.nodeNormals);
  w.dense(s.nodeAreas);
  w.dense(s.faceNormals);
  w.dense(s.inverseMasses);
  w.dense(s.nodeMasses);
  w.dense(s.pendingExtraMasses);
  w.dense(s.pendingImpulses);
  w.pod<std::uint8_t>(s.loadsPending ? 1 : 0);
  w.vector(s.releasedPins);
}

void readClothState(Reader& r, coupling::CoupledSurface& surface) {
  const bool hasCloth = r.pod<std::uint8_t>("cloth marker") != 0;
  if (hasCloth != (surface.bulletCloth() != nullptr)) r.fail("cloth state marker does not match the motion source");
  if (!hasCloth) return;
  cloth::BulletClothState s;
  s.time = r.pod<double>("cloth");
  r.dense(s.positions, "cloth.positions");
  r.dense(s.previousPositions, "cloth.previousPositions");
  r.dense(s.velocities, "cloth.velocities");
  r.dense(s.previousVelocities, "cloth.previousVelocities");
  r.dense(s.forces, "cloth.forces");
  r.dense(s.nodeNormals, "cloth.nodeNormals");
  r.dense(s.nodeAreas, "cloth.nodeAreas");
  r.dense(s.faceNormals, "cloth.faceNormals");
  r.dense(s.inverseMasses, "cloth.inverseMasses");
  r.dense(s.nodeMasses, "cloth.nodeMasses");
  r.dense(s.pendingExtraMasses, "cloth.pendingExtraMasses");
  r.dense(s.pendingImpulses, "cloth.pendingImpulses");
  s.loadsPending = r.pod<std::uint8_t>("cloth") != 0;
  r.vector(s.releasedPins, "cloth.releasedPins");
  try {
    dynamic_cast<cloth::BulletCloth&>(surface.motion()).restoreState(s);
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
  writeClothState(w, surface_->bulletCloth());
  w.dense(surface_->liquidNodeMasses());
  w.dense(surface_->pendingImpulses());
  w.raw(surface_->evaporatedMomentum().data(), 3);
  writeSnapshot(w, surface_->stain().snapshot());

  // Write-then-rename: a reader never sees a half-written state.
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw StateFileError(path + ": cannot open for writing");
    out.write(w.bytes().data(), static_cast<std::streamsize>(w.bytes().size()));
    if (!out) throw StateFileError(path + ": write failed");
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) throw StateFileError(path + ": cannot rename " + temporary);
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
  if (def_.source != MotionSource::Bullet && motionTime > 0) surface->motion().advance(motionTime);
  readClothState(r, *surface);
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
  readSnapshot(r, snapshot);
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
