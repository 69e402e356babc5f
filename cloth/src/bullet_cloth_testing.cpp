// Test-only access to the Bullet body behind a BulletCloth
// (declared in cloth/src/bullet_cloth_testing.h).
#include "bullet_cloth_testing.h"

#include "bullet_cloth_impl.h"

namespace blot::cloth {

using detail::toEigen;

Eigen::MatrixX3i BulletClothTesting::bodyFaces(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX3i faces(body.m_faces.size(), 3);
  for (int f = 0; f < body.m_faces.size(); ++f)
    for (int k = 0; k < 3; ++k) faces(f, k) = static_cast<int>(body.m_faces[f].m_n[k] - &body.m_nodes[0]);
  return faces;
}

Eigen::MatrixX2i BulletClothTesting::bodyLinks(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX2i links(body.m_links.size(), 2);
  for (int l = 0; l < body.m_links.size(); ++l)
    for (int k = 0; k < 2; ++k) links(l, k) = static_cast<int>(body.m_links[l].m_n[k] - &body.m_nodes[0]);
  return links;
}

Eigen::MatrixX3d BulletClothTesting::bodyPositions(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::MatrixX3d positions(body.m_nodes.size(), 3);
  for (int i = 0; i < body.m_nodes.size(); ++i) positions.row(i) = toEigen(body.m_nodes[i].m_x).transpose();
  return positions;
}

Eigen::VectorXd BulletClothTesting::inverseMasses(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::VectorXd im(body.m_nodes.size());
  for (int i = 0; i < body.m_nodes.size(); ++i) im[i] = body.m_nodes[i].m_im;
  return im;
}

Eigen::VectorXd BulletClothTesting::linkConstants(const BulletCloth& cloth) {
  const btSoftBody& body = *cloth.bullet_->body;
  Eigen::VectorXd c0(body.m_links.size());
  for (int l = 0; l < body.m_links.size(); ++l) c0[l] = body.m_links[l].m_c0;
  return c0;
}

void BulletClothTesting::setMassesWithBulletSetMass(BulletCloth& cloth, const Eigen::VectorXd& masses) {
  btSoftBody& body = *cloth.bullet_->body;
  for (int i = 0; i < body.m_nodes.size(); ++i)
    if (!cloth.isPinned(i)) body.setMass(i, static_cast<btScalar>(masses[i]));
}

bool BulletClothTesting::isDisabledByBullet(const BulletCloth& cloth) {
  return cloth.bullet_->body->getActivationState() == DISABLE_SIMULATION;
}

Eigen::Vector3d BulletClothTesting::worldGravity(const BulletCloth& cloth) {
  return toEigen(cloth.bullet_->world->getGravity());
}

Eigen::Vector3d BulletClothTesting::softBodyWorldInfoGravity(const BulletCloth& cloth) {
  return toEigen(cloth.bullet_->world->getWorldInfo().m_gravity);
}

}  // namespace blot::cloth
