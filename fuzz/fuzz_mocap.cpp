// libFuzzer target: the Qualisys TSV and OpenSim TRC readers and the angles from markers.
// Bad input must end in InputError.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "posture/mocap.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    const handskin::MarkerTrack t =
        data[0] & 1 ? handskin::parse_trc(text, "fuzz.trc") : handskin::parse_qualisys_tsv(text, "fuzz.tsv");
    for (const auto& f : t.frames)
      if (f.size() != t.names.size()) __builtin_trap();
    handskin::angles_from_markers(t, "fuzz");
  } catch (const handskin::InputError&) {
  }
  return 0;
}
