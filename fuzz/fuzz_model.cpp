// libFuzzer target: posture models (hand-posture/1) and the solver built from them. Bad input
// must end in InputError; an accepted model must solve to a finite posture within its limits.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "posture/model.hpp"
#include "posture/solver.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const handskin::PostureModel m = handskin::parse_model(handskin::parse_json_object(text, "fuzz.json"), "fuzz.json");
    const handskin::PostureSolver s(m);
    handskin::PostureInputs in;
    in.pins = {{handskin::dof_index("little.mcp.flex").value(), 40.0}};
    const handskin::PostureSolution sol = s.solve(in);
    for (int d = 0; d < handskin::kDofCount; ++d)
      if (!std::isfinite(sol.angles[d]) || sol.angles[d] < m.dof[d].lo - 1e-6 || sol.angles[d] > m.dof[d].hi + 1e-6)
        __builtin_trap();
  } catch (const handskin::InputError&) {
  }
  return 0;
}
