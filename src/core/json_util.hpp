#pragma once
/// Typed access to JSON documents with errors that name the file and the key.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <limits>
#include <string>

namespace handskin {

using Json = nlohmann::json;

/// Parse `text` (the content of `file`); a syntax error or a non-object root is an InputError.
Json parse_json_object(const std::string& text, const std::string& file);
/// read_file + parse_json_object.
Json load_json_object(const std::string& file);
/// Pretty-print and write atomically.
void save_json(const std::string& file, const Json& j);

/// Required keys; each throws InputError(file, "key 'k': ...") when missing or mistyped.
const Json& require(const Json& obj, const std::string& key, const std::string& file);
std::string get_string(const Json& obj, const std::string& key, const std::string& file);
double get_finite(const Json& obj, const std::string& key, const std::string& file);
double get_positive(const Json& obj, const std::string& key, const std::string& file);
/// An integer in [min_value, max_value]; a value outside (however large: it is never cast
/// first) is an InputError naming the key and the range.
long get_int(const Json& obj, const std::string& key, const std::string& file, long min_value,
             long max_value = std::numeric_limits<long>::max());
/// A JSON array of exactly 3 finite numbers; `what` names it in errors.
Eigen::Vector3d to_vec3(const Json& v, const std::string& what, const std::string& file);
/// Optional key with a default.
double get_finite_or(const Json& obj, const std::string& key, double def, const std::string& file);
long get_int_or(const Json& obj, const std::string& key, long def, const std::string& file, long min_value,
                long max_value = std::numeric_limits<long>::max());
bool get_bool_or(const Json& obj, const std::string& key, bool def, const std::string& file);

/// Every key of `obj` must be in `allowed` (for option files where a typo must not pass silently).
void reject_unknown_keys(const Json& obj, std::initializer_list<const char*> allowed, const std::string& file,
                         const std::string& section);

Json to_json(const Eigen::Vector3d& v);

/// A number as messages show it: %g ("1e+300", "0.5", "4096").
std::string number_text(double v);

}  // namespace handskin
