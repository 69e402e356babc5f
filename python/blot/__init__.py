"""Blot for Python: the stain engine (C++, pybind11) and speed-against-accuracy sweeps.

    import blot
    e = blot.Engine.from_scene_file("assets/scenes/two_way_flag.json")
    e.advance_steps(60)
    e.solute            # read-only numpy view of the engine's buffer (no copy)
    e.statistics()      # counters, per-stage times (ms), the mass budget (kg)

Arrays (python/README.md, "Arrays: views or copies"): positions, normals,
the five densities, velocities, world_velocities, colors, rest_positions and
uvs are read-only views of the engine's own buffers; each keeps the engine
alive. faces, vertex_areas, load_mesh(), scene_mesh_order() and homogenize()
return copies.

blot.sweep(...) (blot.sweeps) runs parameter sweeps (docs/sweeps.md).
"""
import json as _json
import math as _math

from ._blot import (AUTO_SUBDIVISIONS, Engine, MeshError, PatternError, SceneError, StepError,  # noqa: F401
                    homogenize, load_mesh, scene_mesh_order)

__all__ = ["Engine", "SceneError", "MeshError", "StepError", "PatternError", "load_mesh", "scene_mesh_order",
           "homogenize", "AUTO_SUBDIVISIONS", "sweep"]


def _non_finite_key(value, path):
    """(key path such as a.b[2], the number) of the first NaN or infinity in value, or None."""
    if isinstance(value, float) and not _math.isfinite(value):
        return path, value
    if isinstance(value, dict):
        for key, item in value.items():
            found = _non_finite_key(item, f"{path}.{key}" if path else str(key))
            if found is not None:
                return found
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            found = _non_finite_key(item, f"{path}[{index}]")
            if found is not None:
                return found
    return None


def _from_dict(scene, base_directory=".", source_name="<dict>", patch_resolution=0):
    """An engine from a scene as a Python dict (the JSON of docs/scene-format.md).

    A NaN or infinity raises SceneError naming its key: JSON has no such numbers.
    """
    try:
        text = _json.dumps(scene, allow_nan=False)
    except ValueError:
        found = _non_finite_key(scene, "")
        if found is None:
            raise
        key, bad = found
        raise SceneError(f"{source_name}: {key}: expected a finite number, got {bad}") from None
    return Engine.from_scene_json(text, base_directory=base_directory, source_name=source_name,
                                  patch_resolution=patch_resolution)


Engine.from_dict = staticmethod(_from_dict)

from .sweeps import sweep  # noqa: E402  (after Engine.from_dict, which the runs use)
