#pragma once
/// Liquid mass and momentum per cloth node (docs/coupling.md).
///
/// The stain stores surface densities (kg/m²) per vertex; the cloth has point
/// masses per node. With lumped (barycentric) mass, a vertex owns one third of
/// its one-ring area A_i, so node i carries m_i = A_i Σ_c σ_c,i of liquid, summed
/// over the components c that ride with the cloth (free and absorbed solvent and
/// solute, adsorbed solute). Σ_i m_i is then exactly the liquid mass on the surface.
#include <Eigen/Core>

namespace blot::coupling {

/// nodeMasses (#V, kg) = vertexDualAreas (#V, m²) ⊙ row sums of surfaceDensities
/// (#V by C, kg/m²). nodeMasses is resized only if needed (no allocation in a
/// steady loop). Throws std::invalid_argument naming the vertex and component if
/// a density is negative or non-finite, or if sizes disagree.
void liquidNodeMasses(const Eigen::VectorXd& vertexDualAreas, const Eigen::MatrixXd& surfaceDensities,
                      Eigen::VectorXd& nodeMasses);

/// Total linear momentum Σ m_i v_i (kg m/s) of point masses (#V) with velocities (#V by 3),
/// summed in index order (deterministic).
Eigen::Vector3d totalMomentum(const Eigen::VectorXd& nodeMasses, const Eigen::MatrixX3d& velocities);

}  // namespace blot::coupling
