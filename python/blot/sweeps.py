"""Speed against accuracy on your own scene: parameter sweeps, run serially or on Dask.

A sweep is a base scene, a set of runs (a grid of overrides, a list of them, or
both) and a reference run. Every run simulates the same duration; each records
its cost (wall and CPU time, per-stage times, peak memory) and its error against
the reference (metrics below), and the sweep writes a CSV table and an
error-against-cost chart with the Pareto front marked. docs/sweeps.md has the
file format and a worked example.

    import blot
    table = blot.sweep("my_sweep.json", executor="local", workers=2)

or from the command line: ``blot sweep my_sweep.json`` (which runs
``python3 -c "$MAIN_COMMAND" my_sweep.json``).

Metrics (all on the final state, on the rest shape of the cloth):
  * ``l2_error``: mass-weighted relative L2 error of the stain field,
    sqrt(sum_i A_i (s_i - r_i)^2 / sum_i A_i r_i^2) over the reference's vertices
    i, A_i their lumped areas, r_i the reference's field and s_i the run's field
    transferred to the reference vertex's rest position: identical meshes
    compare vertex by vertex; otherwise s is interpolated (barycentric) in the
    run's rest mesh at the reference vertex's rest position, in the face of the
    one-ring around the run's nearest rest vertex that contains it (or is
    nearest to containing it, weights clipped to the face).
  * ``stained_area_m2`` (sum of A_i where the field passes the threshold) and
    ``area_error``: |area - reference area| / reference area.
  * ``centroid_distance_m``: distance between the field-weighted centroids
    (sum A_i s_i x_i / sum A_i s_i, rest positions x_i) of run and reference.
The field is ``total_solute`` (free + absorbed + adsorbed solute, the pigment
that stays) unless the sweep names another; the threshold is
``stain_threshold`` kg/m2, default 1e-3 of the reference's maximum.
"""
from __future__ import annotations

import argparse
import copy
import csv
import itertools
import json
import math
import os
import resource
import subprocess
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np

FIELDS = ("solvent", "solute", "absorbed_solvent", "absorbed_solute", "adsorbed_solute",
          "total_solute", "total_solvent")

# Short names for common overrides; anything else is a JSON key path into the
# scene ("fabric.diffusivity", "physics.coriolis", "cloth.pins[0].point").
ALIASES = {
    "time_step": "time_step",
    "strain_tolerance": "strain_tolerance",
    "solver": "cloth.solver",
    "coupling": "coupling",
    "diffusivity": "fabric.diffusivity",
    "viscosity": "fabric.viscosity",
}
# Not a scene key: the loader's patch_resolution (quads across a "patch" mesh).
MESH_RESOLUTION = "mesh_resolution"
# Which end of each known axis is "finest" for reference "finest".
FINEST = {"time_step": min, "strain_tolerance": min, MESH_RESOLUTION: max}

# Table columns whose values depend on the machine and its load; everything
# else is the same whichever executor ran the sweep.
COST_COLUMNS = ("wall_s", "cpu_s", "wall_ms_per_step", "cpu_ms_per_step", "peak_rss_mb", "rss_before_mb", "worker")


# What a fresh interpreter runs for one isolated run (task JSON on stdin,
# result JSON on stdout). `python -m blot.sweeps` would warn that the module
# was imported twice (blot's __init__ imports it).
RUN_ONE_COMMAND = "import sys, blot.sweeps; sys.exit(blot.sweeps.main(['--run-one']))"
MAIN_COMMAND = "import sys, blot.sweeps; sys.exit(blot.sweeps.main())"


class SweepError(ValueError):
    """A sweep file that cannot be run: names the file, the key and what was expected."""


# --------------------------------------------------------------------------- overrides

def _split_path(path: str) -> List[Any]:
    """'cloth.pins[0].point' -> ['cloth', 'pins', 0, 'point']."""
    parts: List[Any] = []
    for token in path.split("."):
        if not token:
            raise KeyError(f"override '{path}': empty key in the path")
        while "[" in token:
            head, rest = token.split("[", 1)
            if head:
                parts.append(head)
            index, token = rest.split("]", 1)
            parts.append(int(index))
        if token:
            parts.append(token)
    return parts


def set_path(scene: Dict[str, Any], path: str, value: Any) -> None:
    """Sets scene[path] (dots between keys, [i] for list items), creating objects on the way."""
    keys = _split_path(ALIASES.get(path, path))
    node: Any = scene
    for i, key in enumerate(keys[:-1]):
        if isinstance(key, int):
            if not isinstance(node, list) or key >= len(node):
                raise KeyError(f"override '{path}': no list item [{key}] in the scene")
            node = node[key]
        else:
            if key not in node or not isinstance(node[key], (dict, list)):
                node[key] = {} if not isinstance(keys[i + 1], int) else []
            node = node[key]
    last = keys[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise KeyError(f"override '{path}': no list item [{last}] in the scene")
    node[last] = value


def apply_overrides(scene: Dict[str, Any], overrides: Dict[str, Any]):
    """The scene with overrides applied, and the patch resolution (0: the scene's)."""
    out = copy.deepcopy(scene)
    resolution = 0
    for key, value in overrides.items():
        if key == MESH_RESOLUTION:
            resolution = int(value)
        else:
            set_path(out, key, value)
    return out, resolution


# --------------------------------------------------------------------------- one run

def _field(engine, name: str) -> np.ndarray:
    if name == "total_solute":
        return np.asarray(engine.solute) + engine.absorbed_solute + engine.adsorbed_solute
    if name == "total_solvent":
        return np.asarray(engine.solvent) + engine.absorbed_solvent
    return np.array(getattr(engine, name))


def run_one(task: Dict[str, Any]) -> Dict[str, Any]:
    """Runs one sweep run in this process and returns its result (never raises).

    task: name, scene (dict), base_directory, resolution, duration, threads, field.
    """
    import blot  # here, so that a Dask worker imports it in its own process

    result: Dict[str, Any] = {"name": task["name"], "status": "ok", "error": "",
                              "worker": f"{os.uname().nodename}:{os.getpid()}"}
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    try:
        text = json.dumps(task["scene"])
        engine = blot.Engine.from_scene_json(text, base_directory=task["base_directory"],
                                             source_name=task["name"],
                                             patch_resolution=task.get("resolution", 0))
        engine.threads = task.get("threads", 1)
        h = engine.time_step
        steps = max(1, int(round(task["duration"] / h)))
        wall0, cpu0 = time.perf_counter(), time.process_time()
        error = ""
        try:
            engine.advance_steps(steps)
        except blot.StepError as e:  # the engine kept the last good state; the run failed
            error = str(e)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        stats = engine.statistics()
        done = stats["steps"]
        result.update({
            "steps": done,
            "time_step_s": h,
            "simulated_time_s": engine.time,
            "vertices": engine.vertex_count,
            "wall_s": wall,
            "cpu_s": cpu,
            "wall_ms_per_step": 1e3 * wall / max(done, 1),
            "cpu_ms_per_step": 1e3 * cpu / max(done, 1),
            "state_hash": f"{engine.state_hash:016x}",
            "intrinsic_refreshes": stats["intrinsic_refreshes"],
            "solute_budget_error": stats["mass_budget"]["solute_error"],
            "solvent_budget_error": stats["mass_budget"]["solvent_error"],
        })
        totals = stats["total_ms"]
        for stage, ms in totals["stages"].items():
            result[f"ms_{stage}"] = ms / max(done, 1)
        for part in ("cloth", "coupling"):
            result[f"ms_{part}"] = totals[part] / max(done, 1)
        if error:
            result["status"], result["error"] = "failed", error
        else:
            # C order, as after the JSON round trip of an isolated run: numpy's
            # sums depend on the layout in the last bits, and tables must not.
            result["rest_positions"] = np.ascontiguousarray(engine.rest_positions)
            result["faces"] = engine.faces
            result["areas"] = engine.vertex_areas
            result["field"] = _field(engine, task.get("field", "total_solute"))
    except Exception as e:  # a bad override or scene: a failed row, not a lost run
        result["status"], result["error"] = "failed", f"{type(e).__name__}: {e}"
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    result["peak_rss_mb"] = peak / 1024.0
    result["rss_before_mb"] = rss_before / 1024.0
    return result


def run_isolated(task: Dict[str, Any]) -> Dict[str, Any]:
    """run_one in a fresh interpreter (RUN_ONE_COMMAND): the peak
    memory is that run's own, and a crash fails this run only."""
    import blot
    package_parent = os.path.dirname(os.path.dirname(os.path.abspath(blot.__file__)))
    env = dict(os.environ)
    env["PYTHONPATH"] = package_parent + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    payload = json.dumps(task).encode()
    try:
        proc = subprocess.run([sys.executable, "-c", RUN_ONE_COMMAND], input=payload,
                              capture_output=True, env=env, check=False)
    except OSError as e:
        return {"name": task["name"], "status": "failed", "error": f"could not start {sys.executable}: {e}"}
    if proc.returncode != 0:
        tail = proc.stderr.decode(errors="replace").strip().splitlines()[-3:]
        return {"name": task["name"], "status": "failed", "worker": f"{os.uname().nodename}:{os.getpid()}",
                "error": f"run process exited with status {proc.returncode}: {' | '.join(tail)}"}
    data = json.loads(proc.stdout.decode())
    data["worker"] = f"{os.uname().nodename}:{os.getpid()}"  # the worker, not its short-lived run process
    for key in ("rest_positions", "faces", "areas", "field"):
        if key in data:
            data[key] = np.asarray(data[key], dtype=np.int32 if key == "faces" else np.float64)
    return data


def _run_one_main() -> int:
    task = json.loads(sys.stdin.buffer.read().decode())
    result = run_one(task)
    for key, value in list(result.items()):
        if isinstance(value, np.ndarray):
            result[key] = value.tolist()  # doubles round-trip exactly through repr-based JSON
    sys.stdout.write(json.dumps(result))
    return 0


# --------------------------------------------------------------------------- metrics

def _vertex_faces(faces: np.ndarray, n: int) -> np.ndarray:
    """#V x k array of incident faces per vertex, padded with -1."""
    counts = np.bincount(faces.ravel(), minlength=n)
    out = -np.ones((n, max(int(counts.max()), 1)), dtype=np.int64)
    fill = np.zeros(n, dtype=np.int64)
    for f, tri in enumerate(faces):
        for v in tri:
            out[v, fill[v]] = f
            fill[v] += 1
    return out


def transfer(points: np.ndarray, rest: np.ndarray, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
    """values (per vertex of the mesh rest/faces) interpolated at `points` (rest positions of
    another mesh of the same surface): barycentric in the face of the nearest vertex's
    one-ring that holds the point's projection (weights clipped to the face)."""
    nearest = np.empty(len(points), dtype=np.int64)
    for start in range(0, len(points), 512):
        chunk = points[start:start + 512]
        d2 = ((chunk[:, None, :] - rest[None, :, :]) ** 2).sum(axis=2)
        nearest[start:start + 512] = d2.argmin(axis=1)
    ring = _vertex_faces(faces, len(rest))[nearest]  # P x k candidate faces
    valid = ring >= 0
    f = np.where(valid, ring, 0)
    a, b, c = rest[faces[f, 0]], rest[faces[f, 1]], rest[faces[f, 2]]
    p = points[:, None, :]
    v0, v1, v2 = b - a, c - a, p - a
    d00 = (v0 * v0).sum(-1); d01 = (v0 * v1).sum(-1); d11 = (v1 * v1).sum(-1)
    d20 = (v2 * v0).sum(-1); d21 = (v2 * v1).sum(-1)
    den = d00 * d11 - d01 * d01
    wb = (d11 * d20 - d01 * d21) / den
    wc = (d00 * d21 - d01 * d20) / den
    wa = 1.0 - wb - wc
    weights = np.stack([wa, wb, wc], axis=-1)
    inside = np.where(valid, weights.min(axis=-1), -np.inf)
    best = inside.argmax(axis=1)
    rows = np.arange(len(points))
    w = np.clip(weights[rows, best], 0.0, None)
    w /= w.sum(axis=1, keepdims=True)
    tri = faces[f[rows, best]]
    return (w * values[tri]).sum(axis=1)


def _same_mesh(a: Dict[str, Any], b: Dict[str, Any]) -> bool:
    return (a["rest_positions"].shape == b["rest_positions"].shape
            and np.array_equal(a["rest_positions"], b["rest_positions"])
            and np.array_equal(a["faces"], b["faces"]))


def errors_against(run: Dict[str, Any], ref: Dict[str, Any], threshold: float) -> Dict[str, float]:
    """The documented metrics of one run against the reference (see the module docstring)."""
    areas, r = ref["areas"], ref["field"]
    s = run["field"] if _same_mesh(run, ref) else transfer(ref["rest_positions"], run["rest_positions"],
                                                           run["faces"], run["field"])
    norm = math.sqrt(float((areas * r * r).sum()))
    l2 = math.sqrt(float((areas * (s - r) ** 2).sum())) / norm if norm > 0 else float("nan")

    def area(result):
        return float(result["areas"][result["field"] > threshold].sum())

    def centroid(result):
        w = result["areas"] * result["field"]
        total = w.sum()
        return (w[:, None] * result["rest_positions"]).sum(axis=0) / total if total > 0 else np.full(3, np.nan)

    ref_area, run_area = area(ref), area(run)
    return {
        "l2_error": l2,
        "stained_area_m2": run_area,
        "area_error": abs(run_area - ref_area) / ref_area if ref_area > 0 else float("nan"),
        "centroid_distance_m": float(np.linalg.norm(centroid(run) - centroid(ref))),
    }


def pareto_front(costs: Sequence[float], errors: Sequence[float]) -> List[bool]:
    """True for each point no other point beats in both cost and error (ties kept)."""
    marks = []
    for i, (c, e) in enumerate(zip(costs, errors)):
        dominated = any((c2 <= c and e2 <= e and (c2 < c or e2 < e))
                        for j, (c2, e2) in enumerate(zip(costs, errors)) if j != i)
        marks.append(not dominated)
    return marks


# --------------------------------------------------------------------------- the sweep file

def _expect(cond: bool, where: str, message: str) -> None:
    if not cond:
        raise SweepError(f"{where}: {message}")


def load_sweep(path: str) -> Dict[str, Any]:
    with open(path, encoding="utf-8") as fh:
        try:
            spec = json.load(fh)
        except json.JSONDecodeError as e:
            raise SweepError(f"{path}: line {e.lineno}: {e.msg}") from None
    spec.setdefault("_source", path)
    spec.setdefault("_directory", os.path.dirname(os.path.abspath(path)))
    return spec


def plan(spec: Dict[str, Any]) -> Dict[str, Any]:
    """Checks a sweep spec and expands it into tasks: the runs, then the reference."""
    src = spec.get("_source", "<sweep>")
    directory = spec.get("_directory", os.getcwd())
    known = {"name", "description", "scene", "duration", "grid", "runs", "reference", "field",
             "stain_threshold", "threads", "output", "cost", "_source", "_directory"}
    for key in spec:
        _expect(key in known, src, f"unknown key '{key}' (expected one of {sorted(k for k in known if k[0] != '_')})")
    _expect("scene" in spec, src, "missing 'scene' (a scene file path or a scene object)")
    scene = spec["scene"]
    if isinstance(scene, str):
        scene_path = scene if os.path.isabs(scene) else os.path.join(directory, scene)
        _expect(os.path.exists(scene_path), f"{src}: scene", f"no file '{scene_path}'")
        with open(scene_path, encoding="utf-8") as fh:
            scene = json.load(fh)
        base_directory = os.path.dirname(os.path.abspath(scene_path))
        scene.setdefault("name", os.path.splitext(os.path.basename(scene_path))[0])
    else:
        _expect(isinstance(scene, dict), f"{src}: scene", "expected a file path or an object")
        base_directory = directory
    duration = spec.get("duration")
    _expect(isinstance(duration, (int, float)) and not isinstance(duration, bool) and 0 < duration <= 1e4,
            f"{src}: duration", f"expected simulated seconds in (0, 1e4], got {duration!r}")
    field = spec.get("field", "total_solute")
    _expect(field in FIELDS, f"{src}: field", f"expected one of {list(FIELDS)}, got {field!r}")
    cost = spec.get("cost", "cpu_s")
    _expect(cost in ("cpu_s", "wall_s"), f"{src}: cost", f"expected \"cpu_s\" or \"wall_s\", got {cost!r}")
    threads = spec.get("threads", 1)
    _expect(isinstance(threads, int) and 0 <= threads <= 1024, f"{src}: threads",
            f"expected an integer in [0, 1024], got {threads!r}")

    runs: List[Dict[str, Any]] = []
    grid = spec.get("grid", {})
    _expect(isinstance(grid, dict), f"{src}: grid", "expected an object of key: [values]")
    for key, values in grid.items():
        _expect(isinstance(values, list) and values, f"{src}: grid.{key}", "expected a non-empty list of values")
    if grid:
        keys = list(grid)
        combos = [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]

        def short(v):
            return f"{v:.4g}" if isinstance(v, float) else json.dumps(v)

        names = [" ".join(f"{k}={short(v)}" for k, v in c.items()) for c in combos]
        if len(set(names)) != len(names):  # values that differ past 4 digits: full precision
            names = [" ".join(f"{k}={json.dumps(v)}" for k, v in c.items()) for c in combos]
        runs += [{"name": n, "overrides": c} for n, c in zip(names, combos)]
    for i, run in enumerate(spec.get("runs", [])):
        where = f"{src}: runs[{i}]"
        _expect(isinstance(run, dict) and isinstance(run.get("overrides", {}), dict), where,
                "expected {\"name\": ..., \"overrides\": {key path: value}}")
        runs.append({"name": run.get("name", f"run {i}"), "overrides": dict(run.get("overrides", {}))})
    _expect(runs, src, "no runs: give 'grid', 'runs' or both")
    names = [r["name"] for r in runs]
    _expect(len(set(names)) == len(names), src, f"run names must be unique, got {names}")

    reference = spec.get("reference", "finest")
    if reference == "finest":
        ref_overrides = {}
        for key, values in grid.items():
            if key in FINEST:
                ref_overrides[key] = FINEST[key](values)
        ref = {"name": "reference (finest)", "overrides": ref_overrides}
    elif isinstance(reference, str):
        _expect(reference in names, f"{src}: reference", f"expected \"finest\" or a run name of {names}, got {reference!r}")
        ref = dict(next(r for r in runs if r["name"] == reference))
    else:
        _expect(isinstance(reference, dict) and isinstance(reference.get("overrides", {}), dict),
                f"{src}: reference", "expected \"finest\", a run name or {\"name\", \"overrides\"}")
        ref = {"name": reference.get("name", "reference"), "overrides": dict(reference.get("overrides", {}))}

    def task(run):
        t = {"name": run["name"], "overrides": run["overrides"], "base_directory": base_directory,
             "duration": float(duration), "threads": threads, "field": field}
        try:
            t["scene"], t["resolution"] = apply_overrides(scene, run["overrides"])
        except (KeyError, ValueError, TypeError) as e:  # a run the driver cannot even build: failed row
            t["scene"], t["resolution"], t["override_error"] = None, 0, str(e)
        return t

    return {"name": spec.get("name", scene.get("name", "sweep")), "tasks": [task(r) for r in runs],
            "reference": task(ref), "reference_is_run": isinstance(reference, str) and reference != "finest",
            "threshold": spec.get("stain_threshold"), "field": field, "axes": list(grid), "cost": cost,
            "output": spec.get("output")}


# --------------------------------------------------------------------------- executors

def _task_fn(isolate: bool) -> Callable[[Dict[str, Any]], Dict[str, Any]]:
    return _run_isolated_task if isolate else _run_task


def _run_task(task):
    if task.get("override_error"):
        return {"name": task["name"], "status": "failed", "error": task["override_error"]}
    return run_one(task)


def _run_isolated_task(task):
    if task.get("override_error"):
        return {"name": task["name"], "status": "failed", "error": task["override_error"]}
    return run_isolated(task)


def run_serial(tasks, isolate=True):
    fn = _task_fn(isolate)
    return [fn(t) for t in tasks]


def run_dask(tasks, scheduler: Optional[str] = None, workers: int = 2, isolate=True):
    """One Dask task per run: on the cluster at `scheduler` (an address such as
    tcp://host:8786) or on a LocalCluster of `workers` single-threaded worker processes."""
    from dask.distributed import Client, LocalCluster

    fn = _task_fn(isolate)
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        futures = client.map(fn, tasks, pure=False, key=[f"blot-run-{i}" for i in range(len(tasks))])
        results = []
        for task, future in zip(tasks, futures):
            try:
                results.append(future.result())
            except Exception as e:  # the worker died or the task could not run there
                results.append({"name": task["name"], "status": "failed", "error": f"dask: {type(e).__name__}: {e}"})
        return results
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# --------------------------------------------------------------------------- table and chart

def _columns(rows, axes):
    first = ["name", "status", "is_reference"] + axes + [
        "l2_error", "area_error", "centroid_distance_m", "stained_area_m2", "pareto",
        "steps", "time_step_s", "simulated_time_s", "vertices",
        "wall_s", "cpu_s", "wall_ms_per_step", "cpu_ms_per_step", "peak_rss_mb", "rss_before_mb"]
    stage = sorted({k for r in rows for k in r if k.startswith("ms_")})
    last = ["intrinsic_refreshes", "solute_budget_error", "solvent_budget_error", "state_hash", "worker",
            "overrides", "error"]
    return first + stage + last


def _format(value):
    if isinstance(value, float):
        return repr(value)  # shortest exact text
    if isinstance(value, bool):
        return "true" if value else "false"
    return "" if value is None else str(value)


def write_csv(path, rows, columns):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_format(row.get(c)) for c in columns])
    os.replace(tmp, path)


def _label(row, axes):
    """A point's label: its grid values in axis order (the title names the axes), else its name."""
    values = [row.get(a, "") for a in axes]
    if axes and all(values):
        return ", ".join(f"{float(v):.4g}" if v.replace(".", "", 1).replace("e-", "", 1).isdigit() else v
                         for v in values)
    return row["name"]


def write_chart(path, rows, title, cost="cpu_s", axes=()):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "ok" and not r.get("is_reference") and
          r.get("l2_error") is not None and math.isfinite(r["l2_error"])]
    failed = [r for r in rows if r["status"] != "ok"]
    fig, ax = plt.subplots(figsize=(7.5, 5), dpi=110)
    if ok:
        positive = [r["l2_error"] for r in ok if r["l2_error"] > 0]
        floor = min(positive) / 10 if positive else 1e-16
        xs = [r[cost] for r in ok]
        ys = [max(r["l2_error"], floor) for r in ok]
        front = [r.get("pareto", False) for r in ok]
        ax.scatter([x for x, f in zip(xs, front) if not f], [y for y, f in zip(ys, front) if not f],
                   c="0.6", s=30, label="run")
        fx = sorted((x, y) for x, y, f in zip(xs, ys, front) if f)
        ax.plot([p[0] for p in fx], [p[1] for p in fx], "o-", c="tab:red", ms=7, lw=1.5, label="Pareto front")
        for k, (r, x, y) in enumerate(zip(ok, xs, ys)):
            ax.annotate(_label(r, axes), (x, y), textcoords="offset points", fontsize=6,
                        xytext=(4, 4 if k % 2 == 0 else -9))
        ax.set_xscale("log")
        ax.set_yscale("log")
    ref = [r for r in rows if r.get("is_reference")]
    if ref and ref[0]["status"] == "ok":
        ax.axvline(ref[0][cost], c="tab:blue", ls=":", lw=1, label=f"reference ({ref[0][cost]:.3g} s)")
    ax.set_xlabel("cost: " + ("wall" if cost == "wall_s" else "CPU") + " time of the run's steps (s)")
    ax.set_ylabel("error: mass-weighted relative L2 of the stain")
    note = f", {len(failed)} failed (see table)" if failed else ""
    legend = f"\nlabels: {', '.join(axes)}" if axes else ""
    ax.set_title(f"{title}: {len(ok)} runs{note}{legend}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path + ".tmp.png"
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


# --------------------------------------------------------------------------- the whole sweep

def sweep(spec, executor: str = "local", scheduler: Optional[str] = None, workers: int = 2,
          output: Optional[str] = None, isolate: bool = True) -> List[Dict[str, Any]]:
    """Runs a sweep and writes <output>/sweep.csv and <output>/sweep.png.

    spec: a sweep file path or the same as a dict. executor: "serial", "local"
    (a Dask LocalCluster of `workers` processes) or "dask" with `scheduler` an
    address. isolate: each run in its own interpreter (per-run peak memory).
    Returns the table rows (dicts); a failed run is a row with status "failed"
    and its error.
    """
    if isinstance(spec, str):
        spec = load_sweep(spec)
    p = plan(spec)
    tasks = p["tasks"] + ([] if p["reference_is_run"] else [p["reference"]])
    if executor == "serial":
        results = run_serial(tasks, isolate=isolate)
    elif executor in ("local", "dask"):
        if executor == "dask" and not scheduler:
            raise SweepError("executor 'dask' needs a scheduler address (e.g. tcp://host:8786)")
        results = run_dask(tasks, scheduler=scheduler, workers=workers, isolate=isolate)
    else:
        raise SweepError(f"executor: expected 'serial', 'local' or 'dask', got {executor!r}")

    runs = results[:len(p["tasks"])]
    ref = (next(r for r in runs if r["name"] == p["reference"]["name"]) if p["reference_is_run"]
           else results[-1])
    rows = []
    for task, result in zip(tasks, results):
        row = {k: v for k, v in result.items() if not isinstance(v, np.ndarray)}
        row["overrides"] = json.dumps(task["overrides"], sort_keys=True)
        for axis in p["axes"]:
            row[axis] = json.dumps(task["overrides"].get(axis)) if axis in task["overrides"] else ""
        row["is_reference"] = task["name"] == p["reference"]["name"] and (result is ref)
        rows.append(row)
    if ref["status"] == "ok":
        threshold = p["threshold"] if p["threshold"] is not None else 1e-3 * float(ref["field"].max())
        for row, result in zip(rows, results):
            if result["status"] == "ok":
                row.update(errors_against(result, ref, threshold))
    else:
        for row in rows:
            if row["status"] == "ok":
                row["error"] = f"no error metrics: the reference failed ({ref['error']})"
    candidates = [r for r in rows if r["status"] == "ok" and not r["is_reference"] and "l2_error" in r
                  and math.isfinite(r["l2_error"])]
    for r, mark in zip(candidates, pareto_front([r[p["cost"]] for r in candidates],
                                                [r["l2_error"] for r in candidates])):
        r["pareto"] = mark

    if output:
        out = output
    elif p["output"]:  # relative to the sweep file
        out = os.path.join(spec.get("_directory", "."), p["output"])
    else:
        out = os.path.join("out", "sweep_" + p["name"].replace(" ", "_"))
    os.makedirs(out, exist_ok=True)
    write_csv(os.path.join(out, "sweep.csv"), rows, _columns(rows, p["axes"]))
    write_chart(os.path.join(out, "sweep.png"), rows, p["name"], cost=p["cost"], axes=p["axes"])
    return rows


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--run-one"]:
        return _run_one_main()
    parser = argparse.ArgumentParser(prog="blot sweep", description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep file (JSON, docs/sweeps.md)")
    parser.add_argument("--executor", choices=["serial", "local", "dask"], default="local",
                        help="serial: this process; local: a Dask LocalCluster (default); dask: --scheduler")
    parser.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://host:8786 (implies --executor dask)")
    parser.add_argument("--workers", type=int, default=2, help="local cluster worker processes (default 2)")
    parser.add_argument("--out", help="output folder (default: the sweep's 'output', else out/sweep_<name>)")
    parser.add_argument("--in-process", action="store_true",
                        help="run each run inside the worker instead of its own interpreter "
                             "(peak memory is then the worker's high-water mark)")
    args = parser.parse_args(argv)
    executor = "dask" if args.scheduler else args.executor
    try:
        rows = sweep(args.sweep, executor=executor, scheduler=args.scheduler, workers=args.workers,
                     output=args.out, isolate=not args.in_process)
    except (SweepError, OSError) as e:
        print(f"blot sweep: error: {e}", file=sys.stderr)
        return 1
    failed = [r for r in rows if r["status"] != "ok"]
    for r in rows:
        err = r.get("l2_error")
        print(f"{r['name']:<40} {r['status']:<7} "
              f"{'' if err is None else f'l2 {err:.3e}'}  {r.get('cpu_s', float('nan')):.3f} s CPU"
              + (f"  {r['error']}" if r["status"] != "ok" else ""))
    print(f"{len(rows)} runs, {len(failed)} failed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
