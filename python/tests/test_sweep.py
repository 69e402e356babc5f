"""Sweeps: the same table from `blot sweep` (serial) and blot.sweep on a 2-worker
Dask LocalCluster, the chart, a failed run kept as a row, and the metrics."""
import csv
import json
import os
import subprocess
import tempfile
import unittest

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


if __name__ == "__main__":
    unittest.main()
