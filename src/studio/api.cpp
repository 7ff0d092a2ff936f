#include "studio/api.hpp"

#include <cmath>

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

const Json* object_member(const Json& body, const char* key) {
  if (!body.contains(key)) return nullptr;
  const Json& m = body[key];
  if (!m.is_object()) throw BadRequest{400, std::string("\"") + key + "\" must be an object of DOF names"};
  return &m;
}

}  // namespace

StudioModel::StudioModel(RiggedSkin skin) : skin_(std::move(skin)), solver_(skin_.model), skeleton_(skin_.rig, "skin.glb rig") {}

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
  return {200, Json{{"dofs", list}, {"parameter_set", skin_.model.name}, {"binding", skin_.binding.mode}}.dump()};
}

ApiResponse StudioModel::solve(const std::string& text) const {
  if (text.size() > kMaxBodyBytes)
    return error(413, "the request body is " + std::to_string(text.size()) + " bytes; at most " + std::to_string(kMaxBodyBytes));
  // Depth is checked while parsing, so a deeply nested body is refused before it is built.
  bool too_deep = false;
  const Json body = Json::parse(text, [&](int depth, Json::parse_event_t, Json&) {
    if (depth > kMaxDepth) too_deep = true;
    return !too_deep;
  }, false);
  if (too_deep) return error(400, "the request nests deeper than " + std::to_string(kMaxDepth) + " levels");
  if (body.is_discarded()) return error(400, "the request body is not JSON");
  if (!body.is_object()) return error(400, "the request body must be a JSON object");
  // A pinned or target angle beyond the DOF's limits is refused (pose clamps; a page should not).
  const auto within_limits = [&](int d, double v, const std::string& where) {
    const DofParams& p = skin_.model.dof[d];
    if (v < p.lo || v > p.hi)
      throw BadRequest{422, where + " = " + number_text(v) + " is outside its limits [" + number_text(p.lo) + ", " +
                                number_text(p.hi) + "]"};
  };
  try {
    for (auto it = body.begin(); it != body.end(); ++it)
      if (it.key() != "inputs" && it.key() != "torques" && it.key() != "targets")
        throw BadRequest{400, "unknown key \"" + it.key() + "\" (inputs, torques, targets)"};
    PostureInputs in;
    if (const Json* m = object_member(body, "inputs"))
      for (auto it = m->begin(); it != m->end(); ++it) {
        const int d = dof_of(it.key(), "inputs");
        const double v = finite_number(it.value(), "inputs." + it.key());
        within_limits(d, v, "inputs." + it.key());
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
        within_limits(d, deg, "targets." + it.key());
        if (weight < 0 || weight > 1e4) throw BadRequest{422, "targets." + it.key() + ".weight must be in [0, 10000]"};
        in.targets.push_back({d, deg, weight});
      }
    PostureSolution sol;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sol = solver_.solve(in);
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

}  // namespace handskin
