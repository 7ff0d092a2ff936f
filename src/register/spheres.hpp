#pragma once
/// Registration, step 2: the replica's spherical markers in one prepared scan — found
/// automatically by Hough voting for sphere centres (each point votes at p − r·n), confirmed
/// by a PCL RANSAC sphere fit and refined by a fixed-radius least-squares fit (Ceres).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "register/prepare.hpp"

namespace handskin {

struct SphereOptions {
  double radius_mm = 4.0;          ///< the markers' radius (known)
  double radius_tolerance = 0.1;   ///< a free-radius fit must land within ± this fraction of it
  double inlier_mm = 0.25;         ///< |distance − r| for a point to belong to the sphere
  double normal_gate_deg = 40.0;   ///< ... and its normal within this of the sphere's
  double steep_floor = 0.3;        ///< fits hold a sphere's height ≥ this × r near its outline (sphere_residual.hpp)
  double max_rms_mm = 0.2;         ///< fit residual above which a bump is not a marker
  long min_points = 10;            ///< fewest samples on a marker cap
  double min_spread_deg = 20.0;    ///< a cap must span this much of the sphere (a flat patch does not)
  long min_votes = 10;             ///< Hough votes (1.5 mm cube) for a candidate
  double min_vote_concentration = 0.5;  ///< share of a 3.5 mm cube's votes in its central 1.5 mm
  double hint_search_mm = 3.0;     ///< manual positions may be off by this much
  bool IsValid(std::string* error) const;
};

struct SphereFit {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< scanner frame, mm
  double radius_free = 0;      ///< radius of an unconstrained fit to the same samples
  double rms_mm = 0;           ///< geometric residual of the fixed-radius fit
  double spread_deg = 0;       ///< largest angle between a sample's direction and the cap's mean
  std::vector<int> inliers;    ///< the centre's samples: indices into PreparedScan::points
  std::vector<int> shell;      ///< the free radius's samples (the distance gate, the visible outline, off the skin)
  bool manual = false;         ///< from a hint file rather than detection
};

struct SphereCandidateReport {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  long votes = 0;
  std::string rejected_because;  ///< empty when accepted
};

/// Every marker-like sphere in the scan, strongest first; at most `max_found` (the strongest:
/// the search stops there, the same as cutting a full list). `candidates` (if given) receives
/// each Hough candidate examined and why it was rejected.
std::vector<SphereFit> detect_spheres(const PreparedScan& scan, const SphereOptions& options,
                                      std::vector<SphereCandidateReport>* candidates = nullptr,
                                      size_t max_found = static_cast<size_t>(-1));

/// Fit a marker sphere near `guess` (a candidate or a manual position). Empty, with the
/// reason in `why`, when the samples there are not a sphere of the marker's radius.
std::optional<SphereFit> fit_sphere_near(const PreparedScan& scan, const Eigen::Vector3d& guess, double search_mm,
                                         const SphereOptions& options, std::string* why);

/// One radius shared by several marker caps, each with its own centre: least squares over
/// every cap's `shell` samples, started at `radius`. A replica's markers share one size, so
/// all their samples together pin it better than the median of the caps' own free fits.
struct SharedRadiusCap {
  const PreparedScan* scan;
  const SphereFit* fit;
};
/// `sd` (if given): the radius's standard deviation from the fit's covariance, the residuals'
/// own scatter standing for the noise.
double fit_shared_radius(const std::vector<SharedRadiusCap>& caps, double radius, double floor, double* sd = nullptr);

}  // namespace handskin
