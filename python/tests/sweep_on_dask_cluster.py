"""`blot sweep --scheduler` against a real Dask cluster: run by
sweep_on_dask_cluster_test.sh inside scripts/with_dask_cluster, which started a
dask-scheduler and two dask-worker processes on loopback and passes their
address and process ids in the environment.

A two-run sweep (a wine drop on a small still patch at two time steps, the finer
one the reference) goes to the cluster through the command line; the table must
say that both runs succeeded on those worker processes and give the same bits
(state hashes, errors) as the same sweep on the serial executor.

usage: sweep_on_dask_cluster.py OUT_DIR   (BLOT_BINARY: the blot executable)
"""
import csv
import json
import os
import subprocess
import sys

BLOT = os.environ.get("BLOT_BINARY", "blot")


def sweep_spec():
    return {
        "name": "dask cluster check",
        "scene": {
            "name": "cluster_drop",
            "mesh": {"patch": {"size": [0.1, 0.1], "resolution": [12, 12]}},
            "cloth": {"source": "static"},
            "fabric": {"diffusivity": 4e-05, "viscosity": 2e-05},
            "liquid": {"preset": "wine"},
            "drops": [{"point": [0, 0, 0], "radius": 0.02, "mass": 2e-04}],
        },
        "duration": 0.2,
        "runs": [{"name": "h=1/50", "overrides": {"time_step": 0.02}},
                 {"name": "h=1/100", "overrides": {"time_step": 0.01}}],
        "reference": "h=1/100",
    }


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def run(command):
    proc = subprocess.run(command, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"FAILED: {' '.join(command)} exited with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout


def main():
    out = sys.argv[1]
    scheduler = os.environ["BLOT_DASK_SCHEDULER"]
    worker_pids = {int(p) for p in os.environ["BLOT_DASK_WORKER_PIDS"].split()}
    with open(os.path.join(out, "cluster_pids"), "w") as fh:  # the test checks they are gone afterwards
        fh.write(" ".join(str(p) for p in [os.environ["BLOT_DASK_SCHEDULER_PID"], *sorted(worker_pids)]) + "\n")
    spec = os.path.join(out, "sweep.json")
    with open(spec, "w") as fh:
        json.dump(sweep_spec(), fh, indent=1)

    print(run([BLOT, "sweep", spec, "--scheduler", scheduler, "--out", os.path.join(out, "cluster")]), end="")
    run([BLOT, "sweep", spec, "--executor", "serial", "--out", os.path.join(out, "serial")])
    rows = read_csv(os.path.join(out, "cluster", "sweep.csv"))
    serial = read_csv(os.path.join(out, "serial", "sweep.csv"))

    problems = []
    if [r["name"] for r in rows] != ["h=1/50", "h=1/100"]:
        problems.append(f"expected the rows h=1/50, h=1/100, got {[r['name'] for r in rows]}")
    for r in rows:
        if r["status"] != "ok":
            problems.append(f"{r['name']}: status {r['status']}: {r['error']}")
        pid = int(r["worker"].rsplit(":", 1)[1]) if ":" in r["worker"] else -1
        if pid not in worker_pids:
            problems.append(f"{r['name']}: ran on {r['worker']!r}, not on a worker of the cluster {sorted(worker_pids)}")
    by_name = {r["name"]: r for r in rows}
    if by_name.get("h=1/100", {}).get("is_reference") != "true":
        problems.append("h=1/100 is not marked as the reference")
    elif by_name["h=1/100"]["l2_error"] != "0.0":
        problems.append(f"the reference's own error is {by_name['h=1/100']['l2_error']}, expected 0.0")
    if rows and not (0 < float(by_name["h=1/50"]["l2_error"] or "nan") < 1):
        problems.append(f"h=1/50: l2_error {by_name['h=1/50']['l2_error']!r}, expected in (0, 1)")
    for a, b in zip(rows, serial):
        for column in ("name", "status", "steps", "state_hash", "l2_error", "area_error", "centroid_distance_m"):
            if a[column] != b[column]:
                problems.append(f"{a['name']}: {column} {a[column]!r} on the cluster, {b[column]!r} serially")
    if problems:
        sys.exit("FAILED:\n  " + "\n  ".join(problems))
    print(f"both runs on the cluster's workers ({', '.join(r['worker'] for r in rows)}), "
          "the same bits as the serial executor")


if __name__ == "__main__":
    main()
