#pragma once
/// The momentum exchange of one stain step with the cloth nodes
/// (docs/coupling.md), as a free function of per-vertex stage outputs.
#include <Eigen/Core>

namespace blot::coupling {

/// The impulses that return to the nodes the momentum the stain step moved:
///   Jᵢ = −[(mᵢ' − mᵢ) vᵢ + (mᶠR)ᵢ' − (mᶠR)ᵢ] − eᵢ vᵢ,
/// with m the liquid mass per vertex before and after the step (#V, kg), mᶠR
/// the free liquid's momentum relative to the cloth before and after (#V by 3,
/// kg m/s; zero rows for a dragged film), v the node velocities the step ran
/// at (#V by 3, m/s), and e the solvent each vertex evaporated in the step
/// (#V, kg; StainSolver::evaporatedMass): vapour leaves with its node's
/// velocity, and vapourMomentum (kg m/s) gains Σ eᵢ vᵢ, summed in vertex
/// order. Writes impulses (#V by 3, N·s). Returns the first vertex whose
/// impulse or end mass is not finite or beyond what a cloth node takes
/// (cloth::kMaxLiquidLoad), or −1.
int exchangeMomentum(const Eigen::VectorXd& startMasses, const Eigen::VectorXd& endMasses,
                     const Eigen::MatrixX3d& startRelative, const Eigen::MatrixX3d& endRelative,
                     const Eigen::MatrixX3d& nodeVelocities, const Eigen::VectorXd& evaporatedMass,
                     Eigen::MatrixX3d& impulses, Eigen::Vector3d& vapourMomentum);

}  // namespace blot::coupling
