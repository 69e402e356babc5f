#!/usr/bin/env bash
# Blender (Debian's `blender`) imports a .glb written by `blot run` headless
# and checks vertices, the colour attribute and the texture (gltf_blender_check.py).
# Usage: blender_gltf_test.sh BLOT SCENE OUT
set -euo pipefail
blot=$1 scene=$2 out=$3
command -v blender > /dev/null || { echo "blender not on PATH: apt-get install -y blender"; exit 1; }
rm -rf "$out"
"$blot" run "$scene" --out "$out" --quiet > "$out.summary.txt"
vertices=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['vertices'])" "$out/summary.json")
blender -b --factory-startup --python-exit-code 1 -P "$(dirname "$0")/gltf_blender_check.py" -- \
  "$out/outputs.glb" "$vertices" 64
