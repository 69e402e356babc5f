#pragma once
/// Where the moving mesh comes from: one small interface for every source of
/// vertex positions with fixed connectivity (static mesh, analytic rigid motion,
/// mesh-sequence playback, Bullet soft-body cloth). The stain solver reads
/// positions through it and never sees how they were produced.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace blot::cloth {

/// Reads or writes a motion's dynamic state field by field (engine save/load):
/// SurfaceMotion::visitDynamicState hands it every field once, by name.
class MotionStateVisitor {
 public:
  virtual ~MotionStateVisitor() = default;
  virtual void field(const char* name, double& value) = 0;
  virtual void field(const char* name, bool& value) = 0;
  virtual void field(const char* name, Eigen::MatrixX3d& value) = 0;
  virtual void field(const char* name, Eigen::VectorXd& value) = 0;
  virtual void field(const char* name, std::vector<char>& value) = 0;
};

/// Everything the coupling and the engine need from a cloth, whatever moves
/// it: positions and velocities out; liquid loads in (a simulated cloth);
/// health; the rollback point of a failed step; a known rigid rotation; the
/// dynamic state for save/load. No caller needs the concrete type.
/// The largest liquid load a cloth node takes: 1e30 kg of liquid, or an
/// impulse component of 1e30 N·s. Far beyond any scene (a drop is at most
/// 1e6 kg), and small enough that the node's mass, its inverse and its
/// momentum at 1e6 m/s all stay inside the float range Bullet keeps them in.
/// The coupling turns a load beyond it into a failed step, and a state file
/// holding one is refused at load (docs/reliability.md, finding 8).
inline constexpr double kMaxLiquidLoad = 1e30;
/// True when every mass lies in [0, kMaxLiquidLoad] (NaN does not).
bool massesWithinLoadLimit(const Eigen::VectorXd& masses);
/// True when every impulse component lies within ±kMaxLiquidLoad (NaN does not).
bool impulsesWithinLoadLimit(const Eigen::MatrixX3d& impulses);

class SurfaceMotion {
 public:
  virtual ~SurfaceMotion() = default;
  virtual int vertexCount() const = 0;
  /// Current time, seconds.
  virtual double time() const = 0;
  /// Vertex positions at time(), #V by 3, metres. Valid until the next advance().
  virtual const Eigen::MatrixX3d& positions() const = 0;
  /// Vertex velocities at time(), #V by 3, m/s.
  virtual const Eigen::MatrixX3d& velocities() const = 0;
  /// Moves the surface to time() + h (h > 0, seconds).
  virtual void advance(double h) = 0;
  /// Remembers the present state for rollBack(). The coupled step calls it
  /// before every advance() so that a step failing later (a stain stage, the
  /// coupling) can leave the surface where it was. Allocates nothing after
  /// the first call.
  virtual void keepRollbackPoint() = 0;
  /// Returns to the state of the last keepRollbackPoint(): time, positions
  /// and velocities bit-identical, and the same steps after it. Before any
  /// keepRollbackPoint() it returns to the state at construction.
  virtual void rollBack() = 0;

  /// True for a simulated cloth that takes the liquid's loads (two-way
  /// coupling); a prescribed motion cannot be pushed back.
  virtual bool acceptsLiquidLoads() const { return false; }
  /// Liquid node masses (#V, kg, in [0, kMaxLiquidLoad]) and impulses (#V by
  /// 3, N·s, each component within ±kMaxLiquidLoad) applied at the next
  /// advance(). Throws std::logic_error unless acceptsLiquidLoads().
  virtual void setLiquidLoads(const Eigen::VectorXd& extraNodeMasses, const Eigen::MatrixX3d& nodeImpulses);
  /// The cloth's own node masses (#V, kg), or null when the motion has none
  /// (a prescribed motion).
  virtual const Eigen::VectorXd* clothNodeMasses() const { return nullptr; }
  /// False once the motion has blown up (a Bullet cloth past its limits).
  virtual bool isHealthy() const { return true; }
  /// For a motion known to be rigid: true, with R (a rotation matrix) such
  /// that positions() = R x̄ + c at time(). False otherwise.
  virtual bool knownRotation(Eigen::Matrix3d& rotation) const {
    (void)rotation;
    return false;
  }
  /// The positions h seconds before time(), where the motion knows them
  /// exactly (a rigid motion: R x̄ + c at that time); false otherwise. The
  /// stain's first step takes them for p(t − h) (StainSolver::
  /// setPositionsBeforeFirstStep).
  virtual bool positionsBefore(double h, Eigen::MatrixX3d& out) const {
    (void)h;
    (void)out;
    return false;
  }
  /// False for a motion that never changes the surface's shape (static,
  /// rigid): a stain on it never rebuilds its metric, so nothing is sized for
  /// a rebuild (StainSolver::prepareForDeformation).
  virtual bool deforms() const { return true; }
  /// The dynamic state beyond time() (a simulated cloth's nodes and loads),
  /// one field at a time: save hands the visitor every field to read, load
  /// has it fill them and then takes them (throws std::invalid_argument on a
  /// size mismatch). A motion that is a pure function of its time has none
  /// (hasDynamicState false; both do nothing).
  virtual bool hasDynamicState() const { return false; }
  /// A simulated cloth's pin moved at runtime (BulletCloth::setPinTarget);
  /// throws std::invalid_argument for a motion without pins.
  virtual void setPinTarget(int vertex, const Eigen::Vector3d& position);
  /// The next frame of a caller-supplied surface (CallerMotion::setNextFrame);
  /// throws std::invalid_argument for any other motion.
  virtual void setNextFrame(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d* velocities);
  virtual void setNextFrame(const double* positions, const double* velocities);
  virtual void saveDynamicState(MotionStateVisitor& visitor) const { (void)visitor; }
  virtual void loadDynamicState(MotionStateVisitor& visitor) { (void)visitor; }
};

/// A surface that does not move.
class StaticSurface final : public SurfaceMotion {
 public:
  explicit StaticSurface(const Eigen::MatrixX3d& restPositions);
  int vertexCount() const override { return static_cast<int>(positions_.rows()); }
  double time() const override { return time_; }
  const Eigen::MatrixX3d& positions() const override { return positions_; }
  const Eigen::MatrixX3d& velocities() const override { return velocities_; }
  void advance(double h) override;
  void keepRollbackPoint() override { rollbackTime_ = time_; }
  void rollBack() override { time_ = rollbackTime_; }
  bool deforms() const override { return false; }

 private:
  Eigen::MatrixX3d positions_, velocities_;
  double time_ = 0, rollbackTime_ = 0;
};

/// Positions the caller supplies every step, for a cloth simulated by
/// anything else (the game's own cloth solver, an animation system). Before
/// each advance(h) the caller hands the positions (and, if it knows them, the
/// velocities) at time() + h with setNextFrame(); advance(h) moves to them.
/// Without velocities they are the finite difference (x_next − x) / h.
/// Without a new frame advance(h) holds the surface still (zero velocity).
/// Prescribed: it takes no liquid loads.
/// Largest |coordinate| of a caller's frame (m, m/s): a scene's bound on its
/// magnitudes (engine/scene.h, kMaxSceneMagnitude).
inline constexpr double kMaxFrameMagnitude = 1e6;

class CallerMotion final : public SurfaceMotion {
 public:
  /// The surface at time 0: rest positions (#V by 3, m) and velocities
  /// (#V by 3, m/s; no rows: at rest). Throws std::invalid_argument for other
  /// row counts or non-finite values.
  explicit CallerMotion(const Eigen::MatrixX3d& restPositions,
                        const Eigen::MatrixX3d& initialVelocities = Eigen::MatrixX3d());
  int vertexCount() const override { return static_cast<int>(positions_.rows()); }
  double time() const override { return time_; }
  const Eigen::MatrixX3d& positions() const override { return positions_; }
  const Eigen::MatrixX3d& velocities() const override { return velocities_; }
  /// Moves to the frame given by setNextFrame (h > 0, s). Allocates nothing.
  void advance(double h) override;
  /// Positions (#V by 3, m) at the end of the next advance(), and their
  /// velocities (#V by 3, m/s) or null for the finite difference. Copied
  /// (no allocation after the first call); replaces a frame not yet used.
  /// Throws std::invalid_argument for a wrong row count or a non-finite value.
  void setNextFrame(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3d* velocities = nullptr) override;
  /// The same from raw arrays, #V × 3 doubles each, row-major (x0 y0 z0 x1 …);
  /// velocities may be null.
  void setNextFrame(const double* positions, const double* velocities) override;
  bool hasNextFrame() const { return hasNext_; }
  void keepRollbackPoint() override;
  void rollBack() override;
  /// Time, positions, velocities and the frame not yet used (save/load).
  bool hasDynamicState() const override { return true; }
  void saveDynamicState(MotionStateVisitor& visitor) const override;
  void loadDynamicState(MotionStateVisitor& visitor) override;

 private:
  void checkNext();
  Eigen::MatrixX3d positions_, velocities_, nextPositions_, nextVelocities_;
  bool hasNext_ = false, nextHasVelocities_ = false;
  double time_ = 0;
  Eigen::MatrixX3d keptPositions_, keptVelocities_, keptNextPositions_, keptNextVelocities_;
  bool keptHasNext_ = false, keptNextHasVelocities_ = false;
  double keptTime_ = 0;
};

/// Analytic rigid motion: rotation at constant angular velocity ω (rad/s, world
/// axis) about a pivot that itself moves with constant velocity v and
/// acceleration a:  x(t) = c(t) + exp(t [ω]×) (x̄ − c̄),  c(t) = c̄ + v t + ½ a t².
struct RigidMotionDef {
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();     ///< rad/s
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();               ///< m, at t = 0
  Eigen::Vector3d linearVelocity = Eigen::Vector3d::Zero();      ///< m/s of the pivot
  Eigen::Vector3d linearAcceleration = Eigen::Vector3d::Zero();  ///< m/s² of the pivot
};

class RigidMotion final : public SurfaceMotion {
 public:
  RigidMotion(const Eigen::MatrixX3d& restPositions, const RigidMotionDef& def);
  int vertexCount() const override { return static_cast<int>(rest_.rows()); }
  double time() const override { return time_; }
  const Eigen::MatrixX3d& positions() const override { return positions_; }
  const Eigen::MatrixX3d& velocities() const override { return velocities_; }
  void advance(double h) override;
  void keepRollbackPoint() override { rollbackTime_ = time_; }
  /// Evaluates the closed form at the kept time (the same value of time()
  /// gives the same positions).
  void rollBack() override;
  /// Always true: R = rotationAt(time()).
  bool knownRotation(Eigen::Matrix3d& rotation) const override {
    rotation = rotationAt(time_);
    return true;
  }
  bool deforms() const override { return false; }
  /// R x̄ + c at time() − h, exact, when the motion rotates or accelerates;
  /// false for a constant velocity (or none), where p − h v is exact already.
  bool positionsBefore(double h, Eigen::MatrixX3d& out) const override;

  /// Rotation exp(t [ω]×) at time t.
  Eigen::Matrix3d rotationAt(double t) const;
  /// Pivot position c(t).
  Eigen::Vector3d pivotAt(double t) const;
  const RigidMotionDef& definition() const { return def_; }

 private:
  void evaluate();
  Eigen::MatrixX3d rest_, positions_, velocities_;
  RigidMotionDef def_;
  double time_ = 0, rollbackTime_ = 0;
};

}  // namespace blot::cloth
