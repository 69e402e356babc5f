#!/usr/bin/env bash
# A program that links only the engine core (blot_engine: no outputs) must not
# carry libpng: neither as a shared-library dependency nor as linked-in code.
#   tests/check_no_png.sh BINARY...
set -euo pipefail
fail=0
for binary in "$@"; do
  if ldd "$binary" | grep -q 'libpng'; then
    echo "$binary depends on libpng:"; ldd "$binary" | grep libpng; fail=1
  fi
  if nm -C "$binary" 2>/dev/null | grep -Eq ' [TtUu] png_'; then
    echo "$binary contains or calls png_* symbols:"; nm -C "$binary" | grep -E ' [TtUu] png_' | head -5; fail=1
  fi
done
[ "$fail" = 0 ] && echo "no libpng in: $*"
exit $fail
