"""The Python bindings against the C++ engine and the `blot` command line.

Run by ctest (python/CMakeLists.txt) with PYTHONPATH at the build tree's
python/ folder, BLOT_BINARY the `blot` executable and BLOT_SOURCE_DIR the
source tree.
"""
import gc
import json
import os
import subprocess
import tempfile
import threading
import time
import unittest

import numpy as np

import blot

SOURCE = os.environ.get("BLOT_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
BLOT = os.environ.get("BLOT_BINARY", "blot")
SCENES = os.path.join(SOURCE, "assets", "scenes")


def small_flag(frames=3, steps_per_frame=4, resolution=12):
    """The two-way flag (Bullet cloth, two-way coupling, a drop) on a coarse patch."""
    with open(os.path.join(SCENES, "two_way_flag.json")) as fh:
        scene = json.load(fh)
    scene["mesh"]["patch"]["resolution"] = [resolution, resolution]
    scene["outputs"] = {"frames": frames, "steps_per_frame": steps_per_frame, "ply_every": 0,
                        "preview": {"enabled": False}}
    return scene


class AgainstTheCommandLine(unittest.TestCase):
    def test_state_hash_equals_blot_run_bit_for_bit(self):
        # Same scene, same internal steps: `blot run`'s summary state_hash (FNV-1a
        # over every simulation array) equals the Python engine's.
        scene = small_flag()
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "flag.json")
            with open(path, "w") as fh:
                json.dump(scene, fh)
            out = subprocess.run([BLOT, "run", path, "--out", os.path.join(tmp, "out"), "--quiet", "--threads", "1"],
                                 capture_output=True, text=True, check=True)
            summary = json.loads(out.stdout)
            e = blot.Engine.from_scene_file(path)
            e.threads = 2  # results do not depend on the thread count
            self.assertTrue(e.adaptive_threads)
            e.adaptive_threads = False  # nor on whether each step may fall back to one
            e.advance_steps(summary["steps"])
        self.assertEqual(summary["steps"], 12)
        self.assertTrue(summary["adaptive_threads"])
        self.assertEqual(f"{e.state_hash:016x}", summary["state_hash"])
        budget = e.mass_budget()
        for key, value in summary["mass_budget_kg"].items():
            if key in budget:
                self.assertEqual(budget[key], value, key)  # JSON doubles round-trip exactly

    def test_dict_json_text_and_file_build_the_same_engine(self):
        scene = small_flag()
        a = blot.Engine.from_dict(scene)
        b = blot.Engine.from_scene_json(json.dumps(scene))
        for e in (a, b):
            e.advance_steps(5)
        self.assertEqual(a.state_hash, b.state_hash)
        self.assertTrue(np.array_equal(a.solute, b.solute))

    def test_scene_error_carries_the_command_lines_message(self):
        scene = small_flag()
        scene["time_step"] = -0.5
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "bad.json")
            with open(path, "w") as fh:
                json.dump(scene, fh)
            cli = subprocess.run([BLOT, "run", path, "--quiet"], capture_output=True, text=True)
            with self.assertRaises(blot.SceneError) as caught:
                blot.Engine.from_scene_file(path)
        self.assertNotEqual(cli.returncode, 0)
        message = str(caught.exception)
        self.assertIn("time_step", message)
        self.assertIn(path, message)
        self.assertIn(f"blot run: error: {message}", cli.stderr)
        self.assertIsInstance(caught.exception, ValueError)

    def test_unknown_key_names_the_key(self):
        with self.assertRaisesRegex(blot.SceneError, r"^mine: .*no_such_key"):
            blot.Engine.from_dict(dict(small_flag(), no_such_key=1), source_name="mine")


class Views(unittest.TestCase):
    def setUp(self):
        self.e = blot.Engine.from_dict(small_flag())

    def test_views_are_read_only_and_share_the_engines_memory(self):
        e = self.e
        for name in ("positions", "normals", "solvent", "solute", "absorbed_solvent", "absorbed_solute",
                     "adsorbed_solute", "velocities", "world_velocities", "colors", "rest_positions"):
            a = getattr(e, name)
            self.assertFalse(a.flags.writeable, name)
            self.assertFalse(a.flags.owndata, name)
            self.assertEqual(a.shape[0], e.vertex_count, name)
            self.assertTrue(np.shares_memory(a, getattr(e, name)), name)  # no copy: the same buffer
            with self.assertRaises(ValueError):
                a[0] = 1.0
        self.assertEqual(e.positions.shape, (e.vertex_count, 3))
        self.assertEqual(e.solute.shape, (e.vertex_count,))
        self.assertTrue(e.faces.flags.owndata)  # a copy, documented

    def test_views_reflect_the_state_after_a_step(self):
        e = self.e
        positions, solvent, velocities, colors = e.positions, e.solvent, e.velocities, e.colors
        before = positions.copy(), solvent.copy(), velocities.copy(), colors.copy()
        e.advance_steps(6)
        # The arrays taken before the step show the new state: the same buffers.
        for old, view, fresh in zip(before, (positions, solvent, velocities, colors),
                                    (e.positions, e.solvent, e.velocities, e.colors)):
            self.assertTrue(np.array_equal(view, fresh))
            self.assertFalse(np.array_equal(view, old))

    def test_a_view_keeps_the_engine_alive(self):
        e = blot.Engine.from_dict(small_flag())
        e.advance_steps(3)
        solute, expected = e.solute, e.solute.copy()
        del e
        gc.collect()
        blot.Engine.from_dict(small_flag()).advance_steps(2)  # reuse freed memory if any was freed
        self.assertTrue(np.array_equal(solute, expected))

    def test_positions_match_the_rest_shape_at_time_zero(self):
        # Bullet holds single-precision positions.
        np.testing.assert_allclose(self.e.positions, self.e.rest_positions, rtol=0, atol=1e-6)


class Engine(unittest.TestCase):
    def grid(self, n=10):
        xs = np.linspace(0.0, 1.0, n + 1)
        vertices = np.array([[x, y, 0.0] for y in xs for x in xs])
        faces = []
        for j in range(n):
            for i in range(n):
                a = j * (n + 1) + i
                faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
        return vertices, np.array(faces, dtype=np.int32)

    def test_from_mesh_drops_and_the_mass_budget(self):
        vertices, faces = self.grid()
        e = blot.Engine.from_mesh(vertices, faces, time_step=0.01, diffusivity=0.004)
        self.assertEqual(e.vertex_count, 121)
        e.add_drop(vertex=60, radius=0.2, solvent_mass=0.01, solute_mass=0.002)
        e.add_drop(point=[0.25, 0.25, 0.1], radius=0.15, solvent_mass=0.005, solute_mass=0.001)
        e.advance_steps(20)
        b = e.mass_budget()
        self.assertAlmostEqual(b["added_solvent"], 0.015, delta=1e-15)
        self.assertAlmostEqual(b["added_solute"], 0.003, delta=1e-15)
        self.assertLess(b["solvent_error"], 1e-12)
        self.assertLess(b["solute_error"], 1e-12)
        areas = e.vertex_areas
        self.assertAlmostEqual(areas.sum(), 1.0, delta=1e-12)
        total_solvent = (areas * (np.asarray(e.solvent) + e.absorbed_solvent)).sum() + b["evaporated_solvent"]
        self.assertAlmostEqual(total_solvent, 0.015, delta=1e-12)
        s = e.statistics()
        self.assertEqual(s["steps"], 20)
        self.assertEqual(s["drops_applied"], 2)
        self.assertIn("diffuse", s["last_profile"]["milliseconds"])
        self.assertGreaterEqual(s["total_ms"]["stages"]["diffuse"], 0.0)
        self.assertEqual(set(e.last_profile()), set(s["last_profile"]))

    def test_bad_arguments_are_value_errors_with_the_engines_message(self):
        vertices, faces = self.grid()
        with self.assertRaisesRegex(ValueError, "timeStep|time step|time_step"):
            blot.Engine.from_mesh(vertices, faces, time_step=-1.0)
        e = blot.Engine.from_mesh(vertices, faces)
        with self.assertRaisesRegex(ValueError, "radius"):
            e.add_drop(vertex=3, radius=-1.0)
        with self.assertRaisesRegex(ValueError, "exactly one"):
            e.add_drop(radius=0.1)
        bad = faces.copy()
        bad[0, 0] = 999
        with self.assertRaises(blot.MeshError):
            blot.Engine.from_mesh(vertices, bad)

    def test_arguments_are_checked_and_named(self):
        vertices, faces = self.grid()
        e = blot.Engine.from_mesh(vertices, faces)
        cases = [
            (lambda: e.add_drop(point=[0, 0]), ValueError, r"add_drop: point: expected 3 numbers \(x, y, z\), got an array of shape \(2,\)"),
            (lambda: e.add_drop(point="abc"), TypeError, "add_drop: point: expected 3 numbers"),
            (lambda: e.add_drop(vertex=1.5), TypeError, "add_drop: vertex: expected an integer vertex index, got float 1.5"),
            (lambda: e.add_drop(vertex=2 ** 40), ValueError, r"add_drop: vertex: vertex index 1099511627776 out of range \[0, 121\)"),
            (lambda: e.add_drop(vertex=-1), ValueError, r"vertex index -1 out of range \[0, 121\)"),
            (lambda: e.add_drop(vertex=np.int64(3), velocity=[1, 0, 0, 0]), ValueError, "add_drop: velocity: expected 3 numbers"),
            (lambda: e.add_drop(vertex=3, splash_speed=1e300), ValueError, "splashSpeed must be finite and at most 1000000"),
            (lambda: blot.Engine.from_mesh(vertices, faces, angular_velocity=[1, 0]), ValueError, "from_mesh: angular_velocity"),
            (lambda: blot.Engine.from_mesh(vertices, faces, gravity=None), TypeError, "from_mesh: gravity"),
            (lambda: blot.Engine.from_mesh(vertices, faces.astype(np.float64) + 0.9), TypeError, "from_mesh: faces: expected integer vertex indices, got an array of float64"),
            (lambda: blot.Engine.from_mesh(vertices, faces[:, :2]), ValueError, r"from_mesh: faces: expected #F x 3 vertex indices, got an array of shape \(200, 2\)"),
            (lambda: blot.Engine.from_mesh(vertices, faces, time_step=1e300), ValueError, r"timeStep must be in \[1e-06, 1\] s"),
            (lambda: blot.Engine.from_dict({"time_step": float("nan")}), blot.SceneError, "<dict>: time_step: expected a finite number, got nan"),
            (lambda: blot.Engine.from_dict({"liquid": {"drops": [{"radius": float("inf")}]}}), blot.SceneError, r"liquid.drops\[0\].radius: expected a finite number, got inf"),
            (lambda: blot.homogenize("plain", subdivisions=759250125), ValueError, "more than the limit of 500000"),
        ]
        for call, kind, message in cases:
            with self.assertRaisesRegex(kind, message):
                call()
        wrapped = faces.astype(np.int64)
        wrapped[0, 0] += 2 ** 32  # a cast to int32 would make it vertex 0 again
        with self.assertRaisesRegex(blot.MeshError, "from_mesh: face 0: vertex index 4294967296 out of range"):
            blot.Engine.from_mesh(vertices, wrapped)
        self.assertEqual(e.step_count, 0)
        e.advance_steps(1)  # nothing refused above was queued
        self.assertEqual(e.statistics()["drops_applied"], 0)

    def test_a_failed_step_raises_step_error_and_keeps_the_state(self):
        e = blot.Engine.from_dict(small_flag())
        e.advance_steps(2)
        good = e.state_hash
        e.inject_fault_for_testing("diffuse", 3, 5)
        with self.assertRaisesRegex(blot.StepError, "^stage 'validate', vertex 5: .*step 3"):
            e.advance_steps(2)
        self.assertEqual(e.state_hash, good)
        self.assertEqual(e.step_count, 2)

    def test_step_releases_the_gil(self):
        e = blot.Engine.from_dict(small_flag(resolution=24))
        ticks = 0
        worker = threading.Thread(target=e.advance_steps, args=(30,))
        start = time.perf_counter()
        worker.start()
        while worker.is_alive():
            ticks += 1
            time.sleep(0.001)
        worker.join()
        elapsed = time.perf_counter() - start
        # With the GIL held through the steps this loop could not run until they end.
        self.assertGreater(ticks, 10, f"{elapsed:.3f} s of steps")

    def test_one_engine_refuses_a_call_from_another_thread_while_it_steps(self):
        # Two threads stepping one engine crashed the interpreter (the step
        # releases the GIL); now every call while a step runs raises.
        e = blot.Engine.from_dict(small_flag(resolution=24))
        refused, extra_steps = [], 0
        worker = threading.Thread(target=e.advance_steps, args=(40,))
        worker.start()
        while worker.is_alive():
            try:
                e.advance_steps(1)
                extra_steps += 1  # between the worker's start and its step, or after it
            except RuntimeError as error:
                refused.append(str(error))
            for read in (lambda: e.step_count, lambda: e.solute, lambda: e.statistics()):
                try:
                    read()
                except RuntimeError as error:
                    refused.append(str(error))
            time.sleep(0.001)
        worker.join()
        self.assertTrue(refused)
        self.assertTrue(all("this engine is stepping on another thread" in m for m in refused), refused[:3])
        self.assertEqual(e.step_count, 40 + extra_steps)  # the refused steps did not run
        alone = blot.Engine.from_dict(small_flag(resolution=24))
        alone.advance_steps(40 + extra_steps)
        self.assertEqual(e.state_hash, alone.state_hash)

    def test_views_of_derived_arrays_show_the_state_after_a_step(self):
        vertices, faces = self.grid()
        e = blot.Engine.from_mesh(vertices, faces, angular_velocity=[0.3, 0.0, 2.0])
        e.add_drop(vertex=60, radius=0.2, solvent_mass=0.01, solute_mass=0.002)
        e.advance_steps(2)
        held = {name: getattr(e, name) for name in ("normals", "velocities", "world_velocities", "colors")}
        before = {name: view.copy() for name, view in held.items()}
        e.advance_steps(3)
        for name, view in held.items():
            self.assertTrue(np.array_equal(view, getattr(e, name)), name)
        self.assertFalse(np.array_equal(before["normals"], held["normals"]))
        self.assertFalse(np.array_equal(before["world_velocities"], held["world_velocities"]))

    def test_frame_time_accumulates_into_internal_steps(self):
        e = blot.Engine.from_dict(small_flag())
        h = e.time_step
        e.step(2.5 * h)
        self.assertEqual(e.step_count, 2)
        e.step(0.5 * h)
        self.assertEqual(e.step_count, 3)
        with self.assertRaises(blot.StepError):
            e.step(float("nan"))


class MeshesAndPatterns(unittest.TestCase):
    def test_load_mesh(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "quad.obj")
            with open(path, "w") as fh:
                fh.write("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
            mesh = blot.load_mesh(path)
            self.assertEqual(mesh["vertices"].shape, (4, 3))
            self.assertEqual(mesh["faces"].tolist(), [[0, 1, 2], [0, 2, 3]])
            bad = os.path.join(tmp, "bad.obj")
            with open(bad, "w") as fh:
                fh.write("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
            with self.assertRaises(blot.MeshError) as caught:
                blot.load_mesh(bad)
            self.assertTrue(str(caught.exception).startswith(bad), str(caught.exception))

    def test_scene_mesh_order_maps_a_renumbered_mesh_to_its_file(self):
        with tempfile.TemporaryDirectory() as tmp:
            scene = {"mesh": {"patch": {"size": [1, 1], "resolution": [10, 10]}},
                     "cloth": {"source": "static"}}
            plain, renumbered = (os.path.join(tmp, n) for n in ("plain.json", "renumbered.json"))
            with open(plain, "w") as fh:
                json.dump(scene, fh)
            scene["mesh"]["vertex_order"] = "locality"
            with open(renumbered, "w") as fh:
                json.dump(scene, fh)
            identity = blot.scene_mesh_order(plain)
            self.assertEqual(identity["vertices"].tolist(), list(range(121)))
            self.assertEqual(identity["faces"].tolist(), list(range(200)))
            order = blot.scene_mesh_order(renumbered)
            self.assertEqual(sorted(order["vertices"].tolist()), list(range(121)))
            self.assertNotEqual(order["vertices"].tolist(), list(range(121)))
            file_positions = blot.Engine.from_scene_file(plain).positions
            engine_positions = blot.Engine.from_scene_file(renumbered).positions
            self.assertTrue(np.array_equal(engine_positions, file_positions[order["vertices"]]))
            with self.assertRaises(blot.SceneError):
                blot.scene_mesh_order(os.path.join(tmp, "missing.json"))

    def test_homogenize_equals_the_command_line(self):
        r = blot.homogenize("twill-2-1", subdivisions=8)
        cli = json.loads(subprocess.run([BLOT, "homogenize", "--preset", "twill-2-1", "-k", "8"],
                                        capture_output=True, text=True, check=True).stdout)
        self.assertEqual(r["effective"].tolist(), cli["effective"])
        self.assertEqual(r["upper"].tolist(), cli["upper"])
        self.assertEqual(r["gap"], cli["gap"])
        with self.assertRaisesRegex(blot.PatternError, "no-such-weave"):
            blot.homogenize("no-such-weave")


if __name__ == "__main__":
    unittest.main()
