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

The free liquid's motion, for stability studies: ``max_speed_m_s`` (the largest
speed relative to the cloth at a vertex holding at least 1e-3 of the largest
free-liquid density) and
``peak_kinetic_energy_j`` (sum_i A_i sigma_i |u_i|^2 / 2, sigma the free solvent
and solute) are the largest over ``samples`` equally spaced measurements of the
run (the last at its end, or at the last good step of a failed run);
``kinetic_energy_j`` and ``free_liquid_kg`` are the last one's.
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
import stat
import subprocess
import sys
import tempfile
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
PATH_SYNTAX = "expected keys between dots and list indices [i], e.g. 'drops[0].radius'"

# The largest sweep or scene file read: the C++ loaders' limit for JSON
# (kJsonFileByteLimit, 16 MiB). Anything else than a regular file is refused.
FILE_BYTE_LIMIT = 16 << 20
# The most runs (grid combinations and listed runs) one sweep may have: each
# holds its own copy of the scene until it runs.
MAX_RUNS = 10000
# The most worker processes of a local cluster.
MAX_WORKERS = 1024
# The most measurements of the liquid's motion per run (the sweep's "samples").
MAX_SAMPLES = 100000
# The share of the largest free-liquid density (solvent + solute) a vertex must
# hold for its speed to count in max_speed_m_s: the film, not the traces of a
# few nanometres at its wet front, where the wicking flux's velocity can be
# large while the liquid it moves is not.
FILM_FRACTION = 1e-3

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
    """'cloth.pins[0].point' -> ['cloth', 'pins', 0, 'point'] (ValueError: what is wrong with it)."""
    parts: List[Any] = []
    for token in path.split("."):
        if not token:
            raise ValueError(f"empty key in the path ({PATH_SYNTAX})")
        while "[" in token:
            head, rest = token.split("[", 1)
            if "]" in head:
                raise ValueError(f"']' without '[' ({PATH_SYNTAX})")
            if head:
                parts.append(head)
            index, closed, token = rest.partition("]")
            if not closed:
                raise ValueError(f"'[' without ']' ({PATH_SYNTAX})")
            if not (index.isascii() and index.isdigit()):
                raise ValueError(f"list index [{index}]: expected an integer >= 0")
            if token and not token.startswith("["):
                raise ValueError(f"'{token}' right after ']' ({PATH_SYNTAX})")
            parts.append(int(index))
        if "]" in token:
            raise ValueError(f"']' without '[' ({PATH_SYNTAX})")
        if token:
            parts.append(token)
    return parts


def _path_text(keys: List[Any]) -> str:
    text = ""
    for key in keys:
        text += f"[{key}]" if isinstance(key, int) else ("." if text else "") + key
    return text


def set_path(scene: Dict[str, Any], path: str, value: Any) -> None:
    """Sets scene[path] (dots between keys, [i] for list items), creating objects on the way.

    ValueError (what is wrong, without the path) for a malformed path or one the
    scene's lists do not have."""
    keys = _split_path(ALIASES.get(path, path))
    node: Any = scene
    for i, key in enumerate(keys):
        here = _path_text(keys[:i + 1])
        if isinstance(key, int):
            if not isinstance(node, list):
                raise ValueError(f"'{here}': the scene has no list there (an object or a value)")
            if key >= len(node):
                raise ValueError(f"'{here}': no list item [{key}] in the scene (the list has {len(node)})")
        elif isinstance(node, list):
            raise ValueError(f"'{here}': the scene has a list there: expected an index [i] before '{key}'")
        if i == len(keys) - 1:
            node[key] = value
        elif isinstance(key, int):
            node = node[key]
        else:
            if key not in node or not isinstance(node[key], (dict, list)):
                node[key] = {} if not isinstance(keys[i + 1], int) else []
            node = node[key]


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _json_problem(value: Any, path: str = "") -> Optional[str]:
    """What in `value` is not plain JSON with finite numbers (the scene loader's input), or None."""
    where = f" at '{path}'" if path else ""
    if isinstance(value, float):
        return None if math.isfinite(value) else f"expected a finite number{where}, got {value!r}"
    if value is None or isinstance(value, (str, int)):  # bool is an int
        return None
    if isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            problem = _json_problem(item, f"{path}[{i}]")
            if problem:
                return problem
        return None
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                return f"expected string keys{where}, got {key!r}"
            problem = _json_problem(item, f"{path}.{key}" if path else key)
            if problem:
                return problem
        return None
    return f"expected JSON data{where}, got a {type(value).__name__} {value!r}"


def _resolution_problem(value: Any) -> Optional[str]:
    if _is_number(value) and math.isfinite(value) and float(value).is_integer() and abs(value) < 2 ** 31:
        return None
    return f"expected an integer number of quads across the patch (0: the scene's), got {value!r}"


def check_override(key: Any, value: Any) -> None:
    """ValueError (naming the key, the value and what was expected) for an override
    that no scene could take: a malformed key path, a non-finite number or a value
    that is not JSON, a mesh_resolution that is not an integer."""
    if not isinstance(key, str):
        raise ValueError(f"override {key!r}: expected a key path string ({PATH_SYNTAX})")
    if key != MESH_RESOLUTION:
        try:
            _split_path(ALIASES.get(key, key))
        except ValueError as e:
            raise ValueError(f"override '{key}' = {value!r}: {e}") from None
    problem = _json_problem(value) or (_resolution_problem(value) if key == MESH_RESOLUTION else None)
    if problem:
        raise ValueError(f"override '{key}': {problem}")


def apply_overrides(scene: Dict[str, Any], overrides: Dict[str, Any]):
    """The scene with overrides applied, and the patch resolution (0: the scene's).

    ValueError naming the override for one that cannot apply (check_override, set_path)."""
    out = copy.deepcopy(scene)
    resolution = 0
    for key, value in overrides.items():
        check_override(key, value)
        if key == MESH_RESOLUTION:
            resolution = int(value)
        else:
            try:
                set_path(out, key, value)
            except ValueError as e:
                raise ValueError(f"override '{key}' = {value!r}: {e}") from None
    return out, resolution


# --------------------------------------------------------------------------- one run

def _field(engine, name: str) -> np.ndarray:
    if name == "total_solute":
        return np.asarray(engine.solute) + engine.absorbed_solute + engine.adsorbed_solute
    if name == "total_solvent":
        return np.asarray(engine.solvent) + engine.absorbed_solvent
    return np.array(getattr(engine, name))


def _liquid_motion(engine, areas: np.ndarray) -> Dict[str, float]:
    """The free liquid's largest speed (m/s, relative to the cloth, over vertices
    holding at least FILM_FRACTION of the largest density), kinetic energy (J, on
    the rest areas) and mass (kg)."""
    sigma = np.asarray(engine.solvent) + np.asarray(engine.solute)
    u = np.asarray(engine.velocities)
    speed2 = np.einsum("ij,ij->i", u, u)
    top = float(sigma.max()) if sigma.size else 0.0
    wet = (sigma >= FILM_FRACTION * top) & (sigma > 0)
    return {"max_speed_m_s": float(np.sqrt(speed2[wet].max())) if wet.any() else 0.0,
            "kinetic_energy_j": float(0.5 * np.dot(areas * sigma, speed2)),
            "free_liquid_kg": float(np.dot(areas, sigma))}


def run_one(task: Dict[str, Any]) -> Dict[str, Any]:
    """Runs one sweep run in this process and returns its result (never raises).

    task: name, scene (dict), base_directory, resolution, duration, threads, field,
    samples (measurements of the liquid's motion, default 1: the end only).
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
        samples = max(1, min(int(task.get("samples", 1)), steps))
        areas = np.asarray(engine.vertex_areas)
        motion: Dict[str, float] = {}
        measure_wall = measure_cpu = 0.0
        wall0, cpu0 = time.perf_counter(), time.process_time()
        error = ""
        done_steps = 0
        for k in range(1, samples + 1):
            # Equal shares of the steps (the same bits as one call: the engine's
            # steps do not depend on how they are grouped into calls).
            count = (k * steps) // samples - done_steps
            try:
                engine.advance_steps(count)
            except blot.StepError as e:  # the engine kept the last good state; the run failed
                error = str(e)
            done_steps += count
            t0, c0 = time.perf_counter(), time.process_time()
            now = _liquid_motion(engine, areas)
            motion["max_speed_m_s"] = max(motion.get("max_speed_m_s", 0.0), now["max_speed_m_s"])
            motion["peak_kinetic_energy_j"] = max(motion.get("peak_kinetic_energy_j", 0.0), now["kinetic_energy_j"])
            motion["kinetic_energy_j"], motion["free_liquid_kg"] = now["kinetic_energy_j"], now["free_liquid_kg"]
            measure_wall += time.perf_counter() - t0
            measure_cpu += time.process_time() - c0
            if error:
                break
        # The cost is the steps' alone.
        wall, cpu = time.perf_counter() - wall0 - measure_wall, time.process_time() - cpu0 - measure_cpu
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
        result.update(motion)
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


def _known_keys(obj: Dict[str, Any], known: Sequence[str], where: str) -> None:
    for key in obj:
        _expect(key in known, where, f"unknown key {key!r} (expected {' or '.join(repr(k) for k in known)})")


def _json_kind(value: Any) -> str:
    if isinstance(value, bool):
        return "true/false"
    if _is_number(value):
        return "a number"
    if value is None:
        return "null"
    kinds = {str: "a string", list: "a list", tuple: "a list", dict: "an object"}
    return kinds.get(type(value), f"a {type(value).__name__}")


def _file_kind(mode: int) -> str:
    for test, kind in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "not a regular file"


def read_json_file(path: str, what: str, where: str = "") -> Any:
    """The JSON value in the file `path`; `what` ("sweep file", "scene") and the
    prefix `where` (the sweep file and key that named it) go into errors.

    SweepError naming the file for anything but a regular file or a named pipe
    of at most FILE_BYTE_LIMIT bytes of UTF-8 JSON: a directory or a device
    (/dev/zero) is refused before one byte is read. A pipe is opened without
    waiting for a writer, then read as the C++ loaders read one
    (stain::readFileBounded): a shell's <(...) gives its bytes, a stray pipe
    nobody writes to reads as empty at once and is refused."""
    try:
        # Without waiting: open() of a named pipe blocks until a writer comes.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as e:
        raise SweepError(f"{where}{path}: cannot open the {what}: {e.strerror}") from None
    chunks: List[bytes] = []
    try:
        info = os.fstat(fd)
        pipe = stat.S_ISFIFO(info.st_mode)
        _expect(stat.S_ISREG(info.st_mode) or pipe, f"{where}{path}",
                f"the {what} is {_file_kind(info.st_mode)}, expected a regular file")
        if pipe:
            os.set_blocking(fd, True)  # a writer's bytes are awaited; with none, EOF at once
        _expect(info.st_size <= FILE_BYTE_LIMIT, f"{where}{path}",
                f"the {what} is {info.st_size} bytes, more than the limit of {FILE_BYTE_LIMIT} bytes")
        size = 0
        while size <= FILE_BYTE_LIMIT:  # no more, should it grow while read
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as e:
        raise SweepError(f"{where}{path}: cannot read the {what}: {e.strerror}") from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    _expect(data or not pipe, f"{where}{path}",
            f"the {what} is a named pipe with nothing written to it (no writer)")
    _expect(len(data) <= FILE_BYTE_LIMIT, f"{where}{path}",
            f"the {what} has more than the limit of {FILE_BYTE_LIMIT} bytes (it grew while read)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise SweepError(f"{where}{path}: line {line}: the {what} is not UTF-8 text "
                         f"(byte 0x{data[e.start]:02x} at offset {e.start})") from None
    if text.startswith("\ufeff"):  # a byte order mark: not part of the JSON
        text = text[1:]
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise SweepError(f"{where}{path}: line {e.lineno}: the {what} is not valid JSON: {e.msg}") from None


def load_sweep(path: str) -> Dict[str, Any]:
    """The sweep file at `path` (read_json_file), with where it came from; plan() checks its keys."""
    spec = read_json_file(path, "sweep file")
    _expect(isinstance(spec, dict), path,
            f"expected a JSON object of sweep keys (docs/sweeps.md), got {_json_kind(spec)}")
    spec.setdefault("_source", path)
    spec.setdefault("_directory", os.path.dirname(os.path.abspath(path)))
    return spec


def plan(spec: Dict[str, Any]) -> Dict[str, Any]:
    """Checks a sweep spec and expands it into tasks: the runs, then the reference.

    Every error in the spec (and in the scene it names, and every override that
    cannot apply to that scene) is a SweepError here, before any run starts."""
    _expect(isinstance(spec, dict), "sweep",
            f"expected a sweep file path or a dict of sweep keys (docs/sweeps.md), got {_json_kind(spec)}")
    src = spec.get("_source", "<sweep>")
    directory = spec.get("_directory", os.getcwd())
    known = {"name", "description", "scene", "duration", "grid", "runs", "reference", "field",
             "stain_threshold", "threads", "output", "cost", "samples", "_source", "_directory"}
    for key in spec:
        _expect(key in known, src, f"unknown key '{key}' (expected one of {sorted(k for k in known if k[0] != '_')})")
    _expect("scene" in spec, src, "missing 'scene' (a scene file path or a scene object)")
    for key in ("name", "description"):
        _expect(isinstance(spec.get(key, ""), str), f"{src}: {key}", f"expected a string, got {spec.get(key)!r}")
    scene = spec["scene"]
    if isinstance(scene, str):
        _expect(bool(scene), f"{src}: scene", "expected a file path or an object, got ''")
        scene_path = scene if os.path.isabs(scene) else os.path.join(directory, scene)
        _expect(os.path.exists(scene_path), f"{src}: scene", f"no file '{scene_path}'")
        scene = read_json_file(scene_path, "scene", where=f"{src}: scene: ")
        _expect(isinstance(scene, dict), f"{src}: scene: {scene_path}",
                f"expected a scene object (docs/scene-format.md), got {_json_kind(scene)}")
        base_directory = os.path.dirname(os.path.abspath(scene_path))
        scene.setdefault("name", os.path.splitext(os.path.basename(scene_path))[0])
    else:
        _expect(isinstance(scene, dict), f"{src}: scene", "expected a file path or an object")
        base_directory = directory
    problem = _json_problem(scene)
    _expect(not problem, f"{src}: scene", problem or "")
    duration = spec.get("duration")
    _expect(_is_number(duration) and 0 < duration <= 1e4,
            f"{src}: duration", f"expected simulated seconds in (0, 1e4], got {duration!r}")
    field = spec.get("field", "total_solute")
    _expect(field in FIELDS, f"{src}: field", f"expected one of {list(FIELDS)}, got {field!r}")
    cost = spec.get("cost", "cpu_s")
    _expect(cost in ("cpu_s", "wall_s"), f"{src}: cost", f"expected \"cpu_s\" or \"wall_s\", got {cost!r}")
    threads = spec.get("threads", 1)
    _expect(isinstance(threads, int) and not isinstance(threads, bool) and 0 <= threads <= 1024, f"{src}: threads",
            f"expected an integer in [0, 1024], got {threads!r}")
    samples = spec.get("samples", 1)
    _expect(isinstance(samples, int) and not isinstance(samples, bool) and 1 <= samples <= MAX_SAMPLES,
            f"{src}: samples", f"expected an integer in [1, {MAX_SAMPLES}], got {samples!r}")
    threshold = spec.get("stain_threshold")
    _expect(threshold is None or (_is_number(threshold) and math.isfinite(threshold) and threshold > 0),
            f"{src}: stain_threshold", f"expected a finite number of kg/m2 > 0, got {threshold!r}")
    output = spec.get("output")
    _expect(output is None or (isinstance(output, str) and output), f"{src}: output",
            f"expected a folder path (relative to the sweep file), got {output!r}")

    runs: List[Dict[str, Any]] = []
    grid = spec.get("grid", {})
    _expect(isinstance(grid, dict), f"{src}: grid", "expected an object of key: [values]")
    for key, values in grid.items():
        _expect(isinstance(values, list) and values, f"{src}: grid.{key}", "expected a non-empty list of values")
        for value in values:
            try:
                check_override(key, value)
            except ValueError as e:
                raise SweepError(f"{src}: grid: {e}") from None
        kinds = sorted({_json_kind(v) for v in values})
        if key in FINEST:
            _expect(kinds == ["a number"], f"{src}: grid.{key}", f"expected numbers, got {values!r}")
        else:
            _expect(len(kinds) == 1, f"{src}: grid.{key}",
                    f"expected values of one type, got {' and '.join(kinds)}: {values!r}")
    listed = spec.get("runs", [])
    _expect(isinstance(listed, list), f"{src}: runs",
            f"expected a list of {{\"name\": ..., \"overrides\": {{key path: value}}}}, got {_json_kind(listed)}")
    combinations = math.prod(len(v) for v in grid.values()) if grid else 0
    _expect(combinations + len(listed) <= MAX_RUNS, src,
            f"{combinations} grid combinations and {len(listed)} listed runs: more than the limit of {MAX_RUNS} runs")
    if grid:
        keys = list(grid)
        combos = [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]

        def short(v):
            return f"{v:.4g}" if isinstance(v, float) else json.dumps(v)

        names = [" ".join(f"{k}={short(v)}" for k, v in c.items()) for c in combos]
        if len(set(names)) != len(names):  # values that differ past 4 digits: full precision
            names = [" ".join(f"{k}={json.dumps(v)}" for k, v in c.items()) for c in combos]
        runs += [{"name": n, "overrides": c, "where": "grid"} for n, c in zip(names, combos)]
    for i, run in enumerate(listed):
        where = f"runs[{i}]"
        _expect(isinstance(run, dict) and isinstance(run.get("overrides", {}), dict), f"{src}: {where}",
                "expected {\"name\": ..., \"overrides\": {key path: value}}")
        _known_keys(run, ("name", "overrides"), f"{src}: {where}")
        name = run.get("name", f"run {i}")
        _expect(isinstance(name, str) and name, f"{src}: {where}.name", f"expected a non-empty string, got {name!r}")
        runs.append({"name": name, "overrides": dict(run.get("overrides", {})), "where": where})
    _expect(runs, src, "no runs: give 'grid', 'runs' or both")
    names = [r["name"] for r in runs]
    _expect(len(set(names)) == len(names), src, f"run names must be unique, got {names}")

    reference = spec.get("reference", "finest")
    if reference == "finest":
        ref_overrides = {}
        for key, values in grid.items():
            if key in FINEST:
                ref_overrides[key] = FINEST[key](values)
        ref = {"name": "reference (finest)", "overrides": ref_overrides, "where": "reference"}
    elif isinstance(reference, str):
        _expect(reference in names, f"{src}: reference", f"expected \"finest\" or a run name of {names}, got {reference!r}")
        ref = dict(next(r for r in runs if r["name"] == reference))
    else:
        _expect(isinstance(reference, dict) and isinstance(reference.get("overrides", {}), dict),
                f"{src}: reference", "expected \"finest\", a run name or {\"name\", \"overrides\"}")
        _known_keys(reference, ("name", "overrides"), f"{src}: reference")
        name = reference.get("name", "reference")
        _expect(isinstance(name, str) and name, f"{src}: reference.name", f"expected a non-empty string, got {name!r}")
        ref = {"name": name, "overrides": dict(reference.get("overrides", {})), "where": "reference"}

    def task(run):
        t = {"name": run["name"], "overrides": run["overrides"], "base_directory": base_directory,
             "duration": float(duration), "threads": threads, "field": field, "samples": samples}
        try:
            t["scene"], t["resolution"] = apply_overrides(scene, run["overrides"])
        except ValueError as e:  # an override no run could take: the sweep file's error, before any run
            raise SweepError(f"{src}: {run['where']}: {e}") from None
        return t

    name = spec.get("name", scene.get("name"))
    return {"name": name if isinstance(name, str) and name else "sweep", "tasks": [task(r) for r in runs],
            "reference": task(ref), "reference_is_run": isinstance(reference, str) and reference != "finest",
            "threshold": threshold, "field": field, "axes": list(grid), "cost": cost, "output": output}


# --------------------------------------------------------------------------- executors

def _task_fn(isolate: bool) -> Callable[[Dict[str, Any]], Dict[str, Any]]:
    return _run_isolated_task if isolate else _run_task


def _run_task(task):
    return run_one(task)


def _run_isolated_task(task):
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
        try:
            client = Client(scheduler)
        except OSError as e:  # no scheduler there (a timeout is an OSError too)
            raise SweepError(f"cannot connect to the Dask scheduler at {scheduler!r}: {e}") from None
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
    last = ["max_speed_m_s", "peak_kinetic_energy_j", "kinetic_energy_j", "free_liquid_kg",
            "intrinsic_refreshes", "solute_budget_error", "solvent_budget_error", "state_hash", "worker",
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
    if ax.get_legend_handles_labels()[0]:  # none when no run has an error to plot
        ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path + ".tmp.png"
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


# --------------------------------------------------------------------------- the whole sweep

# What the checks of sweep()'s arguments call them: the Python names, or the
# command line's options (main).
_PARAMETERS = {"executor": "executor", "scheduler": "scheduler", "workers": "workers", "output": "output"}
_OPTIONS = {"executor": "--executor", "scheduler": "--scheduler", "workers": "--workers", "output": "--out"}


def _scheduler_problem(address: Any) -> Optional[str]:
    """Why `address` is not host:port or tcp://host:port, or None."""
    expected = "expected a Dask scheduler address host:port or tcp://host:port (port 1 to 65535)"
    if not isinstance(address, str):
        return f"{expected}, got {address!r}"
    rest = address[len("tcp://"):] if address.startswith("tcp://") else address
    host, colon, port = rest.rpartition(":")
    if (not colon or not host or "/" in rest or any(c.isspace() for c in rest)
            or host.startswith("[") != host.endswith("]")
            or not (port.isascii() and port.isdigit() and 1 <= int(port) <= 65535)):
        return f"{expected}, got {address!r}"
    return None


def _check_arguments(executor, scheduler, workers, names) -> str:
    """The executor to use ("dask" when only a scheduler is given); SweepError,
    naming the argument or option (names), for anything sweep() cannot run with."""
    if executor is None:
        executor = "dask" if scheduler is not None else "local"
    _expect(executor in ("serial", "local", "dask"), names["executor"],
            f"expected 'serial', 'local' or 'dask', got {executor!r}")
    if scheduler is not None:
        problem = _scheduler_problem(scheduler)
        _expect(not problem, names["scheduler"], problem or "")
        _expect(executor == "dask", names["scheduler"],
                f"a scheduler address runs the sweep on that Dask cluster, but {names['executor']} is {executor!r} "
                f"(give {names['executor']} 'dask', or leave it out)")
    elif executor == "dask":
        raise SweepError(f"{names['executor']} 'dask' needs {names['scheduler']}, a scheduler address "
                         "(e.g. tcp://host:8786)")
    _expect(isinstance(workers, int) and not isinstance(workers, bool) and 1 <= workers <= MAX_WORKERS,
            names["workers"], f"expected a number of local worker processes in [1, {MAX_WORKERS}], got {workers!r}")
    return executor


def _output_folder(out: str, where: str) -> None:
    """Creates the folder `out` (and its parents) and checks that sweep.csv and
    sweep.png can be written there, before any run: SweepError naming `where`."""
    _expect(not os.path.exists(out) or os.path.isdir(out), where, f"'{out}' exists and is not a folder")
    try:
        os.makedirs(out, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as e:
        raise SweepError(f"{where}: cannot write to the output folder '{out}': {e.strerror or e}") from None
    for name in ("sweep.csv", "sweep.png"):
        path = os.path.join(out, name)
        _expect(not os.path.exists(path) or os.path.isfile(path), where,
                f"'{path}' exists and is not a regular file (the sweep writes its table and chart there)")


# Why a metric has no value (errors_against gave NaN), for the row's error column.
_UNDEFINED = {
    "l2_error": "the reference's field is zero",
    "area_error": "no vertex of the reference passes the stain threshold ({threshold!r} kg/m2)",
    "centroid_distance_m": "the run's field is zero everywhere (no centroid)",
}


def sweep(spec, executor: Optional[str] = None, scheduler: Optional[str] = None, workers: int = 2,
          output: Optional[str] = None, isolate: bool = True) -> List[Dict[str, Any]]:
    """Runs a sweep and writes <output>/sweep.csv and <output>/sweep.png.

    spec: a sweep file path or the same as a dict. executor: "serial", "local"
    (a Dask LocalCluster of `workers` processes, the default) or "dask" with
    `scheduler` an address host:port or tcp://host:port (the default when a
    scheduler is given). isolate: each run in its own interpreter (per-run peak
    memory). Returns the table rows (dicts); a failed run is a row with status
    "failed" and its error. A bad argument, sweep file, scene or override, or an
    output folder that cannot be written, is a SweepError before any run starts.
    """
    return _sweep(spec, executor, scheduler, workers, output, isolate, _PARAMETERS)


def _sweep(spec, executor, scheduler, workers, output, isolate, names) -> List[Dict[str, Any]]:
    executor = _check_arguments(executor, scheduler, workers, names)
    if isinstance(spec, (str, os.PathLike)):
        spec = load_sweep(os.fspath(spec))
    p = plan(spec)
    if output is not None:
        _expect(isinstance(output, (str, os.PathLike)) and os.fspath(output), names["output"],
                f"expected a folder path, got {output!r}")
        out, where = os.fspath(output), names["output"]
    elif p["output"]:  # relative to the sweep file
        out, where = os.path.join(spec.get("_directory", "."), p["output"]), f"{spec.get('_source', '<sweep>')}: output"
    else:
        out = os.path.join("out", "sweep_" + p["name"].replace(" ", "_").replace(os.sep, "_"))
        where = "the default output folder"
    _output_folder(out, where)

    tasks = p["tasks"] + ([] if p["reference_is_run"] else [p["reference"]])
    if executor == "serial":
        results = run_serial(tasks, isolate=isolate)
    else:
        try:
            results = run_dask(tasks, scheduler=scheduler, workers=workers, isolate=isolate)
        except SweepError as e:  # the scheduler could not be reached
            raise SweepError(f"{names['scheduler']}: {e}") from None

    runs = results[:len(p["tasks"])]
    ref = (next(r for r in runs if r["name"] == p["reference"]["name"]) if p["reference_is_run"]
           else results[-1])
    if ref["status"] == "ok" and not np.any(ref["field"]):
        # Nothing to measure against: every error would be 0/0.
        ref.update(status="failed", error=f"the reference's stain is empty: its {p['field']} is 0 at every vertex, "
                                          "nothing to measure errors against")
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
                metrics = errors_against(result, ref, threshold)
                undefined = [k for k, v in metrics.items() if not math.isfinite(v)]
                for key in undefined:  # an empty cell and the reason, not nan
                    metrics[key] = None
                row.update(metrics)
                if undefined:
                    row["error"] = "; ".join(f"no {k}: {_UNDEFINED[k]}" for k in undefined).format(threshold=threshold)
    else:
        for row in rows:
            if row["status"] == "ok":
                row["error"] = f"no error metrics: the reference failed ({ref['error']})"
    candidates = [r for r in rows if r["status"] == "ok" and not r["is_reference"] and r.get("l2_error") is not None]
    for r, mark in zip(candidates, pareto_front([r[p["cost"]] for r in candidates],
                                                [r["l2_error"] for r in candidates])):
        r["pareto"] = mark

    write_csv(os.path.join(out, "sweep.csv"), rows, _columns(rows, p["axes"]))
    write_chart(os.path.join(out, "sweep.png"), rows, p["name"], cost=p["cost"], axes=p["axes"])
    return rows


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--run-one"]:
        return _run_one_main()
    parser = argparse.ArgumentParser(prog="blot sweep", description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep file (JSON, docs/sweeps.md)")
    parser.add_argument("--executor", choices=["serial", "local", "dask"],
                        help="serial: this process; local: a Dask LocalCluster (the default); "
                             "dask: the cluster at --scheduler (the default when it is given)")
    parser.add_argument("--scheduler", help="Dask scheduler address host:port or tcp://host:port, "
                                            "e.g. tcp://host:8786 (implies --executor dask)")
    parser.add_argument("--workers", type=int, default=2,
                        help=f"local cluster worker processes, 1 to {MAX_WORKERS} (default 2)")
    parser.add_argument("--out", help="output folder (default: the sweep's 'output', else out/sweep_<name>)")
    parser.add_argument("--in-process", action="store_true",
                        help="run each run inside the worker instead of its own interpreter "
                             "(peak memory is then the worker's high-water mark)")
    args = parser.parse_args(argv)
    try:
        rows = _sweep(args.sweep, args.executor, args.scheduler, args.workers, args.out,
                      not args.in_process, _OPTIONS)
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
