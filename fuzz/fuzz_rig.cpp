// libFuzzer target: the hand-rig/1 reader. Bad input must end in InputError, nothing else.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "core/rig.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const handskin::Rig rig = handskin::parse_rig(text, "fuzz.json");
    for (const auto& j : rig.joints)
      if (!j.allFinite()) __builtin_trap();
    // A parsed rig must survive a round trip.
    handskin::parse_rig(handskin::rig_to_json_text(rig), "roundtrip.json");
  } catch (const handskin::InputError&) {
  }
  return 0;
}
