#pragma once
/// The posture model as a Gaussian (docs/posture.md, "Calibration that generalises"). The
/// thesis's energy ½θᵀKθ + ½(Aθ + b)ᵀW(Aθ + b) is a quadratic form: with some joints pinned its
/// minimum is the conditional mean of a Gaussian of precision K + AᵀWA. Here the mean and the
/// covariance are estimated from recordings with gaps (pairwise-complete statistics, the
/// recordings' own offsets removed), shrunk toward their diagonal, and the precision is
/// written back as springs K plus constraint rows (postural synergies), so the model file and
/// the solver are those of the thesis. A mixture of such Gaussians is the non-linear mode.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "posture/model.hpp"

namespace handskin {

/// Joint angles of several recordings, pooled: one row a frame, one column a measured DOF.
struct PostureSamples {
  std::vector<int> dofs;          ///< DOF index per column
  Eigen::MatrixXd x;              ///< rows × columns, degrees; NaN = not measured in that frame
  std::vector<int> recording;     ///< recording index per row
  int recordings = 1;
  PostureSamples rows(const std::vector<long>& keep) const;
};

struct GaussianStats {
  Eigen::VectorXd mean;           ///< per column: the recordings' means, weighted by their counts
  Eigen::MatrixXd cov;            ///< shrunk, positive definite
  Eigen::MatrixXi pair_counts;    ///< frames that gave both columns
  int floored_eigenvalues = 0;    ///< covariance eigenvalues raised to the floor
};

/// Pairwise-complete covariance about each recording's own mean (`remove_offsets`) or about
/// the pooled mean, shrunk: (1 − shrink)·S + shrink·diag(S); eigenvalues floored at
/// `floor_deg`² so that the precision stays bounded. Column pairs with fewer than `min_pair`
/// common frames get covariance 0.
GaussianStats gaussian_stats(const PostureSamples& s, bool remove_offsets, double shrink, long min_pair = 10,
                             double floor_deg = 0.25);
/// The same in two steps: the moments (EM over the gaps; not shrunk), then the shrinkage —
/// the moments do not depend on it, so a search over shrinkages computes them once.
GaussianStats gaussian_moments(const PostureSamples& s, bool remove_offsets, long min_pair = 10, double floor_deg = 0.25);
GaussianStats shrink_stats(const GaussianStats& moments, double shrink, double floor_deg = 0.25);

/// The energy scale: the precision is multiplied by it so that the median spring of a measured
/// joint is about 1 ("input per degree", as the thesis's K) — raised where needed so that
/// every spring of every covariance given (a mixture's components share one scale) stays at
/// or above the smallest stiffness a model may hold, 1e-3.
double energy_scale_for(const std::vector<Eigen::MatrixXd>& covs);

/// Springs and constraint rows whose sum K + AᵀWA is the scaled precision `scale · cov⁻¹`
/// over `dofs`, and rest angles `mean` (b = −A·mean). Each DOF keeps a spring of half the
/// smallest normalised precision (at most 1e3; the scale keeps it at least 1e-3); the rest,
/// positive semi-definite, is written as its eigen directions, one row each, so that the sum
/// is the precision exactly. Returns the stiffness per column.
std::vector<double> factor_precision(const Eigen::MatrixXd& cov, const Eigen::VectorXd& mean, const std::vector<int>& dofs,
                                     double scale, const std::string& source, std::vector<LinearConstraint>* rows);

/// A mixture of `components` Gaussians fitted by EM (k-means++ start with a fixed seed, full
/// covariances shrunk like the single one). Frames with gaps are completed by the single
/// Gaussian's conditional mean first. EM runs on at most `max_frames` of them (every k-th):
/// a few thousand frames carry a mixture of a few components of a few dozen joints.
/// Returns weights, means and covariances.
struct GaussianMixtureFit {
  std::vector<double> weight;
  std::vector<Eigen::VectorXd> mean;
  std::vector<Eigen::MatrixXd> cov;
  int iterations = 0;
  double log_likelihood = 0;  ///< per frame, at the end
  long imputed_frames = 0;
};
GaussianMixtureFit fit_mixture(const PostureSamples& s, const GaussianStats& single, bool remove_offsets, int components,
                               double shrink, unsigned seed = 1, int max_iterations = 100, double floor_deg = 0.25,
                               long max_frames = 5000);

}  // namespace handskin
