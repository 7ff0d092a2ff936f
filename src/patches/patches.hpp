#pragma once
/// Bézier patch skin (thesis §4.1.4, eqs. 4.5–4.7; docs/patches.md). Each tube of the skin's
/// ring grid (palm, thumb, four fingers) carries a grid of bicubic Bézier patches — periodic
/// around the tube, open along it — whose control points form one net per tube: neighbouring
/// patches share their border control points by construction (G0 exactly, whatever the fit
/// does). The net is fitted to the measured points by linear least squares (eq. 4.5; every
/// control point of the tube in one system, solved by Cholesky), with a C1 penalty on the
/// control points either side of each border (so G1 holds up to the penalty), a small fairness
/// term, and the skin's rings as weak data where the scans saw nothing. The points'
/// parameters start at chord length along and around the rings and are corrected by Newton
/// foot-point projection (eqs. 4.6–4.7) until the largest update falls below a tolerance.
///
/// Not yet: the tubes are not joined into one surface (finger roots overlap the palm tube as
/// the strip skin's tubes do before their union) and the wrist is left open (issue 13 is
/// open; docs/patches.md says what is missing).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "mesh/trimesh.hpp"
#include "posture/skeleton.hpp"
#include "skin/skin_mesh.hpp"

namespace handskin {

struct PatchOptions {
  int palm_around = 8, palm_along = 4;    ///< palm tube: spans (patches) around and along
  int digit_around = 4, digit_along = 3;  ///< each digit
  double fairness = 1e-3;                 ///< second differences of the net, relative to the data's weight
  double c1_weight = 10;                  ///< C1 penalty across borders, relative to the data's weight
  double ring_weight = 0.05;              ///< the skin's ring points as data, relative to a measured point
  int max_corrections = 10;               ///< parameter-correction rounds (eqs. 4.6–4.7)
  double correction_tolerance = 0.02;     ///< stop when no parameter moves more (spans; ~0.3 mm on the palm)
  int tessellation = 8;                   ///< patches.ply: quads per patch side
  /// A layout given back (`--layout`): spans {around, along} per tube (SkinTube index) that
  /// replace the counts above for that tube.
  std::map<int, std::array<int, 2>> tube_spans;
  bool IsValid(std::string* error) const;
};

/// The layout of a patches file (`handskin-patches/1`, its "tubes" with "around" and
/// "along") or of a layout file (`handskin-patch-layout/1`, the same key): the spans per tube.
/// Throws InputError naming `file` and the entry at fault.
std::map<int, std::array<int, 2>> parse_patch_layout(const Json& j, const std::string& file);

/// A bicubic Bézier patch: P[4 * i + j], i along u (around the tube), j along v (along it).
struct BezierPatch {
  std::array<Eigen::Vector3d, 16> P;
  int tube = 0, span_u = 0, span_v = 0;
  int link = -1;  ///< the bone link (index into bones_from_rig) nearest to the patch's centre
  std::array<int, 16> cp_link{};  ///< per control point: its bone link (the net's rigid binding)
  Eigen::Vector3d eval(double u, double v) const;
};

struct TubeSurface {
  int tube = 0;
  int nu = 0, nv = 0;  ///< spans around (periodic) and along
  /// The start (the palm's wrist end) or the end (a digit's tip) is closed: that row of the
  /// net is one point, so its patches have one edge collapsed there.
  bool closed_start = false, closed_end = false;
  /// The Bézier net: 3·nu × (3·nv + 1) points, periodic in the first index; patch (a, b) is
  /// the 4 × 4 block at (3a, 3b). Shared borders are shared entries.
  std::vector<Eigen::Vector3d> net;
  std::vector<int> net_link;  ///< per net point: its bone link (rigid binding, as the thesis)
  Eigen::Vector3d eval(double u, double v) const;            ///< u in [0, nu) (wraps), v in [0, nv]
  void derivatives(double u, double v, Eigen::Vector3d* S, Eigen::Vector3d* Su, Eigen::Vector3d* Sv) const;
  const Eigen::Vector3d& net_at(int i, int j) const;  ///< i wraps
};

struct DistanceFigures {
  double mean = 0, rms = 0, max = 0, p95 = 0;
  size_t points = 0;
};

struct PatchSkin {
  std::vector<TubeSurface> tubes;   ///< the present tubes
  std::vector<BezierPatch> patches;
  std::vector<std::string> bones;   ///< link names (BezierPatch::link)
  /// Data → surface by foot points, per side of the merged cloud (0 palm scan, 1 back scan).
  std::array<DistanceFigures, 2> side;
  /// Every measured point that was fitted, with its scan side and its foot-point distance (mm)
  /// and foot point's (tube, u, v): for the report's pictures and its cell-grid error.
  struct Sample {
    Eigen::Vector3d p;
    float error = 0;
    std::uint8_t side = 0;
    int patch = -1;          ///< index into `patches` of the foot point
    float s = 0, t = 0;      ///< the foot point's parameters in that patch, [0, 1]
  };
  std::vector<Sample> samples;
  std::vector<double> max_update_per_round;  ///< largest parameter update of each correction round
  /// Data → surface RMS at the start of each round (round 0: on the chord-length fit), by
  /// the residuals of that round's foot-point search.
  std::vector<double> rms_per_round;
  double g0_gap_mm = 0;                      ///< largest gap between neighbours' shared borders
  /// G1: angle between the two patches' normals along every shared border (deg), sampled.
  double g1_median_deg = 0, g1_p95_deg = 0, g1_max_deg = 0;
  size_t control_points = 0;
  double seconds = 0;
};

/// Fit the patches on a skin's ring grid and the merged cloud (`points`, rig frame, with
/// `sides`). Throws InputError when the skin has no ring grid to fit on.
PatchSkin fit_patch_skin(const SkinResult& skin, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<std::uint32_t>& sides, const PatchOptions& options);

/// The patches moved to a posture: every net point moves rigidly with its bone link (the
/// thesis's binding): the link from joint p moves by W_p(angles)·W_p(0)⁻¹ of `skeleton`,
/// which must be the rig's the patches were fitted on. Shared borders stay shared (G0 holds in
/// every posture). The fit's figures are kept as they were; its samples (the measured points)
/// are not carried over.
PatchSkin pose_patch_skin(const PatchSkin& s, const Skeleton& skeleton, const Angles& angles);

/// Every patch tessellated at `n` × `n` quads (two triangles each), each tube's shared border
/// vertices made once: no cracks inside a tube.
TriMesh tessellate(const PatchSkin& s, int n);
/// The vertices `tessellate(s, n)` makes, in its order, without building the mesh: posed
/// patches keep the rest posture's topology, so an animation needs only these (16 × 16 per
/// patch: ~0.5 ms for the fixture's 92).
void tessellation_vertices(const PatchSkin& s, int n, std::vector<Eigen::Vector3d>* out);

}  // namespace handskin
