#include "core/json_util.hpp"

#include <cmath>
#include <set>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"

namespace handskin {

Json parse_json_object(const std::string& text, const std::string& file) {
  Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw InputError(file, "not valid JSON");
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

long get_int(const Json& obj, const std::string& key, const std::string& file, long min_value) {
  const Json& v = require(obj, key, file);
  if (!v.is_number_integer()) throw InputError(file, "key '" + key + "' must be an integer");
  const long i = v.get<long>();
  if (i < min_value)
    throw InputError(file, "key '" + key + "' must be >= " + std::to_string(min_value) + " (got " +
                               std::to_string(i) + ")");
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

long get_int_or(const Json& obj, const std::string& key, long def, const std::string& file, long min_value) {
  return obj.contains(key) ? get_int(obj, key, file, min_value) : def;
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

}  // namespace handskin
