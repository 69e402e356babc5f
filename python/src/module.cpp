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

py::dict massBudgetDict(const blot::stain::MassBudget& b) {
  py::dict d;
  d["free_solvent"] = b.freeSolvent;
  d["absorbed_solvent"] = b.absorbedSolvent;
  d["evaporated_solvent"] = b.evaporatedSolvent;
  d["added_solvent"] = b.addedSolvent;
  d["free_solute"] = b.freeSolute;
  d["absorbed_solute"] = b.absorbedSolute;
  d["adsorbed_solute"] = b.adsorbedSolute;
  d["added_solute"] = b.addedSolute;
  d["solvent_error"] = b.solventError();
  d["solute_error"] = b.soluteError();
  return d;
}

/// Stage name with '_' for '-' ("advect_velocity"), as `blot run`'s summary.
std::string stageKey(blot::stain::Stage s) {
  std::string name = blot::stain::stageName(s);
  for (char& c : name)
    if (c == '-') c = '_';
  return name;
}

py::dict profileDict(const blot::stain::StepProfile& p) {
  py::dict ms;
  for (int k = 0; k < blot::stain::kStageCount; ++k) {
    const auto s = static_cast<blot::stain::Stage>(k);
    ms[py::str(stageKey(s))] = p.time(s);
  }
  py::dict d;
  d["milliseconds"] = ms;
  d["total_ms"] = p.total;
  d["terms"] = blot::stain::describeTerms(p);
  d["advection_substeps"] = p.advectionSubsteps;
  d["intrinsic_refreshes"] = p.intrinsicRefreshes;
  d["factorizations"] = p.factorizations;
  d["max_edge_strain"] = p.maxEdgeStrain;
  d["wet_vertices"] = p.wetVertices;
  d["band_vertices"] = p.bandVertices;
  d["diffusion_iterations"] = p.diffusionIterations;
  return d;
}

py::dict statisticsDict(const blot::engine::EngineStatistics& s) {
  py::dict d;
  d["steps"] = s.steps;
  d["time"] = s.time;
  d["dropped_time"] = s.droppedTime;
  d["drops_applied"] = s.dropsApplied;
  d["wall_seconds"] = s.wallSeconds;
  d["steps_per_second"] = s.stepsPerSecond;
  d["intrinsic_refreshes"] = s.intrinsicRefreshes;
  d["last_profile"] = profileDict(s.lastProfile);
  d["last_ms"] = py::dict(py::arg("cloth") = s.lastTimes.cloth, py::arg("stain") = s.lastTimes.stain,
                          py::arg("coupling") = s.lastTimes.coupling, py::arg("total") = s.lastTimes.total);
  // Sums over every internal step since construction (ms): mean = total / steps.
  py::dict stages;
  for (int k = 0; k < blot::stain::kStageCount; ++k) {
    const auto st = static_cast<blot::stain::Stage>(k);
    if (st < blot::stain::kFirstStainStage || st > blot::stain::kLastStainStage) continue;
    stages[py::str(stageKey(st))] = s.totals.stage(st);
  }
  d["total_ms"] = py::dict(py::arg("stages") = stages, py::arg("cloth") = s.totals.cloth,
                           py::arg("stain") = s.totals.stain, py::arg("coupling") = s.totals.coupling,
                           py::arg("total") = s.totals.total);
  d["mass_budget"] = massBudgetDict(s.massBudget);
  return d;
}

blot::stain::DropDef dropDef(py::object vertex, py::object point, double radius, double solventMass,
                             double soluteMass, py::object velocity, double splashSpeed, std::uint64_t splashSeed) {
  blot::stain::DropDef d;
  if (!vertex.is_none() == !point.is_none())
    throw std::invalid_argument("add_drop: give exactly one of vertex= or point=");
  if (!vertex.is_none()) d.centerVertex = vertex.cast<int>();
  if (!point.is_none()) d.centerPoint = point.cast<Eigen::Vector3d>();
  d.radius = radius;
  d.solventMass = solventMass;
  d.soluteMass = soluteMass;
  if (!velocity.is_none()) {
    d.velocity = velocity.cast<Eigen::Vector3d>();
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

std::unique_ptr<Engine> runUnlocked(const std::function<std::unique_ptr<Engine>()>& build) {
  py::gil_scoped_release release;
  return build();
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

  py::class_<Engine, std::unique_ptr<Engine>> engine(m, "Engine", R"doc(
A stain simulation on one moving surface (blot::Engine).

Build it with Engine.from_scene_file, Engine.from_scene_json (a dict is
turned into JSON by blot.Engine.from_dict) or Engine.from_mesh. Array
properties are read-only numpy views of the engine's buffers (no copy) that
keep the engine alive; read them again after a step (docs: python/README.md).
)doc");
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
          [](const Eigen::MatrixX3d& vertices, const Eigen::MatrixX3i& faces, double timeStep, double diffusivity,
             double viscosity, const Eigen::Vector3d& gravity, py::object angularVelocity, py::object pivot,
             py::object linearVelocity, double strainTolerance, int threads) {
            EngineDef def;
            def.mesh = meshFromArrays(vertices, faces);
            blot::stain::validateMesh(def.mesh, "from_mesh");
            def.timeStep = timeStep;
            def.diffusivity = diffusivity;
            def.viscosity = viscosity;
            def.stain.gravity = gravity;
            def.stain.strainTolerance = strainTolerance;
            def.stain.threads = threads;
            if (!angularVelocity.is_none() || !linearVelocity.is_none()) {
              def.source = blot::engine::MotionSource::Rigid;
              if (!angularVelocity.is_none()) def.rigid.angularVelocity = angularVelocity.cast<Eigen::Vector3d>();
              if (!pivot.is_none()) def.rigid.pivot = pivot.cast<Eigen::Vector3d>();
              if (!linearVelocity.is_none()) def.rigid.linearVelocity = linearVelocity.cast<Eigen::Vector3d>();
            }
            return runUnlocked([&] { return std::make_unique<Engine>(def); });
          },
          py::arg("vertices"), py::arg("faces"), py::kw_only(), py::arg("time_step") = 1.0 / 120.0,
          py::arg("diffusivity") = 0.01, py::arg("viscosity") = 2e-3,
          py::arg("gravity") = Eigen::Vector3d(0, 0, -9.8), py::arg("angular_velocity") = py::none(),
          py::arg("pivot") = py::none(), py::arg("linear_velocity") = py::none(),
          py::arg("strain_tolerance") = 1e-3, py::arg("threads") = 0,
          "An engine on your own mesh (vertices #V x 3 in m, faces #F x 3), isotropic fabric, no files: a static "
          "surface, or a rigid motion when angular_velocity or linear_velocity is given. For Bullet cloth, fabric "
          "patterns and every other key use a scene (from_dict / from_scene_json).")
      .def(
          "step",
          [](Engine& e, double frameDt) {
            blot::stain::StepReport r;
            {
              py::gil_scoped_release release;
              r = e.step(frameDt);
            }
            if (!r.ok()) throw StepFailure(r);
          },
          py::arg("frame_dt"),
          "Adds frame_dt (s) of frame time and runs the whole internal steps it covers (GIL released). A failed "
          "step raises StepError with the engine's report (stage, vertex, step); the state stays the last good one.")
      .def(
          "advance_steps",
          [](Engine& e, int count) {
            blot::stain::StepReport r;
            {
              py::gil_scoped_release release;
              r = e.advanceSteps(count);
            }
            if (!r.ok()) throw StepFailure(r);
          },
          py::arg("count"), "Runs exactly count internal steps (GIL released); raises StepError on a failed step.")
      .def(
          "add_drop",
          [](Engine& e, py::object vertex, py::object point, double radius, double solventMass, double soluteMass,
             py::object velocity, double splashSpeed, std::uint64_t splashSeed) {
            e.addDrop(dropDef(vertex, point, radius, solventMass, soluteMass, velocity, splashSpeed, splashSeed));
          },
          py::kw_only(), py::arg("vertex") = py::none(), py::arg("point") = py::none(), py::arg("radius") = 0.05,
          py::arg("solvent_mass") = 1e-3, py::arg("solute_mass") = 1e-4, py::arg("velocity") = py::none(),
          py::arg("splash_speed") = 0.0, py::arg("splash_seed") = 0,
          "Queues a drop for the next internal step, centred at a vertex or where a world point lands on the cloth "
          "(kg, m, m/s). Without velocity it lands moving with the cloth.")
      .def_property_readonly("vertex_count", &Engine::vertexCount)
      .def_property_readonly("time", &Engine::time, "simulated time (s)")
      .def_property_readonly("step_count", &Engine::stepCount)
      .def_property_readonly("time_step", &Engine::timeStep)
      .def_property("threads", &Engine::threadCount, &Engine::setThreadCount)
      .def_property("adaptive_threads", &Engine::adaptiveThreads, &Engine::setAdaptiveThreads)
      .def_property_readonly("state_hash", &Engine::stateHash,
                             "FNV-1a over every simulation array; equal to `blot run`'s summary state_hash")
      .def_property_readonly("faces", [](const Engine& e) { return copyOf(e.faces()); }, "#F x 3 int32 (a copy)")
      .def_property_readonly(
          "rest_positions", [](py::object self) { return readOnlyView(self.cast<const Engine&>().definition().mesh.vertexPositions, self); },
          "#V x 3 rest shape (m), read-only view")
      .def_property_readonly(
          "uvs", [](py::object self) { return readOnlyView(self.cast<const Engine&>().definition().mesh.vertexUVs, self); },
          "#V x 2 texture coordinates of the rest mesh (0 rows when it has none), read-only view")
      .def_property_readonly(
          "positions", [](py::object self) { return readOnlyView(self.cast<const Engine&>().positions(), self); },
          "#V x 3 (m) at time, read-only view")
      .def_property_readonly(
          "normals", [](py::object self) { return readOnlyView(self.cast<const Engine&>().normals(), self); })
      .def_property_readonly(
          "solvent", [](py::object self) { return readOnlyView(self.cast<const Engine&>().solvent(), self); },
          "free solvent density (kg/m²), read-only view")
      .def_property_readonly(
          "solute", [](py::object self) { return readOnlyView(self.cast<const Engine&>().solute(), self); })
      .def_property_readonly(
          "absorbed_solvent",
          [](py::object self) { return readOnlyView(self.cast<const Engine&>().absorbedSolvent(), self); })
      .def_property_readonly(
          "absorbed_solute",
          [](py::object self) { return readOnlyView(self.cast<const Engine&>().absorbedSolute(), self); })
      .def_property_readonly(
          "adsorbed_solute",
          [](py::object self) { return readOnlyView(self.cast<const Engine&>().adsorbedSolute(), self); })
      .def_property_readonly(
          "velocities",
          [](py::object self) { return readOnlyView(self.cast<const Engine&>().liquidVelocities(), self); },
          "#V x 3 liquid velocity relative to the cloth (m/s), read-only view")
      .def_property_readonly(
          "world_velocities",
          [](py::object self) { return readOnlyView(self.cast<const Engine&>().liquidWorldVelocities(), self); })
      .def_property_readonly(
          "colors", [](py::object self) { return readOnlyView(self.cast<const Engine&>().colors(), self); },
          "#V x 3 linear RGB in [0, 1], read-only view")
      .def_property_readonly(
          "vertex_areas",
          [](const Engine& e) {
            // Lumped mass (one third of the one-ring area at the rest shape), the
            // weights of the sweeps' mass-weighted metrics: a copy.
            const auto& mesh = e.definition().mesh;
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
      .def("statistics", [](const Engine& e) { return statisticsDict(e.statistics()); },
           "Counters, timings (last step and sums in ms), the mass budget (kg): a dict")
      .def("mass_budget", [](const Engine& e) { return massBudgetDict(e.statistics().massBudget); })
      .def("last_profile", [](const Engine& e) { return profileDict(e.statistics().lastProfile); },
           "Per-stage times (ms) and counters of the last internal step")
      .def("inject_fault_for_testing",
           [](Engine& e, const std::string& stage, int step, int vertex) {
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
