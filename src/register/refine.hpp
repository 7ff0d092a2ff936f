#pragma once
/// Registration, step 5: refinement of the marker fit that cannot collapse the hand.
///
/// One least-squares problem (Ceres) over the rigid transform and the matched markers'
/// centres: every back and palm sample of a matched marker must lie on one sphere of the
/// known radius (the markers are the anchors; each sample's depth error in its own scanner's frame), plus point-to-plane ICP terms for back/palm
/// sample pairs that are truly the same surface — within a distance gate, normals agreeing
/// (a top-surface point never pairs with the bottom one across the hand), trimmed. The
/// correspondences are re-found until the transform settles. A guard keeps the marker-only
/// result when the refinement worsens the marker fit or strays beyond it.
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "register/prepare.hpp"

namespace handskin {

struct RefineOptions {
  double gate_mm = 0.5;           ///< ICP pairs farther apart than this are not the same surface
  double normal_deg = 20.0;       ///< ... nor are pairs whose normals differ by more than this
  double trim = 0.9;              ///< keep this fraction of the gated pairs (smallest residuals)
  int max_iterations = 15;        ///< correspondence rounds
  long min_surface_pairs = 200;   ///< fewer gated pairs: the markers alone decide
  int surface_stride = 2;         ///< every n-th back sample is tried for a pair
  double converged_deg = 1e-5;    ///< stop when a round turns the transform less than this
  double converged_mm = 1e-4;     ///< ... and moves it less than this
  double max_departure_deg = 0.2; ///< a refinement this far from the marker-only fit is refused
  double max_departure_mm = 0.5;
  bool IsValid(std::string* error) const;
};

/// The samples of one matched marker in both scans, each in its own scanner frame (where
/// its depth error is measured: sphere_residual.hpp).
struct MarkerSamples {
  std::vector<Eigen::Vector3d> back, palm;
};

/// RMS depth error of all marker samples against one sphere per marker (each centre
/// re-fitted: `centres`, palm frame, if given), the back scan placed by `T`: how well T
/// makes the two caps of every marker one sphere. `floor` as SphereOptions::steep_floor.
double marker_sphere_rms(const std::vector<MarkerSamples>& markers, const Eigen::Isometry3d& T, double radius,
                         double floor, std::vector<Eigen::Vector3d>* centres = nullptr);

/// The marker fit's own estimate of its error: the covariance of the transform (angle-axis,
/// then translation; rad² and mm²) in the joint problem of `marker_sphere_rms` (T and one
/// centre per marker) at `T` and `centres`, (JᵀJ)⁻¹ scaled by the residuals' own variance
/// (their sum of squares over residuals − parameters). Markers only: no skin is seen by both
/// scans (docs/registration.md). `valid` is false when the problem is rank-deficient.
struct PoseCovariance {
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double sigma_mm = 0;  ///< the residuals' standard deviation (depth errors)
  bool valid = false;
};
PoseCovariance pose_covariance(const std::vector<MarkerSamples>& markers, const Eigen::Isometry3d& T,
                               const std::vector<Eigen::Vector3d>& centres, double radius, double floor);

/// RMS rotation angle (1σ, degrees) of the transform's covariance `C`: its angle-axis block
/// carried into the rotation's own tangent space at T (δθ with R(aa + δ) = exp(δθ) R(aa)),
/// where the angle is measured. (Near the turnover's 180°, angle-axis coordinates and
/// angles differ by up to ~10 %.)
double rotation_sigma_deg(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& C);

/// Expected RMS displacement (1σ) of `points` (back frame) mapped by T, for the transform's
/// covariance `C` (as PoseCovariance): √(mean over the points of trace(J C Jᵀ)), J = ∂(T·p)/∂pose.
double displacement_sigma(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& C,
                          const std::vector<Eigen::Vector3d>& points);

/// The nearest of `points` (x, y, z floats, in rows) to a query, if nearer than `gate` (strictly):
/// the ICP's correspondence search. FLANN's single k-d tree of 15 points a leaf, the tree PCL's
/// KdTreeFLANN builds, searched with one result set bounded by the gate per thread: the index
/// PCL's radiusSearch of one neighbour gives (the same leaves in the same order, the first of
/// equal distances), without its ~6 allocations a query. A search bounded so settles a query
/// far from every point at once (a back sample across the hand); unbounded it took 8 times as
/// long. Test: Refine.GatedNearestIsPclsRadiusSearchOfOne.
class GatedNearest {
 public:
  GatedNearest(std::vector<float> points, double gate);
  ~GatedNearest();
  GatedNearest(const GatedNearest&) = delete;
  GatedNearest& operator=(const GatedNearest&) = delete;
  /// Per query (x, y, z floats, in rows), the row of its nearest point within the gate, or -1.
  std::vector<int> find(const std::vector<float>& queries) const;

 private:
  struct Tree;
  std::vector<float> points_;
  std::unique_ptr<Tree> tree_;
  float gate2_;
};

struct RefineResult {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< the refined back_to_palm (use only if accepted)
  int iterations = 0;
  bool converged = false;
  size_t surface_pairs = 0;        ///< gated, trimmed ICP pairs in the last round
  size_t gated_pairs = 0;          ///< pairs that passed the gates (used only if >= min_surface_pairs)
  size_t surface_tried = 0;        ///< back samples tried for a pair
  double overlap_fraction = 0;     ///< surface_pairs / surface_tried
  double surface_rms_mm = 0;       ///< point-to-plane RMS of those pairs
  double marker_rms_start = 0;     ///< marker_sphere_rms at the marker-only transform
  double marker_rms_end = 0;       ///< ... at the refined transform
  std::vector<Eigen::Vector3d> centres;  ///< joint sphere centres, palm frame
  bool accepted = false;           ///< false: the guard kept the marker-only result
  std::string note;                ///< why it was refused, or how it ended
};

/// `back_skin` / `palm_skin`: which prepared samples are skin (not marker) and may pair.
RefineResult refine_registration(const PreparedScan& back, const PreparedScan& palm,
                                 const std::vector<char>& back_skin, const std::vector<char>& palm_skin,
                                 const std::vector<MarkerSamples>& markers, const Eigen::Isometry3d& T0,
                                 double radius, double floor, const RefineOptions& options);

/// Rotation angle (deg) and translation (mm) of a ∘ b⁻¹.
void transform_difference(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double* deg, double* mm);

}  // namespace handskin
