#include "register/cloud_align.hpp"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>


#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/errors.hpp"
#include "mesh/point_grid.hpp"
#include "register/cloud_prep.hpp"
#include "scan/cloud.hpp"
#include "scan/pcl_module.hpp"

namespace handskin {

namespace {

using PN = pcl::PointNormal;
using PNCloud = pcl::PointCloud<PN>;

struct Frame {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  // columns: largest spread first
  double thickness = 0;                                // extent along the third axis (2–98 %)
};

Frame frame_of(const std::vector<Eigen::Vector3d>& p) {
  Frame f;
  for (const auto& q : p) f.c += q;
  f.c /= static_cast<double>(p.size());
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (const auto& q : p) C += (q - f.c) * (q - f.c).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  for (int k = 0; k < 3; ++k) f.axes.col(k) = es.eigenvectors().col(2 - k);
  if (f.axes.determinant() < 0) f.axes.col(2) *= -1;
  std::vector<double> t;
  t.reserve(p.size());
  for (const auto& q : p) t.push_back(f.axes.col(2).dot(q - f.c));
  std::sort(t.begin(), t.end());
  f.thickness = t[t.size() * 98 / 100] - t[t.size() * 2 / 100];
  return f;
}

// Points on a voxel grid about `origin` (in float), with their neighbours' normals; points
// with too few neighbours for a normal are left out.
PNCloud::Ptr coarse_cloud(const std::vector<Eigen::Vector3d>& p, const Eigen::Vector3d& origin, double voxel) {
  auto in = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (const auto& q : p) in->push_back(pcl::PointXYZ(static_cast<float>(q.x() - origin.x()), static_cast<float>(q.y() - origin.y()),
                                                      static_cast<float>(q.z() - origin.z())));
  const pcl::PointCloud<pcl::PointXYZ> out = voxel_grid(in, static_cast<float>(voxel), "run --cloud (the halves' voxel grid)");
  std::vector<Eigen::Vector3d> pts;
  for (const auto& q : out) pts.push_back(q.getVector3fMap().cast<double>());
  const std::vector<Eigen::Vector3d> normals = neighbour_normals(pts, 3 * voxel);
  auto cloud = std::make_shared<PNCloud>();
  for (size_t k = 0; k < pts.size(); ++k) {
    if (normals[k].squaredNorm() == 0) continue;
    PN pn;
    pn.getVector3fMap() = pts[k].cast<float>();
    pn.getNormalVector3fMap() = normals[k].cast<float>();
    cloud->push_back(pn);
  }
  return cloud;
}

// Point-to-plane ICP from `T`: Gauss–Newton on the residuals n·(T p − q) to the nearest
// point within `d` (each round's distance in turn), the update applied on the left. Written
// here rather than with PCL's IterativeClosestPointWithNormals, which took 44 s for the
// twelve coarse starts of two halves; this takes milliseconds in the hash grid.
Eigen::Isometry3d icp(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                      const std::vector<Eigen::Vector3d>& dst_n, Eigen::Isometry3d T, std::initializer_list<double> distances,
                      int iterations) {
  for (double d : distances) {
    const PointGrid grid(dst, 0.5 * d);
    for (int it = 0; it < iterations; ++it) {
      // Partial sums over fixed chunks, added in order: the same result on any thread count.
      constexpr size_t kChunk = 512;
      const size_t chunks = (src.size() + kChunk - 1) / kChunk;
      std::vector<Eigen::Matrix<double, 6, 6>> Hc(chunks, Eigen::Matrix<double, 6, 6>::Zero());
      std::vector<Eigen::Matrix<double, 6, 1>> gc(chunks, Eigen::Matrix<double, 6, 1>::Zero());
      std::vector<size_t> nc(chunks, 0);
#pragma omp parallel for schedule(dynamic, 1)
      for (long c = 0; c < static_cast<long>(chunks); ++c)
        for (size_t k = static_cast<size_t>(c) * kChunk; k < std::min(src.size(), (static_cast<size_t>(c) + 1) * kChunk); ++k) {
          const Eigen::Vector3d p = T * src[k];
          const int j = grid.nearest(p, d);
          if (j < 0) continue;
          const Eigen::Vector3d& nj = dst_n[static_cast<size_t>(j)];
          const double r = nj.dot(p - dst[static_cast<size_t>(j)]);
          Eigen::Matrix<double, 6, 1> J;
          J << p.cross(nj), nj;
          Hc[static_cast<size_t>(c)] += J * J.transpose(), gc[static_cast<size_t>(c)] += J * r, ++nc[static_cast<size_t>(c)];
        }
      Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
      Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
      size_t n = 0;
      for (size_t c = 0; c < chunks; ++c) H += Hc[c], g += gc[c], n += nc[c];
      if (n < 12) break;
      const Eigen::Matrix<double, 6, 1> x = -H.ldlt().solve(g);
      if (!x.allFinite()) break;
      Eigen::Isometry3d dT = Eigen::Isometry3d::Identity();
      const double angle = x.head<3>().norm();
      if (angle > 0) dT.linear() = Eigen::AngleAxisd(angle, x.head<3>() / angle).toRotationMatrix();
      dT.translation() = x.tail<3>();
      T = dT * T;
      if (angle < 1e-7 && x.tail<3>().norm() < 1e-6) break;
    }
  }
  return T;
}

struct Meeting {
  double share = 0, rms = 0;
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  size_t pairs = 0;
};

// How the first half meets the second under T: the share of its points within `within` of
// the second's, the point-to-plane RMS over them, and the normal equations of the residuals.
Meeting meeting(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                const std::vector<Eigen::Vector3d>& bn, const PointGrid& grid, const Eigen::Isometry3d& T, double within) {
  Meeting m;
  double ss = 0;
  for (const auto& p0 : a) {
    const Eigen::Vector3d p = T * p0;
    const int j = grid.nearest(p, within);
    if (j < 0) continue;
    const Eigen::Vector3d& n = bn[static_cast<size_t>(j)];
    const double r = n.dot(p - b[static_cast<size_t>(j)]);
    ss += r * r;
    Eigen::Matrix<double, 6, 1> J;
    J << p.cross(n), n;
    m.H += J * J.transpose();
    ++m.pairs;
  }
  m.share = a.empty() ? 0 : static_cast<double>(m.pairs) / static_cast<double>(a.size());
  m.rms = m.pairs ? std::sqrt(ss / static_cast<double>(m.pairs)) : 0;
  return m;
}

}  // namespace

CloudAlignment align_halves(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                            const std::vector<Eigen::Vector3d>& bn, const std::string& a_file, const std::string& b_file,
                            const CloudAlignOptions& o) {
  silence_pcl_console();
  CloudAlignment R;
  auto t = std::chrono::steady_clock::now();
  const auto lap = [&](const char* step) {
    const auto now = std::chrono::steady_clock::now();
    R.timings_ms.emplace_back(step, std::chrono::duration<double, std::milli>(now - t).count());
    t = now;
  };
  // 1. frames, about b's centroid (PCL works in float)
  const Frame fa = frame_of(a), fb = frame_of(b);
  const Eigen::Vector3d origin = fb.c;
  const PNCloud::Ptr ca = coarse_cloud(a, origin, o.coarse_voxel_mm), cb = coarse_cloud(b, origin, o.coarse_voxel_mm);
  std::vector<Eigen::Vector3d> pa, pb, nb;
  for (const auto& q : *ca) pa.push_back(q.getVector3fMap().cast<double>());
  for (const auto& q : *cb) pb.push_back(q.getVector3fMap().cast<double>()), nb.push_back(q.getNormalVector3fMap().cast<double>());
  const PointGrid coarse_grid(pb, o.coarse_voxel_mm);
  std::vector<Eigen::Vector3d> pa_few;  // the coarse fits' source: about 1000 points
  for (size_t k = 0; k < pa.size(); k += std::max<size_t>(1, pa.size() / 1000)) pa_few.push_back(pa[k]);
  lap("frames");
  // 2–3. candidates, each refined; kept: the most overlap per mm of residual. The right fit
  // meets over the flanks at about the noise (0.2 mm on the family's clouds), a wrong one over
  // less at about the correspondence distance (1 mm).
  double best_score = -1;
  Eigen::Isometry3d best = Eigen::Isometry3d::Identity();
  const double one_shell = std::max(fa.thickness, fb.thickness);
  for (int flip = 0; flip < 4; ++flip) {
    const Eigen::Vector3d s(flip & 1 ? -1 : 1, flip & 2 ? -1 : 1, ((flip & 1) != 0) != ((flip & 2) != 0) ? -1 : 1);
    const Eigen::Matrix3d Rm = fb.axes * s.asDiagonal() * fa.axes.transpose();
    for (const double off : {-0.5, 0.0, 0.5}) {
      Eigen::Isometry3d G = Eigen::Isometry3d::Identity();  // a (about origin) → b (about origin)
      G.linear() = Rm;
      G.translation() = (fb.c - origin) + off * one_shell * fb.axes.col(2) - Rm * (fa.c - origin);
      const Eigen::Isometry3d Ti = icp(pa_few, pb, nb, G, {8.0, 4.0, 2.0 * o.coarse_voxel_mm}, 15);
      ++R.candidates;
      const Meeting m = meeting(pa, pb, nb, coarse_grid, Ti, o.coarse_voxel_mm);
      const double score = m.share / std::max(m.rms, 0.05);
      if (score > best_score) best_score = score, best = Ti;
    }
  }
  lap("coarse");
  if (best_score < o.min_overlap_share / 0.5)
    throw InputError(a_file, "does not meet " + b_file + " in any pose (the halves must overlap where both scans saw the "
                                                          "hand's flanks)");
  // 4. fine: the full clouds, correspondences within 1 mm
  std::vector<Eigen::Vector3d> A, B;
  for (const auto& q : a) A.push_back(q - origin);
  for (const auto& q : b) B.push_back(q - origin);
  std::vector<Eigen::Vector3d> A_few;  // the fine fit's source: about 10 000 points
  for (size_t k = 0; k < A.size(); k += std::max<size_t>(1, A.size() / 10000)) A_few.push_back(A[k]);
  const Eigen::Isometry3d fine = icp(A_few, B, bn, best, {2.0, o.overlap_mm}, 15);
  lap("fine");
  // 5. the fit's own 1σ from its residuals
  const PointGrid grid(B, o.overlap_mm);
  const Meeting m = meeting(A, B, bn, grid, fine, o.overlap_mm);
  R.overlap_share = m.share;
  R.rms_mm = m.rms;
  if (m.share > o.same_half_share)
    throw InputError(a_file, "and " + b_file + " are the same half: " + std::to_string(static_cast<int>(100 * m.share)) +
                                 " % of it lies on the other (give the back half and the palm half)");
  if (m.pairs > 6) {
    const double s2 = m.rms * m.rms * static_cast<double>(m.pairs) / static_cast<double>(m.pairs - 6);
    const Eigen::Matrix<double, 6, 6> cov = s2 * m.H.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
    R.rotation_sigma_deg = std::sqrt(std::max(0.0, cov.topLeftCorner<3, 3>().trace())) * 180.0 / M_PI;
    double sum = 0;
    for (size_t k = 0; k < A.size(); k += 10) {
      const Eigen::Vector3d p = fine * A[k];
      Eigen::Matrix<double, 3, 6> J;
      J.rightCols<3>() = Eigen::Matrix3d::Identity();
      J.leftCols<3>() << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;  // δp = ω × p
      sum += (J * cov * J.transpose()).trace();
    }
    R.displacement_sigma_mm = std::sqrt(sum / static_cast<double>((A.size() + 9) / 10));
  }
  // Back to the clouds' own frames: p_b = origin + fine · (p_a − origin).
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity(), unshift = Eigen::Isometry3d::Identity();
  shift.translation() = -origin;
  unshift.translation() = origin;
  R.a_to_b = unshift * fine * shift;
  lap("uncertainty");
  return R;
}

}  // namespace handskin
