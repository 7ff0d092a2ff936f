#pragma once
/// Motion capture to joint angles (thesis §3.2.2: "the angle between the lines joining
/// markers is the joint angle"): Qualisys TSV and OpenSim TRC readers, and the angles a
/// back-of-hand + two-markers-per-digit marker set supports (docs/posture.md).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "posture/angle_table.hpp"

namespace handskin {

struct MarkerTrack {
  std::vector<std::string> names;
  double rate_hz = 0;
  std::vector<std::vector<Eigen::Vector3d>> frames;  ///< [frame][marker], mm; NaN = not seen
};

/// Qualisys Track Manager TSV export (3D). Missing markers (empty, NaN or 0 0 0) become NaN.
MarkerTrack read_qualisys_tsv(const std::string& file);
/// OpenSim TRC (marker trajectories), units mm, cm or m (converted to mm); empty cells = not seen.
MarkerTrack read_trc(const std::string& file);
/// The same from the files' text (`file` names it in errors).
MarkerTrack parse_qualisys_tsv(const std::string& text, const std::string& file);
MarkerTrack parse_trc(const std::string& text, const std::string& file);
/// By extension: .tsv or .trc.
MarkerTrack read_marker_file(const std::string& file);

struct MocapAngles {
  AngleTable table;                 ///< one row per frame (empty cells where markers were missing)
  std::vector<std::string> notes;   ///< which angles, from which markers; what is missing
  size_t frames_with_gaps = 0;
};

/// Joint angles from markers named hand_top, hand_left (thumb side), hand_right on the back
/// of the hand and <digit>_middle, <digit>_tip per digit (thumb, index, middle, ring, little).
/// Left or right hand, and which side marker the thumb is nearer, are told from the recording
/// (the notes say which): a left hand's angles are its mirror image's, a right hand's.
/// Throws InputError naming `file` when the three back-of-hand markers are absent.
MocapAngles angles_from_markers(const MarkerTrack& track, const std::string& file);

}  // namespace handskin
