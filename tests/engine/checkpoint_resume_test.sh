#!/usr/bin/env bash
# A `blot run` killed with SIGKILL and resumed from its last checkpoint
# ends with the same state (summary state hash) and byte-identical PLY frames
# and PNG as an uninterrupted run. The kill is real: the child process sends
# itself SIGKILL after frame 7 (--kill-after-frame, so the test is not timing
# dependent); the last checkpoint before it is frame 6.
#   checkpoint_resume_test.sh BLOT SCENE WORKDIR
set -euo pipefail
blot=$1 scene=$2 work=$3
frames=12
rm -rf "$work" && mkdir -p "$work"

"$blot" run "$scene" --frames $frames --threads 1 --quiet --out "$work/full" > "$work/full.json"

set +e
"$blot" run "$scene" --frames $frames --threads 1 --quiet --out "$work/killed" \
  --checkpoint-every 3 --kill-after-frame 7 > "$work/killed.json" 2> "$work/killed.err"
status=$?
set -e
if [ "$status" -ne 137 ]; then
  echo "FAIL: the first run should die of SIGKILL (exit 137), got $status"; cat "$work/killed.err"; exit 1
fi
[ -f "$work/killed/summary.json" ] && { echo "FAIL: a killed run wrote a summary"; exit 1; }
grep -q '"frame": 6' "$work/killed/checkpoint.json" || { echo "FAIL: last checkpoint is not frame 6"; cat "$work/killed/checkpoint.json"; exit 1; }
ls "$work/killed"/checkpoint_*.state > "$work/states.txt"
[ "$(wc -l < "$work/states.txt")" -eq 1 ] || { echo "FAIL: old checkpoint states were not removed"; cat "$work/states.txt"; exit 1; }

"$blot" run "$scene" --frames $frames --threads 1 --quiet --out "$work/killed" --checkpoint-every 3 --resume \
  > "$work/resumed.json"

hash() { sed -n 's/.*"state_hash": "\([0-9a-f]*\)".*/\1/p' "$1"; }
full=$(hash "$work/full.json") resumed=$(hash "$work/resumed.json")
[ -n "$full" ] && [ "$full" = "$resumed" ] || { echo "FAIL: state hash $resumed after resume, $full uninterrupted"; exit 1; }
compared=0
for f in "$work/full"/*.ply "$work/full"/*.png; do
  [ -e "$f" ] || continue
  cmp -s "$f" "$work/killed/$(basename "$f")" || { echo "FAIL: $(basename "$f") differs after resume"; exit 1; }
  compared=$((compared + 1))
done
[ "$compared" -ge 3 ] || { echo "FAIL: only $compared output files to compare"; exit 1; }
# The summary covers the whole run after a resume too (the counters are in the
# state): equal but for wall-clock timings and the output folder's name.
strip() {
  grep -v -e '"wall_time_s"' -e '"steps_per_second"' -e '"mean_ms_per_step"' -e '"stain' -e '"cloth":' \
    -e '"coupling":' -e '"total":' "$1" | sed 's#/full/#/OUT/#; s#/killed/#/OUT/#; s#"[^"]*/full"#"OUT"#; s#"[^"]*/killed"#"OUT"#'
}
diff <(strip "$work/full.json") <(strip "$work/resumed.json") > "$work/summary.diff" ||
  { echo "FAIL: the resumed run's summary differs"; cat "$work/summary.diff"; exit 1; }
ls "$work/killed" | grep -q '\.tmp$' && { echo "FAIL: a temporary file was left"; ls "$work/killed"; exit 1; }
echo "resume OK: state hash $full, $compared frame/preview files byte-identical"
