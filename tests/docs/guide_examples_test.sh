#!/usr/bin/env bash
# The scene files shown in the guides run: every ```json block of docs/ that
# is a scene (it has "mesh" and "cloth") is written to a file and run with
# `blot run FILE --frames 1`. A guide whose example the parser refuses, or
# that fails its first frame, fails this test with blot's message.
#   guide_examples_test.sh BLOT SOURCE_DIR WORK_DIR
set -euo pipefail
blot=$1
source_dir=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
python3 - "$source_dir/docs" "$work" <<'PY'
import json, os, re, sys
docs, work = sys.argv[1], sys.argv[2]
count = 0
for dirpath, _, names in os.walk(docs):
    for name in sorted(names):
        if not name.endswith(".md"):
            continue
        path = os.path.join(dirpath, name)
        text = open(path, encoding="utf-8").read()
        for k, block in enumerate(re.findall(r"^```json\n(.*?)^```", text, re.S | re.M)):
            scene = json.loads(block)  # a guide's JSON that is not JSON fails here, naming the block
            if not (isinstance(scene, dict) and "mesh" in scene and "cloth" in scene):
                continue
            count += 1
            out = os.path.join(work, f"{os.path.relpath(path, docs).replace(os.sep, '_')}_{k}.json")
            json.dump(scene, open(out, "w"), indent=1)
            print(f"guide_examples: {os.path.relpath(path, docs)} block {k} -> {out}")
if count == 0:
    sys.exit("guide_examples: no scene example found in docs/")
PY
status=0
for scene in "$work"/*.json; do
  if ! "$blot" run "$scene" --frames 1 --quiet --out "${scene%.json}.out" >"${scene%.json}.log" 2>&1; then
    echo "guide_examples: $scene failed:" >&2
    cat "${scene%.json}.log" >&2
    status=1
  else
    echo "guide_examples: $(basename "$scene") runs"
  fi
done
exit $status
