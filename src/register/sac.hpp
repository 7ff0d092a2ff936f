#pragma once
/// PCL's RANSAC (libpcl_sample_consensus) called the way pcl::SACSegmentation calls it, without
/// SACSegmentation itself.
///
/// Why not SACSegmentation: it lives in libpcl_segmentation, which pulls libpcl_features and
/// libpcl_ml in with it. Their ~110 000 symbol relocations (of the program's ~190 000) took
/// ~0.1 s of every handskin process's start on the project's machine, for a wrapper of five
/// calls. The calls below are SACSegmentation::segment's for SAC_RANSAC (PCL 1.12–1.13): the
/// model over every point with PCL's fixed seed (random = false), RANSAC at the threshold with
/// probability 0.99, the iteration cap, serial (threads -1), then optionally the inliers'
/// least-squares refit and the inliers taken again at the refit model. The results are the same
/// bits.
///
/// Nor libpcl_sample_consensus, libpcl_search and libpcl_kdtree: the register library is built
/// with PCL_NO_PRECOMPILE, and the templates it uses (RANSAC, the plane, perpendicular plane
/// and sphere models, PCL's k-d tree search) are made from PCL's own template sources
/// (`pcl/…/impl/*.hpp`) here instead of taken from those libraries. Their ~38 000 symbol
/// relocations, made at every handskin process's start (they are linked to bind at once), took
/// ~12 ms of each start on this project's machine (docs/performance.md, 2026-12-01, fourth
/// session).

#ifndef PCL_NO_PRECOMPILE
#error "the register library is built with PCL_NO_PRECOMPILE (CMakeLists.txt)"
#endif
#include <pcl/point_cloud.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/impl/ransac.hpp>
#include <pcl/sample_consensus/sac_model.h>

#include <Eigen/Core>
#include <memory>

namespace handskin {

struct SacFit {
  pcl::Indices inliers;
  Eigen::VectorXf coefficients;  ///< empty when RANSAC found no model
  bool found() const { return coefficients.size() > 0; }
};

/// RANSAC of `model` (already given its cloud, limits, axis, sample distance): at most
/// `max_iterations` tries, inliers within `threshold`; `optimise`: the inliers' least-squares
/// refit, and its inliers.
template <typename PointT>
SacFit ransac(const typename pcl::SampleConsensusModel<PointT>::Ptr& model, double threshold, int max_iterations,
              bool optimise) {
  SacFit fit;
  pcl::RandomSampleConsensus<PointT> sac(model, threshold);
  sac.setProbability(0.99);
  sac.setMaxIterations(max_iterations);
  sac.setNumberOfThreads(-1);
  if (!sac.computeModel(0)) return fit;
  sac.getInliers(fit.inliers);
  Eigen::VectorXf coefficients(model->getModelSize());
  sac.getModelCoefficients(coefficients);
  if (optimise) {
    Eigen::VectorXf refined(model->getModelSize());
    model->optimizeModelCoefficients(fit.inliers, coefficients, refined);
    model->selectWithinDistance(refined, threshold, fit.inliers);
    coefficients = refined;
  }
  fit.coefficients = coefficients;
  return fit;
}

}  // namespace handskin
