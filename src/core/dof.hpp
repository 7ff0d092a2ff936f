#pragma once
/// The one table of joint and DOF names shared by everything (formats/hand-rig.md).
/// Joints follow WebXR Hand Input names; DOFs follow thesis Table 3.1 (6 + 29 = 35).
#include <array>
#include <optional>
#include <string>
#include <vector>

namespace handskin {

enum class Finger { Thumb = 0, Index, Middle, Ring, Little };
constexpr int kFingerCount = 5;
constexpr int kJointCount = 25;
constexpr int kDofCount = 35;

/// Finger name as DOF prefix: thumb, index, middle, ring, little.
const char* finger_dof_name(Finger f);
/// Thesis letter: T, I, M, R, L.
char finger_letter(Finger f);

struct JointInfo {
  const char* name;        ///< WebXR name, e.g. "index-finger-phalanx-proximal"
  const char* thesis;      ///< thesis notation, e.g. "I2"; "" for wrist and tips
  int parent;              ///< index of the parent joint, -1 for the wrist
  std::optional<Finger> finger;  ///< none for the wrist
  int level;               ///< 0 wrist, 1 metacarpal base (CMC), 2 MCP, 3 PIP/IP, 4 DIP, 5 tip (thumb: 1,2,3,5)
};

/// The 25 joints, parents before children; index 0 is the wrist.
const std::array<JointInfo, kJointCount>& joints();
/// Index of a joint by WebXR name or thesis alias (T1, I2, ...); nullopt if unknown.
std::optional<int> joint_index(const std::string& name);
/// Indices of one finger's joints from its metacarpal base to its tip.
std::vector<int> finger_chain(Finger f);

enum class DofKind { Translation, Rotation, Flexion, Abduction };

struct DofInfo {
  std::string name;    ///< e.g. "index.mcp.flex"
  std::string thesis;  ///< e.g. "I2.flex"; "" for the carpus DOFs
  int joint;           ///< joint whose local frame this DOF rotates (or the wrist)
  DofKind kind;
};

/// The 35 DOFs in canonical order: wrist 6, then per finger cmc(2), mcp(2), ip / pip, dip.
const std::vector<DofInfo>& dofs();
/// Index of a DOF by canonical name or thesis alias (case-insensitive for aliases); nullopt if unknown.
std::optional<int> dof_index(const std::string& name);

}  // namespace handskin
