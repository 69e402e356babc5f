#!/usr/bin/env bash
# A numerical failure stops `blot run` with exit code 3, a message
# naming the stage, the internal step and the vertex, and where the last good
# frame is; every frame written before it is complete (byte-identical to a
# run without the fault) and the engine's last good state is saved. The fault
# is real: --testing-inject-fault cloth:27:1300 gives node 1300 an impulse of
# 1e30 N·s before internal step 27 (frame 5 at 6 steps per frame), and Bullet
# blows up.
#   numerical_fault_test.sh BLOT SCENE WORKDIR
set -euo pipefail
blot=$1 scene=$2 work=$3
rm -rf "$work" && mkdir -p "$work"

"$blot" run "$scene" --frames 4 --threads 1 --quiet --out "$work/clean" > /dev/null

set +e
"$blot" run "$scene" --frames 8 --threads 1 --quiet --out "$work/faulty" \
  --testing-inject-fault cloth:27:1300 > "$work/faulty.json" 2> "$work/faulty.err"
status=$?
set -e
cat "$work/faulty.err"
[ "$status" -eq 3 ] || { echo "FAIL: expected exit code 3, got $status"; exit 1; }
for expected in "numerical failure in frame 5" "stage 'cloth'" "vertex 1300" "internal step 27" \
                "last good frame written: $work/faulty/" "last_good.state"; do
  grep -qF "$expected" "$work/faulty.err" || { echo "FAIL: the message lacks '$expected'"; exit 1; }
done
# The summary says the run failed, where and why (an earlier run's summary in
# the folder would otherwise stand beside this run's frames).
grep -q '"status": "failed"' "$work/faulty/summary.json" || { echo "FAIL: no summary saying the run failed"; exit 1; }
grep -q '"failed_frame": 5' "$work/faulty/summary.json" || { echo "FAIL: the summary lacks the failed frame"; exit 1; }
grep -qF "last_good.state" "$work/faulty/summary.json" || { echo "FAIL: the summary lacks the last good state"; exit 1; }
[ -s "$work/faulty/last_good.state" ] || { echo "FAIL: no last good state saved"; exit 1; }
last=$(sed -n 's/.*last good frame written: //p' "$work/faulty.err")
[ -f "$last" ] || { echo "FAIL: the last good frame $last is not there"; exit 1; }
compared=0
for f in "$work/faulty"/*.ply; do
  cmp -s "$f" "$work/clean/$(basename "$f")" || { echo "FAIL: $(basename "$f") differs from the run without the fault"; exit 1; }
  compared=$((compared + 1))
done
[ "$compared" -eq 2 ] || { echo "FAIL: expected frames 0 and 4 before the failure, found $compared"; exit 1; }
ls "$work/faulty"/*.tmp* 2>/dev/null && { echo "FAIL: a temporary file was left behind"; exit 1; }
echo "fault OK"
