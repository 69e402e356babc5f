#!/usr/bin/python3
"""Draws docs/charts/strain_tolerance_<scene>.png from the strain-tolerance study.

The study (tests/studies/strain_tolerance_study_test.cpp, ctest label "study")
writes $BLOT_STUDY_OUT/strain_tolerance.csv. Run it and draw:

    cmake --build build --target strain_tolerance_study_test
    BLOT_STUDY_OUT=build/studies OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive \
        build/tests/strain_tolerance_study_test
    scripts/strain_tolerance_chart.py [build/studies/strain_tolerance.csv]

(Debian's python3-matplotlib, hence /usr/bin/python3 rather than a pyenv python.)

One chart per scene, two panels: the relative L2 error of the whole solute
(the stain) and of the free solvent at 0.5 s and 2 s against rebuilds per
step (machine-independent cost), and the same errors against the tolerance,
with rebuilds per step and the stain's ms per step relative to the
every-step run (one thread; the CSV's first line records the load average). Each
point is labelled with its tolerance; the "floor" (the reference with the
drops' radii changed by 1e-8) is drawn as a dotted line; the right panel's black lines are the cost.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TITLES = {
    "two_way_flag": "Two-way flag (2601 vertices, Bullet, h = 1/120 s)",
    "tablecloth": "Tablecloth (1681 vertices, Bullet, h = 1/120 s)",
}
FLOOR = 1e-12  # errors of exactly 0 are drawn here (log axes)


def read(path):
    with open(path) as f:
        load = f.readline().strip()
        rows = list(csv.DictReader(f))
    return load, rows


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "studies", "strain_tolerance.csv")
    load, rows = read(path)
    out = os.path.join(ROOT, "docs", "charts")
    os.makedirs(out, exist_ok=True)
    for scene in dict.fromkeys(r["scene"] for r in rows):
        data = [r for r in rows if r["scene"] == scene]
        fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
        series = [("error_stain", "2", "whole solute (stain), 2 s", "C0", "o-"),
                  ("error_stain", "0.5", "whole solute (stain), 0.5 s", "C0", "s--"),
                  ("error_solvent", "0.5", "free solvent, 0.5 s", "C1", "^--"),
                  ("error_solvent", "2", "free solvent, 2 s", "C1", "v-")]
        for ax, xkey, xlabel in ((axes[0], "rebuilds_per_step", "cost: intrinsic rebuilds per step"),
                                 (axes[1], "tolerance_value", "strain tolerance")):
            for key, time, label, colour, style in series:
                points = [r for r in data if abs(float(r["time_s"]) - float(time)) < 1e-6
                          and r["tolerance"] not in ("every step", "floor")]
                if not points or all(float(p[key]) == 0 for p in points):
                    continue
                xs = [max(float(p[xkey]), 1e-3) if xkey == "rebuilds_per_step" else min(float(p[xkey]), 1.0)
                      for p in points]
                ys = [max(float(p[key]), FLOOR) for p in points]
                ax.plot(xs, ys, style, color=colour, label=label, markersize=6)
                if key == "error_stain" and time == "2":
                    for x, y, p in zip(xs, ys, points):
                        ax.annotate(p["tolerance"], (x, y), textcoords="offset points", xytext=(5, 5), fontsize=9)
                floor = [float(r[key]) for r in data
                         if r["tolerance"] == "floor" and abs(float(r["time_s"]) - float(time)) < 1e-6]
                if floor and floor[0] > 0:
                    ax.axhline(floor[0], color=colour, linestyle=":", linewidth=1)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(xlabel + ("  (\"never\" drawn at 1e-3)" if xkey == "rebuilds_per_step" else "  (\"never\" drawn at 1)"))
            ax.set_ylabel("relative L2 error against rebuilding every step")
            ax.grid(True, which="both", color="#dddddd")
        axes[0].legend(fontsize=9, loc="best")
        # Cost on the tolerance panel: rebuilds per step and the stain's ms per step.
        end = [r for r in data if abs(float(r["time_s"]) - 2) < 1e-6 and r["tolerance"] not in ("every step", "floor")]
        twin = axes[1].twinx()
        xs = [min(float(r["tolerance_value"]), 1.0) for r in end]
        twin.plot(xs, [float(r["rebuilds_per_step"]) for r in end], "k.-", linewidth=1, label="rebuilds per step")
        reference = [float(r["stain_ms"]) for r in data if r["tolerance"] == "every step"][0]
        twin.plot(xs, [float(r["stain_ms"]) / reference for r in end], "kx:", linewidth=1,
                  label="stain ms per step / every-step run's")
        twin.set_ylim(0, 1.3)
        twin.set_ylabel("cost (black)")
        twin.legend(fontsize=9, loc="lower left")
        fig.suptitle(f"{TITLES.get(scene, scene)}: strain tolerance of the intrinsic rebuild\n"
                     f"dotted: floor (drop radii x (1 + 1e-8)); errors of 0 drawn at {FLOOR:g}; {load.lstrip('# ')}",
                     fontsize=11)
        fig.tight_layout()
        target = os.path.join(out, f"strain_tolerance_{scene}.png")
        fig.savefig(target, dpi=90)
        print("wrote", target)


if __name__ == "__main__":
    main()
