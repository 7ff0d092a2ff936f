#include "studio/api.hpp"

#include <cmath>
#include <optional>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"

namespace handskin {

namespace {

ApiResponse error(int status, const std::string& message) { return {status, Json{{"error", message}}.dump()}; }

// A request's failure: its status and one line.
struct BadRequest {
  int status;
  std::string message;
};

int dof_of(const std::string& name, const char* where) {
  const auto d = dof_index(name);
  if (!d) throw BadRequest{400, std::string(where) + ": unknown DOF '" + name + "'"};
  return *d;
}

double finite_number(const Json& v, const std::string& where) {
  if (!v.is_number()) throw BadRequest{400, where + " must be a number"};
  const double x = v.get<double>();
  if (!std::isfinite(x)) throw BadRequest{400, where + " must be finite"};
  return x;
}

// A pinned, target or key angle beyond the DOF's limits is refused (pose clamps; a page should not).
void within_limits(const PostureModel& model, int d, double v, const std::string& where) {
  const DofParams& p = model.dof[d];
  if (v < p.lo || v > p.hi)
    throw BadRequest{422, where + " = " + number_text(v) + " is outside its limits [" + number_text(p.lo) + ", " +
                              number_text(p.hi) + "]"};
}

const Json* object_member(const Json& body, const char* key) {
  if (!body.contains(key)) return nullptr;
  const Json& m = body[key];
  if (!m.is_object()) throw BadRequest{400, std::string("\"") + key + "\" must be an object of DOF names"};
  return &m;
}

}  // namespace

StudioModel::StudioModel(RiggedSkin skin) : skin_(std::move(skin)), skeleton_(skin_.rig) {
  solvers_.emplace_back("model", std::make_unique<PostureSolver>(skin_.model));
  for (const char* name : {"anatomical", "thesis"}) solvers_.emplace_back(name, std::make_unique<PostureSolver>(builtin_model(name)));
}

const PostureSolver& StudioModel::solver_for(const Json& body) const {
  if (!body.contains("parameter_set")) return *solvers_.front().second;
  if (!body["parameter_set"].is_string()) throw BadRequest{400, "parameter_set must be a string"};
  const std::string name = body["parameter_set"];
  std::string known;
  for (const auto& [n, solver] : solvers_) {
    if (n == name) return *solver;
    known += (known.empty() ? "" : ", ") + n;
  }
  throw BadRequest{400, "unknown parameter_set \"" + name + "\" (" + known + ")"};
}

ApiResponse StudioModel::dofs() const {
  Json list = Json::array();
  for (int k = 0; k < kDofCount; ++k) {
    const DofInfo& d = ::handskin::dofs()[k];
    const DofParams& p = skin_.model.dof[k];
    list.push_back({{"name", d.name},
                    {"alias", d.thesis},
                    {"joint", joints()[d.joint].name},
                    {"unit", d.kind == DofKind::Translation ? "mm" : "deg"},
                    {"min", p.lo},
                    {"max", p.hi},
                    {"relaxed", p.relaxed}});
  }
  Json sets = Json::array();
  for (const auto& [n, solver] : solvers_) sets.push_back(n);
  return {200, Json{{"dofs", list}, {"parameter_set", skin_.model.name}, {"parameter_sets", sets}, {"binding", skin_.binding.mode}}.dump()};
}

ApiResponse StudioModel::system() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Json sets = Json::object();
  for (const auto& [name, solver] : solvers_) {
    const PostureModel& m = solver->model();
    const Eigen::MatrixXd H = solver->system_matrix();
    const Eigen::VectorXd g = solver->absolute_rhs();
    std::vector<double> h(H.data(), H.data() + H.size()), gv(g.data(), g.data() + g.size()), relaxed, lo, hi;
    for (const DofParams& d : m.dof) relaxed.push_back(d.relaxed), lo.push_back(d.lo), hi.push_back(d.hi);
    const Angles zero{};
    sets[name] = {{"linear", !solver->has_grids() && !solver->has_mixture()},
                  {"H", h},  // symmetric, so row- and column-major agree
                  {"g", gv},
                  {"c", solver->energy(zero, PostureInputs{}, false)},
                  {"relaxed", relaxed},
                  {"lo", lo},
                  {"hi", hi}};
  }
  Json joint_list = Json::array();
  const auto rest = joint_nodes(skeleton_, Angles{});
  for (int j = 0; j < kJointCount; ++j) {
    int flex = -1, abd = -1;
    for (int d = 6; d < kDofCount; ++d)
      if (::handskin::dofs()[d].joint == j) (::handskin::dofs()[d].kind == DofKind::Flexion ? flex : abd) = d;
    const auto finger = joints()[j].finger;
    joint_list.push_back({{"name", joints()[j].name},
                          {"flex", flex},
                          {"abd", abd},
                          {"abd_sign", finger ? Skeleton::abduction_sign(*finger, skeleton_.side()) : 0.0},
                          {"rest", {{"t", rest[j].translation}, {"q", rest[j].rotation}}}});
  }
  return {200, Json{{"dofs", kDofCount}, {"sets", sets}, {"joints", joint_list}}.dump()};
}

namespace {
// The request's JSON object, or the reason it is refused.
std::optional<ApiResponse> parse_body(const std::string& text, Json* body) {
  if (text.size() > kMaxBodyBytes)
    return error(413, "the request body is " + std::to_string(text.size()) + " bytes; at most " + std::to_string(kMaxBodyBytes));
  // Depth is checked while parsing, so a deeply nested body is refused before it is built.
  bool too_deep = false;
  *body = Json::parse(text, [&](int depth, Json::parse_event_t, Json&) {
    if (depth > kMaxDepth) too_deep = true;
    return !too_deep;
  }, false);
  if (too_deep) return error(400, "the request nests deeper than " + std::to_string(kMaxDepth) + " levels");
  if (body->is_discarded()) return error(400, "the request body is not JSON");
  if (!body->is_object()) return error(400, "the request body must be a JSON object");
  return std::nullopt;
}
}  // namespace

ApiResponse StudioModel::solve(const std::string& text) const {
  Json body;
  if (const auto refused = parse_body(text, &body)) return *refused;
  try {
    for (auto it = body.begin(); it != body.end(); ++it)
      if (it.key() != "inputs" && it.key() != "torques" && it.key() != "targets" && it.key() != "parameter_set")
        throw BadRequest{400, "unknown key \"" + it.key() + "\" (inputs, torques, targets, parameter_set)"};
    const PostureSolver& solver = solver_for(body);
    PostureInputs in;
    if (const Json* m = object_member(body, "inputs"))
      for (auto it = m->begin(); it != m->end(); ++it) {
        const int d = dof_of(it.key(), "inputs");
        const double v = finite_number(it.value(), "inputs." + it.key());
        within_limits(solver.model(), d, v, "inputs." + it.key());
        in.pins.emplace_back(d, v);
      }
    if (const Json* m = object_member(body, "torques"))
      for (auto it = m->begin(); it != m->end(); ++it) {
        const int d = dof_of(it.key(), "torques");
        const double v = finite_number(it.value(), "torques." + it.key());
        if (std::abs(v) > 1e4) throw BadRequest{422, "torques." + it.key() + " = " + number_text(v) + " is beyond ±10000"};
        in.torques.emplace_back(d, v);
      }
    if (const Json* m = object_member(body, "targets"))
      for (auto it = m->begin(); it != m->end(); ++it) {
        const int d = dof_of(it.key(), "targets");
        double deg = 0, weight = 1;
        if (it.value().is_object()) {
          for (auto f = it.value().begin(); f != it.value().end(); ++f)
            if (f.key() != "deg" && f.key() != "weight")
              throw BadRequest{400, "targets." + it.key() + ": unknown key \"" + f.key() + "\" (deg, weight)"};
          if (!it.value().contains("deg")) throw BadRequest{400, "targets." + it.key() + " needs \"deg\""};
          deg = finite_number(it.value()["deg"], "targets." + it.key() + ".deg");
          if (it.value().contains("weight")) weight = finite_number(it.value()["weight"], "targets." + it.key() + ".weight");
        } else {
          deg = finite_number(it.value(), "targets." + it.key());
        }
        within_limits(solver.model(), d, deg, "targets." + it.key());
        if (weight < 0 || weight > 1e4) throw BadRequest{422, "targets." + it.key() + ".weight must be in [0, 10000]"};
        in.targets.push_back({d, deg, weight});
      }
    PostureSolution sol;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sol = solver.solve(in);
    }
    Json angles = Json::object();
    for (int k = 0; k < kDofCount; ++k) angles[::handskin::dofs()[k].name] = sol.angles[k];
    Json nodes = Json::object();
    const auto jn = joint_nodes(skeleton_, sol.angles);
    for (int j = 0; j < kJointCount; ++j) nodes[joints()[j].name] = {{"t", jn[j].translation}, {"q", jn[j].rotation}};
    return {200, Json{{"angles", angles}, {"energy", sol.energy}, {"at_limit", sol.at_limit.size()}, {"joints", nodes}}.dump()};
  } catch (const BadRequest& b) {
    return error(b.status, b.message);
  } catch (const InputError& e) {  // the solver's own checks
    return error(400, e.what());
  }
}

ApiResponse StudioModel::animate(const std::string& text) const {
  Json body;
  if (const auto refused = parse_body(text, &body)) return *refused;
  try {
    for (auto it = body.begin(); it != body.end(); ++it)
      if (it.key() != "keys" && it.key() != "fps" && it.key() != "inputs_only" && it.key() != "format" &&
          it.key() != "parameter_set")
        throw BadRequest{400, "unknown key \"" + it.key() + "\" (keys, fps, inputs_only, format, parameter_set)"};
    const PostureSolver& solver = solver_for(body);
    const double fps = body.contains("fps") ? finite_number(body["fps"], "fps") : 30.0;
    if (fps < 1 || fps > 60) throw BadRequest{422, "fps = " + number_text(fps) + " must be in [1, 60]"};
    if (body.contains("inputs_only") && !body["inputs_only"].is_boolean()) throw BadRequest{400, "inputs_only must be true or false"};
    const bool inputs_only = body.value("inputs_only", false);
    const std::string format = body.contains("format") && body["format"].is_string() ? body["format"].get<std::string>() : "frames";
    if (format != "frames" && format != "glb" && format != "csv")
      throw BadRequest{400, "format must be \"frames\", \"glb\" or \"csv\""};
    if (!body.contains("keys") || !body["keys"].is_array()) throw BadRequest{400, "\"keys\" must be an array of keys"};
    const Json& keys = body["keys"];
    if (keys.size() < 2 || keys.size() > static_cast<size_t>(kMaxAnimationKeys))
      throw BadRequest{422, "an animation needs 2 to " + std::to_string(kMaxAnimationKeys) + " keys, got " + std::to_string(keys.size())};
    // The keys' DOFs in order of first appearance; a key that does not give one has NaN there.
    KeyFrames k;
    std::vector<int> column(kDofCount, -1);
    for (size_t r = 0; r < keys.size(); ++r) {
      const std::string where = "keys[" + std::to_string(r) + "]";
      const Json& key = keys[r];
      if (!key.is_object()) throw BadRequest{400, where + " must be an object with time and angles"};
      for (auto it = key.begin(); it != key.end(); ++it)
        if (it.key() != "time" && it.key() != "angles") throw BadRequest{400, where + ": unknown key \"" + it.key() + "\" (time, angles)"};
      const double t = key.contains("time") ? finite_number(key["time"], where + ".time") : static_cast<double>(r);
      if (t < 0 || t > 3600) throw BadRequest{422, where + ".time = " + number_text(t) + " must be in [0, 3600] s"};
      if (r > 0 && t <= k.times.back()) throw BadRequest{422, where + ".time must be after the key before it"};
      k.times.push_back(t);
      k.lines.push_back(static_cast<long>(r));
      k.values.emplace_back(k.dofs.size(), std::nan(""));
      if (!key.contains("angles")) continue;
      if (!key["angles"].is_object()) throw BadRequest{400, where + ".angles must be an object of DOF names"};
      for (auto it = key["angles"].begin(); it != key["angles"].end(); ++it) {
        const int d = dof_of(it.key(), (where + ".angles").c_str());
        const double v = finite_number(it.value(), where + ".angles." + it.key());
        within_limits(solver.model(), d, v, where + ".angles." + it.key());
        if (column[d] < 0) {
          column[d] = static_cast<int>(k.dofs.size());
          k.dofs.push_back(d);
          for (auto& row : k.values) row.push_back(std::nan(""));
        }
        k.values[r][column[d]] = v;
      }
    }
    if ((k.times.back() - k.times.front()) * fps > kMaxAnimationFrames)
      throw BadRequest{422, "the animation would have more than " + std::to_string(kMaxAnimationFrames) + " frames"};
    if (inputs_only)
      for (size_t r = 0; r < k.values.size(); ++r)
        for (size_t c = 0; c < k.dofs.size(); ++c)
          if (!std::isfinite(k.values[r][c]))
            throw BadRequest{422, "keys[" + std::to_string(r) + "] gives no " + ::handskin::dofs()[k.dofs[c]].name +
                                      "; with inputs_only every key gives every input"};
    PostureAnimation anim;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      anim = ::handskin::animate(solver, k, fps, inputs_only, "keys");
    }
    if (format == "glb") {
      const std::vector<unsigned char> glb = skin_glb(skin_, nullptr, &anim);
      return {200, std::string(glb.begin(), glb.end()), "model/gltf-binary"};
    }
    if (format == "csv") return {200, animation_csv(anim), "text/csv"};
    Json frames = Json::array();
    for (const Angles& f : anim.frames) {
      Json nodes = Json::array();
      for (const auto& n : joint_nodes(skeleton_, f))
        nodes.push_back({n.translation[0], n.translation[1], n.translation[2], n.rotation[0], n.rotation[1], n.rotation[2],
                         n.rotation[3]});
      frames.push_back({{"angles", std::vector<double>(f.begin(), f.end())}, {"joints", nodes}});
    }
    Json names = Json::array(), joint_names = Json::array();
    for (int d = 0; d < kDofCount; ++d) names.push_back(::handskin::dofs()[d].name);
    for (int j = 0; j < kJointCount; ++j) joint_names.push_back(joints()[j].name);
    return {200, Json{{"times", anim.times}, {"dofs", names}, {"joint_names", joint_names}, {"frames", frames},
                      {"clamped", anim.clamped}}.dump()};
  } catch (const BadRequest& b) {
    return error(b.status, b.message);
  } catch (const InputError& e) {
    return error(400, e.what());
  }
}

}  // namespace handskin
