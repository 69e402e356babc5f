// The `blot._blot` extension module: blot::Engine and friends for Python
// (pybind11 + numpy). The Python package `blot` (python/blot/) re-exports it
// and adds the sweeps. Arrays: see python/README.md ("Arrays: views or copies").
#include <blot/engine/engine.h>
#include <blot/engine/scene.h>
#include <blot/stain/fabric/homogenization.h>
#include <blot/stain/fabric/weave_pattern.h>
#include <blot/stain/io/mesh_io.h>
#include <blot/stain/step_profile.h>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

namespace py = pybind11;
using blot::engine::Engine;
using blot::engine::EngineDef;

namespace {

/// A step the engine refused or undid (StepReport not ok): Python's StepError,
/// worded as `blot run` reports it.
class StepFailure : public std::runtime_error {
 public:
  explicit StepFailure(const blot::stain::StepReport& r)
      : std::runtime_error(std::string("stage '") + r.stageName() + "'" +
                           (r.vertex >= 0 ? ", vertex " + std::to_string(r.vertex) : std::string()) + ": " +
                           r.message) {}
};

/// A read-only numpy view of an engine buffer, no copy. `owner` (the Python
/// Engine) is the array's base, so the engine outlives every view of it.
template <class Matrix>
py::array readOnlyView(const Matrix& m, py::handle owner) {
  py::array a;
  if constexpr (Matrix::ColsAtCompileTime == 1) {
    a = py::array_t<double>({static_cast<py::ssize_t>(m.rows())}, {static_cast<py::ssize_t>(sizeof(double))}, m.data(),
                            owner);
  } else {
    // Eigen's default is column-major: element (i, j) at data[i + j * rows].
    a = py::array_t<double>({static_cast<py::ssize_t>(m.rows()), static_cast<py::ssize_t>(m.cols())},
                            {static_cast<py::ssize_t>(sizeof(double)),
                             static_cast<py::ssize_t>(sizeof(double) * m.rows())},
                            m.data(), owner);
  }
  a.attr("flags").attr("writeable") = false;
  return a;
}

py::array copyOf(const Eigen::MatrixX3i& m) {
  py::array_t<std::int32_t> a({static_cast<py::ssize_t>(m.rows()), static_cast<py::ssize_t>(3)});
  auto r = a.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = m(i, j);
  return a;
}

/// A listed output record (stain/output_fields.h) as a dict: every field
/// whose line goes to Python, under its key, in the list's order; a nested
/// record as a dict; a per-stage array as a dict keyed by stain::stageKey; a
/// per-term array as a dict keyed by stain::stepTermName.
class PyDictWriter {
 public:
  template <class T>
  void field(const blot::stain::OutputField& f, const T& value) {
    if (f.goesTo(blot::stain::kPythonOutput)) dict[f.key] = value;
  }
  template <class Get>
  void computed(const blot::stain::OutputField& f, Get&& get) {
    if (f.goesTo(blot::stain::kPythonOutput)) dict[f.key] = get();
  }
  template <class Record>
  void record(const blot::stain::OutputField& f, const Record& nested) {
    if (!f.goesTo(blot::stain::kPythonOutput)) return;
    PyDictWriter inner;
    nested.visit(inner);
    dict[f.key] = inner.dict;
  }
  void perStage(const blot::stain::OutputField& f, const std::array<double, blot::stain::kStageCount>& values,
                blot::stain::Stage first, blot::stain::Stage last) {
    if (!f.goesTo(blot::stain::kPythonOutput)) return;
    py::dict stages;
    for (int k = static_cast<int>(first); k <= static_cast<int>(last); ++k)
      stages[py::str(blot::stain::stageKey(static_cast<blot::stain::Stage>(k)))] = values[static_cast<size_t>(k)];
    dict[f.key] = stages;
  }
  void perTerm(const blot::stain::OutputField& f, const std::array<std::int64_t, blot::stain::kStepTermCount>& counts) {
    if (!f.goesTo(blot::stain::kPythonOutput)) return;
    py::dict terms;
    for (int k = 0; k < blot::stain::kStepTermCount; ++k)
      terms[py::str(blot::stain::stepTermName(static_cast<blot::stain::StepTerm>(1u << k)))] =
          counts[static_cast<size_t>(k)];
    dict[f.key] = terms;
  }

  py::dict dict;
};

template <class Record>
py::dict pythonDict(const Record& record) {
  PyDictWriter writer;
  record.visit(writer);
  return writer.dict;
}

/// The Python Engine: a blot::Engine and what the bindings keep per engine.
/// A step runs with the GIL released, so another Python thread could call
/// into the same engine meanwhile; `stepping` (read and written with the GIL
/// held) turns that into a RuntimeError instead of a data race. The `*Viewed`
/// flags say which derived buffers (computed on request, engine.h) have been
/// handed out as views: they are refreshed after every step, so a view taken
/// before a step shows the state after it, as the views of the state do.
struct PyEngine {
  std::unique_ptr<Engine> engine;
  bool stepping = false;
  bool normalsViewed = false, velocitiesViewed = false, worldVelocitiesViewed = false, colorsViewed = false;
};

/// The engine, for a call named `what`, if no step of it is running on
/// another thread.
Engine& idle(PyEngine& w, const char* what) {
  if (w.stepping)
    throw std::runtime_error(std::string("Engine.") + what +
                             ": this engine is stepping on another thread (a step releases the GIL); one engine is "
                             "used by one thread at a time: wait for that step to return, or give each thread its "
                             "own Engine");
  return *w.engine;
}

/// Marks the engine as stepping from construction to destruction; both run
/// with the GIL held (declare it before the gil_scoped_release).
class SteppingGuard {
 public:
  explicit SteppingGuard(PyEngine& w) : w_(w) { w_.stepping = true; }
  ~SteppingGuard() { w_.stepping = false; }
  SteppingGuard(const SteppingGuard&) = delete;
  SteppingGuard& operator=(const SteppingGuard&) = delete;

 private:
  PyEngine& w_;
};

/// Recomputes the derived buffers that views were taken of (in place).
void refreshViewed(PyEngine& w) {
  const Engine& e = *w.engine;
  if (w.normalsViewed) e.normals();
  if (w.velocitiesViewed) e.liquidVelocities();
  if (w.worldVelocitiesViewed) e.liquidWorldVelocities();
  if (w.colorsViewed) e.colors();
}

/// Runs `count` steps (or one step(frameDt)) of the engine with the GIL released.
template <class Call>
void stepUnlocked(PyEngine& w, const char* what, Call call) {
  Engine& e = idle(w, what);
  blot::stain::StepReport r;
  {
    SteppingGuard guard(w);
    py::gil_scoped_release release;
    r = call(e);
  }
  refreshViewed(w);
  if (!r.ok()) throw StepFailure(r);
}

std::unique_ptr<PyEngine> runUnlocked(const std::function<std::unique_ptr<Engine>()>& build) {
  auto w = std::make_unique<PyEngine>();
  {
    py::gil_scoped_release release;
    w->engine = build();
  }
  return w;
}

/// The Python type's name of `o`, for messages.
std::string typeName(py::handle o) { return py::str(py::type::handle_of(o).attr("__name__")); }

/// An array's shape as numpy prints it: (2,) or (200, 2).
std::string shapeText(const py::array& a) {
  std::string shape;
  for (py::ssize_t d = 0; d < a.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(a.shape(d));
  return "(" + shape + (a.ndim() == 1 ? ",)" : ")");
}

/// Three numbers (a list, tuple or numpy array) as a vector, or a TypeError /
/// ValueError naming the argument `what`.
Eigen::Vector3d vector3(py::handle o, const std::string& what) {
  // numpy would make None a 0-d NaN array.
  if (o.is_none()) throw py::type_error(what + ": expected 3 numbers (x, y, z), got None");
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(o);
  if (!a) {
    PyErr_Clear();
    throw py::type_error(what + ": expected 3 numbers (x, y, z), got " + typeName(o));
  }
  if (a.ndim() != 1 || a.shape(0) != 3) {
    throw py::value_error(what + ": expected 3 numbers (x, y, z), got an array of shape " + shapeText(a));
  }
  return {a.at(0), a.at(1), a.at(2)};
}

/// A vertex index (a Python or numpy integer) in [0, count), or a TypeError /
/// ValueError naming the argument `what`.
int vertexIndex(py::handle o, const std::string& what, int count) {
  if (!PyIndex_Check(o.ptr()))
    throw py::type_error(what + ": expected an integer vertex index, got " + typeName(o) + " " +
                         std::string(py::repr(o)));
  const py::int_ value = py::reinterpret_steal<py::int_>(PyNumber_Index(o.ptr()));
  if (!value) throw py::error_already_set();
  if (value < py::int_(0) || value >= py::int_(count))
    throw py::value_error(what + ": vertex index " + std::string(py::repr(value)) + " out of range [0, " +
                          std::to_string(count) + ")");
  return value.cast<int>();
}

/// #F x 3 vertex indices as int, refusing what a cast would change: non-integer
/// arrays (0.9 would become 0) and indices past int's range (2^32 would wrap
/// to 0); out-of-range ones get validateMesh's message.
Eigen::MatrixX3i faceIndices(py::handle o, int vertexCount) {
  const py::array given = py::array::ensure(o);
  if (!given) {
    PyErr_Clear();
    throw py::type_error("from_mesh: faces: expected #F x 3 integer vertex indices, got " + typeName(o));
  }
  const char kind = given.dtype().kind();
  if (given.size() != 0 && kind != 'i' && kind != 'u')
    throw py::type_error("from_mesh: faces: expected integer vertex indices, got an array of " +
                         std::string(py::str(given.dtype())));
  const auto a = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(given);
  if (!a) throw py::error_already_set();
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw py::value_error("from_mesh: faces: expected #F x 3 vertex indices, got an array of shape " + shapeText(a));
  }
  Eigen::MatrixX3i faces(a.shape(0), 3);
  const auto r = a.unchecked<2>();
  for (py::ssize_t f = 0; f < r.shape(0); ++f) {
    for (int k = 0; k < 3; ++k) {
      const std::int64_t index = r(f, k);
      if (index < 0 || index >= vertexCount)
        throw blot::stain::MeshError("from_mesh: face " + std::to_string(f) + ": vertex index " +
                                     std::to_string(index) + " out of range [0, " + std::to_string(vertexCount - 1) +
                                     "]");
      faces(f, k) = static_cast<int>(index);
    }
  }
  return faces;
}

blot::stain::DropDef dropDef(py::object vertex, py::object point, double radius, double solventMass,
                             double soluteMass, py::object velocity, double splashSpeed, std::uint64_t splashSeed,
                             int vertexCount) {
  blot::stain::DropDef d;
  if (!vertex.is_none() == !point.is_none())
    throw std::invalid_argument("add_drop: give exactly one of vertex= or point=");
  if (!vertex.is_none()) d.centerVertex = vertexIndex(vertex, "add_drop: vertex", vertexCount);
  if (!point.is_none()) d.centerPoint = vector3(point, "add_drop: point");
  d.radius = radius;
  d.solventMass = solventMass;
  d.soluteMass = soluteMass;
  if (!velocity.is_none()) {
    d.velocity = vector3(velocity, "add_drop: velocity");
  } else {
    d.velocityIsWorld = false;  // lands and moves with the cloth, as a scene drop without "velocity"
  }
  d.splashSpeed = splashSpeed;
  d.splashSeed = splashSeed;
  return d;
}

blot::stain::TriangleMesh meshFromArrays(const Eigen::MatrixX3d& vertices, const Eigen::MatrixX3i& faces) {
  blot::stain::TriangleMesh mesh;
  mesh.vertexPositions = vertices;
  mesh.faces = faces;
  return mesh;
}

}  // namespace

PYBIND11_MODULE(_blot, m) {
  m.doc() = "Blot stain engine (C++), see help(blot)";

  // C++ exceptions become these, with the C++ message unchanged. Anything
  // else keeps pybind11's mapping (std::invalid_argument -> ValueError,
  // std::runtime_error -> RuntimeError, ...).
  static py::exception<blot::engine::SceneError> sceneError(m, "SceneError", PyExc_ValueError);
  static py::exception<blot::stain::MeshError> meshError(m, "MeshError", PyExc_ValueError);
  static py::exception<StepFailure> stepError(m, "StepError", PyExc_RuntimeError);
  static py::exception<blot::stain::PatternError> patternError(m, "PatternError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StepFailure& e) {
      PyErr_SetString(stepError.ptr(), e.what());
    } catch (const blot::engine::SceneError& e) {
      PyErr_SetString(sceneError.ptr(), e.what());
    } catch (const blot::stain::MeshError& e) {
      PyErr_SetString(meshError.ptr(), e.what());
    } catch (const blot::stain::PatternError& e) {
      PyErr_SetString(patternError.ptr(), e.what());
    }
  });

  py::class_<PyEngine, std::unique_ptr<PyEngine>> engine(m, "Engine", R"doc(
A stain simulation on one moving surface (blot::Engine).

Build it with Engine.from_scene_file, Engine.from_scene_json (a dict is
turned into JSON by blot.Engine.from_dict) or Engine.from_mesh. Array
properties are read-only numpy views of the engine's buffers (no copy) that
keep the engine alive and show the state after each step (docs:
python/README.md). One engine is used by one thread at a time: a call while
a step of it runs on another thread raises RuntimeError.
)doc");
  // A view of an engine buffer, `self` (the Python Engine) its base.
  const auto view = [](auto read, const char* name) {
    return [read, name](py::object self) {
      PyEngine& w = self.cast<PyEngine&>();
      return readOnlyView(read(w, idle(w, name)), self);
    };
  };
  // The same of a derived buffer (computed on request), marked as viewed so
  // that each step refreshes it (refreshViewed).
  const auto derivedView = [](bool PyEngine::*viewed, const Eigen::MatrixX3d& (Engine::*read)() const,
                              const char* name) {
    return [viewed, read, name](py::object self) {
      PyEngine& w = self.cast<PyEngine&>();
      const Engine& e = idle(w, name);
      w.*viewed = true;
      return readOnlyView((e.*read)(), self);
    };
  };
  engine
      .def_static(
          "from_scene_file",
          [](const std::string& path, int patchResolution) {
            return runUnlocked([&] {
              blot::engine::SceneLoadOptions options;
              options.patchResolution = patchResolution;
              return std::make_unique<Engine>(blot::engine::engineDef(blot::engine::loadScene(path, options)));
            });
          },
          py::arg("path"), py::arg("patch_resolution") = 0,
          "Reads a scene file (docs/scene-format.md); patch_resolution > 0 regrids a \"patch\" mesh to that many "
          "quads across. Raises SceneError naming the key.")
      .def_static(
          "from_scene_json",
          [](const std::string& text, const std::string& baseDirectory, const std::string& sourceName,
             int patchResolution) {
            return runUnlocked([&] {
              blot::engine::SceneLoadOptions options;
              options.patchResolution = patchResolution;
              return std::make_unique<Engine>(
                  blot::engine::engineDef(blot::engine::parseScene(text, sourceName, baseDirectory, options)));
            });
          },
          py::arg("text"), py::arg("base_directory") = ".", py::arg("source_name") = "<scene>",
          py::arg("patch_resolution") = 0,
          "The same from scene JSON text; relative paths resolve against base_directory.")
      .def_static(
          "from_mesh",
          [](const Eigen::MatrixX3d& vertices, py::object faces, double timeStep, double diffusivity,
             double viscosity, py::object gravity, py::object angularVelocity, py::object pivot,
             py::object linearVelocity, double strainTolerance, int threads, const std::string& model,
             py::object kinematicViscosity, py::object slipLength, py::object molecularDiffusivity) {
            EngineDef def;
            if (model == "paper") {
              blot::stain::applyPhysicsModel(blot::stain::PhysicsModel::Paper, def.stain.switches, def.stain.liquid);
            } else if (model != "film") {
              throw py::value_error("from_mesh: model \"" + model + "\": expected \"film\" or \"paper\"");
            }
            if (!kinematicViscosity.is_none()) def.stain.liquid.kinematicViscosity = kinematicViscosity.cast<double>();
            if (!slipLength.is_none()) def.stain.liquid.slipLength = slipLength.cast<double>();
            if (!molecularDiffusivity.is_none())
              def.stain.liquid.molecularDiffusivity = molecularDiffusivity.cast<double>();
            def.mesh = meshFromArrays(vertices, faceIndices(faces, static_cast<int>(vertices.rows())));
            blot::stain::validateMesh(def.mesh, "from_mesh");
            def.timeStep = timeStep;
            def.diffusivity = diffusivity;
            def.viscosity = viscosity;
            def.stain.gravity = vector3(gravity, "from_mesh: gravity");
            def.stain.strainTolerance = strainTolerance;
            def.stain.threads = threads;
            if (!angularVelocity.is_none() || !linearVelocity.is_none()) {
              def.source = blot::engine::MotionSource::Rigid;
              if (!angularVelocity.is_none())
                def.rigid.angularVelocity = vector3(angularVelocity, "from_mesh: angular_velocity");
              if (!pivot.is_none()) def.rigid.pivot = vector3(pivot, "from_mesh: pivot");
              if (!linearVelocity.is_none())
                def.rigid.linearVelocity = vector3(linearVelocity, "from_mesh: linear_velocity");
            }
            return runUnlocked([&] { return std::make_unique<Engine>(def); });
          },
          py::arg("vertices"), py::arg("faces"), py::kw_only(), py::arg("time_step") = 1.0 / 120.0,
          py::arg("diffusivity") = 0.01, py::arg("viscosity") = 2e-3,
          py::arg("gravity") = py::make_tuple(0.0, 0.0, -9.8), py::arg("angular_velocity") = py::none(),
          py::arg("pivot") = py::none(), py::arg("linear_velocity") = py::none(),
          py::arg("strain_tolerance") = 1e-3, py::arg("threads") = 0, py::arg("model") = "film",
          py::arg("kinematic_viscosity") = py::none(), py::arg("slip_length") = py::none(),
          py::arg("molecular_diffusivity") = py::none(),
          "An engine on your own mesh (vertices #V x 3 in m, faces #F x 3 integer indices), isotropic fabric, no "
          "files: a static surface, or a rigid motion when angular_velocity or linear_velocity is given. model: "
          "\"film\" (a thin viscous film: friction with the fabric, hydrostatic pressure) or \"paper\" (the "
          "paper's equations); kinematic_viscosity (m²/s, default water's 1e-6) and slip_length (m, default "
          "1e-5) set the film's friction; molecular_diffusivity (m²/s, default 1e-9) the dissolved solute's "
          "diffusion in the liquid (film model). For Bullet "
          "cloth, fabric patterns and every other key use a scene (from_dict / from_scene_json).")
      .def(
          "step",
          [](PyEngine& w, double frameDt) {
            stepUnlocked(w, "step", [frameDt](Engine& e) { return e.step(frameDt); });
          },
          py::arg("frame_dt"),
          "Adds frame_dt (s) of frame time and runs the whole internal steps it covers (GIL released). A failed "
          "step raises StepError with the engine's report (stage, vertex, step); the state stays the last good one.")
      .def(
          "advance_steps",
          [](PyEngine& w, int count) {
            stepUnlocked(w, "advance_steps", [count](Engine& e) { return e.advanceSteps(count); });
          },
          py::arg("count"), "Runs exactly count internal steps (GIL released); raises StepError on a failed step.")
      .def(
          "add_drop",
          [](PyEngine& w, py::object vertex, py::object point, double radius, double solventMass, double soluteMass,
             py::object velocity, double splashSpeed, std::uint64_t splashSeed) {
            Engine& e = idle(w, "add_drop");
            e.addDrop(dropDef(vertex, point, radius, solventMass, soluteMass, velocity, splashSpeed, splashSeed,
                              e.vertexCount()));
          },
          py::kw_only(), py::arg("vertex") = py::none(), py::arg("point") = py::none(), py::arg("radius") = 0.05,
          py::arg("solvent_mass") = 1e-3, py::arg("solute_mass") = 1e-4, py::arg("velocity") = py::none(),
          py::arg("splash_speed") = 0.0, py::arg("splash_seed") = 0,
          "Queues a drop for the next internal step, centred at a vertex or where a world point lands on the cloth "
          "(kg, m, m/s). Without velocity it lands moving with the cloth.")
      .def_property_readonly("vertex_count", [](PyEngine& w) { return idle(w, "vertex_count").vertexCount(); })
      .def_property_readonly("time", [](PyEngine& w) { return idle(w, "time").time(); }, "simulated time (s)")
      .def_property_readonly("step_count", [](PyEngine& w) { return idle(w, "step_count").stepCount(); })
      .def_property_readonly("time_step", [](PyEngine& w) { return idle(w, "time_step").timeStep(); })
      .def_property(
          "threads", [](PyEngine& w) { return idle(w, "threads").threadCount(); },
          [](PyEngine& w, int threads) { idle(w, "threads").setThreadCount(threads); })
      .def_property(
          "adaptive_threads", [](PyEngine& w) { return idle(w, "adaptive_threads").adaptiveThreads(); },
          [](PyEngine& w, bool adaptive) { idle(w, "adaptive_threads").setAdaptiveThreads(adaptive); })
      .def_property_readonly(
          "state_hash", [](PyEngine& w) { return idle(w, "state_hash").stateHash(); },
          "FNV-1a over every simulation array, an int: f\"{e.state_hash:016x}\" is `blot run`'s summary state_hash "
          "(a hex string)")
      .def_property_readonly("faces", [](PyEngine& w) { return copyOf(idle(w, "faces").faces()); },
                             "#F x 3 int32 (a copy)")
      .def_property_readonly(
          "rest_positions",
          view([](PyEngine&, const Engine& e) -> const auto& { return e.definition().mesh.vertexPositions; },
               "rest_positions"),
          "#V x 3 rest shape (m), read-only view")
      .def_property_readonly(
          "uvs", view([](PyEngine&, const Engine& e) -> const auto& { return e.definition().mesh.vertexUVs; }, "uvs"),
          "#V x 2 texture coordinates of the rest mesh (0 rows when it has none), read-only view")
      .def_property_readonly(
          "positions", view([](PyEngine&, const Engine& e) -> const auto& { return e.positions(); }, "positions"),
          "#V x 3 (m) at time, read-only view")
      .def_property_readonly("normals", derivedView(&PyEngine::normalsViewed, &Engine::normals, "normals"),
                             "#V x 3 unit vertex normals at time, read-only view")
      .def_property_readonly(
          "solvent", view([](PyEngine&, const Engine& e) -> const auto& { return e.solvent(); }, "solvent"),
          "free solvent density (kg/m²), read-only view")
      .def_property_readonly("solute",
                             view([](PyEngine&, const Engine& e) -> const auto& { return e.solute(); }, "solute"))
      .def_property_readonly(
          "absorbed_solvent",
          view([](PyEngine&, const Engine& e) -> const auto& { return e.absorbedSolvent(); }, "absorbed_solvent"))
      .def_property_readonly(
          "absorbed_solute",
          view([](PyEngine&, const Engine& e) -> const auto& { return e.absorbedSolute(); }, "absorbed_solute"))
      .def_property_readonly(
          "adsorbed_solute",
          view([](PyEngine&, const Engine& e) -> const auto& { return e.adsorbedSolute(); }, "adsorbed_solute"))
      .def_property_readonly("velocities",
                             derivedView(&PyEngine::velocitiesViewed, &Engine::liquidVelocities, "velocities"),
                             "#V x 3 liquid velocity relative to the cloth (m/s), read-only view")
      .def_property_readonly(
          "world_velocities",
          derivedView(&PyEngine::worldVelocitiesViewed, &Engine::liquidWorldVelocities, "world_velocities"),
          "#V x 3 liquid velocity in the world frame (m/s), read-only view")
      .def_property_readonly("colors", derivedView(&PyEngine::colorsViewed, &Engine::colors, "colors"),
                             "#V x 3 linear RGB in [0, 1], read-only view")
      .def_property_readonly(
          "vertex_areas",
          [](PyEngine& w) {
            // Lumped mass (one third of the one-ring area at the rest shape), the
            // weights of the sweeps' mass-weighted metrics: a copy.
            const auto& mesh = idle(w, "vertex_areas").definition().mesh;
            py::array_t<double> a(static_cast<py::ssize_t>(mesh.vertexPositions.rows()));
            auto r = a.mutable_unchecked<1>();
            for (py::ssize_t i = 0; i < r.shape(0); ++i) r(i) = 0;
            for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
              const Eigen::Vector3d a0 = mesh.vertexPositions.row(mesh.faces(f, 0)).transpose();
              const Eigen::Vector3d a1 = mesh.vertexPositions.row(mesh.faces(f, 1)).transpose();
              const Eigen::Vector3d a2 = mesh.vertexPositions.row(mesh.faces(f, 2)).transpose();
              const double third = 0.5 * (a1 - a0).cross(a2 - a0).norm() / 3.0;
              for (int j = 0; j < 3; ++j) r(mesh.faces(f, j)) += third;
            }
            return a;
          },
          "#V rest-shape lumped vertex areas (m², one third of the one-ring), a copy")
      .def("statistics", [](PyEngine& w) { return pythonDict(idle(w, "statistics").statistics()); },
           "Counters, timings (last step and sums in ms), the mass budget (kg): a dict")
      .def("mass_budget", [](PyEngine& w) { return pythonDict(idle(w, "mass_budget").statistics().massBudget); })
      .def("last_profile", [](PyEngine& w) { return pythonDict(idle(w, "last_profile").statistics().lastProfile); },
           "Per-stage times (ms) and counters of the last internal step")
      .def("inject_fault_for_testing",
           [](PyEngine& w, const std::string& stage, int step, int vertex) {
             Engine& e = idle(w, "inject_fault_for_testing");
             blot::stain::InjectedFault f;
             if (!blot::stain::parseStage(stage, f.stage))
               throw std::invalid_argument("inject_fault_for_testing: unknown stage \"" + stage + "\"");
             f.step = step;
             f.vertex = vertex;
             e.injectFaultForTesting(f);
           },
           py::arg("stage"), py::arg("step"), py::arg("vertex") = 0,
           "Testing only: a NaN after that stage of that internal step (1-based), to exercise StepError.");

  m.def(
      "scene_mesh_order",
      [](const std::string& path, int patchResolution) {
        blot::engine::SceneLoadOptions options;
        options.patchResolution = patchResolution;
        blot::engine::SceneDef scene;
        {
          py::gil_scoped_release release;
          scene = blot::engine::loadScene(path, options);
        }
        const auto identity = [](Eigen::Index n) {
          std::vector<int> v(static_cast<size_t>(n));
          for (size_t k = 0; k < v.size(); ++k) v[k] = static_cast<int>(k);
          return v;
        };
        const blot::stain::MeshOrder& order = scene.meshOrder;
        py::dict d;
        d["vertices"] = py::array_t<int>(py::cast(
            order.vertices.empty() ? identity(scene.engine.mesh.vertexPositions.rows()) : order.vertices));
        d["faces"] =
            py::array_t<int>(py::cast(order.faces.empty() ? identity(scene.engine.mesh.faces.rows()) : order.faces));
        return d;
      },
      py::arg("path"), py::arg("patch_resolution") = 0,
      "The scene's mesh numbering against its file's (mesh.vertex_order, docs/scene-format.md): dict of vertices "
      "(#V int32: the file's index of each engine vertex) and faces (#F, the same for faces); the identity unless "
      "the scene renumbers its mesh. Reads the scene again. Raises SceneError naming the key.");

  m.def(
      "load_mesh",
      [](const std::string& path) {
        const blot::stain::TriangleMesh mesh = blot::stain::loadMesh(path);
        py::dict d;
        d["vertices"] = py::array_t<double>(py::cast(Eigen::MatrixXd(mesh.vertexPositions)));
        d["faces"] = copyOf(mesh.faces);
        d["uvs"] = py::cast(Eigen::MatrixXd(mesh.vertexUVs));
        d["face_labels"] = py::cast(mesh.faceLabels);
        return d;
      },
      py::arg("path"),
      "Loads an OBJ, PLY or OFF mesh (validated): dict of vertices (#V x 3), faces (#F x 3 int32), uvs (#V x 2 "
      "or 0 rows), face_labels (list, may be empty); copies. Raises MeshError naming the file and element.");

  m.def(
      "homogenize",
      [](const std::string& source, int subdivisions, double tolerance) {
        const blot::stain::WeavePattern pattern = [&] {
          if (source.find('{') != std::string::npos) return blot::stain::parseWeavePattern(source, "<pattern>");
          if (source.size() > 5 && source.compare(source.size() - 5, 5, ".json") == 0)
            return blot::stain::loadWeavePattern(source);
          return blot::stain::presetWeavePattern(source);
        }();
        blot::stain::HomogenizationOptions options;
        options.subdivisions = subdivisions;
        options.tolerance = tolerance;
        blot::stain::HomogenizationResult r;
        {
          py::gil_scoped_release release;
          r = blot::stain::homogenize(pattern, options);
        }
        py::dict d;
        d["effective"] = py::cast(Eigen::MatrixXd(r.effective));
        d["upper"] = py::cast(Eigen::MatrixXd(r.upper));
        d["lower"] = py::cast(Eigen::MatrixXd(r.lower));
        d["gap"] = r.gap;
        d["converged"] = r.converged;
        d["eigenvalues"] = py::cast(Eigen::VectorXd(r.eigenvalues));
        d["principal_angle"] = r.principalAngle;
        d["subdivisions"] = r.subdivisions;
        d["vertex_count"] = r.vertexCount;
        return d;
      },
      py::arg("pattern"), py::arg("subdivisions") = blot::stain::kAutoSubdivisions,
      py::arg("tolerance") = blot::stain::kDefaultGapTolerance,
      "Homogenizes a weave pattern (a preset name, a .json file or pattern JSON text): effective tensor with its "
      "two-sided bounds, as `blot homogenize`.");

  m.attr("AUTO_SUBDIVISIONS") = blot::stain::kAutoSubdivisions;
}
