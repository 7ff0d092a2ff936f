#pragma once
/// Keyframe animation of the posture (thesis §4.2.2; issue 16; docs/studio.md): keys from a
/// joint-angle CSV, interpolated per DOF by cubic Bézier segments in time, or — constrained
/// animation — only the keys' inputs interpolated and the solver producing the whole hand at
/// every frame. The frames go into skin.glb as a glTF animation (gltf.hpp) and into a CSV.
#include <string>
#include <vector>

#include "posture/skeleton.hpp"
#include "posture/solver.hpp"

namespace handskin {

/// Keys: strictly increasing times (s) and, per key, the angle of each DOF it gives.
struct KeyFrames {
  std::vector<double> times;
  std::vector<int> dofs;                     ///< the DOFs the table's columns give
  std::vector<std::vector<double>> values;   ///< per key, per `dofs` entry: degrees (NaN: not given)
  std::vector<long> lines;                   ///< file line of each key (for messages)
};

/// A joint-angle CSV (formats/hand-rig.md) with an optional `time` column (seconds; without
/// one the keys are a second apart). Throws InputError naming the file and line: fewer than
/// two keys, times not finite or not increasing, and every error of the angle table.
KeyFrames parse_keyframes(const std::string& text, const std::string& file);
KeyFrames read_keyframes(const std::string& file);

/// The value at time t of the C1 cubic Bézier curve through (times[k], values[k]): on each
/// segment the inner control points lie a third of the segment from its ends along the
/// key's tangent — the slope between its neighbours (Catmull–Rom), but flat at the first and
/// last key (the motion starts and stops at rest) and at a key that is a turning point or
/// equals a neighbour (so the curve never overshoots a key and holds between equal keys).
/// Before the first key its value, after the last key its value.
double bezier_at(const std::vector<double>& times, const std::vector<double>& values, double t);

struct PostureAnimation {
  std::vector<double> times;   ///< s, from 0 at the first key, 1 / fps apart, the last key's time last
  std::vector<Angles> frames;  ///< every DOF of each frame
  int clamped = 0;             ///< frames' values moved onto the model's limits
};

/// Keyframe mode: each key solved into a whole posture (its given DOFs pinned, the solver
/// filling in the rest), then every DOF interpolated. Inputs-only (constrained animation):
/// only the given DOFs interpolated — each must be given at every key — and every frame solved
/// with them pinned. Throws InputError (naming `file`) on a DOF missing from a key in
/// inputs-only mode and on fps outside [1, 240].
PostureAnimation animate(const PostureSolver& solver, const KeyFrames& keys, double fps, bool inputs_only,
                         const std::string& file);

/// CSV text: a `time` column, then every DOF.
std::string animation_csv(const PostureAnimation& a);

}  // namespace handskin
