#include "register/cloud_prep.hpp"

#include <pcl/sample_consensus/sac_model_plane.h>
#include <pcl/sample_consensus/impl/sac_model_plane.hpp>
#include <pcl/search/kdtree.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <unordered_map>

#include "core/errors.hpp"
#include "mesh/point_grid.hpp"
#include "register/sac.hpp"
#include "scan/cloud.hpp"
#include "scan/pcl_module.hpp"
#include "scan/cloud_file.hpp"

namespace handskin {

bool CloudPrepOptions::IsValid(std::string* e) const {
  if (!(voxel_mm >= 0 && voxel_mm <= 5)) return invalid(e, "cloud.voxel_mm must be in [0, 5]");
  if (outlier_neighbours < 1 || outlier_neighbours > 200) return invalid(e, "cloud.outlier_neighbours must be in [1, 200]");
  if (!(outlier_radius_mm > 0 && outlier_radius_mm <= 20)) return invalid(e, "cloud.outlier_radius_mm must be in (0, 20]");
  if (!(support_inlier_mm > 0)) return invalid(e, "cloud.support_inlier_mm must be > 0");
  if (!(support_min_share > 0 && support_min_share < 1)) return invalid(e, "cloud.support_min_share must be in (0, 1)");
  if (!(support_clear_mm > 0)) return invalid(e, "cloud.support_clear_mm must be > 0");
  if (!(part_gap_mm >= 0)) return invalid(e, "cloud.part_gap_mm must be >= 0");
  if (!(min_hand_mm > 0 && max_hand_mm > min_hand_mm)) return invalid(e, "cloud.min_hand_mm must be > 0 and < cloud.max_hand_mm");
  if (min_points < 100) return invalid(e, "cloud.min_points must be >= 100");
  if (!(normal_radius_mm > 0 && normal_radius_mm <= 10)) return invalid(e, "cloud.normal_radius_mm must be in (0, 10]");
  return true;
}

namespace {

using PclCloud = pcl::PointCloud<pcl::PointXYZ>;

// The points as a PCL cloud about their centroid (PCL works in float; centred, a hand's
// coordinates keep 1e-5 mm).
PclCloud::Ptr to_pcl(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& c) {
  auto cloud = std::make_shared<PclCloud>();
  cloud->resize(pts.size());
  for (size_t k = 0; k < pts.size(); ++k) (*cloud)[k].getVector3fMap() = (pts[k] - c).cast<float>();
  return cloud;
}

Eigen::Vector3d centroid(const std::vector<Eigen::Vector3d>& pts) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : pts) c += p;
  return pts.empty() ? c : Eigen::Vector3d(c / static_cast<double>(pts.size()));
}

// 2. A voxel grid: every voxel's points (and normals, when there is one per point) averaged
// into one (PCL VoxelGrid, in handskin's PCL module), worked in float about their centroid.
void voxel_downsample(std::vector<Eigen::Vector3d>* pts, std::vector<Eigen::Vector3d>* nrm, double voxel) {
  const Eigen::Vector3d c = centroid(*pts);
  const float leaf = static_cast<float>(voxel);
  if (nrm->size() != pts->size()) {  // points only: the smaller point type is the faster grid
    const PclCloud::Ptr cloud = to_pcl(*pts, c);
    const PclCloud out = voxel_grid(cloud, leaf, "run --cloud (voxel grid)");
    pts->clear();
    for (const auto& q : out) pts->push_back(q.getVector3fMap().cast<double>() + c);
    return;
  }
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  cloud->resize(pts->size());
  for (size_t k = 0; k < pts->size(); ++k) {
    (*cloud)[k].getVector3fMap() = ((*pts)[k] - c).cast<float>();
    (*cloud)[k].getNormalVector3fMap() = (*nrm)[k].cast<float>();
  }
  const pcl::PointCloud<pcl::PointNormal> out = voxel_grid(cloud, leaf, "run --cloud (voxel grid)");
  pts->clear();
  nrm->clear();
  for (const auto& q : out) {
    pts->push_back(q.getVector3fMap().cast<double>() + c);
    nrm->push_back(q.getNormalVector3fMap().cast<double>().normalized());
  }
}

// A cloud's centroid, principal axes (columns, largest spread first, right-handed) and its
// extents along them between the `q` and 1 − `q` quantiles.
struct PrincipalFrame {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
};
PrincipalFrame principal_frame_of(const std::vector<Eigen::Vector3d>& pts, double q = 0) {
  PrincipalFrame f;
  f.centroid = centroid(pts);
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) C += (p - f.centroid) * (p - f.centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  for (int k = 0; k < 3; ++k) f.axes.col(k) = es.eigenvectors().col(2 - k);
  if (f.axes.determinant() < 0) f.axes.col(2) *= -1;
  std::vector<double> t(pts.size());
  for (int a = 0; a < 3 && !pts.empty(); ++a) {
    for (size_t k = 0; k < pts.size(); ++k) t[k] = f.axes.col(a).dot(pts[k] - f.centroid);
    const size_t lo = static_cast<size_t>(q * static_cast<double>(t.size() - 1)), hi = t.size() - 1 - lo;
    std::nth_element(t.begin(), t.begin() + static_cast<long>(lo), t.end());
    const double tl = t[lo];
    std::nth_element(t.begin(), t.begin() + static_cast<long>(hi), t.end());
    f.extent(a) = t[hi] - tl;
  }
  return f;
}

std::string mm_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, v < 10 ? "%.3g" : "%.0f", v);
  return b;
}

// 1. The cloud's robust extent (2nd–98th percentile along its long axis) must be a hand's
// at the given units, within a factor for a stand or stray points around it.
void check_scale(const std::vector<Eigen::Vector3d>& pts, const std::string& file, const std::string& units,
                 const CloudPrepOptions& o) {
  const double len = principal_frame_of(pts, 0.02).extent(0);
  if (len >= o.min_hand_mm * 0.5 && len <= o.max_hand_mm * 10) return;
  std::string hint;
  const double given = millimetres_per(parse_length_unit(units).value_or(LengthUnit::Millimetre));
  for (const char* u : {"mm", "cm", "m", "in"}) {
    const double l = len * millimetres_per(*parse_length_unit(u)) / given;
    if (l >= o.min_hand_mm && l <= o.max_hand_mm) hint = "; at --units " + std::string(u) + " it would be " + mm_text(l) + " mm";
  }
  throw InputError(file, "the cloud is " + mm_text(len) + " mm long at --units " + units + ": not a hand (" +
                             mm_text(o.min_hand_mm) + "–" + mm_text(o.max_hand_mm) + " mm)" + hint);
}

std::vector<size_t> keep_indices(const std::vector<size_t>& from, const std::vector<int>& picked) {
  std::vector<size_t> out;
  out.reserve(picked.size());
  for (int i : picked) out.push_back(from[static_cast<size_t>(i)]);
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Eigen::Vector3d> gather(const std::vector<Eigen::Vector3d>& v, const std::vector<size_t>& idx) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(idx.size());
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

// 3. Outliers: points with fewer than `outlier_neighbours` others within `outlier_radius_mm`
// (PCL's RadiusOutlierRemoval's rule). Counted in the project's hash grid (mesh/point_grid.hpp)
// rather than with PCL's filter: its k-d tree made this step 0.6 s on 140 000 points.
std::vector<size_t> drop_outliers(const std::vector<Eigen::Vector3d>& pts, const std::vector<size_t>& idx,
                                  const CloudPrepOptions& o) {
  const auto sub = gather(pts, idx);
  const PointGrid grid(sub, o.outlier_radius_mm);
  std::vector<char> keep(sub.size(), 0);
#pragma omp parallel for schedule(static, 1024)
  for (long k = 0; k < static_cast<long>(sub.size()); ++k) {
    int n = -1;  // itself
    grid.within(sub[static_cast<size_t>(k)], o.outlier_radius_mm, [&](int) { ++n; });
    keep[static_cast<size_t>(k)] = n >= o.outlier_neighbours;
  }
  std::vector<size_t> out;
  for (size_t k = 0; k < sub.size(); ++k)
    if (keep[k]) out.push_back(idx[k]);
  return out;
}

// The dominant plane of `few` by RANSAC, each try's three points drawn within 15 mm of each
// other (PCL's samples-max-dist): a try then lands on a plane holding a share s of the points
// with a chance near s, not s³, so 1000 tries find a 2 % support with near certainty.
std::optional<Eigen::Vector4f> dominant_plane(const PclCloud::Ptr& few, double inlier_mm) {
  if (few->size() < 50) return std::nullopt;
  auto search = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  search->setInputCloud(few);
  auto model = std::make_shared<pcl::SampleConsensusModelPlane<pcl::PointXYZ>>(few, false);
  model->setSamplesMaxDist(15.0, search);
  const SacFit fit = ransac<pcl::PointXYZ>(model, inlier_mm, 1000, true);
  if (fit.coefficients.size() != 4) return std::nullopt;
  const Eigen::Vector4f plane = fit.coefficients.head<4>();
  return plane / plane.head<3>().norm();
}

// The plane's inlier band (support_inlier_mm each side) also holds the hand's last millimetre
// where it stands on the support or ends just above it, which went with the support. A band
// point is given back to the hand when it lies outside the support's own noise — 2.5 robust
// sigmas (1.4826 × the median absolute residual of the band's points about their median), at
// least kMinBandMm — and within kNearHandMm of a point beyond the band (the hand's flank goes
// on above it). The second condition keeps the support's own noise tail out: without it, tail
// points 2-4 mm beside the wrist joined the hand through the parts' gap, drew the skin's wrist
// rim out onto the stand and failed the cloud->skin largest-distance gate (H02 of the cloud
// study). A band point's normal cannot tell the flank from the support: within a normal's
// radius of the flank's last points lies the support, whose many points decide the fit.
constexpr double kBandSigmas = 2.5, kMinBandMm = 0.2, kNearHandMm = 1.0;
void give_back_hand_end(const std::vector<Eigen::Vector3d>& sub, const std::vector<Eigen::Vector3d>& off,
                        const Eigen::Vector4d& plane, std::vector<char>* on) {
  const Eigen::Vector3d n = plane.head<3>();
  const double d = plane(3);
  std::vector<double> r;
  for (size_t k = 0; k < sub.size(); ++k)
    if ((*on)[k]) r.push_back(n.dot(sub[k]) + d);
  if (r.size() < 50) return;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  const double med = r[r.size() / 2];
  for (double& x : r) x = std::abs(x - med);
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  const double band = std::max(kBandSigmas * 1.4826 * r[r.size() / 2], kMinBandMm);
  const PointGrid hand(off, kNearHandMm);
  for (size_t k = 0; k < sub.size(); ++k)
    if ((*on)[k] && std::abs(n.dot(sub[k]) + d - med) > band && hand.any_within(sub[k], kNearHandMm)) (*on)[k] = 0;
}

// The spread of q's neighbours within `radius` (q among them): their count, mean offset from q
// and covariance (estimate_noise_mm, estimate_normals).
struct NeighbourSpread {
  int n = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
};
NeighbourSpread neighbour_spread(const PointGrid& grid, const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& q,
                                 double radius) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  Eigen::Matrix3d ss = Eigen::Matrix3d::Zero();
  NeighbourSpread r;
  grid.within(q, radius, [&](int j) {
    const Eigen::Vector3d d = pts[static_cast<size_t>(j)] - q;
    s += d, ss += d * d.transpose(), ++r.n;
  });
  if (r.n == 0) return r;
  r.mean = s / r.n;
  r.C = ss / r.n - r.mean * r.mean.transpose();
  return r;
}

// The points' noise: over an even subsample, each point's neighbours within kNoiseRadiusMm fitted
// by a plane, the root of the least eigenvalue of their spread (a plane's noise along its
// normal; on a finger of 8 mm radius the curvature adds ~0.07 mm), the median of those.
constexpr double kNoiseRadiusMm = 2.0;
double estimate_noise_mm(const std::vector<Eigen::Vector3d>& pts) {
  const PointGrid grid(pts, kNoiseRadiusMm);
  const size_t step = std::max<size_t>(1, pts.size() / 3000);
  std::vector<double> sigma;
  for (size_t k = 0; k < pts.size(); k += step) {
    const NeighbourSpread sp = neighbour_spread(grid, pts, pts[k], kNoiseRadiusMm);
    if (sp.n < 12) continue;
    sigma.push_back(std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sp.C, Eigen::EigenvaluesOnly).eigenvalues()(0))));
  }
  if (sigma.empty()) return 0;
  std::nth_element(sigma.begin(), sigma.begin() + static_cast<long>(sigma.size() / 2), sigma.end());
  return sigma[sigma.size() / 2];
}

// 4. The support: a plane that holds a share of the points, most of them clear of every point
// off it (a hand's own flat stretches — a flat palm, the back — are surrounded by the rest of
// the hand). The dominant plane may be the hand's own (a flat hand's palm holds more points
// than a small stand): then the next plane of what is left is tried, up to four.
std::vector<size_t> drop_support(const std::vector<Eigen::Vector3d>& pts, const std::vector<size_t>& idx,
                                 const CloudPrepOptions& o, PreparedCloud* r) {
  const auto sub = gather(pts, idx);
  const Eigen::Vector3d c = centroid(sub);
  const PclCloud::Ptr cloud = to_pcl(sub, c);
  // The plane's band: support_inlier_mm, or kSupportSigmas of the points' own noise where that
  // is wider. A depth camera's σ ≈ 1.2 mm (synth cloud --noise 1.2) spread the stand's points
  // over ±3.6 mm: within a 1 mm band a third of them lay off the plane beside the rest, no
  // plane was clear of the hand, and the stand stayed in the cloud and the skin (37 mm from
  // the true one). 3.5 σ leaves ~1 point in 2000 of a noisy stand outside its band.
  constexpr double kSupportSigmas = 3.5;
  r->noise_mm = estimate_noise_mm(sub);
  const double band = std::max(o.support_inlier_mm, kSupportSigmas * r->noise_mm);
  r->support_band_mm = band;
  const auto near = [&](const Eigen::Vector4f& plane, const pcl::PointXYZ& q) {
    return std::abs(plane.head<3>().dot(q.getVector3fMap()) + plane(3)) <= band;
  };
  // RANSAC on an even subsample of at most 5000 points; then every point near the plane is on it.
  const size_t stride = std::max<size_t>(1, sub.size() / 5000);
  auto few = std::make_shared<PclCloud>();
  for (size_t k = 0; k < sub.size(); k += stride) few->push_back((*cloud)[k]);
  for (int round = 0; round < 4; ++round) {
    const auto plane = dominant_plane(few, band);
    if (!plane) return idx;
    std::vector<char> on(sub.size(), 0);
    std::vector<size_t> inliers;
    for (size_t k = 0; k < sub.size(); ++k)
      if (near(*plane, (*cloud)[k])) on[k] = 1, inliers.push_back(k);
    if (inliers.size() < o.support_min_share * sub.size()) return idx;  // the next would hold fewer still
    std::vector<Eigen::Vector3d> off;
    for (size_t k = 0; k < sub.size(); ++k)
      if (!on[k]) off.push_back(sub[k]);
    size_t clear = 0, tried = 0;
    const PointGrid off_grid(off, o.support_clear_mm);
    const size_t step = std::max<size_t>(1, inliers.size() / 2000);
    for (size_t k = 0; k < inliers.size(); k += step, ++tried) clear += !off_grid.any_within(sub[inliers[k]], o.support_clear_mm);
    if (2 * clear >= tried) {
      r->support_found = true;
      const Eigen::Vector3d n = plane->head<3>().cast<double>();
      r->support_plane << n, static_cast<double>((*plane)(3)) - n.dot(c);
      give_back_hand_end(sub, off, r->support_plane, &on);
      std::vector<int> kept;
      for (size_t k = 0; k < sub.size(); ++k)
        if (!on[k]) kept.push_back(static_cast<int>(k));
      r->support = sub.size() - kept.size();
      return keep_indices(idx, kept);
    }
    auto rest = std::make_shared<PclCloud>();  // the hand's own plane: look past it
    for (const auto& q : *few)
      if (!near(*plane, q)) rest->push_back(q);
    few = rest;
  }
  return idx;
}

// Median distance to the nearest other point, over an even subsample.
double median_spacing(const std::vector<Eigen::Vector3d>& pts, double cell) {
  const PointGrid grid(pts, cell);
  std::vector<double> d;
  const size_t step = std::max<size_t>(1, pts.size() / 5000);
  for (size_t k = 0; k < pts.size(); k += step) {
    double best = 1e300;
    grid.within(pts[k], 4 * cell, [&](int j) {
      if (static_cast<size_t>(j) != k) best = std::min(best, (pts[static_cast<size_t>(j)] - pts[k]).squaredNorm());
    });
    if (best < 1e300) d.push_back(std::sqrt(best));
  }
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

int find_root(std::vector<int>& parent, int k) {
  while (parent[k] != k) k = parent[k] = parent[parent[k]];
  return k;
}

// 5. The hand as the largest connected part: occupied cells of half the gap joined to the
// occupied cells around them (union-find), so points nearer than half the gap always share a
// part and points farther apart than 1.75 gaps never touch through one pair of cells. Written
// here: PCL's EuclideanClusterExtraction (exact, with its k-d tree) took 0.6 s on 140 000
// points, this 20 ms. Ties between parts: the one holding the lowest index.
std::vector<size_t> keep_largest_part(const std::vector<Eigen::Vector3d>& pts, const std::vector<size_t>& idx,
                                      const CloudPrepOptions& o, PreparedCloud* r) {
  const auto sub = gather(pts, idx);
  // After a voxel grid the points lie about a voxel apart; else it is measured.
  r->spacing_mm = o.voxel_mm > 0 ? o.voxel_mm : median_spacing(sub, 0.25);
  r->part_gap_mm = o.part_gap_mm > 0 ? o.part_gap_mm : std::max(1.5, 4 * r->spacing_mm);
  const double cell = 0.5 * r->part_gap_mm;
  const auto key = [](long x, long y, long z) {
    return (static_cast<std::int64_t>(x & 0x1FFFFF) << 42) | (static_cast<std::int64_t>(y & 0x1FFFFF) << 21) |
           static_cast<std::int64_t>(z & 0x1FFFFF);
  };
  std::unordered_map<std::int64_t, int> cell_id;
  std::vector<Eigen::Vector3i> cells;
  std::vector<int> cell_of(sub.size());
  for (size_t k = 0; k < sub.size(); ++k) {
    const Eigen::Vector3i c((sub[k] / cell).array().floor().cast<int>());
    const auto [it, fresh] = cell_id.emplace(key(c.x(), c.y(), c.z()), static_cast<int>(cells.size()));
    if (fresh) cells.push_back(c);
    cell_of[k] = it->second;
  }
  std::vector<int> parent(cells.size());
  for (size_t k = 0; k < cells.size(); ++k) parent[k] = static_cast<int>(k);
  for (size_t k = 0; k < cells.size(); ++k)
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cell_id.find(key(cells[k].x() + dx, cells[k].y() + dy, cells[k].z() + dz));
          if (it == cell_id.end()) continue;
          const int a = find_root(parent, static_cast<int>(k)), b = find_root(parent, it->second);
          if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
  std::vector<size_t> size(cells.size(), 0);
  for (size_t k = 0; k < sub.size(); ++k) ++size[static_cast<size_t>(find_root(parent, cell_of[k]))];
  int best = 0;
  r->parts = 0;
  for (size_t c = 0; c < cells.size(); ++c) {
    r->parts += size[c] > 0;
    if (size[c] > size[static_cast<size_t>(best)]) best = static_cast<int>(c);
  }
  std::vector<size_t> out;
  for (size_t k = 0; k < sub.size(); ++k)
    if (find_root(parent, cell_of[k]) == best) out.push_back(idx[k]);
  r->other_parts = sub.size() - out.size();
  return out;
}

// 7. Normals: the least-spread axis of the points within `radius` (at least 6 of them;
// else zero), unoriented (label_sides turns them). With `smoothed` (a copy of the points),
// each point there moves onto
// that local plane through its neighbours' mean (one planar moving-least-squares step): the
// scanner's noise along the rays averaged over ~25 neighbours, at the price of a bias of about
// radius² / (4 × curvature radius) inward on curved skin (0.05 mm for a 1.2 mm radius on an
// 8 mm finger). Where the neighbourhood is not flat (the plane's spread over a third of the
// next axis's — an edge, a gap between touching fingers) the point stays. In the hash grid for
// the reason above.
std::vector<Eigen::Vector3d> estimate_normals(const std::vector<Eigen::Vector3d>& pts, double radius,
                                              std::vector<Eigen::Vector3d>* smoothed) {
  const PointGrid grid(pts, radius);
  std::vector<Eigen::Vector3d> out(pts.size(), Eigen::Vector3d::Zero());
#pragma omp parallel for schedule(static, 1024)
  for (long k = 0; k < static_cast<long>(pts.size()); ++k) {
    const Eigen::Vector3d& q = pts[static_cast<size_t>(k)];
    const NeighbourSpread sp = neighbour_spread(grid, pts, q, radius);
    if (sp.n < 6) continue;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(sp.C);
    const Eigen::Vector3d nrm = es.eigenvectors().col(0).normalized();
    out[static_cast<size_t>(k)] = nrm;
    if (smoothed && es.eigenvalues()(0) < es.eigenvalues()(1) / 9.0)
      (*smoothed)[static_cast<size_t>(k)] = q + nrm.dot(sp.mean) * nrm;
  }
  return out;
}

}  // namespace

std::vector<Eigen::Vector3d> neighbour_normals(const std::vector<Eigen::Vector3d>& points, double radius) {
  return estimate_normals(points, radius, nullptr);
}

Eigen::Vector3d thickness_axis(const std::vector<Eigen::Vector3d>& pts) {
  return principal_frame_of(pts).axes.col(2).normalized();
}

PreparedCloud prepare_cloud(const std::vector<Eigen::Vector3d>& points_in, const std::vector<Eigen::Vector3d>& normals_in,
                            const std::string& file, const std::string& units, const CloudPrepOptions& o) {
  silence_pcl_console();  // PCL's RANSAC prints every degenerate sample otherwise
  PreparedCloud r;
  r.read = points_in.size();
  if (points_in.size() < static_cast<size_t>(o.min_points))
    throw InputError(file, "holds " + std::to_string(points_in.size()) + " points; a hand needs at least " +
                               std::to_string(o.min_points));
  for (size_t k = 0; k < points_in.size(); ++k)
    if (!points_in[k].allFinite()) throw InputError(file, "point " + std::to_string(k) + " has a non-finite coordinate");
  auto t = std::chrono::steady_clock::now();
  const auto lap = [&](const char* step) {
    const auto now = std::chrono::steady_clock::now();
    r.timings_ms.emplace_back(step, std::chrono::duration<double, std::milli>(now - t).count());
    t = now;
  };
  check_scale(points_in, file, units, o);  // 1.
  lap("check_scale");
  std::vector<Eigen::Vector3d> points = points_in, normals = normals_in;
  r.normals_from_file = normals.size() == points.size();
  if (o.voxel_mm > 0) voxel_downsample(&points, &normals, o.voxel_mm);
  r.downsampled = points.size();  // 2. the voxel grid
  r.voxel_mm = o.voxel_mm;
  lap("downsample");
  std::vector<size_t> idx(points.size());
  for (size_t k = 0; k < idx.size(); ++k) idx[k] = k;
  idx = drop_outliers(points, idx, o);
  r.outliers = points.size() - idx.size();
  lap("drop_outliers");
  // Too few left already: the cloud is strays, not a surface (a sparse scatter of points had
  // this said of it as of a plane before 2026-11-30).
  if (idx.size() < static_cast<size_t>(o.min_points)) {
    // A surface sampled sparser than the outlier rule's radius reads as scattered points too
    // (synth cloud --spacing 2.5: 1 581 of 12 917 points with 4 neighbours within 2 mm): the
    // message says what density is read.
    throw InputError(file, "only " + std::to_string(idx.size()) + " of its " + std::to_string(points.size()) +
                               " points have " + std::to_string(o.outlier_neighbours) + " neighbours within " +
                               mm_text(o.outlier_radius_mm) + " mm (nearest neighbours " + mm_text(median_spacing(points, 1.0)) +
                               " mm apart, median): scattered points, or a surface sampled too sparsely (a hand's cloud "
                               "needs at least " + std::to_string(o.min_points) + " points, at most ~1.5 mm apart)");
  }
  if (o.remove_support) idx = drop_support(points, idx, o, &r);
  lap("drop_support");
  if (idx.size() < static_cast<size_t>(o.min_points))
    throw InputError(file, "only " + std::to_string(idx.size()) + " points are off its dominant plane: a plane (a stand, a "
                           "table), not a hand");
  idx = keep_largest_part(points, idx, o, &r);
  lap("keep_largest_part");
  if (idx.size() < static_cast<size_t>(o.min_points)) {
    // A hand sampled sparser than the voxel falls apart too (synth cloud --spacing 2.5 on the
    // fixture's hand: parts of 22 points): said when its points lie farther apart than a
    // scanner's after the voxel grid.
    const double spacing = median_spacing(points, 1.0);
    throw InputError(file, "its largest connected part holds " + std::to_string(idx.size()) + " points (gap " +
                               mm_text(r.part_gap_mm) + " mm); a hand needs at least " + std::to_string(o.min_points) +
                               (spacing > 0.9 ? " (its nearest neighbours lie " + mm_text(spacing) +
                                                    " mm apart, median: a surface sampled too sparsely? a hand's cloud "
                                                    "needs its points at most ~1.5 mm apart)"
                                              : std::string()));
  }
  r.points = gather(points, idx);
  r.extent_mm = principal_frame_of(r.points).extent;
  if (r.extent_mm(0) < o.min_hand_mm || r.extent_mm(0) > o.max_hand_mm)
    throw InputError(file, "its largest part is " + mm_text(r.extent_mm(0)) + " mm long at --units " + units +
                               ": not a hand (" + mm_text(o.min_hand_mm) + "–" + mm_text(o.max_hand_mm) + " mm)");
  if (r.extent_mm(2) < 0.02 * r.extent_mm(0))
    throw InputError(file, "its largest part is flat (" + mm_text(r.extent_mm(2)) + " mm thick over " +
                               mm_text(r.extent_mm(0)) + " mm): a plane, not a hand");
  lap("check_hand");
  std::vector<Eigen::Vector3d> smoothed = o.smooth ? r.points : std::vector<Eigen::Vector3d>{};
  std::vector<Eigen::Vector3d> estimated = estimate_normals(r.points, o.normal_radius_mm, o.smooth ? &smoothed : nullptr);
  r.normals = r.normals_from_file ? gather(normals, idx) : std::move(estimated);
  if (o.smooth) r.points = std::move(smoothed);
  lap("estimate_normals");
  return r;
}

namespace {
// The points binned in 2 mm columns along `back` (deterministic order), each column's span of
// heights, and each point's column.
struct Span {
  double lo = 1e300, hi = -1e300;
};
struct Columns {
  Eigen::Vector3d z;
  std::map<std::pair<long, long>, Span> spans;
  std::vector<std::pair<long, long>> of_point;
};
Columns columns_along(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& back) {
  constexpr double kCell = 2.0;
  Columns c;
  c.z = back.normalized();
  const Eigen::Vector3d x = c.z.unitOrthogonal(), y = c.z.cross(x);
  c.of_point.resize(pts.size());
  for (size_t k = 0; k < pts.size(); ++k) {
    c.of_point[k] = {static_cast<long>(std::floor(pts[k].dot(x) / kCell)), static_cast<long>(std::floor(pts[k].dot(y) / kCell))};
    Span& s = c.spans[c.of_point[k]];
    const double h = pts[k].dot(c.z);
    s.lo = std::min(s.lo, h), s.hi = std::max(s.hi, h);
  }
  return c;
}
}  // namespace

double two_sided_share(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& back) {
  constexpr double kSpan = 4.0;
  const Columns c = columns_along(pts, back);
  if (c.spans.empty()) return 0.0;
  size_t thick = 0;
  for (const auto& [key, span] : c.spans) thick += span.hi - span.lo > kSpan;
  return static_cast<double>(thick) / static_cast<double>(c.spans.size());
}

std::vector<std::uint32_t> label_sides(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& back,
                                       std::vector<Eigen::Vector3d>* normals) {
  const Columns columns = columns_along(pts, back);
  const Eigen::Vector3d& z = columns.z;
  const auto& cells = columns.spans;
  const auto& cell = columns.of_point;
  // The mid-surface of a column and its eight neighbours: a column that sees one side only
  // (a hole on the other) takes its neighbours' span.
  std::map<std::pair<long, long>, double> mid;
  for (const auto& [key, s] : cells) {
    Span w;
    for (long di = -1; di <= 1; ++di)
      for (long dj = -1; dj <= 1; ++dj)
        if (const auto it = cells.find({key.first + di, key.second + dj}); it != cells.end())
          w.lo = std::min(w.lo, it->second.lo), w.hi = std::max(w.hi, it->second.hi);
    mid[key] = 0.5 * (w.lo + w.hi);
  }
  std::vector<std::uint32_t> sides(pts.size());
  for (size_t k = 0; k < pts.size(); ++k) {
    sides[k] = pts[k].dot(z) > mid[cell[k]] ? 1u : 0u;
    if (normals && k < normals->size()) {
      Eigen::Vector3d& n = (*normals)[k];
      if ((n.dot(z) < 0) == (sides[k] == 1)) n = -n;
    }
  }
  return sides;
}

}  // namespace handskin
