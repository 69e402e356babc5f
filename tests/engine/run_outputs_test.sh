#!/usr/bin/env bash
# `blot run` artist outputs end to end: N frame PNGs (sRGB chunk), an mp4 and a
# gif with N frames of the image size (ffprobe), the texture bake, the 8- and
# 16-bit stain maps (linear data PNGs) and glTF, and every file listed in
# summary.json. Usage: run_outputs_test.sh BLOT SCENE OUT
set -euo pipefail
blot=$1 scene=$2 out=$3
rm -rf "$out"
"$blot" run "$scene" --out "$out" --quiet --maps png8,png16 > "$out.summary.txt"
frames=6  # frame 0 and frames 1..5
fail() { echo "FAIL: $*"; exit 1; }
n=$(ls "$out"/outputs_frame_*.png | wc -l)
[ "$n" = "$frames" ] || fail "$n frame PNGs, expected $frames"
for v in mp4 gif; do
  read -r w h count < <(ffprobe -v error -count_frames -select_streams v:0 \
      -show_entries stream=width,height,nb_read_frames -of csv=p=0 "$out/outputs.$v" | tr ',' ' ')
  [ "$count" = "$frames" ] || fail "$v has $count frames, expected $frames"
  # H.264 in yuv420p needs even sizes: the 97 px wide frames are padded to 98.
  if [ "$v" = mp4 ]; then [ "$w" = 98 ] || fail "mp4 width $w, expected 98"; else [ "$w" = 97 ] || fail "gif width $w"; fi
  [ "$h" = 64 ] || fail "$v height $h, expected 64"
done
python3 - "$out" <<'PY'
import json, os, struct, sys
out = sys.argv[1]
summary = json.load(open(os.path.join(out, "summary.json")))
# Every physics switch of the scene file's "physics" object is in "terms".
switches = {"gravity", "linear_inertia", "coriolis", "velocity_advection", "density_advection",
            "density_diffusion", "velocity_diffusion", "absorption", "adsorption", "evaporation",
            "sources", "film_pressure", "velocity_on_free_liquid", "boundary_wall",
            "positivity_limiter"}
missing = switches - set(summary["terms"])
assert not missing, f"summary terms lack {missing}"
s = summary["outputs"]
files = s["images"] + s["videos"] + s["textures"] + s["density_maps"] + s["stain_maps"] + s["gltf"]
assert len(s["images"]) == 6 and len(s["videos"]) == 2 and len(s["textures"]) == 1 and len(s["gltf"]) == 1, s
# wetness, saturation, stain; 8-bit then 16-bit each
assert [os.path.basename(f) for f in s["stain_maps"]] == [
    f"outputs_{m}{d}.png" for m in ("wetness", "saturation", "stain") for d in ("", "16")], s["stain_maps"]
listed = {os.path.basename(f) for f in files} | {"summary.json"}
on_disk = set(os.listdir(out))
assert listed == on_disk, f"not listed: {on_disk - listed}, missing: {listed - on_disk}"
def chunks(path):
    data = open(path, "rb").read()
    i, names = 8, []
    while i < len(data):
        n, = struct.unpack(">I", data[i:i + 4]); names.append(data[i + 4:i + 8].decode()); i += 12 + n
    return names, data
names, _ = chunks(s["images"][0])
assert "sRGB" in names, names
names, data = chunks(s["density_maps"][0])
assert "sRGB" not in names and "gAMA" in names and data[24] == 16, (names, data[24])
for path, depth in zip(s["stain_maps"], [8, 16] * 3):  # one grey channel (colour type 0), linear
    names, data = chunks(path)
    assert "sRGB" not in names and "gAMA" in names and data[24] == depth and data[25] == 0, (path, names, data[24:26])
glb = open(s["gltf"][0], "rb").read()
assert glb[:4] == b"glTF" and struct.unpack("<I", glb[4:8])[0] == 2
print("run outputs OK:", len(files), "files")
PY
