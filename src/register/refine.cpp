#include "register/refine.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <flann/flann.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <type_traits>

#include "core/errors.hpp"
#include "register/small_fit.hpp"
#include "register/sphere_residual.hpp"

namespace handskin {

bool RefineOptions::IsValid(std::string* error) const {
  if (!(gate_mm > 0 && gate_mm <= 10)) return invalid(error, "icp gate_mm must be in (0, 10]");
  if (!(normal_deg > 0 && normal_deg <= 90)) return invalid(error, "icp normal_deg must be in (0, 90]");
  if (!(trim > 0 && trim <= 1)) return invalid(error, "icp trim must be in (0, 1]");
  if (max_iterations < 0 || max_iterations > 200) return invalid(error, "icp max_iterations must be in [0, 200]");
  if (min_surface_pairs < 3) return invalid(error, "icp min_surface_pairs must be >= 3");
  if (surface_stride < 1) return invalid(error, "icp surface_stride must be >= 1");
  if (!(max_departure_deg > 0) || !(max_departure_mm > 0)) return invalid(error, "icp max_departure must be > 0");
  return true;
}

void transform_difference(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double* deg, double* mm) {
  const Eigen::Isometry3d d = a * b.inverse();
  *deg = Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI;
  *mm = d.translation().norm();
}

namespace {

struct PointToPlane {
  PointToPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& n) : p_(p), q_(q), n_(n) {}
  template <typename T>
  bool operator()(const T* pose, T* res) const {
    const T p[3] = {T(p_.x()), T(p_.y()), T(p_.z())};
    T x[3];
    ceres::AngleAxisRotatePoint(pose, p, x);
    res[0] = T(n_.x()) * (x[0] + pose[3] - T(q_.x())) + T(n_.y()) * (x[1] + pose[4] - T(q_.y())) +
             T(n_.z()) * (x[2] + pose[5] - T(q_.z()));
    return true;
  }
  Eigen::Vector3d p_, q_, n_;
};

// The joint marker problem's terms: every back sample of marker m (through the pose) and
// every palm sample on one sphere about centres[m].
void add_marker_terms(ceres::Problem* problem, const std::vector<MarkerSamples>& markers, double* pose,
                      std::vector<std::array<double, 3>>* centres, double r, double floor) {
  for (size_t m = 0; m < markers.size(); ++m) {
    double* c = (*centres)[m].data();
    for (const auto& p : markers[m].back) problem->AddResidualBlock(BackOnSphere::Create(p, r, floor), nullptr, pose, c);
    for (const auto& p : markers[m].palm) problem->AddResidualBlock(SphereResidual::Create(p, r, floor), nullptr, c);
  }
}

void to_pose(const Eigen::Isometry3d& T, double pose[6]) {
  const Eigen::Matrix3d R = T.linear();
  ceres::RotationMatrixToAngleAxis(ceres::ColumnMajorAdapter3x3(R.data()), pose);
  for (int k = 0; k < 3; ++k) pose[3 + k] = T.translation()(k);
}

Eigen::Isometry3d from_pose(const double pose[6]) {
  Eigen::Matrix3d R;
  ceres::AngleAxisToRotationMatrix(pose, ceres::ColumnMajorAdapter3x3(R.data()));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = Eigen::Vector3d(pose[3], pose[4], pose[5]);
  return T;
}

ceres::Solver::Options solver_options() {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_SCHUR;  // pose + independent centres: Schur on the centres
  o.max_num_iterations = 30;
  o.function_tolerance = 1e-12;
  o.parameter_tolerance = 1e-12;
  o.logging_type = ceres::SILENT;
  o.num_threads = 1;
  return o;
}

}  // namespace

double marker_sphere_rms(const std::vector<MarkerSamples>& markers, const Eigen::Isometry3d& T, double r, double floor,
                         std::vector<Eigen::Vector3d>* centres) {
  double ss = 0;
  size_t n = 0;
  if (centres) centres->clear();
  double pose[6];
  to_pose(T, pose);
  for (const auto& m : markers) {
    // Start at the samples' mean (the palm cap's own fit is close) and let the solver move it.
    Eigen::Vector3d start = Eigen::Vector3d::Zero();
    for (const auto& p : m.palm) start += p;
    for (const auto& p : m.back) start += T * p;
    start /= static_cast<double>(m.palm.size() + m.back.size());
    double c[3] = {start.x(), start.y(), start.z()};
    // The pose held: one centre's fit, by small_fit (Ceres's steps without a Problem per
    // marker, as the markers' own sphere fits), to Ceres's function tolerance of before.
    std::vector<SphereResidual> palm_parts;
    std::vector<BackOnSphere> back_parts;
    palm_parts.reserve(m.palm.size());
    back_parts.reserve(m.back.size());
    for (const auto& p : m.palm) palm_parts.emplace_back(p, r, floor);
    for (const auto& p : m.back) back_parts.emplace_back(p, r, floor);
    const int n_palm = static_cast<int>(m.palm.size());
    const auto residual = [&](int k, const auto* x, auto* res) {
      using J = std::remove_cv_t<std::remove_pointer_t<decltype(x)>>;  // double or a Jet
      if (k < n_palm) {
        palm_parts[static_cast<size_t>(k)](x, res);
      } else {
        const J held[6] = {J(pose[0]), J(pose[1]), J(pose[2]), J(pose[3]), J(pose[4]), J(pose[5])};
        back_parts[static_cast<size_t>(k - n_palm)](held, x, res);
      }
    };
    const int count = n_palm + static_cast<int>(m.back.size());
    constexpr double kInf = std::numeric_limits<double>::infinity();
    small_fit::Options so;
    so.function_tolerance = 1e-12;
    small_fit::minimise<3>(c, count, residual, {-kInf, -kInf, -kInf}, {kInf, kInf, kInf}, so);
    for (int k = 0; k < count; ++k) {
      double res;
      residual(k, c, &res);
      ss += res * res;
    }
    n += static_cast<size_t>(count);
    if (centres) centres->emplace_back(c[0], c[1], c[2]);
  }
  return n ? std::sqrt(ss / static_cast<double>(n)) : 0.0;
}

PoseCovariance pose_covariance(const std::vector<MarkerSamples>& markers, const Eigen::Isometry3d& T,
                               const std::vector<Eigen::Vector3d>& centres, double r, double floor) {
  HS_CHECK(centres.size() == markers.size(), "one centre per marker");
  PoseCovariance out;
  double pose[6];
  to_pose(T, pose);
  std::vector<std::array<double, 3>> c(centres.size());
  for (size_t m = 0; m < centres.size(); ++m) c[m] = {centres[m].x(), centres[m].y(), centres[m].z()};
  ceres::Problem problem;
  add_marker_terms(&problem, markers, pose, &c, r, floor);
  double C[36];
  if (!residual_scaled_covariance(&problem, pose, 6, C, &out.sigma_mm)) return out;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) out.covariance(i, j) = C[6 * i + j];
  out.valid = out.covariance.allFinite();
  return out;
}

double rotation_sigma_deg(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& C) {
  double pose[6];
  to_pose(T, pose);
  using Jet = ceres::Jet<double, 3>;
  Jet aa[3], R1[9], R0[9], M[9], d[3];
  for (int k = 0; k < 3; ++k) aa[k] = Jet(pose[k], k);
  ceres::AngleAxisToRotationMatrix(aa, ceres::ColumnMajorAdapter3x3(R1));
  const Eigen::Matrix3d R = T.linear();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R0[i + 3 * j] = Jet(R(i, j));
  for (int i = 0; i < 3; ++i)  // M = R1 R0ᵀ, column-major
    for (int j = 0; j < 3; ++j) {
      Jet m(0.0);
      for (int k = 0; k < 3; ++k) m += R1[i + 3 * k] * R0[j + 3 * k];
      M[i + 3 * j] = m;
    }
  ceres::RotationMatrixToAngleAxis(ceres::ColumnMajorAdapter3x3(static_cast<const Jet*>(M)), d);
  Eigen::Matrix3d J;
  for (int k = 0; k < 3; ++k) J.row(k) = d[k].v.transpose();
  return std::sqrt((J * C.topLeftCorner<3, 3>() * J.transpose()).trace()) * 180.0 / M_PI;
}

double displacement_sigma(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& C,
                          const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) return 0;
  double pose[6];
  to_pose(T, pose);
  double sum = 0;
  for (const auto& p : points) {
    // ∂(R(aa) p + t)/∂pose by automatic differentiation on the same rotation as the fit.
    using Jet = ceres::Jet<double, 6>;
    Jet jp[6], x[3], q[3];
    for (int k = 0; k < 6; ++k) jp[k] = Jet(pose[k], k);
    for (int k = 0; k < 3; ++k) x[k] = Jet(p(k));
    ceres::AngleAxisRotatePoint(jp, x, q);
    Eigen::Matrix<double, 3, 6> J;
    for (int k = 0; k < 3; ++k) J.row(k) = (q[k] + jp[3 + k]).v.transpose();
    sum += (J * C * J.transpose()).trace();
  }
  return std::sqrt(sum / static_cast<double>(points.size()));
}

struct GatedNearest::Tree {
  explicit Tree(const flann::Matrix<float>& points) : index(points, flann::KDTreeSingleIndexParams(15)) {}
  flann::KDTreeSingleIndex<flann::L2_Simple<float>> index;
};

GatedNearest::GatedNearest(std::vector<float> points, double gate)
    : points_(std::move(points)), gate2_(static_cast<float>(gate * gate)) {
  HS_CHECK(points_.size() % 3 == 0, "GatedNearest: points are x, y, z rows");
  if (points_.empty()) return;
  tree_ = std::make_unique<Tree>(flann::Matrix<float>(points_.data(), points_.size() / 3, 3));
  tree_->index.buildIndex();
}

GatedNearest::~GatedNearest() = default;

std::vector<int> GatedNearest::find(const std::vector<float>& queries) const {
  HS_CHECK(queries.size() % 3 == 0, "GatedNearest: queries are x, y, z rows");
  const long n = static_cast<long>(queries.size() / 3);
  std::vector<int> out(static_cast<size_t>(n), -1);
  if (!tree_) return out;
#pragma omp parallel
  {
    flann::KNNRadiusResultSet<float> within(gate2_, 1);
    const flann::SearchParams sp(-1, 0.0f, true);
#pragma omp for schedule(static)
    for (long k = 0; k < n; ++k) {
      within.clear();
      tree_->index.findNeighbors(within, &queries[3 * static_cast<size_t>(k)], sp);
      if (within.size() < 1) continue;
      size_t nearest = 0;
      float d2 = 0;
      within.copy(&nearest, &d2, 1, true);
      out[static_cast<size_t>(k)] = static_cast<int>(nearest);
    }
  }
  return out;
}

RefineResult refine_registration(const PreparedScan& back, const PreparedScan& palm, const std::vector<char>& back_skin,
                                 const std::vector<char>& palm_skin, const std::vector<MarkerSamples>& markers,
                                 const Eigen::Isometry3d& T0, double r, double floor, const RefineOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("registration options", err);
  RefineResult out;
  out.T = T0;
  std::vector<Eigen::Vector3d> centres;
  out.marker_rms_start = marker_sphere_rms(markers, T0, r, floor, &centres);

  // Palm skin samples with normals in a k-d tree (GatedNearest), centred for float precision.
  std::vector<int> palm_ids;
  std::vector<float> palm_xyz;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < palm.points.size(); ++k)
    if (palm_skin[k] && palm.has_normal(k)) {
      palm_ids.push_back(static_cast<int>(k));
      origin += palm.points[k];
    }
  std::unique_ptr<GatedNearest> tree;
  if (!palm_ids.empty()) {
    origin /= static_cast<double>(palm_ids.size());
    palm_xyz.reserve(3 * palm_ids.size());
    for (int k : palm_ids) {
      const Eigen::Vector3d d = palm.points[k] - origin;
      for (int c = 0; c < 3; ++c) palm_xyz.push_back(static_cast<float>(d(c)));
    }
    tree = std::make_unique<GatedNearest>(std::move(palm_xyz), o.gate_mm);
  }
  std::vector<int> back_ids;
  for (size_t k = 0; k < back.points.size(); k += o.surface_stride)
    if (back_skin[k] && back.has_normal(k)) back_ids.push_back(static_cast<int>(k));
  out.surface_tried = back_ids.size();

  double pose[6];
  to_pose(T0, pose);
  const double cos_gate = std::cos(o.normal_deg * M_PI / 180.0);
  struct Pair {
    int b, p;
    double res;
  };
  std::vector<Pair> pairs;
  for (int it = 0; it < std::max(1, o.max_iterations); ++it) {
    const Eigen::Isometry3d T = from_pose(pose);
    // --- correspondences: nearest palm skin sample, gated by distance and normal, trimmed ---
    pairs.clear();
    if (!palm_ids.empty() && o.max_iterations > 0) {
      const long n = static_cast<long>(back_ids.size());
      std::vector<Pair> found(back_ids.size(), Pair{-1, -1, 0});
      std::vector<float> query(3 * back_ids.size());
#pragma omp parallel for schedule(static)
      for (long k = 0; k < n; ++k) {
        const Eigen::Vector3d d = T * back.points[back_ids[k]] - origin;
        for (int c = 0; c < 3; ++c) query[3 * k + c] = static_cast<float>(d(c));
      }
      const std::vector<int> nearest = tree->find(query);
#pragma omp parallel for schedule(static)
      for (long k = 0; k < n; ++k) {
        if (nearest[k] < 0) continue;
        const int b = back_ids[k], p = palm_ids[nearest[k]];
        const Eigen::Vector3d nb = T.linear() * back.normals[b];
        if (nb.dot(palm.normals[p]) < cos_gate) continue;
        found[k] = {b, p, std::abs(palm.normals[p].dot(T * back.points[b] - palm.points[p]))};
      }
      for (const auto& f : found)
        if (f.b >= 0) pairs.push_back(f);
      std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
        return a.res != b.res ? a.res < b.res : a.b < b.b;
      });
      pairs.resize(static_cast<size_t>(std::floor(o.trim * static_cast<double>(pairs.size()))));
    }
    const bool use_surface = static_cast<long>(pairs.size()) >= o.min_surface_pairs;
    out.surface_pairs = use_surface ? pairs.size() : 0;
    out.gated_pairs = pairs.size();

    // --- one joint solve: transform + marker centres ---
    ceres::Problem problem;
    std::vector<std::array<double, 3>> c(centres.size());
    for (size_t m = 0; m < centres.size(); ++m) c[m] = {centres[m].x(), centres[m].y(), centres[m].z()};
    add_marker_terms(&problem, markers, pose, &c, r, floor);
    if (use_surface)
      for (const auto& pr : pairs)
        problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PointToPlane, 1, 6>(new PointToPlane(
                                     back.points[pr.b], palm.points[pr.p], palm.normals[pr.p])),
                                 nullptr, pose);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(), &problem, &summary);
    for (size_t m = 0; m < centres.size(); ++m) centres[m] = Eigen::Vector3d(c[m][0], c[m][1], c[m][2]);
    out.iterations = it + 1;

    double deg, mm;
    transform_difference(from_pose(pose), T, &deg, &mm);
    if (!use_surface) {  // nothing to re-pair: the marker solve is final
      out.converged = summary.termination_type == ceres::CONVERGENCE;
      break;
    }
    if (deg < o.converged_deg && mm < o.converged_mm) {
      out.converged = true;
      break;
    }
  }
  out.T = from_pose(pose);
  out.centres = centres;
  if (out.surface_pairs > 0) {
    double ss = 0;
    for (const auto& pr : pairs) {
      const double d = palm.normals[pr.p].dot(out.T * back.points[pr.b] - palm.points[pr.p]);
      ss += d * d;
    }
    out.surface_rms_mm = std::sqrt(ss / static_cast<double>(pairs.size()));
  }
  out.overlap_fraction =
      out.surface_tried ? static_cast<double>(out.surface_pairs) / static_cast<double>(out.surface_tried) : 0.0;
  out.marker_rms_end = marker_sphere_rms(markers, out.T, r, floor, &out.centres);

  // --- guard ---
  double deg, mm;
  transform_difference(out.T, T0, &deg, &mm);
  char buf[256];
  if (!out.T.matrix().allFinite()) {
    out.note = "the refinement diverged";
  } else if (out.marker_rms_end > out.marker_rms_start * 1.01 + 1e-6) {
    std::snprintf(buf, sizeof buf, "the refinement worsened the marker fit (%.4f -> %.4f mm)", out.marker_rms_start,
                  out.marker_rms_end);
    out.note = buf;
  } else if (deg > o.max_departure_deg || mm > o.max_departure_mm) {
    std::snprintf(buf, sizeof buf, "the refinement strayed %.3f deg / %.3f mm from the marker fit (allowed %.3f / %.3f)",
                  deg, mm, o.max_departure_deg, o.max_departure_mm);
    out.note = buf;
  } else {
    out.accepted = true;
    std::snprintf(buf, sizeof buf, "%s after %d round(s); %zu surface pairs", out.converged ? "converged" : "stopped",
                  out.iterations, out.surface_pairs);
    out.note = buf;
  }
  return out;
}

}  // namespace handskin
