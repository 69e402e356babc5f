"""Sweeps: the same table from `blot sweep` (serial) and blot.sweep on a 2-worker
Dask LocalCluster, the chart, a failed run kept as a row, and the metrics; bad
input (arguments, files, keys, overrides, output folders) refused with an error
naming it before any run starts."""
import contextlib
import csv
import io
import json
import os
import signal
import subprocess
import tempfile
import unittest
from unittest import mock

import numpy as np

import blot
from blot import sweeps

SOURCE = os.environ.get("BLOT_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
BLOT = os.environ.get("BLOT_BINARY", "blot")


def grid_mesh(n, size=1.0):
    xs = np.linspace(0.0, size, n + 1)
    vertices = np.array([[x, y, 0.0] for y in xs for x in xs])
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return vertices, np.array(faces, dtype=np.int64)


def sweep_spec():
    # The two-way flag (Bullet cloth) on coarse patches: 4 grid runs, a one-way
    # run, and a run whose override the scene loader rejects.
    return {
        "name": "flag test",
        "scene": os.path.join(SOURCE, "assets", "scenes", "two_way_flag.json"),
        "duration": 0.2,
        "grid": {"time_step": [1 / 60, 1 / 120], "mesh_resolution": [8, 12]},
        "runs": [{"name": "one-way", "overrides": {"coupling": "one-way", "mesh_resolution": 12}},
                 {"name": "bad switch", "overrides": {"physics.no_such_switch": True}}],
        "reference": "finest",
    }


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


class Sweep(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        spec_path = os.path.join(cls.tmp.name, "sweep.json")
        with open(spec_path, "w") as fh:
            json.dump(sweep_spec(), fh)
        cls.serial_dir = os.path.join(cls.tmp.name, "serial")
        cls.dask_dir = os.path.join(cls.tmp.name, "dask")
        # The command line, serial executor (each run in its own interpreter).
        cls.cli = subprocess.run([BLOT, "sweep", spec_path, "--executor", "serial", "--out", cls.serial_dir],
                                 capture_output=True, text=True)
        # The Python API on a local Dask cluster of two worker processes, each
        # run inside its worker (the command line ran each in its own interpreter).
        cls.rows = blot.sweep(spec_path, executor="local", workers=2, output=cls.dask_dir, isolate=False)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_command_line_ran(self):
        self.assertEqual(self.cli.returncode, 0, self.cli.stderr)
        self.assertIn("7 runs, 1 failed", self.cli.stdout)

    def test_same_table_whichever_executor_ran_it(self):
        serial = read_csv(os.path.join(self.serial_dir, "sweep.csv"))
        dask = read_csv(os.path.join(self.dask_dir, "sweep.csv"))
        self.assertEqual(len(serial), 7)  # 6 runs + the reference
        self.assertEqual(list(serial[0]), list(dask[0]))
        costs = set(sweeps.COST_COLUMNS) | {c for c in serial[0] if c.startswith("ms_")} | {"pareto"}
        for a, b in zip(serial, dask):
            for column in serial[0]:
                if column not in costs:
                    self.assertEqual(a[column], b[column], f"{a['name']}: {column}")
        workers = {r["worker"] for r in dask if r["worker"]}
        self.assertEqual(len(workers), 2, workers)  # both workers ran runs

    def test_failed_run_is_a_row_with_its_error(self):
        bad = [r for r in self.rows if r["name"] == "bad switch"]
        self.assertEqual(len(bad), 1)
        self.assertEqual(bad[0]["status"], "failed")
        self.assertIn("physics.no_such_switch", bad[0]["error"])
        self.assertEqual([r["status"] for r in self.rows].count("failed"), 1)

    def test_errors_against_the_reference(self):
        by_name = {r["name"]: r for r in self.rows}
        ref = next(r for r in self.rows if r["is_reference"])
        self.assertEqual(ref["name"], "reference (finest)")
        self.assertEqual(json.loads(ref["overrides"]), {"time_step": 1 / 120, "mesh_resolution": 12})
        # The grid run with the finest settings is the reference, computed again
        # in another process: bit-identical, so every error is exactly zero.
        twin = by_name["time_step=0.008333 mesh_resolution=12"]
        self.assertEqual(twin["state_hash"], ref["state_hash"])
        self.assertEqual(twin["l2_error"], 0.0)
        self.assertEqual(twin["centroid_distance_m"], 0.0)
        for r in self.rows:
            if r["status"] == "ok" and r is not twin and not r["is_reference"]:
                self.assertGreater(r["l2_error"], 0.0, r["name"])
                self.assertLess(r["l2_error"], 2.0, r["name"])
                self.assertGreater(r["wall_s"], 0.0)
                self.assertGreater(r["peak_rss_mb"], 10.0)
        coarse = by_name["time_step=0.01667 mesh_resolution=8"]
        self.assertEqual(coarse["vertices"], 81)  # 8 x 8 quads: the transfer to the 13 x 13 reference ran
        self.assertTrue(any(r.get("pareto") for r in self.rows))

    def test_chart_written(self):
        for folder in (self.serial_dir, self.dask_dir):
            path = os.path.join(folder, "sweep.png")
            with open(path, "rb") as fh:
                head = fh.read(8)
            self.assertEqual(head, b"\x89PNG\r\n\x1a\n")
            self.assertGreater(os.path.getsize(path), 10000)


class Metrics(unittest.TestCase):
    def test_transfer_reproduces_linear_fields(self):
        # Barycentric interpolation is exact for fields linear on the rest shape.
        coarse, coarse_faces = grid_mesh(5)
        fine, _ = grid_mesh(17)
        values = 2 * coarse[:, 0] - 3 * coarse[:, 1] + 1
        sampled = sweeps.transfer(fine, coarse, coarse_faces, values)
        np.testing.assert_allclose(sampled, 2 * fine[:, 0] - 3 * fine[:, 1] + 1, rtol=0, atol=1e-12)

    def test_metrics_of_known_fields(self):
        v, f = grid_mesh(4)
        areas = np.full(len(v), 1.0)
        ref = {"rest_positions": v, "faces": f, "areas": areas, "field": np.where(v[:, 0] < 0.3, 1.0, 0.0)}
        run = dict(ref, field=2 * ref["field"])
        e = sweeps.errors_against(run, ref, threshold=0.5)
        self.assertAlmostEqual(e["l2_error"], 1.0, delta=1e-15)  # |2r - r| / |r|
        self.assertEqual(e["area_error"], 0.0)
        self.assertEqual(e["centroid_distance_m"], 0.0)

    def test_pareto_front(self):
        self.assertEqual(sweeps.pareto_front([1, 2, 3, 2.5], [3, 1, 0.5, 2]), [True, True, True, False])

    def test_bad_sweep_file_names_the_key(self):
        with self.assertRaisesRegex(sweeps.SweepError, "duration"):
            sweeps.plan({"scene": {"mesh": {}}, "grid": {"time_step": [0.01]}})
        with self.assertRaisesRegex(sweeps.SweepError, "unknown key 'gird'"):
            sweeps.plan({"scene": {}, "duration": 1, "gird": {}})
        with self.assertRaisesRegex(sweeps.SweepError, "reference"):
            sweeps.plan({"scene": {}, "duration": 1, "grid": {"time_step": [0.01]}, "reference": "nope"})



STATIC_DROP = os.path.join(SOURCE, "assets", "scenes", "static_drop.json")


def small_spec(**changes):
    spec = {"name": "small", "scene": STATIC_DROP, "duration": 0.05, "grid": {"time_step": [0.02, 0.01]}}
    spec.update(changes)
    return spec


def no_runs(*args, **kwargs):
    raise AssertionError("a run started")


@contextlib.contextmanager
def time_limit(seconds):
    """Fails (instead of hanging) if the block runs longer: a blocking open() of a FIFO is interrupted."""
    def fail(signum, frame):
        raise AssertionError(f"still running after {seconds} s: a hang")
    previous = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


class BadInput(unittest.TestCase):
    """Every error comes before the runs (run_serial and run_dask must not be called)."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)
        for name in ("run_serial", "run_dask"):
            patcher = mock.patch.object(sweeps, name, side_effect=no_runs)
            patcher.start()
            self.addCleanup(patcher.stop)

    def path(self, name):
        return os.path.join(self.tmp.name, name)

    def write(self, name, content):
        with open(self.path(name), "wb" if isinstance(content, bytes) else "w") as fh:
            fh.write(content if isinstance(content, (str, bytes)) else json.dumps(content))
        return self.path(name)

    def refused(self, spec, *patterns, **kwargs):
        """blot.sweep(spec) raises a SweepError whose message holds every pattern."""
        kwargs.setdefault("executor", "serial")
        kwargs.setdefault("output", self.path("out"))
        with self.assertRaises(sweeps.SweepError) as caught:
            blot.sweep(spec, **kwargs)
        for pattern in patterns:
            self.assertIn(pattern, str(caught.exception))
        return str(caught.exception)

    def cli(self, *args):
        """sweeps.main(args): (exit status, stderr)."""
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                status = sweeps.main(list(args))
            except SystemExit as e:  # argparse
                status = e.code
        return status, err.getvalue()

    def test_workers_below_one(self):
        for workers in (0, -1, True, 1.5):
            self.refused(small_spec(), "workers", repr(workers), executor="local", workers=workers)
        spec = self.write("s.json", small_spec())
        status, err = self.cli(spec, "--workers", "0", "--out", self.path("out"))
        self.assertEqual(status, 1)
        self.assertIn("blot sweep: error: --workers: expected", err)

    def test_workers_zero_on_the_command_line_does_not_hang(self):
        spec = self.write("s.json", small_spec())
        proc = subprocess.run([BLOT, "sweep", spec, "--workers", "0"], capture_output=True, text=True, timeout=60)
        self.assertEqual(proc.returncode, 1, proc.stderr)
        self.assertIn("--workers", proc.stderr)
        self.assertNotIn("Traceback", proc.stderr)

    def test_files_that_are_not_regular_files(self):
        with time_limit(60):
            self.check_files_that_are_not_regular_files()

    def check_files_that_are_not_regular_files(self):
        fifo = self.path("fifo.json")
        os.mkfifo(fifo)
        self.refused(fifo, fifo, "named pipe")
        self.refused(self.tmp.name, "directory")
        self.refused("/dev/zero", "/dev/zero", "character device")
        self.refused(self.path("missing.json"), "missing.json", "cannot open")
        self.refused(small_spec(scene=fifo), "scene", fifo, "named pipe")
        self.refused(small_spec(scene=self.tmp.name), "scene", "directory")
        big = self.path("big.json")
        with open(big, "wb") as fh:
            fh.truncate(sweeps.FILE_BYTE_LIMIT + 1)  # sparse: refused by its size, never read
        self.refused(big, "big.json", "more than the limit of 16777216 bytes")
        self.refused(small_spec(scene=big), "scene", "more than the limit")
        bad = self.write("bad.json", b'{"scene": "\xff"}')
        self.refused(bad, "bad.json", "not UTF-8", "0xff")
        bad_scene = self.write("bad_scene.json", b'{"name": "\xc3"}')
        self.refused(small_spec(scene=bad_scene), "scene", "bad_scene.json", "not UTF-8")
        status, err = self.cli(fifo, "--executor", "serial")
        self.assertEqual(status, 1)
        self.assertIn("named pipe with nothing written to it", err)
        # A pipe with a writer, as a shell's <(...) gives (/dev/fd/N), is read as a file is.
        text = json.dumps({"name": "piped", "runs": []}).encode()
        read_end, write_end = os.pipe()
        try:
            os.write(write_end, text)
            os.close(write_end)
            self.assertEqual(sweeps.read_json_file(f"/dev/fd/{read_end}", "sweep file"), json.loads(text))
        finally:
            os.close(read_end)

    def test_malformed_sweep_files(self):
        self.refused(self.write("list.json", [1, 2]), "list.json", "expected a JSON object", "got a list")
        self.refused(self.write("str.json", "\"text\""), "str.json", "got a string")
        self.refused(self.write("syntax.json", "{\"scene\": }"), "syntax.json", "line 1", "not valid JSON")
        for spec in ([1, 2], None, 5):
            self.refused(spec, "expected a sweep file path or a dict")
        self.refused(small_spec(stain_threshold="x"), "stain_threshold", "'x'")
        self.refused(small_spec(runs=[{"name": ["a"], "overrides": {}}]), "runs[0].name", "['a']")
        self.refused(small_spec(runs=[{"name": 5, "overrides": {}}]), "runs[0].name", "got 5")
        self.refused(small_spec(runs=[{"name": "a", "overides": {}}]), "runs[0]", "unknown key 'overides'")
        self.refused(small_spec(runs={"name": "a"}), "runs", "expected a list")
        self.refused(small_spec(name=5), "name", "got 5")
        self.refused(small_spec(name=["x"]), "name", "['x']")
        self.refused(small_spec(output=5), "output", "got 5")
        self.refused(small_spec(output=""), "output", "got ''")
        self.refused(small_spec(reference={"name": 3}), "reference.name", "got 3")
        self.refused(small_spec(grid={"time_step": [0.01, "a"]}), "grid.time_step", "expected numbers")
        self.refused(small_spec(grid={"mesh_resolution": [None, 20]}), "mesh_resolution", "expected an integer")
        self.refused(small_spec(grid={"drops[0].radius": [0.01, "a"]}), "grid.drops[0].radius", "one type")
        self.refused(small_spec(grid={"a": list(range(200)), "b": list(range(200))}), "limit of 10000 runs")
        scene = self.write("scene.json", "{\"name\": ")
        self.refused(small_spec(scene=scene), "scene", "scene.json", "not valid JSON")
        self.refused(small_spec(scene=self.write("scene_list.json", [1])), "scene", "expected a scene object")
        # The command line: the message, exit status 1, no traceback.
        status, err = self.cli(self.path("list.json"), "--executor", "serial")
        self.assertEqual(status, 1)
        self.assertIn("blot sweep: error: " + self.path("list.json") + ": expected a JSON object", err)

    def test_scheduler_addresses(self):
        for address in ("garbage", "tcp://host", "host:0", "host:99999", "host:port", "tls://host:8786", ""):
            self.refused(small_spec(), "scheduler", "host:port", repr(address), executor="dask", scheduler=address)
        self.refused(small_spec(), "scheduler", "'serial'", executor="serial", scheduler="tcp://host:8786")
        self.assertIsNone(sweeps._scheduler_problem("tcp://head:8786"))
        self.assertIsNone(sweeps._scheduler_problem("10.0.0.1:8786"))
        self.assertIsNone(sweeps._scheduler_problem("tcp://[::1]:8786"))
        spec = self.write("s.json", small_spec())
        status, err = self.cli(spec, "--scheduler", "garbage")
        self.assertEqual(status, 1)
        self.assertIn("--scheduler: expected", err)
        status, err = self.cli(spec, "--scheduler", "tcp://host:8786", "--executor", "serial")
        self.assertEqual(status, 1)
        self.assertIn("--scheduler", err)
        self.assertIn("--executor is 'serial'", err)

    def test_stain_threshold_finite_and_positive(self):
        for value in (float("nan"), float("inf"), -1, 0, True, "x"):
            self.refused(small_spec(stain_threshold=value), "stain_threshold", "expected a finite number")
        sweeps.plan(small_spec(stain_threshold=1e-4))  # accepted

    def test_samples_an_integer_in_range(self):
        for value in (0, -1, 100001, 2.5, True, "4"):
            self.refused(small_spec(samples=value), "samples", "expected an integer in [1, 100000]")
        sweeps.plan(small_spec(samples=100000))  # accepted

    def test_overrides_name_the_key_and_value(self):
        cases = [
            ({"fabric.diffusivity": float("nan")}, ["'fabric.diffusivity'", "finite number", "nan"]),
            ({"mesh_resolution": "abc"}, ["'mesh_resolution'", "integer", "'abc'"]),
            ({"mesh_resolution": 20.7}, ["'mesh_resolution'", "integer", "20.7"]),
            ({"drops[0": 1}, ["'drops[0'", "'[' without ']'"]),
            ({"drops.radius": 1}, ["'drops.radius'", "list", "index"]),
            ({"drops[-1].radius": 0.005}, ["'drops[-1].radius'", "[-1]", "integer >= 0"]),
            ({"drops[5].radius": 0.005}, ["'drops[5].radius'", "no list item [5]"]),
            ({"a..b": 1}, ["'a..b'", "empty key"]),
            ({"x": {1, 2}}, ["'x'", "JSON"]),
        ]
        for overrides, patterns in cases:
            with self.subTest(overrides=overrides):
                self.refused(small_spec(runs=[{"name": "r", "overrides": overrides}]), "runs[0]", *patterns)
        self.refused(small_spec(reference={"overrides": {"drops[0": 1}}), "reference", "'drops[0'")
        # Still fine: a whole-number float resolution, a scene key the loader will judge.
        sweeps.plan(small_spec(runs=[{"name": "r", "overrides": {"mesh_resolution": 20.0, "physics.nope": 1}}]))

    def test_output_folder_checked_before_the_runs(self):
        a_file = self.write("file", "x")
        message = self.refused(small_spec(), "output", a_file, "not a folder", output=a_file)
        self.assertNotIn("Errno", message)
        self.refused(small_spec(), "output", output="")
        spec = self.write("s.json", small_spec(output="file/sub"))
        self.refused(spec, "s.json: output", output=None)
        status, err = self.cli(spec, "--executor", "serial", "--out", a_file)
        self.assertEqual(status, 1)
        self.assertIn("--out: '" + a_file + "' exists and is not a folder", err)
        # A good folder exists (created) when the runs start.
        out = self.path("new/out")
        sweeps.run_serial.side_effect = lambda *a, **k: self.assertTrue(os.path.isdir(out)) or no_runs()
        with self.assertRaisesRegex(AssertionError, "a run started"):
            blot.sweep(small_spec(), executor="serial", output=out)


class UndefinedMetrics(unittest.TestCase):
    def test_empty_reference_is_a_failed_reference_not_nan(self):
        # No drops in the reference: its stain is empty, every error would be 0/0.
        with tempfile.TemporaryDirectory() as tmp:
            rows = blot.sweep(small_spec(reference={"name": "dry", "overrides": {"drops": []}}),
                              executor="serial", output=tmp, isolate=False)
            table = read_csv(os.path.join(tmp, "sweep.csv"))
        ref = next(r for r in rows if r["is_reference"])
        self.assertEqual(ref["status"], "failed")
        self.assertIn("stain is empty", ref["error"])
        for row in table:
            for column in ("l2_error", "area_error", "centroid_distance_m"):
                self.assertEqual(row[column], "", f"{row['name']}: {column}")
            if row["status"] == "ok":
                self.assertIn("the reference failed", row["error"])

    def test_no_nan_in_the_table(self):
        # A run without drops (no centroid) and a threshold no reference vertex passes.
        with tempfile.TemporaryDirectory() as tmp:
            blot.sweep(small_spec(stain_threshold=1e9, runs=[{"name": "dry", "overrides": {"drops": []}}]),
                       executor="serial", output=tmp, isolate=False)
            with open(os.path.join(tmp, "sweep.csv")) as fh:
                text = fh.read()
            table = read_csv(os.path.join(tmp, "sweep.csv"))
        self.assertNotIn("nan", text)
        by_name = {r["name"]: r for r in table}
        self.assertIn("no area_error", by_name["time_step=0.02"]["error"])
        self.assertIn("no centroid_distance_m", by_name["dry"]["error"])
        self.assertEqual(by_name["dry"]["centroid_distance_m"], "")


class LiquidMotion(unittest.TestCase):
    def test_samples_measure_the_motion_without_changing_the_run(self):
        # A drop on a still patch, one of them thrown across it: it spreads under
        # its own weight and slows down (friction, interaction), so its speed and
        # kinetic energy peak early, not at the end.
        spec = small_spec(duration=0.2, grid={"time_step": [0.01]},
                          runs=[{"name": "thrown", "overrides": {"drops[0].relative_velocity": [0.05, 0, 0]}}])
        with tempfile.TemporaryDirectory() as tmp:
            once = blot.sweep(spec, executor="serial", output=tmp, isolate=False)
            often = blot.sweep(dict(spec, samples=20), executor="serial", output=tmp, isolate=False)
        for a, b in zip(once, often):
            self.assertEqual(a["state_hash"], b["state_hash"], a["name"])
            self.assertEqual(a["kinetic_energy_j"], b["kinetic_energy_j"], a["name"])
            self.assertEqual(a["free_liquid_kg"], b["free_liquid_kg"], a["name"])
            self.assertGreater(b["free_liquid_kg"], 0.0)
            self.assertGreaterEqual(b["peak_kinetic_energy_j"], a["peak_kinetic_energy_j"])
            self.assertGreaterEqual(b["max_speed_m_s"], a["max_speed_m_s"])
            self.assertEqual(a["peak_kinetic_energy_j"], a["kinetic_energy_j"])  # one sample: the end
        thrown = next(r for r in often if r["name"] == "thrown")
        self.assertGreater(thrown["max_speed_m_s"], 0.01)
        self.assertGreater(thrown["peak_kinetic_energy_j"], 2 * thrown["kinetic_energy_j"])


class Docs(unittest.TestCase):
    def test_docs_name_every_column(self):
        with open(os.path.join(SOURCE, "docs", "sweeps.md"), encoding="utf-8") as fh:
            text = fh.read()
        for column in sweeps._columns([], []):
            self.assertTrue(f"`{column}`" in text, f"docs/sweeps.md does not name the column {column}")


if __name__ == "__main__":
    unittest.main()
