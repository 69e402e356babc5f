#pragma once
/// Tests that look inside the Bullet cloth of a coupled surface (strain,
/// node masses). Library code never needs this: SurfaceMotion carries what
/// the coupling and the engine use.
#include <blot/cloth/bullet_cloth.h>
#include <blot/coupling/coupled_surface.h>

namespace blot::testing {

inline const cloth::BulletCloth& bulletClothOf(const coupling::CoupledSurface& surface) {
  return dynamic_cast<const cloth::BulletCloth&>(surface.motion());
}

}  // namespace blot::testing
