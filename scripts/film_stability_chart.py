#!/usr/bin/python3
"""The stability map of the film model against the paper's equations, from the
table of `blot sweep docs/sweeps/film_stability.json` (scripts/film_stability
runs the sweep on a local Dask cluster, then this).

Each run is classed by what happened to the liquid, a drop released at rest on
the wall of a still bowl. dz is the height of the drop's highest surface above
the bowl's lowest point (the highest rest vertex within the landing radius plus
the landing bump's peak thickness, 3 m / (rho pi r^2)). Released at rest, no
liquid can move faster than a frictionless fall from there, sqrt(2 g dz), and
the liquid's kinetic energy cannot pass M g dz (M its mass: every drop falling
the whole height, the pressure's energy included). A run breaks a bound when
its largest speed (sweeps' max_speed_m_s, over the film) or its peak kinetic
energy passes it.
  * "step failed": the engine refused a step (a non-finite value, a negative mass);
  * "blows up": a bound broken, and the kinetic energy at the end still more
    than half of its peak (moving on at an unphysical speed);
  * "overshoots": a bound broken, then the liquid comes to rest (the end's
    kinetic energy under half the peak);
  * "not settling": no bound broken, but still moving at the end;
  * "stable": none of these; the liquid comes to rest.

usage: film_stability_chart.py SWEEP_JSON SWEEP_CSV CHART_PNG [--doc ACCURACY_MD --command TEXT --wall S] [--check]
With --doc, the table between the markers <!-- film_stability:begin --> and
<!-- film_stability:end --> in that file is replaced by this run's, with a line
saying when, on which machine and by which command it was made. --check exits 1
unless every run of the paper's model blows up and every run of the film model
is stable.
"""
import argparse
import csv
import datetime
import json
import math
import os
import platform
import re

import numpy as np

G = 9.8  # the scene's |gravity| (the default [0, 0, -9.8])
RHO = 1000.0  # liquid_density (kg/m3), the default
STATES = [  # (class, marker, colour, legend)
    ("stable", "o", "#2a9d3a", "stable: within the bounds, comes to rest"),
    ("not settling", "s", "#9ab000", "within the bounds, still moving at the end"),
    ("overshoots", "D", "#e0a000", "overshoots: speed > sqrt(2 g dz) or energy > M g dz, then rests"),
    ("blows up", "^", "#e05000", "blows up: beyond a bound and still moving at the end"),
    ("step failed", "X", "#b00020", "step failed: the engine refused a step"),
]


def load_mesh_z(path):
    vertices = []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                vertices.append([float(t) for t in line.split()[1:4]])
    return np.array(vertices)


def fall_height(spec, spec_dir, mass):
    """dz (m) for a drop of `mass` kg landing as the sweep's scene says."""
    scene = spec["scene"]
    vertices = load_mesh_z(os.path.join(spec_dir, scene["mesh"]["file"]))
    drop = scene["drops"][0]
    centre, radius = np.array(drop["point"]), drop["radius"]
    near = np.linalg.norm(vertices - centre, axis=1) < radius
    peak_thickness = 3.0 * mass / (RHO * math.pi * radius ** 2)
    return vertices[near, 2].max() - vertices[:, 2].min() + peak_thickness


def classify(row, dz):
    if row["status"] != "ok":
        return "step failed"
    beyond = (float(row["max_speed_m_s"]) > math.sqrt(2.0 * G * dz)
              or float(row["peak_kinetic_energy_j"]) > float(row["free_liquid_kg"]) * G * dz)
    moving = float(row["kinetic_energy_j"]) > 0.5 * float(row["peak_kinetic_energy_j"])
    if beyond:
        return "blows up" if moving else "overshoots"
    return "not settling" if moving else "stable"


def read_runs(spec, spec_dir, csv_path):
    scene = spec["scene"]
    base_model = scene.get("physics", {}).get("model", "film")
    base_nu = scene.get("liquid", {}).get("kinematic_viscosity", 1e-6)
    runs = []
    with open(csv_path, newline="") as fh:
        for row in csv.DictReader(fh):
            o = json.loads(row["overrides"])
            mass = o.get("drops[0].solvent_mass", scene["drops"][0]["solvent_mass"])
            dz = fall_height(spec, spec_dir, mass)
            runs.append({
                "model": o.get("physics.model", base_model),
                "h": o.get("time_step", scene["time_step"]),
                "nu": o.get("liquid.kinematic_viscosity", base_nu),
                "mass": mass,
                "thickness_mm": 1e3 * mass / (RHO * math.pi * scene["drops"][0]["radius"] ** 2),
                "bound": math.sqrt(2.0 * G * dz),
                "speed": float(row["max_speed_m_s"]) if row["max_speed_m_s"] else float("nan"),
                "energy_ratio": (float(row["peak_kinetic_energy_j"]) / (float(row["free_liquid_kg"]) * G * dz)
                                 if row["peak_kinetic_energy_j"] else float("nan")),
                "t_end": float(row["simulated_time_s"]) if row["simulated_time_s"] else float("nan"),
                "class": classify(row, dz),
                "error": row["error"],
                "cpu_s": float(row["cpu_s"]) if row["cpu_s"] else float("nan"),
            })
    return runs


def draw(runs, png, duration):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    film_nus = sorted({r["nu"] for r in runs if r["model"] == "film"})
    panels = [("film", nu) for nu in film_nus] + [("paper", None)]
    cols = 2
    rows = (len(panels) + cols - 1) // cols
    fig, grid = plt.subplots(rows, cols, figsize=(11, 4.1 * rows + 1.2), sharey=True, squeeze=False)
    axes = grid.ravel()
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    hs = sorted({r["h"] for r in runs})
    thick = sorted({r["thickness_mm"] for r in runs})
    for ax, (model, nu) in zip(axes, panels):
        mine = [r for r in runs if r["model"] == model and (nu is None or r["nu"] == nu)]
        for name, marker, colour, legend in STATES:
            pts = [r for r in mine if r["class"] == name]
            ax.scatter([r["h"] for r in pts], [r["thickness_mm"] for r in pts], marker=marker, s=170,
                       color=colour, edgecolor="black", linewidth=0.6, label=legend, zorder=3)
        for r in mine:
            text = f"{r['speed']:.2g} m/s" if r["class"] != "step failed" else f"t={r['t_end']:.2g} s"
            ax.annotate(text, (r["h"], r["thickness_mm"]), textcoords="offset points", xytext=(0, 11),
                        ha="center", fontsize=7.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(hs)
        ax.set_xticklabels([f"{h:g}" for h in hs])
        ax.set_yticks(thick)
        ax.set_yticklabels([f"{t:.2g}" for t in thick])
        ax.minorticks_off()
        ax.set_xlim(hs[0] / 1.8, hs[-1] * 1.8)
        ax.set_ylim(thick[0] / 2.2, thick[-1] * 2.5)
        ax.set_xlabel("time step h (s)")
        ax.grid(True, color="#dddddd", zorder=0)
        ax.set_title(f"film model, ν = {nu:g} m²/s" if model == "film" else "paper's equations (no friction: any ν)",
                     fontsize=10)
    for ax in grid[:, 0]:
        ax.set_ylabel("drop's mean thickness m / (ρ π r²) (mm)")
    handles, labels = axes[0].get_legend_handles_labels()
    for ax in axes[1:]:
        for h, l in zip(*ax.get_legend_handles_labels()):
            if l not in labels:
                handles.append(h)
                labels.append(l)
    order = [s[3] for s in STATES]
    pairs = sorted(zip(handles, labels), key=lambda p: order.index(p[1]))
    fig.legend([p[0] for p in pairs], [p[1] for p in pairs], loc="lower center", ncol=2, fontsize=9, frameon=False)
    fig.suptitle(f"A drop released on the wall of a still bowl, {duration:g} s: where each model blows up\n"
                 "(label: the liquid's largest speed, or when the failed step came)", fontsize=11)
    fig.tight_layout(rect=(0, 0.09, 1, 0.95))
    fig.savefig(png, dpi=110)


def table(runs):
    """Markdown: one row per (model, h, thickness), one column per viscosity; each
    cell the class, the largest speed (m/s) and the peak kinetic energy over M g dz."""
    nus = sorted({r["nu"] for r in runs if r["model"] == "film"})
    lines = ["| model | h (s) | mean thickness (mm) | √(2 g dz) (m/s) | "
             + " | ".join(f"ν = {nu:g} m²/s" for nu in nus) + " |",
             "|---|---:|---:|---:|" + "---|" * len(nus)]

    def cell(r):
        if r["class"] == "step failed":
            return f"**step failed** at {r['t_end']:.3g} s"
        mark = {"blows up": "**blows up**", "overshoots": "overshoots", "not settling": "not settling",
                "stable": "stable"}[r["class"]]
        return f"{mark}: {r['speed']:.3g} m/s, {r['energy_ratio']:.2g}"

    for model in ("film", "paper"):
        for h in sorted({r["h"] for r in runs}):
            for t in sorted({r["thickness_mm"] for r in runs}):
                mine = [r for r in runs if r["model"] == model and r["h"] == h and r["thickness_mm"] == t]
                if not mine:
                    continue
                if model == "paper":  # one run: no friction, the viscosity does not enter
                    cells = [cell(mine[0]) + " (any ν)"] + [""] * (len(nus) - 1)
                else:
                    by_nu = {r["nu"]: r for r in mine}
                    cells = [cell(by_nu[nu]) if nu in by_nu else "" for nu in nus]
                lines.append(f"| {model} | {h:g} | {t:.3g} | {mine[0]['bound']:.3g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{platform.node()} ({cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f})"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sweep_json")
    ap.add_argument("sweep_csv")
    ap.add_argument("chart_png")
    ap.add_argument("--doc", help="markdown file whose film_stability markers get this run's table")
    ap.add_argument("--command", default="scripts/film_stability", help="the command named in the generated line")
    ap.add_argument("--wall", type=float, help="the sweep's wall-clock seconds, for the generated line")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 unless every run of the paper's model blows up (the known failure) and every run "
                         "of the film model is stable")
    args = ap.parse_args()
    with open(args.sweep_json) as fh:
        spec = json.load(fh)
    runs = read_runs(spec, os.path.dirname(os.path.abspath(args.sweep_json)), args.sweep_csv)
    draw(runs, args.chart_png, spec["duration"])
    md = table(runs)
    print(md)
    counts = {m: {s[0]: sum(1 for r in runs if r["model"] == m and r["class"] == s[0]) for s in STATES}
              for m in ("film", "paper")}
    for m, c in counts.items():
        print(f"{m}: " + ", ".join(f"{n} {k}" for k, n in c.items()))
    if args.doc:
        now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        took = f", {args.wall:.0f} s of wall clock for {len(runs)} runs on two workers" if args.wall else ""
        generated = f"Generated by `{args.command}` on {now}; machine: {machine()}{took}."
        with open(args.doc, encoding="utf-8") as fh:
            text = fh.read()
        pattern = re.compile(r"(<!-- film_stability:begin -->\n).*?(<!-- film_stability:end -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"{args.doc}: no <!-- film_stability:begin --> ... <!-- film_stability:end --> markers")
        text = pattern.sub(lambda m: m.group(1) + md + "\n\n" + generated + "\n" + m.group(2), text)
        with open(args.doc, "w", encoding="utf-8") as fh:
            fh.write(text)

    if args.check:
        problems = [f"paper, h={r['h']:g}, {r['thickness_mm']:.3g} mm: {r['class']}, expected to blow up"
                    for r in runs if r["model"] == "paper" and r["class"] not in ("blows up", "step failed")]
        problems += [f"film, h={r['h']:g}, ν={r['nu']:g}, {r['thickness_mm']:.3g} mm: {r['class']}"
                     for r in runs if r["model"] == "film" and r["class"] != "stable"]
        if problems:
            print("film_stability: FAILED:\n  " + "\n  ".join(problems))
            raise SystemExit(1)
        print("film_stability: map OK (the paper's model blows up in every run; the film model is stable in "
              "every run)")


if __name__ == "__main__":
    main()
