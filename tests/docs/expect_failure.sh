#!/usr/bin/env bash
# Runs a checker on a planted fixture and requires it to fail there: exit
# status 1 (not a crash or a usage error) and the finding named in its output.
#   expect_failure.sh REGEX COMMAND [ARG...]
set -uo pipefail
expected=$1
shift
output=$("$@" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" != 1 ]; then
  echo "expect_failure: '$*' exited $status on its planted fixture; expected 1 (a finding)" >&2
  exit 1
fi
if ! printf '%s\n' "$output" | grep -Eq -- "$expected"; then
  echo "expect_failure: '$*' failed but did not report /$expected/" >&2
  exit 1
fi
echo "expect_failure: the checker failed on its planted fixture, as it must"
