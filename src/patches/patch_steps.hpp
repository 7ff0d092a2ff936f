#pragma once
/// The patch fit's named steps (patches.hpp: fit_patches runs them in order), internal to the
/// patches library:
///   1. start_net           the layout's control net (one point per corner, two per edge, four
///                          inside each face), started on its bilinear faces
///   2. gather_data         the measured points near the skin, thinned for the least squares,
///                          and the polygon skin's samples where the scans saw nothing
///   3. place_data          each datum's first foot point: the nearest sample, then Newton
///                          (foot_points.cpp)
///   4. NetFit::fit         least squares for every control point at once (eq. 4.5; net_fit.cpp)
///   5. correct_parameters  the parameter correction rounds (eqs. 4.6–4.7), refitting with 4;
///                          the round with the lowest RMS is kept
///   6. measure_points      every measured point's foot point on the final surface: the exact
///                          distances
///   7. bind_and_check      each control point's link, and the continuity figures (G0, G1)
#include <Eigen/Core>
#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "mesh/point_grid.hpp"
#include "patches/patches.hpp"

namespace handskin::patch_steps {

/// What a fit kept in place of `from` takes over from it: the layouts tried and the one kept
/// (fit_patch_skin's choices, before any refit). Its skin weight is its own (fit_patches).
inline void carry_fit_choices(PatchSkin* from, PatchSkin* to) {
  to->layout_tries = std::move(from->layout_tries);
  to->layout_try_crossings = std::move(from->layout_try_crossings);
  to->layout_try_folds = std::move(from->layout_try_folds);
  to->thumb_ring_shift = from->thumb_ring_shift;
  to->layout_try_turns = std::move(from->layout_try_turns);
  to->thumb_turn_deg = from->thumb_turn_deg;
  to->crossings_before_fairness = from->crossings_before_fairness;
}

/// The Bernstein basis of degree 3 at t (B), and its derivatives (D, when given).
void bernstein(double t, double B[4], double D[4]);
/// The bone nearest p (index into bones), -1 when there is none.
int nearest_link(const Eigen::Vector3d& p, const std::vector<Bone>& bones);

/// The control net of a layout: one control point per corner, two per edge, four inside each
/// face. Patch f's P(i, j) (i along corner 0 → 1, j along corner 0 → 3) is ids[f][4 i + j].
///
/// At a T-junction (LayoutTopology) the short sides' control points and the hanging corner
/// are not unknowns: each is a fixed combination of the long side's four (de Casteljau at its
/// midpoint), so the short sides' curves are the long side's halves exactly (G0 holds there
/// too). `derived` gives, per control point, those combinations in the unknowns (empty for an
/// unknown). Throws InputError (naming `what`) when they depend on one another in a loop.
struct Net {
  std::vector<std::array<int, 16>> ids;
  int count = 0;
  std::vector<std::vector<std::pair<int, double>>> derived;
};
Net build_net(const PatchLayout& L, const LayoutTopology& T);
/// A cubic's halves by de Casteljau at 1/2: kHalfCurve[h][i][j] is half h's control point i as a
/// combination of the whole curve's control points j.
inline constexpr double kHalfCurve[2][4][4] = {
    {{1, 0, 0, 0}, {0.5, 0.5, 0, 0}, {0.25, 0.5, 0.25, 0}, {0.125, 0.375, 0.375, 0.125}},
    {{0.125, 0.375, 0.375, 0.125}, {0, 0.25, 0.5, 0.25}, {0, 0, 0.5, 0.5}, {0, 0, 0, 1}}};
/// Side s of a patch (from its corner s to corner s + 1): the border's control points in that
/// order, as (i, j), and each one's inner neighbour.
void border(int s, std::array<std::array<int, 2>, 4>* on, std::array<std::array<int, 2>, 4>* in);
/// The parameters of the point a fraction q along side s.
Eigen::Vector2d on_side(int s, double q);

/// A point the surface is fitted to, and its foot point on the surface.
struct Datum {
  Eigen::Vector3d p;
  double w = 1;
  int side = -1;  ///< 0 palm, 1 back; -1 a sample of the polygon skin (weak data)
  bool fit = true;  ///< in the least squares (the measured points are thinned for it)
  int patch = -1;
  double s = 0.5, t = 0.5;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();  ///< the surface's unit normal at the foot point (after the first fit)
};

}  // namespace handskin::patch_steps

namespace handskin {
/// What measuring every point on a fitted surface needs: the layout's topology, which point
/// was fitted as which datum (-1 not fitted, -2 left out), and the data with their last foot
/// points (the measurement's starts).
struct PendingMeasure {
  LayoutTopology topology;
  std::vector<int> in_fit;
  std::vector<patch_steps::Datum> data;
};
}  // namespace handskin

namespace handskin::patch_steps {

/// fit_patches without its last step: the measured points' distances are left to
/// measure_pending (PatchSkin::pending_measure holds what it needs).
PatchSkin fit_patches_unmeasured(const PatchLayout& layout, const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<std::uint32_t>& sides, const std::vector<Eigen::Vector3d>& support,
                                 const std::vector<Bone>& bones, const PatchOptions& options,
                                 const std::vector<std::array<Eigen::Vector3d, 16>>* seed = nullptr,
                                 const std::vector<Separation>& separations = {});
/// The distances of every measured point (the same `points` and `sides` the fit had) on the
/// surface of a fit made by fit_patches_unmeasured; its time is added to the fit's. Nothing
/// to do when it is measured already.
void measure_pending(PatchSkin* s, const std::vector<Eigen::Vector3d>& points, const std::vector<std::uint32_t>& sides);

/// Newton (Gauss–Newton) foot point of d.p on the surface from (d.patch, d.s, d.t), at most
/// `iterations` steps; true when it ends pushing out of its patch still (foot_points.cpp).
bool foot_point(const std::vector<BezierPatch>& P, const LayoutTopology& T, Datum* d, int iterations,
                bool across = true);

// The whole surface sampled on an m × m grid per patch, for the nearest-point search that
// (re)assigns a point to its patch.
struct SurfaceSamples {
  std::vector<Eigen::Vector3d> p;
  std::vector<std::array<float, 3>> at;  ///< patch, s, t
  /// Per patch, how far a point of it can lie from its nearest sample: the largest distance
  /// from a cell's middle to the nearest of its four corners, with a margin (a bicubic cell
  /// bulges little between its corners and middle).
  std::vector<double> cover;
  double widest = 0;  ///< the largest cover
  SurfaceSamples(const std::vector<BezierPatch>& P, int m);
};

/// Place d on the surface: the nearest sample, then Newton in its patch.
void locate_globally(const std::vector<BezierPatch>& P, const LayoutTopology& T, const SurfaceSamples& S,
                     const PointGrid& grid, Datum* d);
/// The nearest foot point over the patches that can hold one nearer than r (foot_points.cpp
/// says why); returns its distance (r when none is nearer).
double nearest_sheet(const std::vector<BezierPatch>& P, const LayoutTopology& T, const SurfaceSamples& S,
                     const PointGrid& grid, Datum* d, double r);

struct NetSolver;
/// The least squares for the whole net (net_fit.cpp), its solver kept from round to round.
class NetFit {
 public:
  NetFit();
  ~NetFit();
  NetFit(const NetFit&) = delete;
  NetFit& operator=(const NetFit&) = delete;
  /// Every control point at once from the data at their foot points (eq. 4.5).
  void fit(PatchSkin* out, const LayoutTopology& T, const std::vector<Datum>& data, const PatchOptions& o);
  /// The last system solved again to full precision (the rounds stop theirs earlier).
  void polish(PatchSkin* out);

 private:
  std::unique_ptr<NetSolver> solver_;
};

/// The finger a patch of the hand's layout belongs to ("index.0.ulnar/v1" → "index"), or ""
/// when it is not one of the four fingers' (the thumb's tube meets the palm, not a finger).
std::string finger_of(const std::string& name);
/// Of c's pairs of crossing patches, those not between two fingers' tubes (fingers pressed
/// together cross there until fit_patch_skin holds their walls apart): a patch of the palm or
/// the thumb in the pair, or two of one finger's. The refinement answers for these while it
/// runs; fit_patch_skin raises the fairness only where they are all there are.
size_t crossings_not_between_fingers(const PatchSkin& s, const PatchCrossings& c);

/// Refinement to a tolerance (refine.cpp): while a patch's measured points lie farther than
/// o.tolerance_mm, the patches that miss are split (balance_cuts, split_layout) and `refit`
/// fits the split layout from its seed; the result and its figures replace *s
/// (PatchSkin::refinement). `finish`, when given, is applied to the refined surface before its
/// crossings are judged (fit_patch_skin: the fingers' tubes held apart).
void refine_to_tolerance(PatchSkin* s, const PatchOptions& o, const std::function<PatchSkin(const LayoutSplit&)>& refit,
                         const std::function<void(PatchSkin*)>& finish = {});

}  // namespace handskin::patch_steps
