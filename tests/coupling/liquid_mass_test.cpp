// Liquid node masses: exact sums, and bad densities named by vertex and component.
#include <blot/coupling/liquid_mass.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace blot::coupling {
namespace {

TEST(LiquidMass, NodeMassIsAreaTimesSummedDensity) {
  Eigen::VectorXd areas(3);
  areas << 0.5, 0.25, 2.0;
  Eigen::MatrixXd densities(3, 2);
  densities << 1.0, 0.5, 0.0, 0.0, 0.25, 4.0;
  Eigen::VectorXd masses;
  liquidNodeMasses(areas, densities, masses);
  EXPECT_DOUBLE_EQ(masses[0], 0.75);
  EXPECT_DOUBLE_EQ(masses[1], 0.0);
  EXPECT_DOUBLE_EQ(masses[2], 8.5);
  Eigen::MatrixX3d v(3, 3);
  v << 1, 0, 0, 5, 5, 5, 0, 2, -1;
  const Eigen::Vector3d p = totalMomentum(masses, v);
  EXPECT_DOUBLE_EQ(p.x(), 0.75);
  EXPECT_DOUBLE_EQ(p.y(), 17.0);
  EXPECT_DOUBLE_EQ(p.z(), -8.5);
}

TEST(LiquidMass, RejectsNegativeOrNonFiniteDensityNamingTheVertex) {
  Eigen::VectorXd areas = Eigen::VectorXd::Ones(2), masses;
  Eigen::MatrixXd densities = Eigen::MatrixXd::Zero(2, 3);
  densities(1, 2) = -1e-3;
  try {
    liquidNodeMasses(areas, densities, masses);
    FAIL() << "negative density accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 1 component 2"), std::string::npos) << e.what();
  }
  densities(1, 2) = std::nan("");
  EXPECT_THROW(liquidNodeMasses(areas, densities, masses), std::invalid_argument);
  EXPECT_THROW(liquidNodeMasses(Eigen::VectorXd::Ones(3), densities, masses), std::invalid_argument);
}

}  // namespace
}  // namespace blot::coupling
