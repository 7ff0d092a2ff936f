#pragma once
/// The skin stage's named steps (skin_mesh.hpp: build_skin runs them in order), internal to
/// the skin library. Everything here works in the hand frame of the rig (X along the hand,
/// Z out of the back), millimetres:
///   1. to_hand_frame   the cloud and the rig in the hand frame; the rig must sit in the cloud
///   2. assign_points   each point to the tube of its nearest link (assign.cpp)
///   3. find_webs       the finger webs and the palm's end plane (webs.cpp)
///   4. palm_planes, digit_planes   cross-section planes (stations) and their slabs (planes.cpp)
///   5. resample_rings, keep_apart, add_dome   rings of a fixed number of points (rings.cpp)
///   6. stitch_tubes    tube meshes united into one closed surface (stitch.cpp)
///   7. decimate        CGAL edge collapse to the triangle budget (decimate.cpp)
///   8. fit_to_data     the decimated skin fitted to the cloud in least squares (fit_data.cpp;
///                      in the rig frame, as the stitched skin is)
///   9. fair_unseen     the unseen skin round concave creases made fair (fair_unseen.cpp), then
///                      take_back_crossings: moves of 8 and 9 that cross the skin taken back
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/dof.hpp"
#include "core/rig.hpp"
#include "skin/skin_mesh.hpp"
#include "skin/slices.hpp"

namespace handskin::skin_steps {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SM = CGAL::Surface_mesh<K::Point_3>;
constexpr double kDeg = M_PI / 180.0;

/// A ring's plane: polar centre `o`, in-plane axes u, v, normal n (u × v = n, pointing along
/// the tube toward its far end). Angles are sampled on an ellipse of half-axes a (along u)
/// and b (along v), so a flat palm section gets its points spread along the contour.
struct Station {
  Eigen::Vector3d o, u, v, n;
  double a = 1, b = 1;
};

/// One tube under construction: its stations, their slabs of points, then its rings.
struct TubeBuild {
  int id = 0;
  std::vector<Station> st;
  std::vector<std::vector<Eigen::Vector2d>> slab;  ///< per station: in-plane points relative to o
  std::vector<Eigen::Vector3d> beyond;            ///< points past the last station (fingertip dome)
  std::vector<std::vector<Eigen::Vector3d>> rings;
  std::vector<int> ring_station;
  std::vector<Eigen::Vector3d> ring_centre;
  std::optional<Eigen::Vector3d> pole;
  WristCut cut;  ///< the palm: the wrist cut its first station lies in
  double station_step = 0;  ///< a digit's: the stations' spacing along its links, mm
  SkinTubeReport report;
};

/// Which tube a link's points go to: the carpus and the four metacarpals make the palm; the
/// thumb's three links the thumb; the phalanges of a finger its tube.
int tube_of_bone(const Bone& b);
/// A station at `o` with normal `n`: v toward the back of the hand, u = v × n.
Station frame_at(const Eigen::Vector3d& o, const Eigen::Vector3d& n);

// A polyline with arc length, extended straight beyond both ends.
struct Polyline {
  std::vector<Eigen::Vector3d> p;
  std::vector<double> s;
  explicit Polyline(std::vector<Eigen::Vector3d> pts) : p(std::move(pts)) {
    s.push_back(0);
    for (size_t i = 1; i < p.size(); ++i) s.push_back(s.back() + (p[i] - p[i - 1]).norm());
  }
  Eigen::Vector3d at(double t) const {
    size_t i = 0;
    while (i + 2 < p.size() && t > s[i + 1]) ++i;
    const double L = std::max(s[i + 1] - s[i], 1e-9);
    return p[i] + (t - s[i]) / L * (p[i + 1] - p[i]);
  }
  Eigen::Vector3d tangent(double t, double h) const { return (at(t + h) - at(t - h)).normalized(); }
  // Arc length of the point of the (extended) polyline nearest to q.
  double project(const Eigen::Vector3d& q) const {
    double best = 1e300, bs = 0;
    for (size_t i = 0; i + 1 < p.size(); ++i) {
      const Eigen::Vector3d d = p[i + 1] - p[i];
      const double L2 = std::max(d.squaredNorm(), 1e-12);
      double t = (q - p[i]).dot(d) / L2;
      const double lo = i == 0 ? -1e9 : 0, hi = i + 2 == p.size() ? 1e9 : 1;
      t = std::clamp(t, lo, hi);
      const double dist = (p[i] + t * d - q).squaredNorm();
      if (dist < best) best = dist, bs = s[i] + t * std::sqrt(L2);
    }
    return bs;
  }
};


/// Step 1: the cloud, the joints and the links in the hand frame of the rig.
struct HandFrame {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< rig → hand frame
  std::vector<Eigen::Vector3d> q;                      ///< the points
  std::array<Eigen::Vector3d, kJointCount> J;          ///< the joints
  Eigen::Vector3d lo, hi;                              ///< the points' bounding box
  std::vector<Eigen::Vector3d> A, B;                   ///< each link's ends
  std::vector<int> bone_tube;                          ///< each link's tube (tube_of_bone)
};
/// Throws InputError when one of the palm's joints (wrist, metacarpal bases and heads) lies
/// more than 15 mm outside the cloud's bounding box (a digit's outer joints may: that digit is
/// then missing from the scan, a warning later).
HandFrame to_hand_frame(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const std::vector<Bone>& bones);

/// Step 2: each point to the tube of its nearest link; thumb and palm share the points within
/// `thumb_overlap_mm` of their boundary. `palm` is every point the palm's planes may take.
struct TubePoints {
  std::vector<std::vector<Eigen::Vector3d>> tube;  ///< per SkinTube
  std::vector<Eigen::Vector3d> palm;
};
TubePoints assign_points(const HandFrame& H, double thumb_overlap_mm);

/// Step 3: the finger webs (where the skin between neighbouring fingers ends) and the palm's
/// end plane through them: its angle about Z (clamped to ±35°) and where it crosses y = centre.y.
struct Webs {
  std::vector<Eigen::Vector3d> points;  ///< index|middle, middle|ring, ring|little
  std::vector<std::string> warnings;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double alpha_end = 0, x_end = 0;
};
/// Throws InputError when the webs lie at the wrist end (a rig that does not fit).
Webs find_webs(const HandFrame& H, double h);

/// Rim points: in each of 72 angular bins about the proximal sections' middle (the Y-Z plane),
/// the most proximal point within `band_mm` of `x0` (the cloud's proximal end). A plane
/// x = a + b y + c z fitted to them by least squares, twice trimmed at 3 robust sigmas; kept
/// when at least 16 bins spread over 20 mm across the hand and it tilts less than 20 deg.
WristCut fit_wrist_cut(const std::vector<Eigen::Vector3d>& palm_pts, double x0, double band_mm = 15.0);

/// Step 4: the palm's stations (planes across the hand from the wrist cut, turned from the
/// cut's plane to square with the axis over the first planes and fanned to the end plane),
/// their slabs, polar centres and sampling ellipses.
TubeBuild palm_planes(const HandFrame& H, const TubePoints& P, const Webs& webs, double h);
/// A digit's stations (perpendicular to its links, from its root to where its tip's dome
/// starts) and slabs, with the axis-offset figures in its report; report.present is false
/// when the digit is missing from the scan. A finger's stations turn through a bent joint
/// over two tip radii; the thumb's at once, or, with `thumb_turns_slowly`, from its MCP on as
/// a finger's (the window growing from one station at the MCP).
/// With `to_tip_joint` (a given rig) the digit reaches at least its tip joint, where its
/// points stop short of it.
TubeBuild digit_planes(const HandFrame& H, const TubePoints& P, int finger, double h, bool thumb_turns_slowly = false,
                       bool to_tip_joint = false);
/// A digit's measured sections (digit_planes' slabs of 20 points or more; the thumb's from its
/// MCP on): the middle and size of each one's extent in its station's (u, v), and whether it
/// counts toward the axis offset (round enough to have a middle; every one when fewer than 3
/// are).
struct SectionMiddle {
  int station = 0;
  double s = 0;  ///< arc length along the digit's links, mm
  Eigen::Vector2d mid, ext;  ///< the middle and the extent of the section's points (u, v)
  bool counted = false;      ///< its middle is the digit's (see section_middles)
  /// Seen round: its extent one way at least kMinSectionAspect of the other's; else seen from
  /// one side only.
  bool round() const;
  /// How far the links (the plane's origin) pass from the digit's middle as the section shows
  /// it, mm. A section seen from one side only (not round()) shows the middle across its width
  /// only: along its short extent the digit's middle lies up to half its width off the seen
  /// arc's (the arc's depth does not say how much of the round it is), so its offset is the
  /// origin's distance from that segment.
  double offset() const;
};
std::vector<SectionMiddle> section_middles(const TubeBuild& digit, const HandFrame& H, int finger);

/// Step 5: give each point to its station's slab (`beyond` past the last when `dome`).
void fill_slabs(TubeBuild* t, const std::vector<Eigen::Vector3d>& pts, double h, bool dome);
/// Rings of M points per station: polar profiles, wrinkle filter, rings without enough
/// samples filled from their neighbours (shrinking toward a digit's root when `shrink_root`).
void resample_rings(TubeBuild* t, int M, const SkinOptions& o, bool shrink_root);
/// Pull a finger's ring points back where they come nearer a neighbouring finger's links
/// than their own (less 0.5 mm): neighbouring tubes never touch.
void keep_apart(TubeBuild* t, const HandFrame& H, int finger);
/// The fingertip's dome: `rings` rings about the last station and a pole.
void add_dome(TubeBuild* t, int M, int rings, const SkinOptions& o);

/// Exact position → (tube, ring) of the tubes' vertices, looked up again after the union. A
/// hash map: only lookups by equal position are made (std::hash<double> gives 0.0 and −0.0
/// one hash), and for the fixture's ~24 000 positions and ~30 000 lookups the ordered map
/// took ~9 ms, this one ~3 ms.
struct PositionHash {
  size_t operator()(const std::array<double, 3>& a) const {
    size_t h = std::hash<double>()(a[0]);
    h ^= std::hash<double>()(a[1]) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h ^= std::hash<double>()(a[2]) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    return h;
  }
};
using PositionOrigin = std::unordered_map<std::array<double, 3>, std::pair<int, int>, PositionHash>;

/// Step 6: each tube's triangles (strips, caps), then one corefinement union. `origin` maps
/// every tube vertex's exact position (rig frame) to its (tube, ring); `pockets` counts the
/// inner shells dropped. Throws InputError naming a tube that folds into itself, or when the
/// tubes do not join into one surface. With `mend_caps` a tube that folds is first made again
/// with its open ends closed on their rings' own vertices (docs/skin.md, step 8): the given
/// rig's skin (an automatic placement whose tube folds is refused, and another tried).
/// `palm_folds` (fault injection for tests: build_skin's HANDSKIN_FAULT=fold:N) has it find
/// the palm tube folded.
SM stitch_tubes(const std::vector<TubeBuild>& tubes, const Eigen::Isometry3d& hand_to_rig,
                PositionOrigin* origin, int* pockets, bool mend_caps, bool palm_folds = false);

/// Step 7: quadric-error decimation of a closed mesh to `max_faces`, moving it by at most
/// about `tolerance_mm`; each vertex's (tube, ring) in `origin` follows it.
using Origin = SM::Property_map<SM::Vertex_index, std::pair<int, int>>;
void decimate(SM* sm, size_t max_faces, double tolerance_mm, Origin origin);

/// Step 8 (fit_data.cpp; docs/skin.md's step 11): each vertex moved along its normal so that
/// the piecewise-linear skin fits the cloud's points in least squares (point to nearest face,
/// an edge smoothness term, DataFitOptions::rounds rounds).
DataFit fit_to_data(SM* sm, const std::vector<Eigen::Vector3d>& points, const DataFitOptions& options);
/// Step 9 (fair_unseen.cpp; docs/skin.md's step 12): the unseen vertices near a concave crease
/// moved to the fair surface (CGAL's cotangent bi-Laplacian fairing) that the seen skin round
/// them holds. Vertices within `cut_margin_mm` distal of the wrist cut `cut` (n . p = d, rig
/// frame, n distal) or proximal of it stay: the sawn face is unseen and flat by construction.
/// `moved` (if given) receives each moved vertex and where it was, for the figures after the
/// take-back (`settle_fair_figures`).
using Moves = std::vector<std::pair<SM::Vertex_index, K::Point_3>>;
FairUnseen fair_unseen(SM* sm, const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& cut_n, double cut_d,
                       const FairUnseenOptions& options, Moves* moved = nullptr);
/// After steps 8 and 9: every position rounded to single precision (as skin.ply holds it),
/// then the corners of triangles that cross another go back to `before` (positions by vertex
/// index, rounded the same), until nothing crosses; the last self-intersection test is
/// reported (the stage's own check, true of the written file).
struct Crossings {
  size_t reverted = 0;
  bool self_intersects = false;
};
Crossings take_back_crossings(SM* sm, const std::vector<K::Point_3>& before);
/// Every vertex rounded to single precision, as skin.ply stores it (take_back_crossings does it too).
void round_as_written(SM* sm);
/// The crossings the take-back leaves are the union's own (stitch_tubes): where a digit's tube
/// meets the palm's in a near-degenerate way, the corefinement's output can hold slivers and
/// zero-area triangles crossing one another at one spot (R07 of
/// `scripts/random_hands_study.py --draw 70` with its rig: 27 pairs within 0.2 mm at the middle
/// finger's root). They are mended with CGAL's self-intersection repair, the result rounded as
/// written. Returns the crossing pairs mended, 0 when there were none, -1 when there were more
/// than it takes on (100: a fold, left as it is) or the repair failed (the surface is then as
/// the repair left it: not closed, or crossing).
int mend_crossings(SM* sm);
/// Step 9's figures from its moves: the moves kept (mean, largest) and, given the positions
/// the take-back restores (`before`, by vertex index), the vertices it put back.
void settle_fair_figures(const SM& sm, const Moves& moved, const std::vector<K::Point_3>* before, FairUnseen* f);

}  // namespace handskin::skin_steps
