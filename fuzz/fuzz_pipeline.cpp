// libFuzzer target: the pipeline file (handskin-pipeline/1). Input: JSON text, or (first
// byte 0xFF) extreme numbers substituted into the shipped defaults. Bad input must end in
// InputError; an accepted file must be valid, finite, and survive its own round trip.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.hpp"
#include "extreme_numbers.hpp"
#include "pipeline/options.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace handskin;
  try {
    Json j;
    if (size > 0 && data[0] == 0xFF) {
      j = pipeline_to_json(PipelineOptions{});
      j["markers"]["radius_mm"] = 4.0;  // a number to fuzz (null = estimated)
      fuzz::substitute_numbers(j, data + 1, size - 1);
    } else {
      j = parse_json_object(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
    }
    const PipelineOptions o = parse_pipeline(j, "fuzz.json");
    std::string err;
    if (!o.IsValid(&err)) __builtin_trap();
    std::vector<Json*> leaves;
    Json back = pipeline_to_json(o);
    fuzz::numeric_leaves(back, &leaves);
    for (const Json* v : leaves)
      if (!std::isfinite(v->get<double>())) __builtin_trap();
    if (pipeline_to_json(parse_pipeline(back, "round trip")) != back) __builtin_trap();
  } catch (const InputError&) {
  }
  return 0;
}
