#!/usr/bin/python3
"""Draws docs/charts/table1_windows.png: the stain's cost step by step on Table 1's Bullet rows.

Table 1 (tests/bench/table1_bench.cpp) times 100 steps after a warm-up of 30,
and a second window from the warm-up to step 300 (docs/performance.md,
"How to read Table 1"). This chart shows where those windows fall in each row's run: the
stain's ms a step (Engine statistics, one internal step a frame) for steps
0-299 of table1_tablecloth.json, table1_flag.json and table1_flag_two_way.json,
the median of RUNS runs of each step (default 3), with the metric rebuilds
marked, Table 1's timed window shaded, and the level at which the stain is
100x faster than the paper's Inert + Adv + Diff of that row (kPaperStainMs
of table1_bench.cpp) dashed. Each panel's title gives both windows' means and
their paper ratios. It runs, for each scene and run,

    build/demos/blot_game_loop --scene assets/scenes/S.json --rate 100 --seconds 3 \
        --drop-interval 1000 --frames-csv F

(the row's own scene, no random drops), one thread. On this shared 2-core
machine pin it to one CPU: `taskset -c 1 scripts/table1_windows.py [RUNS]`
(the two vCPUs of a shared machine can differ by about 1.4x at a time).
Debian's python3-matplotlib, hence /usr/bin/python3.
"""
import csv
import os
import statistics
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GAME_LOOP = os.path.join(ROOT, "build", "demos", "blot_game_loop")
# (scene file, title, the paper's Inert + Adv + Diff in ms: kPaperStainMs of tests/bench/table1_bench.cpp)
ROWS = [
    ("table1_tablecloth", "Tablecloth (2,500 vertices)", 16 + 15 + 0.5),
    ("table1_flag", "Flag (2,500 vertices)", 15 + 15 + 0.5),
    ("table1_flag_two_way", "Flag, two-way coupling (2,500 vertices)", 16 + 16 + 0.5),
]
WARM_UP, TIMED_END, THROUGH = 30, 130, 300  # Table 1's windows (steps)


def run_scene(scene, runs):
    """Per step: the stain's ms in each run, and the metric rebuilds (the same in every run)."""
    stain, rebuilds = [], None
    env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="passive")
    with tempfile.TemporaryDirectory() as folder:
        for r in range(runs):
            path = os.path.join(folder, f"{scene}_{r}.csv")
            subprocess.run([GAME_LOOP, "--scene", os.path.join(ROOT, "assets", "scenes", scene + ".json"),
                            "--rate", "100", "--seconds", "3", "--drop-interval", "1000", "--frames-csv", path],
                           check=True, env=env, stdout=subprocess.DEVNULL)
            with open(path, newline="") as f:
                rows = list(csv.DictReader(f))
            if any(int(row["internal_steps"]) != 1 for row in rows):
                sys.exit(f"table1_windows: {scene}: a frame took other than one internal step")
            stain.append([float(row["stain_ms"]) for row in rows])
            steps = [int(row["metric_rebuilds"]) for row in rows]
            if rebuilds is not None and steps != rebuilds:
                sys.exit(f"table1_windows: {scene}: the runs rebuilt on different steps (not deterministic)")
            rebuilds = steps
    return [statistics.median(s[k] for s in stain) for k in range(len(stain[0]))], rebuilds


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    if runs < 1:
        sys.exit("table1_windows: expected a count of runs >= 1")
    if not os.access(GAME_LOOP, os.X_OK):
        sys.exit(f"table1_windows: {GAME_LOOP} not found; build first (scripts/build)")
    fig, axes = plt.subplots(len(ROWS), 1, figsize=(9, 9), sharex=True)
    for ax, (scene, title, paper) in zip(axes, ROWS):
        stain, rebuilds = run_scene(scene, runs)
        steps = list(range(len(stain)))
        timed = statistics.fmean(stain[WARM_UP:TIMED_END])
        through = statistics.fmean(stain[WARM_UP:THROUGH])
        rebuilt = [k for k in steps if rebuilds[k] > 0]
        line = (f"{scene}: steps {WARM_UP}-{TIMED_END - 1} {timed:.3f} ms ({paper / timed:.0f}x), "
                f"{WARM_UP}-{THROUGH - 1} {through:.3f} ms ({paper / through:.0f}x), "
                f"rebuilds {sum(rebuilds[WARM_UP:TIMED_END]) / (TIMED_END - WARM_UP):.2f} and "
                f"{sum(rebuilds[WARM_UP:THROUGH]) / (THROUGH - WARM_UP):.2f} a step")
        print(line)
        ax.axvspan(WARM_UP, TIMED_END, color="0.9", label="Table 1's timed window")
        ax.plot(steps, stain, color="C0", linewidth=0.8, label=f"stain, ms a step (median of {runs} runs)")
        ax.plot(rebuilt, [stain[k] for k in rebuilt], "v", color="C3", markersize=3, label="step with a metric rebuild")
        ax.axhline(paper / 100, color="k", linestyle="--", linewidth=0.8, label="100x the paper's Inert + Adv + Diff")
        ax.set_yscale("log")
        ax.set_ylabel("ms a step")
        ax.set_title(f"{title}: steps {WARM_UP}-{TIMED_END - 1} {paper / timed:.0f}x, "
                     f"{WARM_UP}-{THROUGH - 1} {paper / through:.0f}x", fontsize=10)
    axes[-1].set_xlabel("internal step (h = 0.01 s)")
    axes[0].legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    out = os.path.join(ROOT, "docs", "charts", "table1_windows.png")
    fig.savefig(out, dpi=110)
    print(f"wrote {os.path.relpath(out, ROOT)}")


if __name__ == "__main__":
    main()
