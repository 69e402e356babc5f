#!/usr/bin/env bash
# `blot sweep --scheduler` on a real multi-process Dask cluster: a dask-scheduler
# and two dask-worker processes on 127.0.0.1 at ports the OS chooses
# (scripts/with_dask_cluster), a two-run sweep through the command line
# (sweep_on_dask_cluster.py checks its table), then every process of the
# cluster must be gone. About 10 s.
#
# usage: sweep_on_dask_cluster_test.sh SOURCE_DIR OUT_DIR PYTHON
#   (environment: BLOT_BINARY, PYTHONPATH with the blot package for the workers)
set -euo pipefail
src=$1 out=$2 python=$3
rm -rf "$out"
mkdir -p "$out"
BLOT_PYTHON=$python "$src/scripts/with_dask_cluster" --workers 2 --logs "$out/logs" -- \
  "$python" "$src/python/tests/sweep_on_dask_cluster.py" "$out"
for pid in $(cat "$out/cluster_pids"); do
  if kill -0 "$pid" 2>/dev/null; then
    echo "FAILED: process $pid of the cluster is still running" >&2
    exit 1
  fi
done
echo "dask cluster sweep OK"
