#pragma once
/// Initial conditions and sources: drops (with optional "splash" velocity
/// fields) and regions held at fixed densities ("fluid constantly added").
#include <blot/stain/stain_state.h>
#include <blot/stain/step_context.h>
#include <blot/stain/geometry/surface_geometry.h>

#include <cstdint>
#include <vector>

namespace blot::stain {

struct DropDef {
  int centerVertex = -1;         ///< vertex at the drop's centre (or -1 and use centerPoint)
  Vector3 centerPoint = Vector3::Zero();  ///< world point; the nearest vertex is used
  double radius = 0.05;          ///< m, Euclidean distance in the newest positions (t + h), not across folds
  double solventMass = 1e-3;     ///< kg spread over the drop
  double soluteMass = 1e-4;      ///< kg spread over the drop
  /// Initial velocity in the world (inertial) frame (m/s): the liquid's
  /// velocity relative to the cloth is this minus the cloth's own velocity at
  /// each vertex, projected into the vertex frame (the normal part is lost).
  Vector3 velocity = Vector3::Zero();
  /// Added velocity relative to the cloth (m/s, world axes), e.g. liquid
  /// poured along a moving sleeve; projected the same way.
  Vector3 relativeVelocity = Vector3::Zero();
  /// false: `velocity` is not a world velocity but taken relative to the
  /// cloth like relativeVelocity (a drop given no world velocity lands and
  /// moves with the cloth; scene drops without a "velocity" key do this).
  bool velocityIsWorld = true;
  /// Splash: outgoing radial speed (m/s) with a random angular profile from seed.
  double splashSpeed = 0;
  std::uint64_t splashSeed = 0;
};

/// A drop's bump (1 − d²)² below this (d = distance / radius) is no liquid:
/// a vertex within rounding of the radius took ~1e-30 of the peak, far below
/// any wet threshold, and a change of the radius in its last bit then moved
/// the stain seconds later (1e-16 relative radius, 2.6e-4 of the stain at 2
/// s, through the sets of vertices holding liquid). Vertices within about
/// 5e-7 R of the rim are left dry instead.
inline constexpr double kDropProfileFloor = 1e-12;

/// Adds a drop: a smooth bump (A_i-weighted, so Σ A_i Δσ_i equals the masses
/// exactly) over vertices within `radius` of the centre whose bump passes
/// kDropProfileFloor (the centre always); the added mass goes to
/// state.addedSolvent / addedSolute. Velocity: mass-weighted blend of the old
/// velocity and the drop's. Throws std::invalid_argument naming the field for
/// bad values (negative mass, radius ≤ 0, vertex out of range, non-finite).
/// surfaceVelocities (optional, #V by 3, m/s, world): the cloth's velocity
/// at each vertex that drop.velocity is made relative to (StainSolver passes
/// it; without it the cloth is taken at rest).
void addDrop(const DropDef& drop, const SurfaceTopology& topology, const IntrinsicGeometry& intrinsic,
             const ExtrinsicGeometry& extrinsic, StainState& state,
             const RowVectors3* surfaceVelocities = nullptr);

/// A region held at fixed densities: each step its vertices are set to
/// max(σ, held σ); the added mass is recorded.
struct HeldRegion {
  std::vector<int> vertices;
  double solventDensity = 0;  ///< kg/m²
  double soluteDensity = 0;   ///< kg/m²
  /// Every field, once (save/load and the state hash are built on it).
  template <class Visitor> void visit(Visitor& v) { fields(*this, v); }
  template <class Visitor> void visit(Visitor& v) const { fields(*this, v); }
  template <class Self, class Visitor>
  static void fields(Self& s, Visitor& v) {
    v.field("vertices", s.vertices);
    v.field("solventDensity", s.solventDensity);
    v.field("soluteDensity", s.soluteDensity);
  }
};

void applySources(const StepContext& ctx, const std::vector<HeldRegion>& regions,
                  const IntrinsicGeometry& geometry, StainState& state);

}  // namespace blot::stain
