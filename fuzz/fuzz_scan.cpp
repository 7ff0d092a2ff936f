// libFuzzer target: the cubist-range/1 reader (sidecar JSON + 16-bit PNG).
// Input layout: <json text> '\0' <png bytes>. Bad input must end in InputError, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "scan/cubist_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
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
