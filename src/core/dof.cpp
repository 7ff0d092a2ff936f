#include "core/dof.hpp"

#include <algorithm>
#include <cctype>
#include <map>

namespace handskin {

const char* finger_dof_name(Finger f) {
  static const char* n[] = {"thumb", "index", "middle", "ring", "little"};
  return n[static_cast<int>(f)];
}

char finger_letter(Finger f) { return "TIMRL"[static_cast<int>(f)]; }

const std::array<JointInfo, kJointCount>& joints() {
  using F = Finger;
  static const std::array<JointInfo, kJointCount> table = {{
      {"wrist", "", -1, std::nullopt, 0},
      {"thumb-metacarpal", "T1", 0, F::Thumb, 1},
      {"thumb-phalanx-proximal", "T2", 1, F::Thumb, 2},
      {"thumb-phalanx-distal", "T3", 2, F::Thumb, 3},
      {"thumb-tip", "", 3, F::Thumb, 5},
      {"index-finger-metacarpal", "I1", 0, F::Index, 1},
      {"index-finger-phalanx-proximal", "I2", 5, F::Index, 2},
      {"index-finger-phalanx-intermediate", "I3", 6, F::Index, 3},
      {"index-finger-phalanx-distal", "I4", 7, F::Index, 4},
      {"index-finger-tip", "", 8, F::Index, 5},
      {"middle-finger-metacarpal", "M1", 0, F::Middle, 1},
      {"middle-finger-phalanx-proximal", "M2", 10, F::Middle, 2},
      {"middle-finger-phalanx-intermediate", "M3", 11, F::Middle, 3},
      {"middle-finger-phalanx-distal", "M4", 12, F::Middle, 4},
      {"middle-finger-tip", "", 13, F::Middle, 5},
      {"ring-finger-metacarpal", "R1", 0, F::Ring, 1},
      {"ring-finger-phalanx-proximal", "R2", 15, F::Ring, 2},
      {"ring-finger-phalanx-intermediate", "R3", 16, F::Ring, 3},
      {"ring-finger-phalanx-distal", "R4", 17, F::Ring, 4},
      {"ring-finger-tip", "", 18, F::Ring, 5},
      {"pinky-finger-metacarpal", "L1", 0, F::Little, 1},
      {"pinky-finger-phalanx-proximal", "L2", 20, F::Little, 2},
      {"pinky-finger-phalanx-intermediate", "L3", 21, F::Little, 3},
      {"pinky-finger-phalanx-distal", "L4", 22, F::Little, 4},
      {"pinky-finger-tip", "", 23, F::Little, 5},
  }};
  return table;
}

std::optional<int> joint_index(const std::string& name) {
  const auto& t = joints();
  for (int i = 0; i < kJointCount; ++i)
    if (name == t[i].name || (t[i].thesis[0] != '\0' && name == t[i].thesis)) return i;
  return std::nullopt;
}

std::vector<int> finger_chain(Finger f) {
  std::vector<int> out;
  for (int i = 0; i < kJointCount; ++i)
    if (joints()[i].finger == f) out.push_back(i);
  return out;
}

const std::vector<DofInfo>& dofs() {
  static const std::vector<DofInfo> table = [] {
    std::vector<DofInfo> t;
    for (const char* axis : {"tx", "ty", "tz"}) t.push_back({std::string("wrist.") + axis, "", 0, DofKind::Translation});
    for (const char* axis : {"rx", "ry", "rz"}) t.push_back({std::string("wrist.") + axis, "", 0, DofKind::Rotation});
    for (int fi = 0; fi < kFingerCount; ++fi) {
      const Finger f = static_cast<Finger>(fi);
      const std::string n = finger_dof_name(f);
      const std::string L(1, finger_letter(f));
      const std::vector<int> chain = finger_chain(f);  // metacarpal, proximal, [intermediate], distal, tip
      t.push_back({n + ".cmc.flex", L + "1.flex", chain[0], DofKind::Flexion});
      t.push_back({n + ".cmc.abd", L + "1.abd", chain[0], DofKind::Abduction});
      t.push_back({n + ".mcp.flex", L + "2.flex", chain[1], DofKind::Flexion});
      t.push_back({n + ".mcp.abd", L + "2.abd", chain[1], DofKind::Abduction});
      if (f == Finger::Thumb) {
        t.push_back({n + ".ip.flex", L + "3.flex", chain[2], DofKind::Flexion});
      } else {
        t.push_back({n + ".pip.flex", L + "3.flex", chain[2], DofKind::Flexion});
        t.push_back({n + ".dip.flex", L + "4.flex", chain[3], DofKind::Flexion});
      }
    }
    return t;
  }();
  return table;
}

std::optional<int> dof_index(const std::string& name) {
  static const std::map<std::string, int> lookup = [] {
    std::map<std::string, int> m;
    const auto& t = dofs();
    for (int i = 0; i < static_cast<int>(t.size()); ++i) {
      m[t[i].name] = i;
      if (!t[i].thesis.empty()) {
        std::string a = t[i].thesis;
        std::transform(a.begin(), a.end(), a.begin(), [](unsigned char c) { return std::tolower(c); });
        m["alias:" + a] = i;
      }
    }
    return m;
  }();
  if (auto it = lookup.find(name); it != lookup.end()) return it->second;
  std::string a = name;
  std::transform(a.begin(), a.end(), a.begin(), [](unsigned char c) { return std::tolower(c); });
  if (auto it = lookup.find("alias:" + a); it != lookup.end()) return it->second;
  return std::nullopt;
}

}  // namespace handskin
