// libFuzzer target: the joint-angle CSV reader. Bad input must end in InputError; a table it
// accepts has one finite-or-empty cell per column in every row.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "posture/angle_table.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const handskin::AngleTable t = handskin::parse_angle_table(text, "fuzz.csv");
    for (const auto& row : t.rows) {
      if (row.size() != t.columns.size()) __builtin_trap();
      for (double v : row)
        if (std::isinf(v)) __builtin_trap();
    }
  } catch (const handskin::InputError&) {
  }
  return 0;
}
