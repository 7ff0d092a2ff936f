#include "posture/solution_io.hpp"

#include <cmath>

#include "core/dof.hpp"
#include "core/errors.hpp"

namespace handskin {

BatchSolution solve_batch(const PostureSolver& solver, const AngleTable& in, bool linear) {
  BatchSolution out;
  for (int d = 0; d < kDofCount; ++d) out.angles.columns.push_back(d);
  PostureInputs pi;
  for (size_t r = 0; r < in.rows.size(); ++r) {
    pi.pins.clear();
    for (size_t c = 0; c < in.columns.size(); ++c)
      if (std::isfinite(in.rows[r][c])) pi.pins.emplace_back(in.columns[c], in.rows[r][c]);
    const PostureSolution s = linear ? solver.solve_linear(pi) : solver.solve(pi);
    if (s.clamped_inputs) ++out.clamped_rows, out.clamped_cells += s.clamped_inputs;
    out.angles.rows.emplace_back(s.angles.begin(), s.angles.end());
  }
  return out;
}

Json posture_solution_to_json(const PostureModel& model, const PostureInputs& in, const PostureSolution& s,
                              const std::array<Eigen::Vector3d, kJointCount>* joint_pos) {
  std::vector<char> pinned(kDofCount, 0), limited(kDofCount, 0);
  for (const auto& [d, v] : in.pins) pinned[d] = 1;
  for (int d : s.at_limit) limited[d] = 1;
  Json j;
  j["format"] = "handskin-posture-solution/1";
  j["model"] = model.name;
  Json angles = Json::object();
  for (int d = 0; d < kDofCount; ++d) angles[dofs()[d].name] = s.angles[d];
  j["angles"] = angles;
  Json p = Json::array(), l = Json::array();
  for (int d = 0; d < kDofCount; ++d) {
    if (pinned[d]) p.push_back(dofs()[d].name);
    if (limited[d]) l.push_back(dofs()[d].name);
  }
  j["pinned"] = p;
  j["at_limit"] = l;
  j["iterations"] = s.iterations;
  j["energy"] = s.energy;
  j["converged"] = s.converged;
  if (!s.component_weights.empty()) j["component_weights"] = s.component_weights;
  j["clamped_inputs"] = s.clamped_inputs;
  if (joint_pos) {
    Json jp = Json::object();
    for (int k = 0; k < kJointCount; ++k) jp[joints()[k].name] = to_json((*joint_pos)[k]);
    j["joints"] = jp;
  }
  return j;
}

}  // namespace handskin
