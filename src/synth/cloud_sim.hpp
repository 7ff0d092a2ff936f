#pragma once
/// Point clouds as today's scanners make them (issue 37), from a hand of the synthetic
/// family: views from around the hand (a hand-held or turntable scanner), noise along each
/// view's rays, dropouts where the surface grazes the ray, the stand the hand rests on, stray
/// outliers, an arbitrary pose and units; one merged cloud, or two halves (the views from the
/// back and the views from the palm) each in a pose of its own. With the truth: the true skin
/// and the rig in the (second half's) cloud frame, and the first half's true transform into it.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "mesh/mesh.hpp"

namespace handskin {

struct CloudSimOptions {
  int views = 8;                    ///< directions around the hand's long axis, alternately tilted
  double tilt_deg = 25;             ///< … toward the fingertips and the wrist, so both ends are seen
  double spacing_mm = 0.7;          ///< ray spacing in each view
  double noise_mm = 0.2;            ///< Gaussian noise along the ray (sigma)
  double max_incidence_deg = 80;    ///< steeper (grazing) surface never returns
  double dropout_from_deg = 60;     ///< from here to max_incidence_deg, returns thin out linearly
  bool stand = true;                ///< a disc the wrist end rests on (square to the long axis)
  double stand_radius_mm = 70;
  double stand_gap_mm = 0.5;        ///< between the hand's wrist end and the disc
  double outlier_share = 0.003;     ///< stray points, uniform in the box around the hand (× points)
  bool arbitrary_pose = true;       ///< a random rotation and offset (else the hand frame)
  double units_per_mm = 1.0;        ///< 0.001 writes metres
  bool IsValid(std::string* error) const;
};

struct CloudSim {
  std::vector<Eigen::Vector3d> points;          ///< merged: every view, the stand, outliers (output units)
  std::vector<Eigen::Vector3d> half_a, half_b;  ///< the back views and the palm views, each in its own pose
  Eigen::Isometry3d a_to_b = Eigen::Isometry3d::Identity();  ///< p_b = a_to_b · p_a (mm)
  Eigen::Isometry3d cloud_from_hand = Eigen::Isometry3d::Identity();  ///< the merged cloud's pose = half b's (mm)
  Mesh skin;        ///< the true skin in the merged cloud's frame (mm)
  Rig rig;             ///< the rig in that frame, palm_normal set (frame "palm", mm)
  size_t hand_points = 0, stand_points = 0, outliers = 0, dropped_grazing = 0;
};

/// Scan `hand` (with `rig`, same frame) from around. Deterministic for a seed.
CloudSim simulate_cloud(const Mesh& hand, const Rig& rig, const CloudSimOptions& options, std::uint64_t seed);

}  // namespace handskin
