#include "core/json_util.hpp"

#include <cstdint>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"

namespace handskin {

Json parse_json_object(const std::string& text, const std::string& file) {
  Json j;
  try {
    j = Json::parse(text);
  } catch (const Json::exception& e) {
    // Keep the parser's position and context ("line 3, column 20: ... last read: '...'"),
    // which names the offending key for NaN, inf or overflowing numbers.
    std::string m = e.what();
    const size_t at = m.find("parse error at ");
    if (at != std::string::npos) throw InputError(file, "not valid JSON: " + m.substr(at + 15));
    // Number overflow (e.g. 1e999) carries no position: find the token and the key before it.
    const size_t q = m.find("parsing '");
    if (q != std::string::npos) {
      const std::string token = m.substr(q + 9, m.find('\'', q + 9) - (q + 9));
      const size_t pos = text.find(token);
      if (pos != std::string::npos) {
        const long line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(pos), '\n');
        const size_t kend = text.rfind("\":", pos);
        const size_t kbeg = kend == std::string::npos ? kend : text.rfind('"', kend - 1);
        const std::string key = kbeg == std::string::npos ? "" : text.substr(kbeg + 1, kend - kbeg - 1);
        throw InputError(file, "not valid JSON: line " + std::to_string(line) + (key.empty() ? "" : ", key '" + key + "'") +
                                   ": number '" + token + "' is out of range");
      }
    }
    throw InputError(file, "not valid JSON: " + m);
  }
  if (!j.is_object()) throw InputError(file, "expected a JSON object at the top level");
  return j;
}

Json load_json_object(const std::string& file) { return parse_json_object(read_file(file), file); }

void save_json(const std::string& file, const Json& j) { write_file_atomic(file, j.dump(2) + "\n"); }

const Json& require(const Json& obj, const std::string& key, const std::string& file) {
  auto it = obj.find(key);
  if (it == obj.end()) throw InputError(file, "missing key '" + key + "'");
  return *it;
}

std::string get_string(const Json& obj, const std::string& key, const std::string& file) {
  const Json& v = require(obj, key, file);
  if (!v.is_string()) throw InputError(file, "key '" + key + "' must be a string");
  return v.get<std::string>();
}

double get_finite(const Json& obj, const std::string& key, const std::string& file) {
  const Json& v = require(obj, key, file);
  if (!v.is_number()) throw InputError(file, "key '" + key + "' must be a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw InputError(file, "key '" + key + "' must be finite");
  return d;
}

double get_positive(const Json& obj, const std::string& key, const std::string& file) {
  const double d = get_finite(obj, key, file);
  if (!(d > 0)) throw InputError(file, "key '" + key + "' must be > 0 (got " + std::to_string(d) + ")");
  return d;
}

long get_int(const Json& obj, const std::string& key, const std::string& file, long min_value, long max_value) {
  const Json& v = require(obj, key, file);
  if (!v.is_number_integer()) throw InputError(file, "key '" + key + "' must be an integer");
  const std::string range = max_value == std::numeric_limits<long>::max()
                                ? ">= " + std::to_string(min_value)
                                : "in [" + std::to_string(min_value) + ", " + std::to_string(max_value) + "]";
  // Unsigned values above the long range, and every value outside the range, are refused
  // before any narrowing (4294967808 must not become 512 as an int).
  if (v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(std::numeric_limits<long>::max()))
    throw InputError(file, "key '" + key + "' must be " + range + " (got " + v.dump() + ")");
  const long i = v.get<long>();
  if (i < min_value || i > max_value)
    throw InputError(file, "key '" + key + "' must be " + range + " (got " + std::to_string(i) + ")");
  return i;
}

Eigen::Vector3d to_vec3(const Json& v, const std::string& what, const std::string& file) {
  if (!v.is_array() || v.size() != 3) throw InputError(file, what + " must be an array of 3 numbers");
  Eigen::Vector3d out;
  for (int k = 0; k < 3; ++k) {
    if (!v[k].is_number()) throw InputError(file, what + " must be an array of 3 numbers");
    out[k] = v[k].get<double>();
    if (!std::isfinite(out[k])) throw InputError(file, what + " has a non-finite value");
  }
  return out;
}

double get_finite_or(const Json& obj, const std::string& key, double def, const std::string& file) {
  return obj.contains(key) ? get_finite(obj, key, file) : def;
}

long get_int_or(const Json& obj, const std::string& key, long def, const std::string& file, long min_value,
                long max_value) {
  return obj.contains(key) ? get_int(obj, key, file, min_value, max_value) : def;
}

bool get_bool_or(const Json& obj, const std::string& key, bool def, const std::string& file) {
  if (!obj.contains(key)) return def;
  if (!obj[key].is_boolean()) throw InputError(file, "key '" + key + "' must be true or false");
  return obj[key].get<bool>();
}

void reject_unknown_keys(const Json& obj, std::initializer_list<const char*> allowed, const std::string& file,
                         const std::string& section) {
  const std::set<std::string> ok(allowed.begin(), allowed.end());
  for (auto it = obj.begin(); it != obj.end(); ++it)
    if (!ok.count(it.key()))
      throw InputError(file, "unknown key '" + (section.empty() ? "" : section + ".") + it.key() + "'");
}

Json to_json(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace handskin
