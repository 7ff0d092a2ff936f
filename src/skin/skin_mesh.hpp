#pragma once
/// Skin, step 5 (thesis §4.1.3, done so that the result is usable as it is): polygon strips
/// between consecutive cross-section planes, closed into one watertight triangle mesh.
///
/// The hand is cut into six tubes of strips — the palm (planes across the hand's long axis,
/// as the thesis cut it, fanned at the knuckles to follow the line of the finger webs) and
/// each digit (planes perpendicular to its own links, so that the thumb is not cut
/// obliquely). Every measured point goes to the tube of its nearest bone link. Each plane's
/// ring is resampled in polar coordinates about the link with a fixed number of points, so
/// consecutive rings pair up into strips. Fingertips get a dome of rings about a tip centre,
/// the wrist cut and the tubes' inner ends flat caps. The tubes are then stitched into one
/// surface by a CGAL corefinement union (finger roots into the palm, the thumb web),
/// decimated to the triangle budget (CGAL edge collapse, Garland–Heckbert quadrics) and checked: closed, manifold, outward, free
/// of self-intersections. docs/skin.md has the details and the figures.
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/errors.hpp"
#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "skin/slices.hpp"

namespace handskin {

/// build_skin's step 8, the skin fitted to the data (docs/skin.md, step 11): after decimation each vertex moves along
/// its normal onto the cloud's surface, where the cloud has one.
struct DataFitOptions {
  bool enabled = true;
  double max_move_mm = 2.0;  ///< a point farther from the skin is not its surface; no vertex moves farther
  double smoothness = 0.2;   ///< λ per point per vertex: the weight of equal moves along an edge
  int rounds = 2;            ///< the least squares solved this many times, the nearest faces found again
  int max_points = 10000;    ///< the cloud is thinned to about this many points
};
/// Step 9 (docs/skin.md's step 12): the skin neither scan saw, where the union or the rings
/// left a concave crease in it (the V between two fingers' tubes short of their web, where a
/// tube's rings meet the palm's), made fair: those vertices move to the surface of least
/// bending that meets the seen skin round them.
struct FairUnseenOptions {
  bool enabled = true;
  double seen_mm = 1.0;       ///< a vertex with a cloud point this near is seen, and stays
  double crease_deg = 15;     ///< an edge whose faces turn by more, concave, is a crease
  int rings = 4;              ///< unseen vertices this many edges from a crease's move too
  double cut_margin_mm = 2;   ///< vertices this near the wrist cut (or beyond it) stay
  double away_mm = 2.0;       ///< a vertex the fairing takes this much farther from the cloud is held
};
/// What step 9 did.
struct FairUnseen {
  size_t vertices = 0;         ///< the skin's vertices, and of them
  size_t unseen = 0;           ///< those with no cloud point within seen_mm (the wrist cut's counted as seen)
  size_t crease_vertices = 0;  ///< unseen vertices on a concave crease
  size_t faired = 0;           ///< vertices moved (the creases' regions)
  size_t held = 0;             ///< region vertices held where they were (fairing took them away from the cloud)
  size_t taken_back = 0;       ///< of those, put back because the skin crossed itself there
  double mean_move_mm = 0, max_move_mm = 0;  ///< of the moves kept
};
/// What step 8 did.
struct DataFit {
  size_t points = 0;    ///< points fitted (the last round)
  size_t moved = 0;     ///< vertices moved
  size_t reverted = 0;  ///< moves taken back because the skin crossed itself
  bool self_intersects = false;  ///< after the moves and the take-backs (checked when enabled)
  double mean_move_mm = 0, max_move_mm = 0;
};

struct SkinOptions {
  /// planes: cuts from the wrist to the middle fingertip (the spacing of every tube's rings);
  /// points_per_segment: ring points per link and arc (a finger ring has 2 arcs — dorsal and
  /// palmar — the palm 8: 4 metacarpals × 2); min_points: fewer points in a ring's slab and
  /// the ring is not measured (it is filled from its neighbours). Its `smoothing` is the
  /// thesis slicing's (slices.json); the skin's is `smoothing_rings`.
  SliceOptions slicing;
  /// Wrinkle filter: a radius that strays by more than wrinkle_mm from the quadratic fitted
  /// over ± smoothing_rings neighbouring rings (Savitzky–Golay) is replaced by the fit; the
  /// others are kept, so the skin does not shrink where it curves along a tube. 0: off.
  int smoothing_rings = 2;
  double wrinkle_mm = 0.15;
  /// Points within this distance of the thumb/palm boundary (difference of their distances to
  /// the nearest thumb and non-thumb link) measure both tubes.
  double thumb_overlap_mm = 3.0;
  int cap_rings = 4;              ///< rings of a fingertip's dome, plus its pole
  double window_deg = 2.0;        ///< radius at an angle: mean of the samples within ± this
  double min_coverage_deg = 150;  ///< a ring's samples must cover this much of the circle
  /// Decimation (CGAL edge collapse, quadric error) to at most this many triangles, moving the
  /// surface by at most decimation_tolerance_mm; 0: keep every strip triangle.
  int max_triangles = 8000;
  double decimation_tolerance_mm = 0.15;
  DataFitOptions data_fit;
  FairUnseenOptions fair_unseen;
  bool check_self_intersections = true;
  /// The rig was given, not placed: its digits are held to their sections as these show them
  /// (SkinTubeReport::axis_offset_seen_mm), sections seen from one side only included. A
  /// placed skeleton is held to the sections seen round (axis_offset_mm), as its placement's
  /// retries expect. A given rig's tube that folds is also made again with its ends closed
  /// on their rings (stitch_tubes' mend_caps); a placement's is refused. Set by the skin stage.
  bool rig_given = false;
  bool IsValid(std::string* error) const;
};

/// The six tubes of strips.
enum class SkinTube { Palm = 0, Thumb, Index, Middle, Ring, Little };
constexpr int kSkinTubes = 6;
const char* skin_tube_name(int tube);

struct SkinTubeReport {
  std::string name;
  int rings = 0;            ///< plane rings (dome rings not counted)
  int measured = 0;         ///< rings resampled from their own slab's points
  int filled = 0;           ///< rings filled from measured neighbours (no or too few points)
  int partial = 0;          ///< of those, rings whose own samples (too few angles to stand alone) corrected the fill
  size_t points = 0;        ///< measured points given to this tube
  bool present = true;      ///< false: no ring measured (a digit missing from the scan)
  /// A digit: median over its sections (the thumb's: those beyond its MCP, not the thenar's)
  /// of how far the middle of the section's extent lies from the link axis, and those
  /// sections' median radius. A rig that fits puts its links near the middle (the bones lie
  /// a little dorsal); one of another scan does not.
  double axis_offset_mm = 0, section_radius_mm = 0;
  /// The links' median offset over every section, one seen from one side only by what it shows
  /// (skin_steps::SectionMiddle::offset): what a given rig is held to.
  double axis_offset_seen_mm = 0;
};

/// One tube's regular ring grid before stitching and decimation (rig frame, mm): its rings
/// in order along the tube (the plane rings, then a digit's dome rings), each of the same
/// number of points at the same angles, and a digit's fingertip pole. The Bézier patches are
/// fitted on it.
struct RingGrid {
  int tube = 0;                                  ///< SkinTube
  bool present = true;                           ///< false: the tube is missing (no rings)
  std::vector<std::vector<Eigen::Vector3d>> rings;
  std::vector<int> station;                      ///< per ring: its plane, -1 for a dome ring
  std::optional<Eigen::Vector3d> pole;           ///< a digit's fingertip
};

/// The wrist cut: the plane where the cast was sawn off, fitted to the cloud's proximal rim.
/// A cast is cut square to the forearm, which need not be square to the hand's axis (the
/// wrist slightly bent, the rig's axis a few degrees off): a cut plane taken square to the
/// axis put the wrist's fan up to 1.6 mm off the true cut's rim (a 6.7 deg tilt on the family).
struct WristCut {  // hand frame (the rig's axes, X toward the fingers)
  Eigen::Vector3d n = Eigen::Vector3d::UnitX();  ///< unit normal, distal (toward the fingers)
  double d = 0;                                  ///< the plane: n . p = d
  bool fitted = false;                           ///< false: too few rim points, square to the axis
  int rim_points = 0;                            ///< angular bins that gave a rim point
  double tilt_deg = 0;                           ///< angle between n and the hand's axis
  double rms_mm = 0;                             ///< the rim points' distance to the plane
};
struct SkinResult {
  Mesh mesh;                 ///< palm frame (the rig's), mm, outward-oriented
  std::vector<int> vertex_bone; ///< per vertex: index into `bones` (nearest link, for binding)
  std::vector<int> vertex_tube; ///< per vertex: SkinTube it came from
  std::vector<int> vertex_ring; ///< per vertex: its ring (plane) in the tube; -1 on caps and seams
  std::vector<Bone> bones;      ///< the 24 links (bones_from_rig)
  std::vector<SkinTubeReport> tubes;
  std::vector<RingGrid> grid;   ///< per tube (SkinTube order): the ring grid before stitching
  MeshHealth health;
  bool self_intersects = false;
  bool self_intersection_checked = false;
  int pockets_removed = 0;            ///< inner shells the union enclosed between tubes, dropped
  int crossings_mended = 0;           ///< crossing pairs of the union mended (mend_crossings; -1: it failed)
  bool thumb_turns_slowly = false;    ///< the thumb's tube folded with its planes turning at once, and was made again
  std::vector<Eigen::Vector3d> webs;  ///< the finger webs found (palm end plane goes through them)
  WristCut wrist_cut;                 ///< the plane the palm's first ring lies in
  std::vector<std::string> warnings;
  size_t triangles_before_decimation = 0;
  DataFit data_fit;
  FairUnseen fair_unseen;
  double seconds_rings = 0, seconds_union = 0, seconds_decimation = 0, seconds_fit = 0, seconds_checks = 0;
  /// Closed, manifold, one component, positive volume, and (when checked) no self-intersection.
  bool watertight() const;
};

/// Empty when every joint of the rig's palm (the wrist, each digit's first two) lies within
/// 15 mm of the cloud's bounding box in the rig's hand frame, as build_skin requires; else why
/// not (build_skin's error).
std::string rig_outside_cloud(const std::vector<Eigen::Vector3d>& points, const Rig& rig);

/// build_skin's refusal of the rig for a digit's links beside its sections (or for a palm joint
/// outside the cloud), without building the skin: empty when it would take the rig so far.
std::string digits_off_their_sections(const std::vector<Eigen::Vector3d>& points, const Rig& rig,
                                      const SkinOptions& options);

/// A placed skeleton whose digits' links lie off the middle of their sections (build_skin's
/// refusal: "the thumb's links lie 2.9 mm from the middle of its sections") with those digits'
/// joints beyond their roots (the thumb's MCP, IP and tip; a finger's PIP, DIP and tip) fitted
/// so that the links pass through their sections' middles, three times (each time the points
/// given to the links again); none when no digit is off. `also`: digits (0 the thumb) to fit so
/// whether off or not (those whose tubes folded on a placement). The skin stage's last try for
/// a skeleton it placed itself; a rig given is never moved.
std::optional<Rig> centre_digit_links(const std::vector<Eigen::Vector3d>& points, const Rig& rig,
                                      const SkinOptions& options, const std::vector<int>& also = {});

/// build_skin's error when a tube folds into itself on the rig: the surface cannot be closed
/// there, which says of a placed skeleton what a refusal of it does (the skin stage then
/// tries its other placements).
class TubeFoldsError : public InputError {
 public:
  TubeFoldsError(const std::string& where, const std::string& detail, int tube)
      : InputError(where, detail), tube(tube) {}
  int tube;  ///< the tube that folds (SkinTube: 0 the palm, 1 the thumb, 2-5 the fingers)
};

/// Build the skin from the merged cloud `points` (rig frame, mm, markers removed) and the
/// rig's joints. Throws InputError when the rig does not fit the cloud (joints outside it,
/// the palm not found) or the surface cannot be closed (TubeFoldsError where a tube folds
/// into itself); a missing digit is a warning.
///
/// `beside`, when given, is the caller's work run on a second thread while the first steps
/// (the points to their tubes, the webs, the rings, the tubes' union: ~125 ms on the fixture,
/// which two threads make hardly faster) run on one; the skin stage's check of a given rig,
/// its sections and the run's picture of the merged cloud go there. It is run once, also
/// when those steps throw (their error is the one thrown).
///
/// `accepted`, when given, is called once, on the thread of the first steps, when the rig has
/// passed the check of its links against the digits' sections (before the tubes' union, the
/// longest step, which runs on one thread): the skin stage starts the next placement's skin
/// there, on the second thread.
///
/// Fault injection for tests (docs/architecture.md): HANDSKIN_FAULT=fold:N has the N-th call
/// of the process (counted as they start) find the palm tube folded at its union; fold:all
/// every call.
SkinResult build_skin(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& options,
                      const std::function<void(const std::string&)>& progress = {},
                      const std::function<void()>& beside = {}, const std::function<void()>& accepted = {});

/// skin.ply: binary PLY with per-vertex int properties `bone`, `tube` and `ring`; written
/// through a temporary file. The bone names are in the report (`skin.bones`).
void save_skin_ply(const std::string& path, const SkinResult& skin);

}  // namespace handskin
