#pragma once
// Structured fuzzing of the numbers in a JSON document: the fuzzer's bytes pick numeric
// leaves of a valid document and set them to extreme finite values (±(1 + m/65536)·10^e,
// e in [-300, 308]), zero, or the largest and smallest doubles. A reader must refuse them
// with an InputError or accept them into a result that stays finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/json_util.hpp"

namespace handskin::fuzz {

inline void numeric_leaves(Json& j, std::vector<Json*>* out) {
  if (j.is_number()) out->push_back(&j);
  else if (j.is_object() || j.is_array())
    for (auto& v : j) numeric_leaves(v, out);
}

/// Apply the substitutions `data` encodes (4 bytes each: leaf, exponent, mantissa) to `j`.
inline void substitute_numbers(Json& j, const std::uint8_t* data, std::size_t size) {
  std::vector<Json*> leaves;
  numeric_leaves(j, &leaves);
  if (leaves.empty()) return;
  for (std::size_t k = 0; k + 4 <= size; k += 4) {
    Json& leaf = *leaves[data[k] % leaves.size()];
    const int code = data[k + 1];
    const double m = 1.0 + (data[k + 2] * 256 + data[k + 3]) / 65536.0;
    double v;
    if (code == 0) v = 0;
    else if (code == 1) v = std::numeric_limits<double>::max();
    else if (code == 2) v = -std::numeric_limits<double>::max();
    else if (code == 3) v = std::numeric_limits<double>::denorm_min();
    else if (code == 4) v = leaf.is_number_integer() ? 4294967296.0 * m : m;
    else v = (code % 2 ? -1 : 1) * m * std::pow(10.0, (code - 5) * 608 / 250 - 300);
    if (leaf.is_number_integer() && std::abs(v) < 9e18) leaf = static_cast<long long>(v);
    else leaf = v;
  }
}

}  // namespace handskin::fuzz
