#pragma once
/// The plaster replica (hand + nine spherical markers), its two placements on the table and
/// the synthetic scan pair with its ground truth.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "core/png_io.hpp"
#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "synth/scanner.hpp"

namespace handskin {

struct ReplicaOptions {
  int marker_count = 9;            ///< markers on the flanks and the wrist end
  double marker_radius_mm = 4.0;   ///< sphere radius; centres on the surface (half embedded); see docs/registration.md
  double min_signature_gap_mm = 2.5;  ///< markers must differ this much in their distance pattern
  int min_marker_returns = 12;     ///< samples each marker must return in each scan
  double max_yaw_deg = 15.0;       ///< random yaw on the table, ±
  // Hard cases for the registration tests:
  int omit_marker_in_back = -1;    ///< this marker is missing from the back scan (broken off), -1 none
  bool extra_bump = false;         ///< a marker-sized plaster blob on the back of the hand (back scan only)
  /// Saw the replica flat this far proximal of the wrist joint (square to the hand's long
  /// axis), as a cast is sawn, before the markers go on; the true skin is the sawn one. For
  /// meshes that end in a rounded forearm (a hand model, not a cast). Unset: as given.
  std::optional<double> saw_mm;
  bool IsValid(std::string* error) const;
};

/// Sphere triangulation by subdividing an icosahedron `levels` times (20·4^levels faces).
void icosphere(const Eigen::Vector3d& centre, double radius, int levels, std::vector<Eigen::Vector3d>* vertices,
               std::vector<std::array<int, 3>>* faces);


struct ScanPair {
  ScanSimulation back, palm;
  Eigen::Isometry3d T_back_hand, T_palm_hand;     ///< scanner frame from hand frame
  Eigen::Isometry3d back_to_palm;                 ///< p_palm = back_to_palm · p_back
  std::vector<Eigen::Vector3d> markers_hand;      ///< marker centres, hand frame
  std::optional<Eigen::Vector3d> extra_bump_hand; ///< the blob's centre, hand frame (if any)
  Rig rig_palm;                                   ///< joints in the palm scan's frame
  Mesh skin_palm;                                 ///< the true skin (no markers), palm frame
  /// Each scan's photo: the camera's colour image on the range image's grid (row = scanline),
  /// the hand painted by SkinAlbedo, the markers white plaster, the table grey.
  Rgb8Image back_photo, palm_photo;
  int placement_attempts = 0;
};

/// A hand mesh and its rig that a scanner may take: a hand's size in mm (wrist to middle
/// fingertip 80–450 mm; a hint names the unit it looks like otherwise) and every joint within
/// the mesh's bounding box (widened by the larger of 10 mm and 5 % of the hand's length): one
/// frame and one unit. InputError naming --rig or --mesh otherwise (synth scan and synth
/// cloud: a mesh in metres, or a rig of another frame, made garbage scans or a failure to
/// place the markers).
void check_hand_and_rig(const Mesh& hand, const Rig& rig);

/// Build the replica from `hand` + `rig` (same frame), place it twice on the table (back up,
/// then turned over about its long axis) with random yaw and shift, and scan both sides.
/// Every marker is visible in both scans (placements are redrawn until so, or InputError).
ScanPair synthesize_scan_pair(const Mesh& hand, const Rig& rig, const ReplicaOptions& replica,
                              const ScannerOptions& scanner, std::uint64_t seed, bool verbose);

}  // namespace handskin
