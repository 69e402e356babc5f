#pragma once
/// One moving surface with its stain: the cloth (any SurfaceMotion: Bullet
/// cloth, mesh sequence, rigid or static) leads, the stain follows, and in
/// two-way mode the liquid's mass and momentum go back into the cloth nodes
/// (docs/coupling.md). CoupledSurface::step is the one place the whole step
/// is written down, top to bottom: cloth → stain geometry → stain stages →
/// exchange with the cloth; blot::Engine adds the fixed-step accumulator,
/// drops, scene loading and outputs on top.
#include <blot/cloth/bullet_cloth.h>
#include <blot/cloth/surface_motion.h>
#include <blot/stain/stain_solver.h>
#include <blot/stain/geometry/surface_topology.h>
#include <blot/stain/geometry/triangle_mesh.h>
#include <Eigen/Core>
#include <memory>
#include <vector>

namespace blot::coupling {

/// OneWay: the cloth moves the stain, the stain does not act on the cloth.
/// TwoWay: liquid mass is added to the cloth nodes and the liquid's momentum
/// exchange is applied to them as impulses. Two-way needs a motion that
/// accepts liquid loads (a simulated cloth; a prescribed motion cannot be
/// pushed back).
enum class CouplingMode { OneWay, TwoWay };

/// Two-way mode: what momentum the free liquid's motion relative to the cloth
/// carries (docs/coupling.md).
///  - Dragged (default): none of its own. The weave drags the film to the
///    cloth's velocity (viscous drag in the fibres), so the cloth carries the
///    liquid's full weight and inertia, and liquid moving between nodes
///    exchanges momentum with them. Robust for any liquid-to-cloth mass ratio.
///  - Free: a frictionless film. The liquid at vertex i moves with vᵢ + Fᵢuᵢ
///    (the stain's u), the cloth carries only what the film does not take
///    (the normal part of its weight, liquid stopping at the hem or soaking
///    in). Exact bookkeeping too, but the exchange is explicit and one step
///    behind: a free film several times heavier than the cloth under it makes
///    the cloth crumple (measured on the 2.5K flag with a 0.17 kg stain on a
///    0.15 kg cloth: edges at 2-25 % of their rest length within 0.5 s).
enum class RelativeMomentum { Dragged, Free };

/// Wall-clock milliseconds of the last step, per part.
struct CoupledStepTimes {
  double cloth = 0, stain = 0, coupling = 0, total = 0;

  /// Every field, once (stain/output_fields.h): Python "last_ms", blotStatistics.
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static constexpr void fields(Self& s, Visitor& v) {
    v.field(stain::outputField("cloth", "cloth", "ms"), s.cloth);
    v.field(stain::outputField("stain", "stain", "ms"), s.stain);
    v.field(stain::outputField("coupling", "coupling", "ms"), s.coupling);
    v.field(stain::outputField("total", "total", "ms"), s.total);
  }
};
static_assert(stain::describesEveryMember<CoupledStepTimes>(),
              "CoupledStepTimes changed: list the new field in CoupledStepTimes::fields");

/// Fills the mesh-derived fields of a ClothDef (rest positions, faces, UVs,
/// edge list, bending pairs, lumped node areas) from a stain mesh, so that
/// cloth/ never needs stain/ types. Other ClothDef fields are left as they are.
void describeClothMesh(const stain::TriangleMesh& mesh, const stain::SurfaceTopology& topology,
                       cloth::ClothDef& def);

class CoupledSurface {
 public:
  /// Takes ownership of the motion. The stain solver is built on
  /// (topology, motion->positions() at time 0, fabric, stainDef), with the
  /// motion's initial velocities. Throws std::invalid_argument naming the
  /// problem (e.g. "coupling mode two-way needs a Bullet cloth source").
  CoupledSurface(std::unique_ptr<cloth::SurfaceMotion> motion, const stain::SurfaceTopology& topology,
                 const stain::FabricField& fabric, const stain::StainSolverDef& stainDef, CouplingMode mode,
                 RelativeMomentum relative = RelativeMomentum::Dragged);
  ~CoupledSurface();
  CoupledSurface(const CoupledSurface&) = delete;
  CoupledSurface& operator=(const CoupledSurface&) = delete;

  /// One step of h seconds: motion->advance(h) → stain geometry on the new
  /// positions (the known rotation of a rigid motion) → stain stages →
  /// coupling loads for the next cloth step (two-way). Each stage is checked
  /// (the cloth: finite positions and velocities, and SurfaceMotion::isHealthy;
  /// the stain: its own stages; the coupling: finite loads). On a failure the
  /// report names the stage and the vertex, and the step is undone by one
  /// rollback (abandonStep): the cloth is back at t exactly
  /// (SurfaceMotion::rollBack), the stain keeps its densities and velocities
  /// of t, and its geometry restarts from the cloth at t. Drops added before
  /// the step stay added.
  stain::StepReport step(double h);

  /// Testing only: arms a fault (stain::InjectedFault) for the step numbered
  /// fault.step (stain().stepCount() + 1 when it runs). Stage::Cloth: an
  /// impulse of 1e30 N·s at the vertex before the cloth step, so the cloth
  /// itself blows up (a motion that accepts loads only); Stage::Coupling: that
  /// vertex's exchange is made non-finite (two-way); a stain stage goes to the
  /// stain. Throws std::invalid_argument for another stage or a bad vertex.
  void injectFaultForTesting(const stain::InjectedFault& fault);

  CouplingMode mode() const { return mode_; }
  RelativeMomentum relativeMomentum() const { return relative_; }
  const cloth::SurfaceMotion& motion() const { return *motion_; }
  cloth::SurfaceMotion& motion() { return *motion_; }
  const stain::StainSolver& stain() const { return *stain_; }
  stain::StainSolver& stain() { return *stain_; }
  const CoupledStepTimes& lastTimes() const { return times_; }

  /// Liquid mass per vertex (kg, #V) as last fed to the cloth (two-way) or as
  /// the stain holds it now (one-way).
  const Eigen::VectorXd& liquidNodeMasses() const { return liquidMasses_; }
  /// Σ (cloth node mass + liquid mass) vᵢ (+ Σ free liquid mass · Fᵢuᵢ with
  /// RelativeMomentum::Free) (kg m/s): the momentum of cloth and liquid
  /// together (pinned nodes included at their node mass; a pinned cloth is
  /// not a closed system).
  /// Includes the impulses computed but not yet applied (pendingImpulses()),
  /// which are momentum already owed to the nodes; liquid masses are read from
  /// the stain state now (a drop added since the last step counts). Without a
  /// Bullet cloth the cloth's own mass is unknown and only the liquid's
  /// momentum is summed. Summed in vertex order, double precision.
  Eigen::Vector3d totalMomentum() const;
  /// Total mass (kg) of cloth (when the motion has node masses; 0 otherwise)
  /// and liquid on it now.
  double totalMass() const;
  /// Impulses (N·s, #V by 3) the last step computed for the next cloth step
  /// (two-way; zero in one-way mode).
  const Eigen::MatrixX3d& pendingImpulses() const { return impulses_; }
  /// Momentum (kg m/s) carried out of the system by evaporated solvent since
  /// construction: vapour leaves with the velocity of the cloth node it left
  /// (docs/coupling.md). totalMomentum() + evaporatedMomentum() is what a
  /// closed system conserves.
  const Eigen::Vector3d& evaporatedMomentum() const { return evaporatedMomentum_; }

  /// Restores what the coupling carries from one step to the next (engine
  /// save/load; the stain and cloth restore their own state): the liquid
  /// masses last fed to the cloth (#V, kg), the impulses owed to it (#V by 3,
  /// N·s) and the vapour momentum so far. Throws std::invalid_argument on a size
  /// mismatch or a load outside cloth::kMaxLiquidLoad's range.
  void restoreCarriedState(const Eigen::VectorXd& liquidMasses, const Eigen::MatrixX3d& impulses,
                           const Eigen::Vector3d& evaporatedMomentum) {
    if (liquidMasses.size() != liquidMasses_.size() || impulses.rows() != impulses_.rows())
      throw std::invalid_argument("CoupledSurface::restoreCarriedState: expected " +
                                  std::to_string(liquidMasses_.size()) + " vertices");
    if (!cloth::massesWithinLoadLimit(liquidMasses))
      throw std::invalid_argument("CoupledSurface::restoreCarriedState: liquid masses must lie in [0, 1e30] kg");
    if (!cloth::impulsesWithinLoadLimit(impulses))
      throw std::invalid_argument("CoupledSurface::restoreCarriedState: impulses must lie within 1e30 N s");
    liquidMasses_ = liquidMasses;
    impulses_ = impulses;
    evaporatedMomentum_ = evaporatedMomentum;
  }

 private:
  void gatherLiquid(Eigen::VectorXd& masses, Eigen::MatrixX3d* relativeMomenta) const;
  /// Two-way, before the cloth moves: the liquid as the stain holds it now (a
  /// drop added since the last step changes it; the cloth must carry that too).
  /// A failed report (a vertex holding more than a node takes) changes nothing.
  stain::StepReport takeLiquidAtStart();
  /// Stage Cloth: keeps the rollback point, advances the motion, checks it.
  stain::StepReport advanceCloth(double h);
  /// Stage Coupling: the loads for the next cloth step (exchangeMomentum).
  /// On a failure it puts back its own carried state before reporting.
  stain::StepReport exchangeWithCloth();
  /// The one rollback of a failed step, whatever stage failed: the cloth back
  /// at t, the stain's state of t with its geometry restarted there. Returns
  /// `report` with the note that the state was restored.
  stain::StepReport abandonStep(stain::StepReport report);
  /// Stage Cloth's check: finite positions and velocities (naming the first
  /// bad vertex), and a healthy motion.
  stain::StepReport checkMotion() const;
  /// World velocity (m/s) of the free liquid at vertex i relative to the
  /// cloth: Fᵢuᵢ, without its outward part at boundary vertices (the edge is
  /// a wall; docs/coupling.md).
  Eigen::Vector3d relativeVelocity(int i) const;

  std::unique_ptr<cloth::SurfaceMotion> motion_;
  // The stain's SurfaceGeometry keeps a pointer to its topology: own a copy so
  // the caller's may go away.
  std::unique_ptr<stain::SurfaceTopology> topology_;
  std::unique_ptr<stain::StainSolver> stain_;
  CouplingMode mode_;
  RelativeMomentum relative_;
  Eigen::VectorXd liquidMasses_;       // #V kg, at the end of the last step (fed to the cloth)
  Eigen::VectorXd startMasses_;        // #V kg, at the start of this step
  Eigen::MatrixX3d startRelative_;     // #V by 3, free mass × F u at the start of this step (kg m/s)
  Eigen::MatrixX3d endRelative_;       // the same after the stain step
  stain::InjectedFault fault_;         // testing: Stage::Cloth or Stage::Coupling
  Eigen::MatrixX3d previousImpulses_;  // #V by 3, the impulses before this step's (restored on a coupling failure)
  // Per vertex: its neighbours before and after it along its boundary loop
  // (the wall direction), or -1 for interior vertices.
  std::vector<int> wallPrevious_, wallNext_;
  Eigen::MatrixX3d impulses_;          // #V by 3 (N·s), owed to the nodes
  Eigen::MatrixX3d positionsBefore_;   // #V by 3: p(t − h) for the stain's first step, where the motion knows it
  Eigen::Vector3d evaporatedMomentum_ = Eigen::Vector3d::Zero();
  CoupledStepTimes times_;
};

}  // namespace blot::coupling
