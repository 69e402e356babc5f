#!/usr/bin/env bash
# blot-viewer under Xvfb with Mesa's software GL: the two-way flag, 60 frames
# with and without a scripted drop; the drop's stain must show in the
# screenshot (pixels of the ink's hue, against the one without the drop) and
# the frame and step counters must have advanced.
# usage: viewer_test.sh VIEWER STAIN_PIXELS SCENE OUT_DIR
set -euo pipefail
viewer=$1 pixels=$2 scene=$3 out=$4
mkdir -p "$out"
if ! command -v xvfb-run >/dev/null; then
  echo "viewer_test: xvfb-run not found (Debian package xvfb; scripts/setup installs it)" >&2
  exit 1
fi
export LIBGL_ALWAYS_SOFTWARE=1   # Mesa's llvmpipe, no GPU needed
run() { xvfb-run -a -s "-screen 0 1280x800x24" "$viewer" "$scene" --no-scene-drops --liquid ink \
          --frames 60 --exit "$@"; }

# Bad input: a clear error, exit 2, before any window opens.
if "$viewer" --drop 2,0.5 2>"$out/bad.txt"; then echo "viewer_test: --drop 2,0.5 was accepted" >&2; exit 1; fi
grep -q "fractions of the view" "$out/bad.txt" || { cat "$out/bad.txt"; exit 1; }

run --screenshot "$out/no_drop.png" | tee "$out/no_drop.txt"
# Two-way coupling off from frame 30: the engine is rebuilt and its state carried over.
run --drop 0.5,0.4,0.3,0,0 --toggle two-way@30 --screenshot "$out/drop.png" | tee "$out/drop.txt"
grep -q "frame 30: two-way off" "$out/drop.txt"
# 60 frames of 1/60 s at h = 1/120 s: 120 internal steps, 1 s.
grep -q "frames 60 steps 120 time 1.0000 s drops 0" "$out/no_drop.txt"
grep -q "frames 60 steps 120 time 1.0000 s drops 1" "$out/drop.txt"
# The 3D view starts at x = 340 (the panel is left of it).
"$pixels" "$out/drop.png" --pigment ink --from-x 340 --baseline "$out/no_drop.png" \
  --min-more 2000 --max-baseline 50
echo "viewer_test: passed"
