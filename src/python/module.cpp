// The Python module `handskin` (its compiled part, `handskin._core`; docs/python.md): the
// pipeline's functions over NumPy arrays and dicts. Only conversion lives here — every
// computation is the C++ stages' own, so a figure from Python equals the CLI's on the same
// inputs. The long calls release the GIL; errors become Python exceptions with the CLI's
// one-line messages (see `translate`).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/output_set.hpp"
#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "pipeline/mesh_files.hpp"
#include "pipeline/options.hpp"
#include "pipeline/patch_stage.hpp"
#include "pipeline/registration_stage.hpp"
#include "pipeline/run.hpp"
#include "pipeline/skin_stage.hpp"
#include "pipeline/stage_options.hpp"
#include "posture/model.hpp"
#include "posture/solution_io.hpp"
#include "posture/solver.hpp"
#include "rigging/gltf.hpp"
#include "rigging/pose.hpp"
#include "scan/cubist_io.hpp"

namespace py = pybind11;
using namespace handskin;

namespace {

// ---------------------------------------------------------------- JSON → Python

py::object to_py(const Json& j) {
  switch (j.type()) {
    case Json::value_t::boolean: return py::bool_(j.get<bool>());
    case Json::value_t::number_integer: return py::int_(j.get<std::int64_t>());
    case Json::value_t::number_unsigned: return py::int_(j.get<std::uint64_t>());
    case Json::value_t::number_float: return py::float_(j.get<double>());
    case Json::value_t::string: return py::str(j.get_ref<const std::string&>());
    case Json::value_t::array: {
      py::list l;
      for (const auto& e : j) l.append(to_py(e));
      return std::move(l);
    }
    case Json::value_t::object: {
      py::dict d;
      for (const auto& [k, v] : j.items()) d[py::str(k)] = to_py(v);
      return std::move(d);
    }
    default: return py::none();  // null (and nothing else occurs in our JSON)
  }
}

// ---------------------------------------------------------------- arrays

/// A read-only (rows, cols) view of `data`, kept alive by `base` (the Python object that owns
/// the memory): no copy.
template <class T>
py::array view(const T* data, size_t rows, size_t cols, py::handle base) {
  py::array_t<T> a({static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(cols)},
                   {static_cast<py::ssize_t>(cols * sizeof(T)), static_cast<py::ssize_t>(sizeof(T))}, data, base);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return std::move(a);
}
py::array view3(const std::vector<Eigen::Vector3d>& v, py::handle base) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "Vector3d is three packed doubles");
  return view(v.empty() ? nullptr : v.front().data(), v.size(), 3, base);
}
py::array view_faces(const std::vector<std::array<int, 3>>& f, py::handle base) {
  static_assert(sizeof(std::array<int, 3>) == 3 * sizeof(int), "a face is three packed ints");
  return view(f.empty() ? nullptr : f.front().data(), f.size(), 3, base);
}
/// An array that owns `v` (moved into a capsule): no copy, writable (the caller's now).
template <class T, size_t N, class Elem>
py::array owned(std::vector<Elem>&& v) {
  static_assert(sizeof(Elem) == N * sizeof(T), "elements are N packed values");
  auto* p = new std::vector<Elem>(std::move(v));
  py::capsule owner(p, [](void* q) { delete static_cast<std::vector<Elem>*>(q); });
  const T* data = p->empty() ? nullptr : reinterpret_cast<const T*>(p->data());
  return py::array_t<T>({static_cast<py::ssize_t>(p->size()), static_cast<py::ssize_t>(N)},
                        {static_cast<py::ssize_t>(N * sizeof(T)), static_cast<py::ssize_t>(sizeof(T))}, data, owner);
}

/// `obj` as a C-contiguous array of T (converted when it must be); an empty handle when it
/// cannot be (the callers then say what they wanted).
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> as_array(const py::handle& obj) {
  try {
    return py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(obj);
  } catch (const py::error_already_set&) {
    return {};
  }
}

/// An (n, 3) array of finite numbers as points; ValueError naming `what` otherwise.
std::vector<Eigen::Vector3d> points_from(const py::handle& obj, const std::string& what) {
  const auto a = as_array<double>(obj);
  if (!a || a.ndim() != 2 || a.shape(1) != 3)
    throw UsageError(what, "must be an (n, 3) array of numbers");
  std::vector<Eigen::Vector3d> out(static_cast<size_t>(a.shape(0)));
  const double* d = a.data();
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Eigen::Vector3d(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
    if (!out[i].allFinite()) throw UsageError(what, "row " + std::to_string(i) + " is not finite");
  }
  return out;
}

/// One label per point, 0 (palm scan) or 1 (back scan); ValueError naming `sides` otherwise.
std::vector<std::uint32_t> sides_from(const py::handle& obj, size_t points) {
  const auto s = as_array<std::int64_t>(obj);
  if (!s || s.ndim() != 1 || static_cast<size_t>(s.shape(0)) != points)
    throw UsageError("sides", "must be a 1-D array with one label per point (0 palm scan, 1 back scan)");
  std::vector<std::uint32_t> out;
  out.reserve(points);
  for (py::ssize_t i = 0; i < s.shape(0); ++i) {
    if (s.data()[i] != 0 && s.data()[i] != 1) throw UsageError("sides", "label " + std::to_string(i) + " is not 0 or 1");
    out.push_back(static_cast<std::uint32_t>(s.data()[i]));
  }
  return out;
}

/// The pipeline's stages (run, register, build_skin, fit_patches) one at a time in a process:
/// two runs at once on two threads crashed (a segfault in 1 of 2 fresh-clone CI runs; the
/// shared state at fault is not found yet), so a second call waits, with the GIL released,
/// for the first. Each run uses both cores by itself; posture models and skins stay parallel.
std::mutex& pipeline_mutex() {
  static std::mutex m;
  return m;
}

// ---------------------------------------------------------------- progress

/// A Python callable that receives the stages' progress lines. Called from the thread that
/// made the call (the GIL taken for it); lines from other threads (side work) are dropped.
/// A callback that raises — or a Ctrl-C seen between lines — stops the call: the exception
/// propagates and nothing is written.
class Progress {
 public:
  explicit Progress(py::object fn) : fn_(std::move(fn)), caller_(std::this_thread::get_id()) {}
  void operator()(const std::string& stage, const std::string& line) const {
    if (std::this_thread::get_id() != caller_) return;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    if (!fn_.is_none()) fn_(stage, line);
  }
  std::function<void(const std::string&)> stage(const std::string& name) const {
    return [this, name](const std::string& line) { (*this)(name, line); };
  }

 private:
  py::object fn_;
  std::thread::id caller_;
};

PipelineOptions pipeline_from(const std::optional<std::string>& path) {
  return path ? load_pipeline(*path) : PipelineOptions{};
}

Rig rig_from(const py::object& rig) {
  if (py::isinstance<py::str>(rig) || py::isinstance(rig, py::module_::import("os").attr("PathLike")))
    return load_palm_rig(py::str(py::module_::import("os").attr("fspath")(rig)));
  if (py::isinstance<py::dict>(rig)) {
    const std::string text = py::str(py::module_::import("json").attr("dumps")(rig));
    return parse_rig(text, "rig");
  }
  throw UsageError("rig", "must be a hand-rig/1 file's path or its dict");
}

// ---------------------------------------------------------------- posture

int dof_named(const std::string& name, const std::string& where) { return require_dof(name, where); }

/// A pin's, torque's or target's value: a finite number within ±kMaxTorque (as the CLI's --set).
double number_in(const py::handle& v, const std::string& where) {
  try {
    const double x = v.cast<double>();
    if (!std::isfinite(x)) throw UsageError(where, "is not finite");
    if (!(std::abs(x) <= kMaxTorque)) throw UsageError(where, "must be within ±1e4");
    return x;
  } catch (const py::cast_error&) {
    throw UsageError(where, "is not a number");
  }
}

py::dict dict_of(const py::object& o, const std::string& what, const std::string& form) {
  if (!py::isinstance<py::dict>(o)) throw UsageError(what, "must be a dict " + form);
  return o.cast<py::dict>();
}

PostureInputs posture_inputs(const py::object& pins, const py::object& torques, const py::object& targets) {
  PostureInputs in;
  if (!pins.is_none())
    for (const auto& [k, v] : dict_of(pins, "pins", "{DOF name: degrees}")) {
      const std::string name = py::str(k);
      in.pins.emplace_back(dof_named(name, "pins"), number_in(v, "pins['" + name + "']"));
    }
  if (!torques.is_none())
    for (const auto& [k, v] : dict_of(torques, "torques", "{DOF name: input}")) {
      const std::string name = py::str(k);
      in.torques.emplace_back(dof_named(name, "torques"), number_in(v, "torques['" + name + "']"));
    }
  if (!targets.is_none())
    for (const auto& [k, v] : dict_of(targets, "targets", "{DOF name: (degrees, weight)}")) {
      const std::string name = py::str(k), where = "targets['" + name + "']";
      if (!py::isinstance<py::sequence>(v) || py::isinstance<py::str>(v) || py::len(v) != 2)
        throw UsageError(where, "must be (angle, weight)");
      const py::sequence t = v.cast<py::sequence>();
      in.targets.push_back({dof_named(name, "targets"), number_in(t[0], where + "[0]"), number_in(t[1], where + "[1]")});
    }
  return in;
}

py::dict angles_dict(const Angles& a) {
  py::dict d;
  for (int k = 0; k < kDofCount; ++k) d[py::str(dofs()[k].name)] = a[k];
  return d;
}

/// A posture model with its solver. The solver caches factorisations as it goes, so calls on
/// one model are serialised (two models solve in parallel).
struct PyModel {
  PostureModel model;
  std::unique_ptr<PostureSolver> solver;
  std::mutex mutex;
  explicit PyModel(PostureModel m) : model(std::move(m)), solver(std::make_unique<PostureSolver>(model)) {}
};

py::dict model_solve(PyModel& m, const py::object& pins, const py::object& torques, const py::object& targets, bool linear,
               bool details) {
  const PostureInputs in = posture_inputs(pins, torques, targets);
  PostureSolution s;
  {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(m.mutex);
    s = linear ? m.solver->solve_linear(in) : m.solver->solve(in);
  }
  if (!details) return angles_dict(s.angles);
  py::dict d = to_py(posture_solution_to_json(m.model, in, s)).cast<py::dict>();
  return d;
}

py::array model_solve_batch(PyModel& m, const std::vector<std::string>& columns, const py::object& values, bool linear) {
  std::vector<int> col;
  for (const auto& c : columns) {
    const int d = dof_named(c, "columns");
    for (int e : col)
      if (e == d) throw UsageError("columns", "'" + c + "' is given twice");
    col.push_back(d);
  }
  const auto x = as_array<double>(values);
  if (!x || x.ndim() != 2 || x.shape(1) != static_cast<py::ssize_t>(col.size()))
    throw UsageError("values", "must be an (n, " + std::to_string(col.size()) + ") array: one column per name in columns");
  const size_t n = static_cast<size_t>(x.shape(0)), k = col.size();
  py::array_t<double> out({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(kDofCount)});
  const double* in = x.data();
  double* o = out.mutable_data();
  {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(m.mutex);
    PostureInputs pi;
    pi.pins.reserve(k);
    for (size_t r = 0; r < n; ++r) {
      pi.pins.clear();
      for (size_t c = 0; c < k; ++c)
        if (!std::isnan(in[r * k + c])) pi.pins.emplace_back(col[c], in[r * k + c]);  // NaN: free, as an empty CSV cell
      const PostureSolution s = linear ? m.solver->solve_linear(pi) : m.solver->solve(pi);
      std::copy(s.angles.begin(), s.angles.end(), o + r * kDofCount);
    }
  }
  return std::move(out);
}

/// Every DOF's angle from a dict naming all of them, or an array of kDofCount; nullopt for a
/// dict naming only some (the caller solves for the rest with them pinned).
std::optional<Angles> full_angles(const py::object& angles, PostureInputs* pins) {
  if (py::isinstance<py::dict>(angles)) {
    Angles a{};
    std::vector<char> seen(kDofCount, 0);
    for (const auto& [k, v] : angles.cast<py::dict>()) {
      const std::string name = py::str(k);
      const int d = dof_named(name, "angles");
      a[d] = number_in(v, "angles['" + name + "']");
      seen[d] = 1;
      pins->pins.emplace_back(d, a[d]);
    }
    for (char s : seen)
      if (!s) return std::nullopt;
    return a;
  }
  const auto x = as_array<double>(angles);
  if (!x || x.ndim() != 1 || x.shape(0) != kDofCount)
    throw UsageError("angles", "must be a dict {DOF name: degrees} or a sequence of " + std::to_string(kDofCount) +
                                   " angles in dofs() order");
  Angles a{};
  for (int d = 0; d < kDofCount; ++d) {
    a[d] = x.data()[d];
    if (!std::isfinite(a[d])) throw UsageError("angles", "angle " + std::to_string(d) + " (" + dofs()[d].name + ") is not finite");
  }
  return a;
}

/// skin.glb as read: the mesh, its rig and binding, its posture model; posed on request.
struct PySkin {
  RiggedSkin skin;
  std::string path;
  std::unique_ptr<PyModel> model;
  std::unique_ptr<SkinPoser> guarded, plain;
  std::mutex mutex;
  explicit PySkin(const std::string& file) : skin(read_skin_glb(file)), path(file) {
    model = std::make_unique<PyModel>(skin.model);
  }
  const SkinPoser& poser(bool guard) {
    auto& p = guard ? guarded : plain;
    if (!p) p = std::make_unique<SkinPoser>(skin.mesh.vertices, skin.mesh.faces, skin.binding, skin.rig, guard);
    return *p;
  }
};

py::array pose_skin(PySkin& s, const py::object& angles, const std::string& blend_name, bool crease_guard) {
  const Blend blend = parse_blend(blend_name, "blend");
  PostureInputs pins;
  std::optional<Angles> a = full_angles(angles, &pins);
  std::vector<Eigen::Vector3d> posed;
  {
    py::gil_scoped_release nogil;
    if (!a) {
      std::lock_guard<std::mutex> lock(s.model->mutex);
      a = s.model->solver->solve(pins).angles;
    }
    std::lock_guard<std::mutex> lock(s.mutex);
    posed = s.poser(crease_guard).pose(*a, blend);
  }
  return owned<double, 3>(std::move(posed));
}

// ---------------------------------------------------------------- stages

struct PyRegistration {
  Registration reg;
  MergedArrays merged;
  Json figures;
};
struct PySkinResult {
  SkinStageResult r;
  Json figures;
};
struct PyPatches {
  PatchStageResult r;
  std::vector<double> bezier;  ///< per patch its 16 control points (P00…P33), 3 each
  Json figures;
};

std::string path_of(const py::object& p) { return py::str(py::module_::import("os").attr("fspath")(p)); }
std::optional<std::string> opt_path(const py::object& p) {
  if (p.is_none()) return std::nullopt;
  return path_of(p);
}

// ---------------------------------------------------------------- errors

/// InputError → FileNotFoundError ("no such file"), OSError (a file or folder that cannot be
/// opened, created, written or locked; an output in the way), else ValueError; GateFailure →
/// handskin.GateFailure (a RuntimeError). The message is the CLI's line without "error: ".
PyObject* g_gate_failure = nullptr;

void translate(std::exception_ptr p) {
  try {
    if (p) std::rethrow_exception(p);
  } catch (const InputError& e) {
    const std::string& d = e.detail();
    auto starts = [&](const char* s) { return d.rfind(s, 0) == 0; };
    PyObject* type = PyExc_ValueError;
    if (starts("no such file"))
      type = PyExc_FileNotFoundError;
    else if (starts("cannot open") || starts("cannot read") || starts("cannot write") || starts("cannot be created") ||
             starts("cannot lock") || starts("cannot move") || starts("is not writable") || starts("is in the way") ||
             starts("write failed") || starts("exists and is not a folder") || starts("another handskin command"))
      type = PyExc_OSError;
    PyErr_SetString(type, InputError(as_output_path(e.where()), d).what());  // the output, not its staging
  } catch (const GateFailure& e) {
    PyErr_SetString(g_gate_failure, e.what());
  }
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "handskin's compiled core (use the package `handskin`; docs/python.md)";
  m.attr("__version__") = HANDSKIN_VERSION;
  static py::exception<GateFailure> gate(m, "GateFailure", PyExc_RuntimeError);
  g_gate_failure = gate.ptr();
  py::register_exception_translator(&translate);

  m.def("dofs", [] {
    std::vector<std::string> names;
    for (int d = 0; d < kDofCount; ++d) names.push_back(dofs()[d].name);
    return names;
  });

  // --- run ---
  m.def(
      "run",
      [](const py::object& back, const py::object& palm, const std::vector<std::string>& clouds, const py::object& rig,
         const py::object& out, const std::string& units, const std::optional<std::string>& hand, bool auto_rig,
         const py::object& markers, const py::object& pipeline, const py::object& truth, const std::string& posture_model,
         std::optional<double> patch_tolerance, bool scan_clouds, bool force, bool strict, const py::object& progress) {
        RunInputs in;
        if (!back.is_none()) in.back_stem = scan_stem(path_of(back));
        if (!palm.is_none()) in.palm_stem = scan_stem(path_of(palm));
        in.clouds = clouds;
        if (!rig.is_none()) in.rig_path = path_of(rig);
        if (out.is_none()) throw UsageError("out", "no output folder given");
        const std::string out_dir = path_of(out);
        const auto unit = parse_length_unit(units);
        if (!unit) throw UsageError("units", "'" + units + "' is not one of mm, cm, m, in");
        in.units = *unit;
        if (hand) {
          if (*hand != "left" && *hand != "right") throw UsageError("hand", "'" + *hand + "' is not left or right");
          in.hand = *hand == "left" ? HandSide::Left : HandSide::Right;
        }
        in.auto_rig = auto_rig;
        in.scan_clouds = scan_clouds;
        if (auto p = opt_path(markers)) in.markers_path = *p;
        if (auto p = opt_path(pipeline)) in.pipeline_path = *p;
        if (auto p = opt_path(truth)) in.truth_path = *p;
        in.posture_model = posture_model;
        if (in.back_stem.empty() != in.palm_stem.empty())
          throw UsageError(in.back_stem.empty() ? "back" : "palm", "back and palm go together");
        if (in.back_stem.empty() == in.clouds.empty())
          throw UsageError("back", "give back and palm (two scans) or clouds, not both and not neither");
        if (!in.pipeline_path.empty()) in.options = load_pipeline(in.pipeline_path);
        if (patch_tolerance) {
          in.options.patches.tolerance_mm = *patch_tolerance;
          std::string err;
          if (!in.options.IsValid(&err)) throw UsageError("patch_tolerance", err);
        }
        OutputSetOptions oo;
        oo.force = force;
        oo.signal_cleanup = false;  // Python owns the signals; Ctrl-C stops the run at its next line
        const Progress pr(progress);
        RunWritten w;
        {
          py::gil_scoped_release nogil;
          std::lock_guard<std::mutex> one_at_a_time(pipeline_mutex());
          w = run_into_folder(in, out_dir, oo, pr.stage("run"), [&](const QualityGates& g) {
            if (strict && !g.all_pass())
              throw GateFailure(out_dir + ": " + std::to_string(g.failed().size()) + " quality gate(s) failed (" +
                                g.failed_list() + "); strict: nothing was written");
          });
        }
        return to_py(w.report);
      },
      py::arg("back") = py::none(), py::arg("palm") = py::none(), py::arg("clouds") = std::vector<std::string>{},
      py::arg("rig") = py::none(), py::arg("out") = py::none(), py::arg("units") = "mm", py::arg("hand") = py::none(),
      py::arg("auto_rig") = false, py::arg("markers") = py::none(), py::arg("pipeline") = py::none(),
      py::arg("truth") = py::none(), py::arg("posture_model") = "builtin:anatomical",
      py::arg("patch_tolerance") = py::none(), py::arg("scan_clouds") = false, py::arg("force") = false,
      py::arg("strict") = false, py::arg("progress") = py::none());

  // --- meshes ---
  m.def(
      "read_mesh",
      [](const py::object& file) {
        const std::string path = path_of(file);
        Mesh mesh;
        {
          py::gil_scoped_release nogil;
          mesh = read_any_mesh(path);
        }
        return py::make_tuple(owned<double, 3>(std::move(mesh.vertices)), owned<int, 3>(std::move(mesh.faces)));
      },
      py::arg("path"));

  // --- posture models ---
  py::class_<PyModel>(m, "PostureModel")
      .def(py::init([](const py::object& source) {
             const std::string s = py::isinstance<py::str>(source) && py::str(source).cast<std::string>().rfind("builtin:", 0) == 0
                                       ? source.cast<std::string>()
                                       : path_of(source);
             try {
               return std::make_unique<PyModel>(load_model(s));
             } catch (const UsageError& e) {  // a built-in name the CLI's --model would not take
               throw UsageError("source", e.detail());
             }
           }),
           py::arg("source") = "builtin:anatomical")
      .def_property_readonly("name", [](const PyModel& m) { return m.model.name; })
      .def_property_readonly("dofs",
                             [](const PyModel&) {
                               std::vector<std::string> names;
                               for (int d = 0; d < kDofCount; ++d) names.push_back(dofs()[d].name);
                               return names;
                             })
      .def_property_readonly("relaxed",
                             [](const PyModel& m) {
                               Angles a{};
                               for (int d = 0; d < kDofCount; ++d) a[d] = m.model.dof[d].relaxed;
                               return angles_dict(a);
                             })
      .def_property_readonly("limits",
                             [](const PyModel& m) {
                               py::dict d;
                               for (int k = 0; k < kDofCount; ++k)
                                 d[py::str(dofs()[k].name)] = py::make_tuple(m.model.dof[k].lo, m.model.dof[k].hi);
                               return d;
                             })
      .def("to_dict", [](const PyModel& m) { return to_py(model_to_json(m.model)); })
      .def("solve", &model_solve, py::arg("pins") = py::none(), py::kw_only(), py::arg("torques") = py::none(),
           py::arg("targets") = py::none(), py::arg("linear") = false, py::arg("details") = false)
      .def("solve_batch", &model_solve_batch, py::arg("columns"), py::arg("values"), py::kw_only(), py::arg("linear") = false)
      .def("__repr__", [](const PyModel& m) { return "<handskin.PostureModel '" + m.model.name + "'>"; });

  // --- a rigged skin (skin.glb) ---
  py::class_<PySkin>(m, "RiggedSkin")
      .def(py::init([](const py::object& file) {
             const std::string path = path_of(file);
             py::gil_scoped_release nogil;
             return std::make_unique<PySkin>(path);
           }),
           py::arg("path"))
      .def_property_readonly("vertices", [](py::object self) { return view3(self.cast<PySkin&>().skin.mesh.vertices, self); })
      .def_property_readonly("faces", [](py::object self) { return view_faces(self.cast<PySkin&>().skin.mesh.faces, self); })
      .def_property_readonly("rig", [](const PySkin& s) {
        return py::module_::import("json").attr("loads")(rig_to_json_text(s.skin.rig));
      })
      .def_property_readonly("model", [](const PySkin& s) { return std::make_unique<PyModel>(s.skin.model); })
      .def_property_readonly("has_texture", [](const PySkin& s) { return !s.skin.texture.empty(); })
      .def("pose", &pose_skin, py::arg("angles"), py::kw_only(), py::arg("blend") = "dqs",
           py::arg("crease_guard") = true)
      .def("__repr__", [](const PySkin& s) {
        return "<handskin.RiggedSkin " + s.path + ": " + std::to_string(s.skin.mesh.vertices.size()) + " vertices>";
      });

  // --- the stages on their own ---
  py::class_<PyRegistration>(m, "Registration")
      .def_property_readonly("transform", [](const PyRegistration& r) {
        py::array_t<double> t({4, 4});
        const Eigen::Matrix4d M = r.reg.back_to_palm.matrix();
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) t.mutable_at(i, j) = M(i, j);
        return t;
      })
      .def_property_readonly("points", [](py::object self) { return view3(self.cast<PyRegistration&>().merged.points, self); })
      .def_property_readonly("normals", [](py::object self) { return view3(self.cast<PyRegistration&>().merged.normals, self); })
      .def_property_readonly("sides", [](py::object self) {
        const auto& s = self.cast<PyRegistration&>().merged.sides;
        py::array a = view(s.empty() ? nullptr : s.data(), s.size(), 1, self);
        return a.attr("reshape")(-1);
      })
      .def_property_readonly("markers", [](py::object self) { return view3(self.cast<PyRegistration&>().reg.markers_palm, self); })
      .def_property_readonly("marker_radius_mm", [](const PyRegistration& r) { return r.reg.marker_radius_mm; })
      .def_property_readonly("refined", [](const PyRegistration& r) { return r.reg.refined; })
      .def_property_readonly("warnings", [](const PyRegistration& r) { return r.reg.warnings; })
      .def_property_readonly("figures", [](const PyRegistration& r) { return to_py(r.figures); });

  m.def(
      "register",
      [](const py::object& back, const py::object& palm, const py::object& markers, const py::object& pipeline,
         bool refine, const py::object& progress) {
        const std::string b = scan_stem(path_of(back)), p = scan_stem(path_of(palm));
        const PipelineOptions po = pipeline_from(opt_path(pipeline));
        RegistrationOptions ro = registration_options(po);
        if (!refine) ro.refine_enabled = false;
        MarkerHints hints;
        const auto mk = opt_path(markers);
        const Progress pr(progress);
        auto r = std::make_unique<PyRegistration>();
        {
          py::gil_scoped_release nogil;
          std::lock_guard<std::mutex> one_at_a_time(pipeline_mutex());
          if (mk) hints = load_marker_hints(*mk);
          const RangeScan bs = load_scan_side(b, ScanSide::Back, "back");
          const RangeScan ps = load_scan_side(p, ScanSide::Palm, "palm");
          r->reg = register_scans(bs, ps, b + ".png", p + ".png", ro, mk ? &hints : nullptr, pr.stage("register"));
          r->merged = merged_arrays(*r->reg.merged);
          r->figures = registration_to_json(r->reg);
        }
        return r;
      },
      py::arg("back"), py::arg("palm"), py::kw_only(), py::arg("markers") = py::none(), py::arg("pipeline") = py::none(),
      py::arg("refine") = true, py::arg("progress") = py::none());

  m.def(
      "read_merged",
      [](const py::object& file) {
        const std::string path = path_of(file);
        MergedArrays a;
        {
          py::gil_scoped_release nogil;
          a = read_merged(path);
        }
        return py::make_tuple(owned<double, 3>(std::move(a.points)), owned<double, 3>(std::move(a.normals)),
                              owned<std::uint32_t, 1>(std::move(a.sides)).attr("reshape")(-1));
      },
      py::arg("path"));

  py::class_<PySkinResult>(m, "Skin")
      .def_property_readonly("vertices", [](py::object self) { return view3(self.cast<PySkinResult&>().r.skin.mesh.vertices, self); })
      .def_property_readonly("faces", [](py::object self) { return view_faces(self.cast<PySkinResult&>().r.skin.mesh.faces, self); })
      .def_property_readonly("rig", [](const PySkinResult& s) {
        return py::module_::import("json").attr("loads")(rig_to_json_text(s.r.rig));
      })
      .def_property_readonly("automatic_rig", [](const PySkinResult& s) { return s.r.automatic; })
      .def_property_readonly("watertight", [](const PySkinResult& s) { return s.r.skin.watertight(); })
      .def_property_readonly("warnings", [](const PySkinResult& s) { return s.r.warnings; })
      .def_property_readonly("figures", [](const PySkinResult& s) { return to_py(s.figures); })
      .def("save", [](const PySkinResult& s, const py::object& file, bool force) {
        const std::string path = path_of(file);
        py::gil_scoped_release nogil;
        // Owned as the CLI's single files are (core/output_set.hpp, OutputFiles): a file of the
        // user's in the way is refused (with force, moved aside), never overwritten.
        OutputSetOptions oo;
        oo.force = force;
        oo.signal_cleanup = false;  // Python owns the signals
        OutputFiles files({path}, oo);
        save_mesh(files.stage(path), s.r.skin.mesh);
        files.commit();
      }, py::arg("path"), py::kw_only(), py::arg("force") = false);

  m.def(
      "build_skin",
      [](const py::object& points, const py::object& normals, const py::object& sides, const py::object& rig,
         const py::object& pipeline, bool auto_rig, const py::object& progress) {
        SkinStageInputs in;
        in.points = points_from(points, "points");
        in.normals = points_from(normals, "normals");
        if (in.normals.size() != in.points.size())
          throw UsageError("normals", std::to_string(in.normals.size()) + " rows for " + std::to_string(in.points.size()) + " points");
        in.sides = sides_from(sides, in.points.size());
        in.cloud_name = "points";
        if (!rig.is_none()) {
          in.rig = rig_from(rig);
          in.rig_name = py::isinstance<py::dict>(rig) ? "rig" : path_of(rig);
        }
        in.auto_rig = auto_rig;
        PipelineOptions po = pipeline_from(opt_path(pipeline));
        in.baseline = false;
        in.slices = false;
        const Progress pr(progress);
        auto r = std::make_unique<PySkinResult>();
        {
          py::gil_scoped_release nogil;
          std::lock_guard<std::mutex> one_at_a_time(pipeline_mutex());
          r->r = run_skin_stage(in, po, pr.stage("skin"));
          r->figures = to_json(r->r);
        }
        return r;
      },
      py::arg("points"), py::arg("normals"), py::arg("sides"), py::kw_only(), py::arg("rig") = py::none(),
      py::arg("pipeline") = py::none(), py::arg("auto_rig") = false, py::arg("progress") = py::none());

  py::class_<PyPatches>(m, "Patches")
      .def_property_readonly("control", [](py::object self) { return view3(self.cast<PyPatches&>().r.patches.control, self); })
      .def_property_readonly("patch_control", [](py::object self) {
        const auto& pc = self.cast<PyPatches&>().r.patches.patch_control;
        return view(pc.empty() ? nullptr : pc.front().data(), pc.size(), 16, self);
      })
      .def_property_readonly("bezier", [](py::object self) {
        const auto& b = self.cast<PyPatches&>().bezier;
        py::array a = view(b.empty() ? nullptr : b.data(), b.size() / 3, 3, self);
        return a.attr("reshape")(-1, 4, 4, 3);
      })
      .def_property_readonly("names", [](const PyPatches& p) {
        std::vector<std::string> n;
        for (const auto& q : p.r.patches.patches) n.push_back(q.name);
        return n;
      })
      .def_property_readonly("vertices", [](py::object self) { return view3(self.cast<PyPatches&>().r.tessellation.vertices, self); })
      .def_property_readonly("faces", [](py::object self) { return view_faces(self.cast<PyPatches&>().r.tessellation.faces, self); })
      .def_property_readonly("figures", [](const PyPatches& p) { return to_py(p.figures); })
      .def("to_dict", [](const PyPatches& p) { return to_py(patches_to_json(p.r.patches)); });

  m.def(
      "fit_patches",
      [](const PySkinResult& skin, const py::object& points, const py::object& sides, const py::object& pipeline,
         std::optional<double> tolerance, const py::object& progress) {
        std::vector<Eigen::Vector3d> pts = points_from(points, "points");
        const std::vector<std::uint32_t> sd = sides_from(sides, pts.size());
        PipelineOptions po = pipeline_from(opt_path(pipeline));
        if (tolerance) {
          po.patches.tolerance_mm = *tolerance;
          std::string err;
          if (!po.IsValid(&err)) throw UsageError("tolerance", err);
        }
        const Progress pr(progress);
        auto r = std::make_unique<PyPatches>();
        {
          py::gil_scoped_release nogil;
          std::lock_guard<std::mutex> one_at_a_time(pipeline_mutex());
          pr("patches", "fitting bicubic patches, correcting the parameters");
          r->r = run_patch_stage(skin.r.skin, skin.r.rig, pts, sd, patch_options(po), nullptr,
                                 static_cast<int>(po.patches.error_grid), /*pictures=*/false);
          for (const auto& pc : r->r.patches.patch_control)
            for (int k : pc)
              for (int c = 0; c < 3; ++c) r->bezier.push_back(r->r.patches.control[k][c]);
          r->figures = to_json(r->r);
        }
        return r;
      },
      py::arg("skin"), py::arg("points"), py::arg("sides"), py::kw_only(), py::arg("pipeline") = py::none(),
      py::arg("tolerance") = py::none(), py::arg("progress") = py::none());
}
