#pragma once
/// Proportions of an adult right hand: bone lengths (mm) close to the mean lengths reported
/// by Buryanov & Kotiuk, "Proportions of hand segments", Int. J. Morphol. 28(3), 2010, and
/// where the bones sit in the hand plane. The synthetic hand is built from them, and the
/// automatic skeleton placement uses them as its anatomical prior (docs/skin.md).
///
/// Hand frame: origin at the wrist joint, +X toward the middle fingertip, +Y toward the
/// thumb, +Z out of the back of the hand.
#include <Eigen/Core>

namespace handskin::proportions {

// Bone lengths (mm): metacarpal, proximal, middle, distal; the thumb has no middle phalanx.
struct FingerSpec {
  double metacarpal, proximal, middle, distal;
  Eigen::Vector2d cmc;   // metacarpal base in the hand plane
  double angle_deg;      // metacarpal heading, + toward the thumb
  double spread_steps;   // multiples of finger_spread added to the phalanges' heading
  double width;          // proximal phalanx half-width
};
inline const FingerSpec kFingers[5] = {
    {46.0, 31.5, 0.0, 24.0, {14.0, 19.0}, 0.0, 0.0, 11.0},   // thumb (heading from options)
    {68.0, 40.0, 22.5, 16.0, {27.0, 12.0}, 10.0, 1.0, 9.6},  // index
    {64.5, 44.5, 26.5, 17.5, {29.0, 1.5}, 1.0, 0.0, 9.9},    // middle
    {58.0, 41.5, 25.5, 17.5, {27.5, -8.5}, -8.0, -1.0, 9.3}, // ring
    {53.5, 33.0, 18.0, 16.0, {24.0, -17.5}, -17.0, -2.2, 8.3},  // little
};
// Skin beyond the fingertip joint (mm): the tip joint lies this far inside the skin.
constexpr double kTipInset = 2.0;
// Wrist joint to middle fingertip skin for the nominal lengths above (mm).
constexpr double kNominalHandLength = 29.0 + 64.5 + 44.5 + 26.5 + 17.5 + kTipInset;

// The replica's flat wrist cut lies this far proximal of the wrist joint (nominal mm).
constexpr double kWristCut = 12.0;

}  // namespace handskin::proportions
