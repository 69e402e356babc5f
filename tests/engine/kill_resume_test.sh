#!/usr/bin/env bash
# `blot run` killed with SIGKILL at random moments, over and over, and resumed
# each time with --resume, ends with the same state hash, byte-identical
# frames and previews, the same summary.json (but for wall-clock timings and
# the folder name) as an uninterrupted run, and no temporary file left.
# Kill moments come from a seeded RNG (bash's RANDOM, so a failure reruns
# with the same kills): half of them are a real SIGKILL sent from outside
# after a random delay (anywhere: in a step, in a write, between files), half
# are the process killing itself half-way through its N-th file write
# (--testing-kill-in-write N: a temporary file with half its bytes is left
# behind, as a kill in the middle of a write leaves it), N random.
#   kill_resume_test.sh BLOT WORKDIR SEED KILLS_PER_SCENE FRAMES SCENE...
set -euo pipefail
blot=$1 work=$2 seed=$3 kills_per_scene=$4 frames=$5
shift 5
RANDOM=$seed
rm -rf "$work" && mkdir -p "$work"

strip() {  # the summary without wall-clock timings and folder names
  grep -v -e '"wall_time_s"' -e '"steps_per_second"' -e '"mean_ms_per_step"' -e '"stain' -e '"cloth":' \
    -e '"coupling":' -e '"total":' "$1" | sed 's#/full/#/OUT/#; s#/killed/#/OUT/#; s#"[^"]*/full"#"OUT"#; s#"[^"]*/killed"#"OUT"#'
}
hash() { sed -n 's/.*"state_hash": "\([0-9a-f]*\)".*/\1/p' "$1"; }

total_kills=0 in_write=0 outside=0 temporaries=0
for scene in "$@"; do
  name=$(basename "$scene" .json)
  dir=$work/$name
  mkdir -p "$dir"
  args=(run "$scene" --frames "$frames" --threads 1 --quiet --checkpoint-every 1)
  start=$(date +%s%N)
  "$blot" "${args[@]}" --out "$dir/full" > "$dir/full.json"
  full_ms=$(( ($(date +%s%N) - start) / 1000000 ))
  kills=0 attempts=0 resume=()
  while :; do
    attempts=$((attempts + 1))
    [ $attempts -le $((4 * kills_per_scene + 10)) ] || { echo "FAIL: $name: no progress after $attempts runs"; exit 1; }
    mode=none
    if [ $kills -lt "$kills_per_scene" ]; then
      if [ $((RANDOM % 2)) -eq 0 ]; then mode=write; else mode=outside; fi
    fi
    set +e
    case $mode in
      write)
        # Each remaining frame writes its PLY, a state and checkpoint.json;
        # the end adds the previews and summary.json.
        done_frames=0
        [ -f "$dir/killed/checkpoint.json" ] &&
          done_frames=$(sed -n 's/.*"frame": *\([0-9]*\).*/\1/p' "$dir/killed/checkpoint.json")
        writes=$((3 * (frames - done_frames) + 2))
        n=$((1 + RANDOM % writes))
        # (The braces keep bash's "Killed" report of the child out of the log.)
        { "$blot" "${args[@]}" --out "$dir/killed" "${resume[@]}" --testing-kill-in-write "$n" \
            > "$dir/killed.json" 2> "$dir/killed.err"; status=$?; } 2> /dev/null ;;
      outside)
        delay_ms=$((RANDOM % (full_ms + 1)))
        "$blot" "${args[@]}" --out "$dir/killed" "${resume[@]}" > "$dir/killed.json" 2> "$dir/killed.err" &
        pid=$!
        sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
        kill -KILL "$pid" 2> /dev/null
        { wait "$pid"; status=$?; } 2> /dev/null ;;
      none)
        "$blot" "${args[@]}" --out "$dir/killed" "${resume[@]}" > "$dir/killed.json" 2> "$dir/killed.err"
        status=$? ;;
    esac
    set -e
    if [ $status -eq 0 ]; then
      [ $mode = none ] && break
      # The kill came after the run had finished (a late outside kill): the
      # run is complete; start the chain again so that every kill counts.
      rm -rf "$dir/killed"; resume=(); continue
    fi
    [ $status -eq 137 ] || { echo "FAIL: $name: run ended with $status, not SIGKILL"; cat "$dir/killed.err"; exit 1; }
    # A kill during a write leaves its temporary for --resume to remove.
    [ -n "$(find "$dir/killed" -name '*.tmp' 2> /dev/null)" ] && temporaries=$((temporaries + 1))
    if [ -f "$dir/killed/checkpoint.json" ]; then
      kills=$((kills + 1))
      [ $mode = write ] && in_write=$((in_write + 1)) || outside=$((outside + 1))
      resume=(--resume)
    else
      # Killed before its first checkpoint: nothing to resume from; start over.
      rm -rf "$dir/killed"; resume=()
    fi
  done
  h_full=$(hash "$dir/full.json") h_resumed=$(hash "$dir/killed.json")
  [ -n "$h_full" ] && [ "$h_full" = "$h_resumed" ] ||
    { echo "FAIL: $name: state hash $h_resumed after $kills kills, $h_full uninterrupted"; exit 1; }
  compared=0
  for f in "$dir/full"/*; do
    case $f in *.ply|*.png) ;; *) continue ;; esac
    cmp -s "$f" "$dir/killed/$(basename "$f")" || { echo "FAIL: $name: $(basename "$f") differs after $kills kills"; exit 1; }
    compared=$((compared + 1))
  done
  [ $compared -ge "$frames" ] || { echo "FAIL: $name: only $compared output files to compare"; exit 1; }
  diff <(strip "$dir/full/summary.json") <(strip "$dir/killed/summary.json") > "$dir/summary.diff" ||
    { echo "FAIL: $name: summary.json differs after $kills kills"; cat "$dir/summary.diff"; exit 1; }
  leftover=$(find "$dir/killed" -name '*.tmp')
  [ -z "$leftover" ] || { echo "FAIL: $name: temporary files left: $leftover"; exit 1; }
  ls "$dir/full" | sed 's/^checkpoint_[0-9]*\.state$/checkpoint_N.state/' | sort > "$dir/full.ls"
  ls "$dir/killed" | sed 's/^checkpoint_[0-9]*\.state$/checkpoint_N.state/' | sort > "$dir/killed.ls"
  diff "$dir/full.ls" "$dir/killed.ls" > /dev/null ||
    { echo "FAIL: $name: other files after resume"; diff "$dir/full.ls" "$dir/killed.ls"; exit 1; }
  echo "$name: $kills kills resumed ($attempts runs; uninterrupted run $full_ms ms), state hash $h_full, $compared files identical"
  total_kills=$((total_kills + kills))
done
echo "kill-resume OK: $total_kills kills ($in_write in a write, $outside from outside at random times;" \
  "$temporaries kills left a temporary file), seed $seed"
