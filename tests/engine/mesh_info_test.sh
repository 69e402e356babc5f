#!/usr/bin/env bash
# `blot mesh-info` on a 60 x 60 grid written in row order and with its
# vertices shuffled: the same topology, and the vertex-order report suggests
# mesh.vertex_order "locality" for the shuffled file only.
#   mesh_info_test.sh BLOT WORKDIR
set -euo pipefail
blot=$1 work=$2
rm -rf "$work" && mkdir -p "$work"
python3 - "$work" <<'PY'
import random, sys
n = 60
index = lambda i, j: j * (n + 1) + i
faces = []
for j in range(n):
    for i in range(n):
        a, b, c, d = index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)
        faces += [(a, b, c), (a, c, d)]
count = (n + 1) ** 2
shuffle = list(range(count))
random.Random(7).shuffle(shuffle)
for name, order in (("rows", list(range(count))), ("shuffled", shuffle)):
    where = [0] * count
    for k, v in enumerate(order):
        where[v] = k
    with open(f"{sys.argv[1]}/{name}.obj", "w") as f:
        for v in order:
            f.write(f"v {v % (n + 1) / n} {v // (n + 1) / n} 0\n")
        for t in faces:
            f.write("f %d %d %d\n" % tuple(where[v] + 1 for v in t))
PY
"$blot" mesh-info "$work/rows.obj" > "$work/rows.json"
"$blot" mesh-info "$work/shuffled.obj" > "$work/shuffled.json"
python3 - "$work" <<'PY'
import json, sys
rows, shuffled = (json.load(open(f"{sys.argv[1]}/{n}.json")) for n in ("rows", "shuffled"))
for key in ("vertices", "faces", "edges", "boundary_loops", "genus"):
    assert rows[key] == shuffled[key], (key, rows[key], shuffled[key])
r, s = rows["vertex_order"], shuffled["vertex_order"]
assert not r["locality_suggested"], r
assert s["locality_suggested"], s
assert s["median_edge_index_span"] > 500, s              # a random order: about a third of 3,721
assert s["median_edge_index_span_locality"] <= 2 * 61, s  # about one breadth-first level
print("rows", r, "shuffled", s)
PY
# Preview directions are checked as blot run's scene keys are (a zero --view
# failed as a camera error, a zero or parallel --up was ignored).
for bad in "--view 0 0 0|--view: expected a non-zero direction" "--view 1e308 0 0|--view: expected a non-zero direction" \
           "--up 0 0 0|--up: expected a non-zero direction" "--view 0 0 -1 --up 0 0 2|not parallel to --view"; do
  args=${bad%%|*} expected=${bad#*|}
  set +e
  # shellcheck disable=SC2086
  "$blot" mesh-info "$work/rows.obj" --render "$work/bad.png" $args > /dev/null 2> "$work/bad.err"
  status=$?
  set -e
  [ "$status" -eq 1 ] || { cat "$work/bad.err"; echo "FAIL: mesh-info $args exited $status"; exit 1; }
  grep -qF -- "$expected" "$work/bad.err" || { cat "$work/bad.err"; echo "FAIL: mesh-info $args: no '$expected'"; exit 1; }
  [ -e "$work/bad.png" ] && { echo "FAIL: mesh-info $args wrote a preview"; exit 1; }
done
echo "mesh info OK"
