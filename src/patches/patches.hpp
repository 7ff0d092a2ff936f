#pragma once
/// Bézier patch skin (thesis §4.1.4, eqs. 4.5–4.7; docs/patches.md). One bicubic Bézier patch
/// per face of a closed quad layout over the whole hand (patches/layout.hpp: palm, back,
/// flanks, digits, fingertips, the wrist cut). Neighbouring patches share their border's
/// control points — one control point per layout corner, two per layout edge, four inside
/// each face — so G0 holds exactly whatever the fit does. All control points are fitted to
/// the measured points in one sparse least-squares system (eq. 4.5, Cholesky), with a C1
/// penalty on the control points either side of every border (G1 up to the penalty, except
/// where three, five or six patches meet), a small fairness term, and the polygon skin's
/// vertices as weak data where the scans saw nothing. The points' parameters start at their
/// nearest point on the layout's bilinear faces and are corrected by Newton foot-point
/// projection on the current surface (eqs. 4.6–4.7; a point whose foot point leaves its patch
/// is found again on the whole surface) until the largest correction falls below a tolerance.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "patches/layout.hpp"
#include "posture/skeleton.hpp"
#include "rigging/binding.hpp"
#include "rigging/deform.hpp"
#include "skin/skin_mesh.hpp"

namespace handskin {

struct PatchOptions {
  int subdivision = 1;                    ///< each face of the hand's layout split k × k (98 k² patches)
  double fairness = 1e-3;                 ///< second differences inside each patch, relative to the data's weight
  double c1_weight = 10;                  ///< C1 penalty across borders, relative to the data's weight
  double corner_weight = 0.1;             ///< one tangent plane where 3, 5 or 6 patches meet, relative to the data's weight
  double skin_weight = 0.5;               ///< the polygon skin's samples as data where the scans saw nothing, relative to a measured point
  int max_corrections = 10;               ///< parameter-correction rounds (eqs. 4.6–4.7)
  double correction_tolerance = 0.05;     ///< stop when 99.9 % of the foot points move less (mm, on the surface)
  int tessellation = 8;                   ///< patches.ply: quads per patch side
  /// A layout given back (`--layout`): used as it is (no subdivision) instead of the hand's.
  std::optional<PatchLayout> layout;
  /// Refinement to a tolerance (`--patch-tolerance`, issue 38; 0: none, the layout as it is).
  /// After the fit, every patch whose measured points' largest distance to the surface exceeds
  /// it is split at its midpoints (de Casteljau: the surface unchanged), leaving T-junctions
  /// whose short sides are held to the long side's halves exactly (balance_cuts, build_net), and
  /// the net refitted from that surface; until every patch holds it, `refine_rounds` rounds
  /// were made, or a further split would exceed `max_patches` (refine.cpp). Patches that hold
  /// it but are rough (refine.cpp) are split too in the first `rough_rounds` rounds only.
  double tolerance_mm = 0;
  int max_patches = 300;
  int refine_rounds = 6;
  int rough_rounds = 4;
  bool IsValid(std::string* error) const;
};

/// A bicubic Bézier patch: P[4 * i + j], i along u (the face's corner 0 → 1), j along v
/// (corner 0 → 3); (u, v) in [0, 1]², the normal Su × Sv pointing out of the hand.
struct BezierPatch {
  std::array<Eigen::Vector3d, 16> P;
  std::string name;  ///< the layout face's name
  int link = -1;     ///< the bone link (index into bones_from_rig) nearest to the patch's centre
  std::array<int, 16> cp_link{};  ///< per control point: its bone link (rigid binding)
  Eigen::Vector3d eval(double u, double v) const;
  void derivatives(double u, double v, Eigen::Vector3d* S, Eigen::Vector3d* Su, Eigen::Vector3d* Sv) const;
};

struct DistanceFigures {
  double mean = 0, rms = 0, max = 0, p95 = 0;
  size_t points = 0;
};

/// Where a tessellation of a patch surface (tessellate's mesh and face_patch) passes through itself.
struct PatchCrossings {
  size_t pairs = 0;                   ///< pairs of its triangles that cross
  std::vector<std::string> patches;   ///< the patches they lie on, by name, each pair once ("a | b", sorted)
  std::vector<std::pair<int, int>> patch_pairs;  ///< the same pairs by patch index (a <= b), each once, sorted
  /// Per entry of patch_pairs, where its triangles cross: the centroids of each crossing pair's two.
  std::vector<std::vector<Eigen::Vector3d>> where;
};

/// Two neighbouring fingers' tubes of patches held apart (fit_patch_skin): where the fingers
/// are pressed together, the two patches either side of their web's border follow the same
/// crease and can pass through each other. Every control point of the patches `faces[0]` is
/// kept at least kSeparationMarginMm on the plane's negative side (normal · x <= offset - margin),
/// of `faces[1]` on its positive side, and those of both (their shared border) on the plane:
/// a Bézier patch lies within its control points' convex hull, so the two then meet along
/// their border only.
struct Separation {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();  ///< unit, from faces[0]'s side to faces[1]'s
  double offset = 0;                                  ///< the plane: normal · x = offset
  std::array<std::vector<int>, 2> faces;              ///< indices into the layout's faces
  std::string between;                                ///< "a | b": the two patches that crossed (for the report)
};
inline constexpr double kSeparationMarginMm = 0.02;

/// A fit's state for measuring every point on its surface later (patch_steps.hpp).
struct PendingMeasure;

struct PatchSkin {
  PatchLayout layout;                      ///< the faces fitted on, one patch each
  std::vector<Eigen::Vector3d> control;    ///< every control point once (shared borders shared)
  std::vector<int> control_link;           ///< per control point: its bone link (rigid binding, as the thesis)
  /// Per control point: its smooth weights (bind_patch_controls, from the rigged polygon
  /// skin's binding); empty when the patches are bound rigidly only (control_link).
  std::vector<VertexWeights> control_weights;
  std::string binding_mode;                ///< the polygon skin's binding the weights came from ("smooth", "rigid")
  std::vector<std::array<int, 16>> patch_control;  ///< per patch: its 16 control points (P00…P33)
  /// Per control point: empty when the fit solves for it; at a T-junction of a layout refined
  /// locally (LayoutTopology), the control points it is a fixed combination of and their
  /// weights: a short side's border curve is one half of the long side's (de Casteljau), so
  /// G0 holds exactly there. rebuild_patches sets them from the others (also after posing).
  std::vector<std::vector<std::pair<int, double>>> control_derived;
  std::vector<BezierPatch> patches;
  std::vector<std::string> bones;   ///< link names (BezierPatch::link)
  /// Data → surface by foot points, per side of the merged cloud (0 palm scan, 1 back scan).
  std::array<DistanceFigures, 2> side;
  /// Every measured point that was fitted, with its scan side, its foot-point distance (mm)
  /// and its foot point's patch and parameters: for the report's pictures and cell-grid error.
  struct Sample {
    Eigen::Vector3d p;
    float error = 0;
    std::uint8_t side = 0;
    int patch = -1;          ///< index into `patches` of the foot point
    float s = 0, t = 0;      ///< the foot point's parameters in that patch, [0, 1]
  };
  std::vector<Sample> samples;
  std::vector<double> max_update_per_round;  ///< largest foot-point move of each correction round (mm)
  std::vector<double> update_p999_per_round;  ///< the move 99.9 % of the points stayed under (the stopping test)
  std::vector<size_t> reassigned_per_round;  ///< points whose foot point went to a patch not touching its last
  /// Data → surface RMS at the start of each round (round 0: on the first fit), by the
  /// residuals of that round's foot-point search.
  std::vector<double> rms_per_round;
  /// The round whose surface was kept: the one with the lowest RMS (the last, unless a round
  /// raised it and the correction ended before it fell below that again).
  int kept_round = -1;
  /// The hand's layout tried (fit_patch_skin): per try, the shift of the palm ring the thumb's
  /// base ends at (hand_patch_layout) and the 95th percentile of the surface's distance to the
  /// polygon skin (mm); the first is the default. `thumb_ring_shift`: the one kept.
  std::vector<std::pair<int, double>> layout_tries;
  /// Per layout tried, the pairs of its tessellation's triangles (PatchOptions::tessellation)
  /// that cross; a try with fewer is kept before one nearer the skin.
  std::vector<size_t> layout_try_crossings;
  /// Per layout tried, its largest G1 jump away from the irregular corners (deg) and the
  /// border it is at; one folded over 30 deg at the thumb's, the palm's or the wrist's patches
  /// is kept after one that is not.
  std::vector<std::pair<double, std::string>> layout_try_folds;
  /// Per layout tried, the turn of the thumb's base toward the palm (deg; hand_patch_layout):
  /// 0 but where the rings' shifts left the surface crossing or folded at the base.
  std::vector<double> layout_try_turns;
  int thumb_ring_shift = 0;
  double thumb_turn_deg = 0;
  /// The polygon skin's samples' weight it was fitted with (fit_patches): PatchOptions::skin_weight,
  /// or 0.05 where fit_patch_skin's fit crossed itself and one with 0.05 crossed less.
  double skin_weight_used = 0;
  /// The fairness it was fitted with: PatchOptions::fairness, or that raised 1.5, 2 or 3 times
  /// where fit_patch_skin's fit still crossed itself within a digit or the palm and the fit so
  /// raised crossed nowhere (the first such raise).
  double fairness_used = 0;
  /// Pairs of triangles that crossed in the fit before the fairness was raised; 0 when it was not.
  size_t crossings_before_fairness = 0;
  /// The kept surface tessellated at PatchOptions::tessellation passing through itself, as
  /// fit_patch_skin measured it for the choice of layout and the fingers held apart (on every
  /// path; none once posed).
  std::optional<PatchCrossings> crossings;
  /// The fingers' tubes held apart (Separation), and the crossing pairs of the fit before
  /// they were (`crossings_before_separation`); both empty when none crossed.
  std::vector<Separation> separations;
  size_t crossings_before_separation = 0;
  double g0_gap_mm = 0;                      ///< largest gap between neighbours' shared borders
  /// G1: angle between the two patches' normals along every shared border (deg), 9 samples
  /// per border; "away" leaves out the two samples nearest a corner where 3, 5 or 6 patches
  /// meet, which the `near` figures take.
  double g1_median_deg = 0, g1_p95_deg = 0, g1_max_deg = 0;
  double g1_near_median_deg = 0, g1_near_max_deg = 0;
  std::string g1_max_where;                  ///< the two patches whose border has the largest jump (away)
  std::array<std::string, 2> worst_patch;    ///< per side: the patch of the farthest point's foot point
  int irregular_corners = 0;                 ///< layout corners where other than 4 patches meet
  /// The refinement to a tolerance, when asked (PatchOptions::tolerance_mm).
  struct Refinement {
    double tolerance_mm = 0;
    std::vector<int> patches;            ///< per fit (0: the layout's): the patch count
    std::vector<int> over;               ///< per fit: patches whose points' largest distance exceeds the tolerance
    std::vector<double> worst_mm;        ///< per fit: the largest distance of a measured point
    std::vector<double> seconds;         ///< per fit: its time
    bool held = false;                   ///< every patch of the kept fit holds the tolerance
    std::string stopped;                 ///< why it stopped short of that (rounds, patches, no gain)
    int frozen = 0;                      ///< faces left whole: their split made the surface pass through itself
  };
  std::optional<Refinement> refinement;
  size_t control_points = 0;
  double seconds = 0;
  /// Set while the measured points' distances (`side`, `samples`, `worst_patch`) are not
  /// made yet: fit_patch_skin fits candidates (other layouts, the fingers held apart, a lighter
  /// skin weight) without them and measures the one it keeps. Null on every fit it returns.
  std::shared_ptr<const PendingMeasure> pending_measure;
};

/// Fit one patch per face of `layout` to the measured `points` (palm frame, with their scan
/// `sides`), with `support` (the polygon skin's vertices) as weak data; `bones` bind the
/// control points. The net starts on the layout's bilinear faces, or on `seed` (per face its
/// 16 control points, P00…P33) when given; `separations` hold pairs of faces apart (with a seed
/// only: they act in the rounds that fit along the foot points' normals).
PatchSkin fit_patches(const PatchLayout& layout, const std::vector<Eigen::Vector3d>& points,
                      const std::vector<std::uint32_t>& sides, const std::vector<Eigen::Vector3d>& support,
                      const std::vector<Bone>& bones, const PatchOptions& options,
                      const std::vector<std::array<Eigen::Vector3d, 16>>* seed = nullptr,
                      const std::vector<Separation>& separations = {});

/// Cuts of a face (refine.cpp): kCutU splits it at u = 1/2 (its sides 0 and 2 at their
/// midpoints), kCutV at v = 1/2 (sides 1 and 3); both: four faces.
constexpr int kCutU = 1, kCutV = 2;
/// The cuts balanced so that no side lies against more than two (LayoutTopology's T-junctions):
/// a face that would split a short side (a half of a long side across) has the long side's
/// face cut along it too, and so on. A cut of a side shared whole leaves a T-junction, but
/// beside a corner where other than four patches meet, where the face across is cut along it too.
std::vector<int> balance_cuts(const PatchLayout& layout, const LayoutTopology& topology, std::vector<int> cuts);
/// A fitted surface's layout with faces cut (balanced cuts, one per face): the new corners on
/// the surface (each split side's midpoint once; a long side's is the vertex hanging on it),
/// each new face's 16 control points by de Casteljau at the midpoints (the same surface: a
/// split border's curve is split the same way from both faces on it, and a side left whole
/// beside a split one is the long side of a T-junction, whose halves the split faces' sides
/// are), its name the old one's with "/u0", "/v1", "/00"… appended, the creases split with their
/// edges, each new face's parent, and which of its sides lie on its parent's same side (a
/// face cut at u = ½: its halves' sides 0 and 2 and the outer one of 1 and 3).
struct LayoutSplit {
  PatchLayout layout;
  std::vector<std::array<Eigen::Vector3d, 16>> seed;
  std::vector<int> parent;
  std::vector<std::array<bool, 4>> on_parent_side;
};
LayoutSplit split_layout(const PatchSkin& s, const std::vector<int>& cuts);
/// Separations carried to a split layout: each side's faces are those split from its faces.
std::vector<Separation> separations_after_split(const std::vector<Separation>& separations, const LayoutSplit& split);
/// Per patch, the q-quantile of its measured points' distances (0 with fewer than 40 points).
std::vector<double> patch_error_percentile(const PatchSkin& s, double q);
/// The largest distance of a measured point (PatchSkin::samples) with its foot point on each patch.
std::vector<double> patch_max_error(const PatchSkin& s);

/// A layout given back (PatchOptions::layout) must lie on the skin it is fitted to: throws
/// InputError naming the first corner farther than 20 mm from the skin's surface.
void check_layout_on_skin(const PatchLayout& layout, const Mesh& skin);
/// The hand's patches: the layout given in `options`, else the hand's (hand_patch_layout on
/// the skin and its rig, subdivided), fitted to the merged cloud with the skin as support.
PatchSkin fit_patch_skin(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<std::uint32_t>& sides, const PatchOptions& options);

/// The patches' control points bound smoothly: each takes the weights of the polygon skin's
/// `binding` (rigging/binding.hpp, one entry per vertex of `skin`) at its nearest point on
/// `skin` (the three corners' weights blended barycentrically, the 4 largest kept and
/// normalised), into `control_weights`. Throws InputError when the binding does not fit the skin.
void bind_patch_controls(PatchSkin* s, const Mesh& skin, const SkinBinding& binding);

/// The patches moved to a posture. With `control_weights`, every control point is blended
/// from its links' motions as the polygon skin's vertices are (rigging/deform.hpp: dual
/// quaternions by default, or linear); without, it moves rigidly with its bone link (the
/// thesis's binding). The link from joint p moves by W_p(angles)·W_p(0)⁻¹ of `skeleton`, which
/// must be the rig's the patches were fitted on. Shared borders stay shared (G0 holds in every
/// posture). The fit's figures are kept as they were; its samples (the measured points) are
/// not carried over.
PatchSkin pose_patch_skin(const PatchSkin& s, const Skeleton& skeleton, const Angles& angles,
                          Blend blend = Blend::DualQuaternion);

/// Each patch's 16 control points (and their links) copied from the net (`control`,
/// `control_link`, `patch_control`), the T-junctions' control points first set from the
/// others (`control_derived`).
void rebuild_patches(PatchSkin* s);

/// Every patch tessellated at `n` × `n` quads (two triangles each), the vertices on shared
/// borders and corners made once: a closed mesh without cracks. With `face_patch`, each
/// triangle's patch (an index into `s.patches`).
Mesh tessellate(const PatchSkin& s, int n, std::vector<int>* face_patch = nullptr);
/// Where the tessellation passes through itself, measured on the coordinates patches.ply
/// stores (floats), with CGAL's exact predicates (as the skin's check reads skin.ply back).
/// Neighbouring fingers pressed together (the family's H04 and H12) gave tubes of patches that
/// pass through each other at their roots; `crossings(s, n)` tessellates `s` first.
PatchCrossings tessellation_crossings(const PatchSkin& s, const Mesh& tessellation, const std::vector<int>& face_patch);
PatchCrossings crossings(const PatchSkin& s, int n);
/// The vertices `tessellate(s, n)` makes, in its order, without building the mesh: posed
/// patches keep the rest posture's topology, so an animation needs only these (16 × 16 per
/// patch: ~0.5 ms for the fixture's 92).
void tessellation_vertices(const PatchSkin& s, int n, std::vector<Eigen::Vector3d>* out);

}  // namespace handskin
