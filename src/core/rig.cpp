#include "core/rig.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"

namespace handskin {

namespace {
// Below this distance (mm) two joints of one chain count as "at the same place".
constexpr double kCoincidentMm = 1e-3;

// nlohmann's object keeps only the last of duplicated keys, so duplicates are found
// with a SAX pass over the raw text before the DOM parse.
struct KeyCounter : nlohmann::json_sax<Json> {
  int depth = 0;
  bool in_joints = false;
  int joints_depth = -1;
  std::string last_key;
  std::map<std::string, int> seen;
  std::string duplicate;
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override {
    ++depth;
    if (depth == 2 && last_key == "joints") joints_depth = depth;
    return true;
  }
  bool end_object() override {
    if (depth == joints_depth) joints_depth = -1;
    --depth;
    return true;
  }
  bool start_array(std::size_t) override { ++depth; return true; }
  bool end_array() override { --depth; return true; }
  bool key(string_t& k) override {
    last_key = k;
    if (depth == joints_depth && ++seen[k] == 2 && duplicate.empty()) duplicate = k;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }
};
}  // namespace

Rig parse_rig(const std::string& text, const std::string& file) {
  const Json j = parse_json_object(text, file);
  KeyCounter counter;
  Json::sax_parse(text, &counter);
  if (!counter.duplicate.empty()) throw InputError(file, "joint '" + counter.duplicate + "' is given twice");

  if (get_string(j, "format", file) != "hand-rig/1")
    throw InputError(file, "key 'format' must be \"hand-rig/1\"");
  Rig rig;
  if (j.contains("units") && get_string(j, "units", file) != "mm")
    throw InputError(file, "key 'units' must be \"mm\"");
  if (j.contains("frame")) rig.frame = get_string(j, "frame", file);
  const Json& jj = require(j, "joints", file);
  if (!jj.is_object()) throw InputError(file, "key 'joints' must be an object of name: [x, y, z]");
  std::array<bool, kJointCount> have{};
  for (auto it = jj.begin(); it != jj.end(); ++it) {
    const auto idx = joint_index(it.key());
    if (!idx) throw InputError(file, "unknown joint '" + it.key() + "'");
    if (have[*idx]) throw InputError(file, "joint '" + std::string(joints()[*idx].name) + "' is given twice");
    have[*idx] = true;
    rig.joints[*idx] = to_vec3(it.value(), "joint '" + it.key() + "'", file);
  }
  for (int i = 0; i < kJointCount; ++i)
    if (!have[i]) throw InputError(file, "missing joint '" + std::string(joints()[i].name) + "'");
  for (int i = 1; i < kJointCount; ++i) {
    const int p = joints()[i].parent;
    if ((rig.joints[i] - rig.joints[p]).norm() < kCoincidentMm)
      throw InputError(file, "joint '" + std::string(joints()[i].name) + "' is at the same place as '" +
                                 joints()[p].name + "'");
  }
  if (j.contains("palm_normal")) {
    Eigen::Vector3d n = to_vec3(j["palm_normal"], "key 'palm_normal'", file);
    if (n.norm() < 1e-9) throw InputError(file, "key 'palm_normal' must not be the zero vector");
    // A unit vector is kept as written: normalizing one again moves its last bits, and a
    // skeleton placed by a run (rig_auto.json) would not come back as the run built on it
    // (`patches --skin-dir` then built another skin).
    rig.palm_normal = std::abs(n.squaredNorm() - 1) <= 1e-12 ? n : Eigen::Vector3d(n.normalized());
  }
  return rig;
}

Rig load_rig(const std::string& file) { return parse_rig(read_file(file), file); }

std::string rig_to_json_text(const Rig& rig) {
  Json j;
  j["format"] = "hand-rig/1";
  j["units"] = "mm";
  j["frame"] = rig.frame;
  Json jj = Json::object();
  for (int i = 0; i < kJointCount; ++i) jj[joints()[i].name] = to_json(rig.joints[i]);
  j["joints"] = jj;
  if (rig.palm_normal) j["palm_normal"] = to_json(*rig.palm_normal);
  return j.dump(2) + "\n";
}

void save_rig(const std::string& file, const Rig& rig) { write_file_atomic(file, rig_to_json_text(rig)); }

Eigen::Isometry3d hand_frame_from_rig(const Rig& rig) {
  const auto J = [&](const char* n) { return rig.joints[joint_index(n).value()]; };
  const Eigen::Vector3d o = J("wrist");
  const Eigen::Vector3d x = (J("middle-finger-phalanx-proximal") - o).normalized();
  Eigen::Vector3d z = rig.palm_normal ? *rig.palm_normal
                                      : x.cross(J("index-finger-phalanx-proximal") - J("pinky-finger-phalanx-proximal"));
  z = (z - z.dot(x) * x).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;  // rows: hand axes in rig coordinates
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = -R * o;
  return T;
}

const char* hand_side_name(HandSide s) { return s == HandSide::Left ? "left" : "right"; }

HandSide rig_side(const Rig& rig) {
  const Eigen::Isometry3d T = hand_frame_from_rig(rig);
  const auto J = [&](const char* n) { return Eigen::Vector3d(T * rig.joints[joint_index(n).value()]); };
  // The thumb's MCP against the middle finger's: across the hand, toward the thumb.
  const double y = J("thumb-phalanx-proximal").y() - J("middle-finger-phalanx-proximal").y();
  return y >= 0 ? HandSide::Right : HandSide::Left;
}


std::string Bone::name() const { return std::string(joints()[joint].name) + ">" + joints()[child].name; }

std::vector<Bone> bones_from_rig(const Rig& rig) {
  std::vector<Bone> out;
  for (int j = 1; j < kJointCount; ++j) {
    const int p = joints()[j].parent;
    out.push_back({p, j, rig.joints[p], rig.joints[j]});
  }
  return out;
}

double distance_to_bone(const Eigen::Vector3d& p, const Bone& bone) {
  const Eigen::Vector3d ab = bone.b - bone.a;
  const double t = ab.squaredNorm() > 0 ? std::clamp((p - bone.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (p - (bone.a + t * ab)).norm();
}

}  // namespace handskin
