#pragma once
/// `handskin run --cloud`: the stage that takes the place of ingest and registration for a
/// cloud from any scanner (issue 37, docs/clouds.md). run_cloud_stage runs:
///   1. read        every --cloud file (scan/cloud_file.hpp), in mm
///   2. register    two halves: each cleaned, the first registered into the second without
///                  markers (register/cloud_align.hpp); their points merged in the second's frame
///   3. prepare     outliers, the support and other parts away, the hand's size checked,
///                  normals (register/cloud_prep.hpp)
///   4. orient      which way the back of the hand faces: the given rig's palm normal, or
///                  --hand, or the fingers' flexion (fingers bend toward the palm)
///   5. label       palm and back sides about the hand's mid-surface (the labels a scan pair's
///                  merged cloud carries, which the skin's steps and figures use)
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "register/cloud_align.hpp"
#include "register/cloud_prep.hpp"
#include "register/registration.hpp"
#include "scan/cloud_file.hpp"
#include "scan/truth_io.hpp"

namespace handskin {

struct CloudStageInputs {
  std::vector<std::string> files;        ///< one merged cloud, or two halves (the first registered into the second)
  LengthUnit units = LengthUnit::Millimetre;
  std::optional<HandSide> hand;          ///< --hand: which hand it is (else from the rig or the fingers)
  const Rig* rig = nullptr;              ///< the given rig (palm frame = the cloud's), or none
  CloudPrepOptions prep;
  CloudAlignOptions align;
};

/// How the back's direction was decided.
struct CloudOrientation {
  std::string by;                        ///< "rig", "hand", "flexion"
  Eigen::Vector3d back = Eigen::Vector3d::UnitZ();
  double flexion = 0;                    ///< finger_flexion of the hand found (−: toward the palm)
  HandSide side = HandSide::Right;       ///< the hand it is
  std::string note;
};

struct CloudFileFigures {
  std::string path, format;
  size_t points = 0, no_return = 0;
  bool normals = false;
  size_t faces = 0;            ///< a mesh's triangles (0: a cloud)
  size_t surface_samples = 0;  ///< points sampled on a sparse mesh's surface (sample_sparse_mesh)
};

/// Two halves' registration: the fit and what each half's cleaning kept.
struct HalvesRegistration {
  CloudAlignment alignment;
  size_t kept_a = 0, kept_b = 0;
};

struct CloudStageResult {
  std::vector<CloudFileFigures> files;
  std::optional<HalvesRegistration> halves;  ///< two files: the first into the second's frame
  std::string units;
  PreparedCloud prepared;                ///< the hand's points, normals turned to the sides
  std::vector<std::uint32_t> sides;      ///< 0 palm, 1 back
  std::vector<std::uint32_t> sheets;     ///< sheet_labels: 1 facing the back, 0 the palm, 2 neither
  CloudOrientation orientation;
  double two_sided_share = 0;            ///< two_sided_share of the hand's points along the back
  double seconds = 0;
  /// The merged arrays the skin and patch stages take (points, normals, sides).
  MergedArrays merged() const;
};

/// What a back scan and a palm scan would each have seen of a cloud seen from around: 1 where
/// the (outward) normal faces `back` within kSheetCos, 0 where it faces away within it, 2 on
/// the flanks between (where two touching fingers meet). The skeleton's placement parts the
/// digits by these sheets when the silhouette's parting fails (auto_rig.hpp, DigitParting).
constexpr double kSheetCos = 0.3;  // ~73 deg: about where a scanner's returns grow sparse
std::vector<std::uint32_t> sheet_labels(const std::vector<Eigen::Vector3d>& normals, const Eigen::Vector3d& back);

/// Read and prepare the clouds. Throws InputError naming the file (or --hand).
CloudStageResult run_cloud_stage(const CloudStageInputs& in, const std::function<void(const std::string&)>& progress);

/// The fingers' (index to little) mean bend toward the back of the hand in `points` whose
/// joints `rig` holds (palm_normal set): the drop of the hand's mid-depth (halfway between
/// back and palm, over a 3 mm disc) from each PIP to 60 % of the way from its DIP to its tip,
/// over their distance in the hand's plane. Negative: bent toward the palm; about 0 for
/// straight fingers.
double finger_flexion(const std::vector<Eigen::Vector3d>& points, const Rig& rig);

/// The stage's figures for the run report's "cloud" stage.
Json to_json(const CloudStageResult& r);

/// Two halves' registration against a synthetic cloud's truth (truth.json's back_to_palm maps
/// the first half into the second): {"rotation_deg", "skin_mean_mm", "skin_max_mm", "file"}.
Json halves_against_truth(const CloudStageResult& r, const TruthSkin& truth);

/// registration.json of two halves (handskin-registration/1, "method": "markerless"):
/// back_to_palm maps the first half into the second's frame.
Json halves_registration_json(const CloudStageResult& r);

/// The merged cloud (merged.ply) of the stage's arrays.
MergedCloud::Ptr merged_cloud(const MergedArrays& a);

}  // namespace handskin
