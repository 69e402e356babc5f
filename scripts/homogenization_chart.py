#!/usr/bin/python3
"""Chart of the homogenization gap against unknowns, uniform vs graded meshes.

Reads the CSV that tests/stain/homogenization_bounds_test.cpp writes
(GradedMeshesBeatUniformOnesInGapPerUnknown, with BLOT_STUDY_OUTPUT_DIR set)
and writes docs/charts/homogenization_gap.png:

    BLOT_STUDY_OUTPUT_DIR=/tmp/h build/tests/homogenization_bounds_test \
        --gtest_filter='*GapAgainst*:*BeatUniform*'
    python3 scripts/homogenization_chart.py /tmp/h/homogenization_gap.csv docs/charts/homogenization_gap.png

Needs python3-matplotlib (not needed by any test).
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rate(points):
    """Slope of log(gap) against log(unknowns) over the last three points."""
    (n0, g0), (n1, g1) = points[-3], points[-1]
    return math.log(g1 / g0) / math.log(n1 / n0)


def main(source, target):
    series = {}
    with open(source, newline="") as f:
        for row in csv.DictReader(f):
            series.setdefault(row["series"], []).append((int(row["unknowns"]), float(row["gap"])))
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    styles = {"uniform": ("o", "--"), "graded": ("s", "-")}
    colours = {}
    for name, points in series.items():
        tile, kind = name.rsplit(", ", 1)
        colour = colours.setdefault(tile, f"C{len(colours)}")
        marker, line = styles[kind]
        ax.loglog([n for n, _ in points], [g for _, g in points], line, marker=marker, color=colour,
                  label=f"{tile}, {kind} (rate {rate(points):.2f})")
    ax.axhline(0.01, color="grey", linewidth=0.8, linestyle=":")
    ax.text(12, 0.0115, "1 % tolerance", color="grey", fontsize=8)
    ax.set_xlabel("unknowns (mesh vertices)")
    ax.set_ylabel("relative gap |upper − lower| / λmax")
    ax.set_title("Homogenization bounds: gap against unknowns")
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(target)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
