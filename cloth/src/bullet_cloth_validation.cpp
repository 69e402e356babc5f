// Validation of a ClothDef (mesh arrays and parameters) before a BulletCloth is
// built from it; every error names the field and row.
#include "bullet_cloth_impl.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace blot::cloth::detail {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("ClothDef: " + what);
}

namespace {

// The same for checks inside per-row loops: the message is built only on
// failure (building it for every row was a quarter of a 140K cloth's load).
template <class Message>
void requireEach(bool ok, const Message& message) {
  if (!ok) require(false, message());
}

bool inUnitInterval(double x) { return x >= 0 && x <= 1; }

std::string at(const char* field, Eigen::Index row) { return std::string(field) + "[" + std::to_string(row) + "]"; }

// The mesh arrays: shapes, finiteness, index ranges, each error naming the
// field and row. Manifoldness is the describer's job (coupling::describeClothMesh
// builds them through stain::SurfaceTopology, which rejects non-manifold meshes).
void validateMesh(const ClothDef& def) {
  const Eigen::Index n = def.restPositions.rows();
  require(n > 0, "restPositions is empty (#V by 3 expected)");
  require(def.faces.rows() > 0, "faces is empty (#F by 3 expected)");
  for (Eigen::Index i = 0; i < n; ++i)
    requireEach(def.restPositions.row(i).allFinite(), [&] { return at("restPositions", i) + " is not finite"; });
  for (Eigen::Index f = 0; f < def.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      requireEach(def.faces(f, k) >= 0 && def.faces(f, k) < n, [&] {
        return at("faces", f) + " has vertex " + std::to_string(def.faces(f, k)) + " outside [0, " + std::to_string(n) + ")";
      });
    requireEach(def.faces(f, 0) != def.faces(f, 1) && def.faces(f, 1) != def.faces(f, 2) && def.faces(f, 2) != def.faces(f, 0),
                [&] { return at("faces", f) + " repeats a vertex (degenerate face)"; });
  }
  require(def.uvs.rows() == 0 || def.uvs.rows() == n,
          "uvs has " + std::to_string(def.uvs.rows()) + " rows; expected " + std::to_string(n) + " (one per vertex) or 0");
  for (Eigen::Index i = 0; i < def.uvs.rows(); ++i)
    requireEach(def.uvs.row(i).allFinite(), [&] { return at("uvs", i) + " is not finite"; });
  require(def.edges.rows() > 0, "edges is empty (#E by 2 expected)");
  auto checkPairs = [n](const Eigen::MatrixX2i& pairs, const char* field) {
    for (Eigen::Index e = 0; e < pairs.rows(); ++e) {
      requireEach(pairs(e, 0) >= 0 && pairs(e, 0) < n && pairs(e, 1) >= 0 && pairs(e, 1) < n, [&] {
        return at(field, e) + " = (" + std::to_string(pairs(e, 0)) + ", " + std::to_string(pairs(e, 1)) +
               ") has a vertex outside [0, " + std::to_string(n) + ")";
      });
      requireEach(pairs(e, 0) != pairs(e, 1),
                  [&] { return at(field, e) + " joins vertex " + std::to_string(pairs(e, 0)) + " to itself"; });
    }
  };
  checkPairs(def.edges, "edges");
  checkPairs(def.bendingPairs, "bendingPairs");
  require(def.nodeAreas.size() == n,
          "nodeAreas has " + std::to_string(def.nodeAreas.size()) + " entries; expected " + std::to_string(n));
  for (Eigen::Index i = 0; i < n; ++i)
    requireEach(std::isfinite(def.nodeAreas[i]) && def.nodeAreas[i] >= 0, [&] {
      return at("nodeAreas", i) + " = " + std::to_string(def.nodeAreas[i]) + " (expected finite and >= 0, m²)";
    });
  require(def.nodeAreas.sum() > 0, "nodeAreas sum to zero (the mesh has no area)");
}

}  // namespace

void validate(const ClothDef& def) {
  validateMesh(def);
  require(def.body == nullptr || def.world != nullptr, "body is set but world is null (a caller's body lives in the caller's world)");
  require(std::isfinite(def.totalMass) && def.totalMass > 0, "totalMass must be positive (kg)");
  {
    // The lightest node's mass (its share of the area) must have a float
    // inverse: 1e-300 kg became an infinite inverse mass in Bullet, and the
    // first failed step could not be rolled back.
    double lightest = std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < def.nodeAreas.size(); ++i)
      if (def.nodeAreas[i] > 0) lightest = std::min(lightest, def.nodeAreas[i]);
    const double share = lightest / def.nodeAreas.sum();
    if (!(def.totalMass * share >= kMinNodeMass)) {
      std::ostringstream message;
      message << std::setprecision(12) << "totalMass = " << def.totalMass << " kg gives the lightest node "
              << def.totalMass * share << " kg, below " << kMinNodeMass
              << " kg (Bullet keeps 1 / mass in a float): expected at least " << kMinNodeMass / share << " kg";
      require(false, message.str());
    }
  }
  require(def.stretchStiffness > 0 && def.stretchStiffness <= 1, "stretchStiffness must be in (0, 1]");
  require(def.shearStiffness > 0 && def.shearStiffness <= 1, "shearStiffness must be in (0, 1]");
  require(inUnitInterval(def.bendStiffness), "bendStiffness must be in [0, 1]");
  require(std::isfinite(def.dampingRate) && def.dampingRate >= 0, "dampingRate must be >= 0 (1/s)");
  require(def.positionIterations >= 1, "positionIterations must be >= 1");
  require(def.velocityIterations >= 0, "velocityIterations must be >= 0");
  require(def.driftIterations >= 0, "driftIterations must be >= 0");
  require(def.substeps >= 1, "substeps must be >= 1");
  require(std::isfinite(def.tetherSlack) && def.tetherSlack >= 0, "tetherSlack must be >= 0");
  require(def.gravity.allFinite(), "gravity must be finite");
  require(def.wind.velocity.allFinite(), "wind.velocity must be finite");
  require(std::isfinite(def.wind.dragCoefficient) && def.wind.dragCoefficient >= 0, "wind.dragCoefficient must be >= 0");
  require(std::isfinite(def.wind.liftCoefficient) && def.wind.liftCoefficient >= 0, "wind.liftCoefficient must be >= 0");
  require(std::isfinite(def.wind.airDensity) && def.wind.airDensity >= 0, "wind.airDensity must be >= 0 (kg/m³)");
  require(def.contactHardness > 0 && def.contactHardness <= 1, "contactHardness must be in (0, 1]");
  require(std::isfinite(def.collisionMargin) && def.collisionMargin >= 0, "collisionMargin must be >= 0 (m)");
  if (!(def.collisionVoxelSize == 0 ||
        (def.collisionVoxelSize >= kMinCollisionVoxelSize && std::isfinite(def.collisionVoxelSize)))) {
    std::ostringstream message;
    message << std::setprecision(12) << "collisionVoxelSize must be 0 (automatic) or in [" << kMinCollisionVoxelSize
            << ", inf) m, got " << def.collisionVoxelSize;
    require(false, message.str());
  }
  const auto vertexCount = def.restPositions.rows();
  std::vector<char> seen(static_cast<size_t>(vertexCount), 0);
  for (size_t p = 0; p < def.pins.size(); ++p) {
    const ClothPin& pin = def.pins[p];
    const std::string name = "pins[" + std::to_string(p) + "]";
    require(pin.vertex >= 0 && pin.vertex < vertexCount, name + ".vertex out of range");
    require(!seen[static_cast<size_t>(pin.vertex)], name + ".vertex pinned twice");
    seen[static_cast<size_t>(pin.vertex)] = 1;
    const PinMotion& m = pin.motion;
    require(m.velocity.allFinite() && m.amplitude.allFinite() && std::isfinite(m.frequency) &&
                std::isfinite(m.phase) && !std::isnan(m.releaseTime),
            name + ".motion must be finite (releaseTime may be +inf)");
  }
  for (size_t c = 0; c < def.colliders.size(); ++c) {
    const ClothCollider& col = def.colliders[c];
    const std::string name = "colliders[" + std::to_string(c) + "]";
    require(col.center.allFinite(), name + ".center must be finite");
    require(inUnitInterval(col.friction), name + ".friction must be in [0, 1]");
    switch (col.shape) {
      case ClothCollider::Shape::Plane:
        require(col.normal.allFinite() && col.normal.norm() > 0, name + ".normal must be a nonzero vector");
        break;
      case ClothCollider::Shape::Box:
        require(col.halfExtents.allFinite() && col.halfExtents.minCoeff() > 0, name + ".halfExtents must be positive");
        require(col.orientation.allFinite() &&
                    (col.orientation.transpose() * col.orientation - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                    col.orientation.determinant() > 0,
                name + ".orientation must be a rotation");
        break;
      case ClothCollider::Shape::Sphere:
        require(std::isfinite(col.radius) && col.radius > 0, name + ".radius must be positive");
        break;
    }
  }
}

}  // namespace blot::cloth::detail
