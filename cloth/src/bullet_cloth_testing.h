#pragma once
/// Test-only access to the Bullet body behind a BulletCloth (private header:
/// only blot_cloth and its tests see cloth/src). No Bullet type leaks here
/// either; everything is read or written through Eigen arrays.
#include <blot/cloth/bullet_cloth.h>

#include <Eigen/Core>

namespace blot::cloth {

struct BulletClothTesting {
  /// Bullet's faces as node indices (#F by 3), read from the body.
  static Eigen::MatrixX3i bodyFaces(const BulletCloth& cloth);
  /// Bullet's links as node indices (#L by 2), read from the body.
  static Eigen::MatrixX2i bodyLinks(const BulletCloth& cloth);
  /// Bullet's node positions (#V by 3), read from the body now.
  static Eigen::MatrixX3d bodyPositions(const BulletCloth& cloth);
  /// Node inverse masses m_im (#V, 1/kg; 0 = pinned).
  static Eigen::VectorXd inverseMasses(const BulletCloth& cloth);
  /// Link constants m_c0 = (m_im,a + m_im,b) / kLST (#L).
  static Eigen::VectorXd linkConstants(const BulletCloth& cloth);
  /// The trap, for tests that demonstrate it: btSoftBody::setMass on every
  /// free node (mass in kg, #V). Bullet then resets every link's rest length
  /// to its current length at the start of the next step.
  static void setMassesWithBulletSetMass(BulletCloth& cloth, const Eigen::VectorXd& masses);
  /// True when Bullet has switched the body off (activation state DISABLE_SIMULATION).
  static bool isDisabledByBullet(const BulletCloth& cloth);
  /// Gravity as the dynamics world and as the soft-body world info hold it (m/s²).
  static Eigen::Vector3d worldGravity(const BulletCloth& cloth);
  static Eigen::Vector3d softBodyWorldInfoGravity(const BulletCloth& cloth);
};

}  // namespace blot::cloth
