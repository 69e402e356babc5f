#!/usr/bin/env bash
# The dependency direction is a build fact: stain/ never sees Bullet, stain/ and
# cloth/ never see each other, and no module outside cloth/ includes a Bullet header.
set -euo pipefail
root=${1:-$(dirname "$0")/..}
fail=0
bullet='#include *[<"](bt[A-Z]|btBulletDynamicsCommon|BulletSoftBody/|BulletDynamics/|BulletCollision/|LinearMath/)'
for dir in stain coupling engine demos; do
  # demos/shared_world.cpp plays the game that owns a Bullet world (docs/embedding.md).
  if hits=$(grep -rEn "$bullet" "$root/$dir" 2>/dev/null | grep -v '^[^:]*/demos/shared_world\.cpp:'); then
    echo "Bullet header included outside cloth/ (in $dir/):"; echo "$hits"; fail=1
  fi
done
if hits=$(grep -rEn '#include *[<"]blot/(cloth|coupling|engine)/' "$root/stain" 2>/dev/null); then
  echo "stain/ includes a module above it:"; echo "$hits"; fail=1
fi
if hits=$(grep -rEn '#include *[<"]blot/(coupling|engine)/' "$root/cloth" 2>/dev/null); then
  echo "cloth/ includes a module above it:"; echo "$hits"; fail=1
fi
# stain/ and cloth/ never see each other: the cloth takes plain arrays
# (coupling::describeClothMesh derives them from the stain's mesh).
if hits=$(grep -rEn '#include *[<"]blot/stain/' "$root/cloth" 2>/dev/null); then
  echo "cloth/ includes stain/:"; echo "$hits"; fail=1
fi
if hits=$(grep -En 'blot_(stain|coupling|engine)' "$root/cloth/CMakeLists.txt" 2>/dev/null); then
  echo "blot_cloth links a module it must not see:"; echo "$hits"; fail=1
fi
if hits=$(grep -En 'blot_(cloth|coupling|engine)' "$root/stain/CMakeLists.txt" 2>/dev/null); then
  echo "blot_stain links a module above it:"; echo "$hits"; fail=1
fi
if hits=$(grep -rEn '#include *[<"]blot/engine/' "$root/coupling" 2>/dev/null); then
  echo "coupling/ includes engine/:"; echo "$hits"; fail=1
fi
# SurfaceMotion carries what the coupling and the engine need: nothing above
# cloth/ asks which concrete motion it has.
if hits=$(grep -rEn 'dynamic_cast *<' "$root/coupling" "$root/engine" "$root/demos" 2>/dev/null); then
  echo "dynamic_cast outside cloth/ (SurfaceMotion should carry what is needed):"; echo "$hits"; fail=1
fi
# Stages are named by stain::Stage, never compared as strings.
if hits=$(grep -rEn 'strcmp|stage *== *"|"(forces|diffuse|coriolis|interact|sources|coupling|cloth)" *== *' "$root/stain/src" "$root/coupling/src" "$root/engine/src" 2>/dev/null); then
  echo "a stage compared as a string (use stain::Stage):"; echo "$hits"; fail=1
fi
[ "$fail" = 0 ] && echo "layering OK: engine -> coupling -> {stain, cloth}; stain and cloth independent; Bullet only in cloth/; no downcasts or stage strings above cloth/"
exit $fail
