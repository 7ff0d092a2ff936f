// libFuzzer target: posture models (hand-posture/1) and the solver built from them. Input:
// JSON text, or (first byte 0xFF) extreme numbers substituted into the thesis model and the
// solve's inputs. Bad input must end in InputError; an accepted model must solve to a finite
// posture within its limits.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "extreme_numbers.hpp"
#include "posture/model.hpp"
#include "posture/solver.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    handskin::Json j, inputs = {{"pin", 40.0}, {"torque", 2.0}, {"target", 10.0}, {"weight", 1.0}};
    if (size > 0 && data[0] == 0xFF) {
      j = handskin::model_to_json(handskin::builtin_model("thesis"));
      handskin::Json both = {{"model", j}, {"inputs", inputs}};
      handskin::fuzz::substitute_numbers(both, data + 1, size - 1);
      j = both["model"];
      inputs = both["inputs"];
    } else {
      j = handskin::parse_json_object(text, "fuzz.json");
    }
    const handskin::PostureModel m = handskin::parse_model(j, "fuzz.json");
    const handskin::PostureSolver s(m);
    handskin::PostureInputs in;
    in.pins = {{handskin::dof_index("little.mcp.flex").value(), inputs["pin"].get<double>()}};
    in.torques = {{handskin::dof_index("ring.pip.flex").value(), inputs["torque"].get<double>()}};
    in.targets = {{handskin::dof_index("index.mcp.flex").value(), inputs["target"].get<double>(), inputs["weight"].get<double>()}};
    const handskin::PostureSolution sol = s.solve(in);
    for (int d = 0; d < handskin::kDofCount; ++d)
      if (!std::isfinite(sol.angles[d]) || sol.angles[d] < m.dof[d].lo - 1e-6 || sol.angles[d] > m.dof[d].hi + 1e-6)
        __builtin_trap();
  } catch (const handskin::InputError&) {
  }
  return 0;
}
