// Building the Bullet body: the balanced tree of node bounding volumes and the
// automatic collision voxel size.
#include "bullet_cloth_impl.h"

#include <LinearMath/btAlignedAllocator.h>

#include <algorithm>
#include <new>
#include <vector>

namespace blot::cloth::detail {

// Balanced btDbvt over the nodes in [begin, end): split at the median along
// the longest axis of their positions (ties by index, so the tree is the same
// everywhere). Tree nodes are allocated the way btDbvt frees them.
btDbvtNode* buildNodeTree(btSoftBody& body, std::vector<int>::iterator begin, std::vector<int>::iterator end,
                          btDbvtNode* parent, btScalar margin) {
  btDbvtNode* tree = new (btAlignedAlloc(sizeof(btDbvtNode), 16)) btDbvtNode();
  tree->parent = parent;
  if (end - begin == 1) {
    btSoftBody::Node& node = body.m_nodes[*begin];
    tree->volume = btDbvtVolume::FromCR(node.m_x, margin);
    tree->data = &node;
    tree->childs[1] = nullptr;  // marks a leaf
    node.m_leaf = tree;
    return tree;
  }
  btVector3 low = body.m_nodes[*begin].m_x, high = low;
  for (auto it = begin; it != end; ++it) {
    low.setMin(body.m_nodes[*it].m_x);
    high.setMax(body.m_nodes[*it].m_x);
  }
  const int axis = (high - low).maxAxis();
  const auto middle = begin + (end - begin) / 2;
  std::nth_element(begin, middle, end, [&](int a, int b) {
    const btScalar xa = body.m_nodes[a].m_x[axis], xb = body.m_nodes[b].m_x[axis];
    return xa < xb || (xa == xb && a < b);
  });
  tree->childs[0] = buildNodeTree(body, begin, middle, tree, margin);
  tree->childs[1] = buildNodeTree(body, middle, end, tree, margin);
  Merge(tree->childs[0]->volume, tree->childs[1]->volume, tree->volume);
  return tree;
}

double automaticVoxelSize(const ClothDef& def) {
  double size = 0.25;  // Bullet's default
  for (const ClothCollider& col : def.colliders) {
    if (col.shape == ClothCollider::Shape::Sphere) size = std::min(size, col.radius / 4);
    if (col.shape == ClothCollider::Shape::Box) size = std::min(size, col.halfExtents.minCoeff() / 4);
  }
  return std::max(size, kMinCollisionVoxelSize);
}

}  // namespace blot::cloth::detail
