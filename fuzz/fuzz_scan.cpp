// libFuzzer target: the cubist-range/1 reader (sidecar JSON + 16-bit PNG).
// Input layout: <json text> '\0' <png bytes>, or (first byte 0xFF) extreme numbers substituted
// into a valid sidecar. Bad input must end in InputError, nothing else; an accepted sidecar
// gives finite coordinates for every sample it can hold.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "extreme_numbers.hpp"
#include "scan/cubist_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 0 && data[0] == 0xFF) {
    handskin::ScanMeta defaults;
    handskin::Json j = handskin::parse_json_object(handskin::scan_meta_to_json_text(defaults), "defaults");
    handskin::fuzz::substitute_numbers(j, data + 1, size - 1);
    try {
      const handskin::ScanMeta m = handskin::parse_scan_meta(j.dump(), "fuzz.json");
      if (static_cast<long>(m.scanlines) * m.points > handskin::kMaxScanPixels) __builtin_trap();
      for (const double v : {m.x_origin_mm + (m.scanlines - 1) * m.x_step_mm, m.y_origin_mm + (m.points - 1) * m.y_step_mm,
                             m.z_origin_mm + 65535 * m.z_step_mm})
        if (!std::isfinite(v)) __builtin_trap();
    } catch (const handskin::InputError&) {
    }
    return 0;
  }
  const std::string all(reinterpret_cast<const char*>(data), size);
  const size_t cut = all.find('\0');
  const std::string json = all.substr(0, cut == std::string::npos ? all.size() : cut);
  const std::string png = cut == std::string::npos ? std::string() : all.substr(cut + 1);
  try {
    const handskin::RangeScan scan = handskin::decode_scan(png, "fuzz.png", json, "fuzz.json");
    if (scan.values.size() != static_cast<size_t>(scan.meta.scanlines) * scan.meta.points) __builtin_trap();
  } catch (const handskin::InputError&) {
  }
  return 0;
}
