#include "register/prepare.hpp"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/sac_model_perpendicular_plane.h>
#include <pcl/sample_consensus/impl/sac_model_plane.hpp>
#include <pcl/sample_consensus/impl/sac_model_perpendicular_plane.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "register/sac.hpp"

namespace handskin {

bool PrepareOptions::IsValid(std::string* error) const {
  if (!(table_margin_mm >= 0 && table_margin_mm <= 20)) return invalid(error, "table_margin_mm must be in [0, 20]");
  if (!(table_max_tilt_deg > 0 && table_max_tilt_deg <= 45)) return invalid(error, "table_max_tilt_deg must be in (0, 45]");
  if (!(table_inlier_mm > 0 && table_inlier_mm <= 10)) return invalid(error, "table_inlier_mm must be in (0, 10]");
  if (min_component_points < 1) return invalid(error, "min_component_points must be >= 1");
  if (normal_window < 1 || normal_window > 5) return invalid(error, "normal_window must be in [1, 5]");
  return true;
}

namespace {

// Least-squares plane (PCA) through the points `each` visits, normal oriented upward. `each(f)`
// calls f(p) for every point, in the same order each time: the mean, then the covariance about
// it, in two passes over the scan. (The table's points were copied out first; that copy,
// ~190 000 points grown by doubling, twice a scan, was a fresh process's largest cost of
// preparing a scan: 18–30 ms of its ~55, its pages new to the process. The sums are the same,
// in the same order.)
template <class Visit>
Eigen::Vector4d fit_plane(const Visit& each, double* rms) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  size_t count = 0;
  each([&](const Eigen::Vector3d& p) {
    mean += p;
    ++count;
  });
  mean /= static_cast<double>(count);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  each([&](const Eigen::Vector3d& p) { cov += (p - mean) * (p - mean).transpose(); });
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.z() < 0) n = -n;
  *rms = std::sqrt(std::max(0.0, es.eigenvalues()(0)) / static_cast<double>(count));
  return {n.x(), n.y(), n.z(), -n.dot(mean)};
}

}  // namespace

PreparedScan prepare_scan(const RangeScan& scan, const PrepareOptions& o, const std::string& file) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("registration options", err);
  PreparedScan s;
  s.side = scan.meta.side;
  s.rows = scan.meta.scanlines;
  s.cols = scan.meta.points;
  s.x_origin = scan.meta.x_origin_mm;
  s.y_origin = scan.meta.y_origin_mm;
  s.x_step = scan.meta.x_step_mm;
  s.y_step = scan.meta.y_step_mm;
  s.z_step = scan.meta.z_step_mm;
  const size_t npix = static_cast<size_t>(s.rows) * s.cols;
  s.returns = scan.count_valid();

  // --- table plane: PCL RANSAC (plane perpendicular to the scanner's Z within the tilt bound)
  // on every 4th return, then a least-squares refit on all returns near it. The table fills
  // most of the field, so it is the dominant plane; the fixed RANSAC seed makes it repeatable.
  pcl::PointCloud<pcl::PointXYZ>::Ptr sub(new pcl::PointCloud<pcl::PointXYZ>);
  sub->reserve(s.returns / 4 + 1);
  size_t k = 0;
  for (int i = 0; i < s.rows; ++i)
    for (int j = 0; j < s.cols; ++j)
      if (scan.valid(i, j) && (k++ % 4) == 0) {
        const Eigen::Vector3d p = scan.position(i, j);
        sub->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
      }
  if (sub->size() < 100) throw InputError(file, "too few returns (" + std::to_string(s.returns) + ") to find the table");
  // RANSAC in coordinates centred on the subsample's mean: PCL works in float, and this keeps
  // the plane's offset small so its rounding stays far below the scanner's depth step.
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  for (const auto& p : *sub) centre += p.getVector3fMap();
  centre /= static_cast<float>(sub->size());
  for (auto& p : *sub) p.getVector3fMap() -= centre;
  auto model = std::make_shared<pcl::SampleConsensusModelPerpendicularPlane<pcl::PointXYZ>>(sub, false);
  model->setAxis(Eigen::Vector3f::UnitZ());
  model->setEpsAngle(static_cast<float>(o.table_max_tilt_deg * M_PI / 180.0));  // as float, as before
  const SacFit table = ransac<pcl::PointXYZ>(model, o.table_inlier_mm, 300, false);
  const Eigen::VectorXf& coeff = table.coefficients;
  if (coeff.size() != 4 || table.inliers.size() < sub->size() / 10)
    throw InputError(file, "no table plane found (a plane within " + std::to_string(o.table_max_tilt_deg) +
                               " deg of level must hold at least 10% of the returns)");
  Eigen::Vector3d n(coeff[0], coeff[1], coeff[2]);
  double d = coeff[3] / n.norm();
  n.normalize();
  d -= n.dot(centre.cast<double>());
  const auto near_table = [&](const auto& f) {  // the returns within the inlier distance of (n, d)
    for (int i = 0; i < s.rows; ++i)
      for (int j = 0; j < s.cols; ++j)
        if (scan.valid(i, j)) {
          const Eigen::Vector3d p = scan.position(i, j);
          if (std::abs(n.dot(p) + d) < o.table_inlier_mm) f(p);
        }
  };
  for (int round = 0; round < 2; ++round) {
    const Eigen::Vector4d pl = fit_plane(near_table, &s.table_rms_mm);
    n = pl.head<3>();
    d = pl(3);
  }
  s.table_plane << n, d;
  s.table_tilt_deg = std::acos(std::min(1.0, n.z())) * 180.0 / M_PI;

  // --- keep what stands above the table by more than the margin ---
  std::vector<char> keep(npix, 0);
  for (int i = 0; i < s.rows; ++i)
    for (int j = 0; j < s.cols; ++j) {
      if (!scan.valid(i, j)) continue;
      const double h = n.dot(scan.position(i, j)) + d;
      if (h < -3 * o.table_inlier_mm) ++s.below_table;
      else if (h <= o.table_margin_mm) ++s.table_points;
      else keep[static_cast<size_t>(i) * s.cols + j] = 1;
    }

  // --- speckle: 8-connected islands of kept pixels smaller than the minimum. A flood fill on
  // the scan grid is linear in the pixels; a k-d tree Euclidean clustering would give the
  // same islands for a height field at several times the cost.
  std::vector<int> comp(npix, -1);
  std::vector<int> stack;
  std::vector<int> members;
  for (size_t p0 = 0; p0 < npix; ++p0) {
    if (!keep[p0] || comp[p0] >= 0) continue;
    members.clear();
    stack.assign(1, static_cast<int>(p0));
    comp[p0] = static_cast<int>(p0);
    while (!stack.empty()) {
      const int p = stack.back();
      stack.pop_back();
      members.push_back(p);
      const int i = p / s.cols, j = p % s.cols;
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const int ii = i + di, jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= s.rows || jj >= s.cols) continue;
          const size_t q = static_cast<size_t>(ii) * s.cols + jj;
          if (keep[q] && comp[q] < 0) {
            comp[q] = static_cast<int>(p0);
            stack.push_back(static_cast<int>(q));
          }
        }
    }
    if (static_cast<long>(members.size()) < o.min_component_points) {
      ++s.speckle_islands;
      s.speckle_points += members.size();
      for (int p : members) keep[p] = 0;
    }
  }

  s.point_of_pixel.assign(npix, -1);
  const size_t kept = static_cast<size_t>(std::count(keep.begin(), keep.end(), 1));
  s.points.reserve(kept);
  s.pixel.reserve(kept);
  for (int i = 0; i < s.rows; ++i)
    for (int j = 0; j < s.cols; ++j) {
      const size_t p = static_cast<size_t>(i) * s.cols + j;
      if (!keep[p]) continue;
      s.point_of_pixel[p] = static_cast<int>(s.points.size());
      s.points.push_back(scan.position(i, j));
      s.pixel.push_back(static_cast<int>(p));
    }
  if (s.points.size() < 100)
    throw InputError(file, "only " + std::to_string(s.points.size()) +
                               " returns stand above the table: no object in this scan");
  height_field_normals(&s, o.normal_window, 4.0 * std::max(s.x_step, s.y_step) * o.normal_window);
  return s;
}

void height_field_normals(PreparedScan* s, int w, double max_step_mm) {
  // The scan is a height field z(x, y) on a regular grid, so a plane fit over a pixel window
  // gives the normal directly; this is exact to first order on a symmetric window and costs a
  // few ms, where PCL's k-d-tree NormalEstimation on the same points costs ~100 ms.
  s->normals.assign(s->points.size(), Eigen::Vector3d::Zero());
  const int min_count = (2 * w + 1) * (2 * w + 1) / 2 + 1;
#pragma omp parallel for schedule(static)
  for (long k = 0; k < static_cast<long>(s->points.size()); ++k) {
    const int i0 = s->pixel[k] / s->cols, j0 = s->pixel[k] % s->cols;
    const Eigen::Vector3d& c = s->points[k];
    // The normal equations of the plane z = a + b x + c y through the window: Σ r rᵀ and Σ r z
    // for r = (1, x, y), their six distinct sums kept as scalars (the same sums, in the same
    // order, as Eigen's 3 × 3 outer products, in half the time).
    double a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, b0 = 0, b1 = 0, b2 = 0;
    int count = 0;
    for (int i = std::max(0, i0 - w); i <= std::min(s->rows - 1, i0 + w); ++i) {
      const int* row_points = &s->point_of_pixel[static_cast<size_t>(i) * s->cols];
      for (int j = std::max(0, j0 - w); j <= std::min(s->cols - 1, j0 + w); ++j) {
        const int q = row_points[j];
        if (q < 0) continue;
        const Eigen::Vector3d& p = s->points[q];
        const double dx = p.x() - c.x(), dy = p.y() - c.y(), dz = p.z() - c.z();
        if (std::abs(dz) > max_step_mm) continue;
        a01 += dx, a02 += dy, a11 += dx * dx, a12 += dx * dy, a22 += dy * dy;
        b0 += dz, b1 += dx * dz, b2 += dy * dz;
        ++count;
      }
    }
    if (count < min_count) continue;
    Eigen::Matrix3d A;
    A << count, a01, a02, a01, a11, a12, a02, a12, a22;
    const Eigen::Vector3d b(b0, b1, b2);
    const Eigen::Vector3d abc = A.ldlt().solve(b);
    if (!abc.allFinite()) continue;
    s->normals[k] = Eigen::Vector3d(-abc(1), -abc(2), 1.0).normalized();
  }
}

}  // namespace handskin
