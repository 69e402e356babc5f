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
(the stain) at 2 s and of the free solvent at 0.5 s against the Geometry
stage's ms per step (the cost the tolerance controls; one thread, wall clock,
the CSV's first line records the load average), points labelled with their
tolerance; and the same errors against the tolerance, with the rebuilds per
step in black. Solid: whole rebuilds; dashed: partial ones (both with every
edge tested); dash-dotted: whole rebuilds with the strain tested around the
free liquid only; dotted with triangles: the region around the liquid
rebuilt (IntrinsicRefresh::Region) on that test. The "floor" (the
reference with the drops' radii changed by 1e-8) is drawn dotted.
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


def at(rows, time):
    return [r for r in rows if abs(float(r["time_s"]) - time) < 1e-6]


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "studies", "strain_tolerance.csv")
    load, rows = read(path)
    out = os.path.join(ROOT, "docs", "charts")
    os.makedirs(out, exist_ok=True)
    styles = {"full": ("o-", "whole rebuild"), "partial": ("s--", "partial rebuild"),
              "around-liquid": ("^-.", "whole rebuild, strain tested around the liquid"),
              "region": ("v:", "region rebuild around the liquid, strain tested there")}
    errors = [("error_stain", 2.0, "whole solute (stain), 2 s", "C0"),
              ("error_solvent", 0.5, "free solvent, 0.5 s", "C1")]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        data = [r for r in rows if r["scene"] == scene]
        runs = [r for r in data if r["tolerance"] not in ("every step", "floor")]
        fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
        for ax, xkey, xlabel in ((axes[0], "geometry_ms", "cost: Geometry stage, ms per step (one thread, wall clock)"),
                                 (axes[1], "tolerance_value", "strain tolerance  (\"never\" drawn at 1)")):
            for refresh, (style, name) in styles.items():
                for key, time, label, colour in errors:
                    points = [r for r in at(runs, time) if r["refresh"] == refresh]
                    if not points:
                        continue
                    xs = [min(float(p[xkey]), 1.0) if xkey == "tolerance_value" else float(p[xkey]) for p in points]
                    ys = [max(float(p[key]), FLOOR) for p in points]
                    ax.plot(xs, ys, style, color=colour, label=f"{label}, {name}", markersize=5,
                            alpha=1.0 if refresh == "full" else 0.8)
                    if key == "error_stain" and xkey == "geometry_ms":
                        for x, y, p in zip(xs, ys, points):
                            ax.annotate(p["tolerance"], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
            for key, time, label, colour in errors:
                floor = [float(r[key]) for r in at(data, time) if r["tolerance"] == "floor"]
                if floor and floor[0] > 0:
                    ax.axhline(floor[0], color=colour, linestyle=":", linewidth=1)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(xlabel)
            ax.set_ylabel("relative L2 error against rebuilding every step")
            ax.grid(True, which="both", color="#dddddd")
        axes[0].legend(fontsize=8, loc="best")
        twin = axes[1].twinx()
        for refresh, (style, name) in styles.items():
            end = [r for r in at(runs, 2.0) if r["refresh"] == refresh]
            xs = [min(float(r["tolerance_value"]), 1.0) for r in end]
            twin.plot(xs, [float(r["rebuilds_per_step"]) for r in end], "k" + style[0] + style[1:], linewidth=0.8,
                      markersize=3, label=f"rebuilds per step, {name}")
        twin.set_ylim(0, 1.3)
        twin.set_ylabel("rebuilds per step (black)")
        twin.legend(fontsize=8, loc="lower left")
        fig.suptitle(f"{TITLES.get(scene, scene)}: strain tolerance of the intrinsic rebuild\n"
                     f"dotted: floor (drop radii x (1 + 1e-8)); errors of 0 drawn at {FLOOR:g}; {load.lstrip('# ')}",
                     fontsize=11)
        fig.tight_layout()
        target = os.path.join(out, f"strain_tolerance_{scene}.png")
        fig.savefig(target, dpi=90)
        print("wrote", target)


if __name__ == "__main__":
    main()
