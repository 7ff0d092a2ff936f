#include "register/spheres.hpp"

#include <ceres/ceres.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/sac_model_sphere.h>
#include <pcl/sample_consensus/impl/sac_model_sphere.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <unordered_map>

#include "core/errors.hpp"
#include "register/sac.hpp"
#include "register/small_fit.hpp"
#include "register/sphere_residual.hpp"

namespace handskin {

bool SphereOptions::IsValid(std::string* error) const {
  if (!(radius_mm > 0 && radius_mm <= 20)) return invalid(error, "radius_mm must be in (0, 20]");
  if (!(radius_tolerance > 0 && radius_tolerance < 0.5)) return invalid(error, "radius_tolerance must be in (0, 0.5)");
  if (!(inlier_mm > 0 && inlier_mm < radius_mm)) return invalid(error, "inlier_mm must be in (0, radius_mm)");
  if (!(max_rms_mm > 0)) return invalid(error, "max_rms_mm must be > 0");
  if (min_points < 4) return invalid(error, "min_points must be >= 4");
  if (!(min_spread_deg >= 0 && min_spread_deg < 90)) return invalid(error, "min_spread_deg must be in [0, 90)");
  if (min_votes < 1) return invalid(error, "min_votes must be >= 1");
  if (!(min_vote_concentration >= 0 && min_vote_concentration <= 1)) return invalid(error, "min_vote_concentration must be in [0, 1]");
  if (!(hint_search_mm > 0 && hint_search_mm <= 50)) return invalid(error, "hint_search_mm must be in (0, 50]");
  return true;
}

namespace {

// Fixed-radius centre of the samples `idx`, by their depth errors (sphere_residual.hpp), or by
// their distances (`coarse`: while the cap is still being found); Levenberg–Marquardt as
// Ceres's (small_fit.hpp, which says why not Ceres itself).
Eigen::Vector3d fit_centre(const PreparedScan& s, const std::vector<int>& idx, const Eigen::Vector3d& start, double r, double floor,
                           bool coarse) {
  double c[3] = {start.x(), start.y(), start.z()};
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const std::array<double, 3> lo{-kInf, -kInf, -kInf}, hi{kInf, kInf, kInf};
  const auto solve = [&](const auto& parts) {  // parts[k]: sample k's residual functor
    small_fit::minimise<3>(c, static_cast<int>(parts.size()), [&](int k, const auto* x, auto* res) { parts[static_cast<size_t>(k)](x, res); },
                           lo, hi);
  };
  if (coarse) {
    std::vector<SphereDistanceResidual> parts;
    parts.reserve(idx.size());
    for (int k : idx) parts.emplace_back(s.points[k], r, SphereDistanceResidual::weight(s.points[k], start, r, floor));
    solve(parts);
  } else {
    std::vector<SphereResidual> parts;
    parts.reserve(idx.size());
    for (int k : idx) parts.emplace_back(s.points[k], r, floor);
    solve(parts);
  }
  return {c[0], c[1], c[2]};
}

// The centre and the radius both free (the radius within [0.1, 10] × r).
double fit_free_radius(const PreparedScan& s, const std::vector<int>& idx, const Eigen::Vector3d& start, double r,
                       double floor) {
  double x[4] = {start.x(), start.y(), start.z(), r};
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<FreeRadiusResidual> parts;
  parts.reserve(idx.size());
  for (int k : idx) parts.emplace_back(s.points[k], floor);
  small_fit::minimise<4>(x, static_cast<int>(idx.size()),
                         [&](int k, const auto* y, auto* res) { parts[static_cast<size_t>(k)](y, y + 3, res); },
                         {-kInf, -kInf, -kInf, 0.1 * r}, {kInf, kInf, kInf, 10.0 * r});
  return x[3];
}

std::string fmt(const char* f, double a, double b = 0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

}  // namespace

std::optional<SphereFit> fit_sphere_near(const PreparedScan& s, const Eigen::Vector3d& guess, double search,
                                         const SphereOptions& o, std::string* why) {
  const double r = o.radius_mm;
  const double reach = r + search + 2 * o.inlier_mm;
  // Samples near the guess: a window of the scan grid around its footprint.
  std::vector<int> near;
  const int i0 = static_cast<int>(std::floor((guess.x() - reach - s.x_origin) / s.x_step));
  const int i1 = static_cast<int>(std::ceil((guess.x() + reach - s.x_origin) / s.x_step));
  const int j0 = static_cast<int>(std::floor((guess.y() - reach - s.y_origin) / s.y_step));
  const int j1 = static_cast<int>(std::ceil((guess.y() + reach - s.y_origin) / s.y_step));
  for (int i = std::max(0, i0); i <= std::min(s.rows - 1, i1); ++i)
    for (int j = std::max(0, j0); j <= std::min(s.cols - 1, j1); ++j) {
      const int k = s.point_of_pixel[static_cast<size_t>(i) * s.cols + j];
      if (k >= 0 && (s.points[k] - guess).norm() < reach) near.push_back(k);
    }
  if (static_cast<long>(near.size()) < o.min_points) {
    *why = "only " + std::to_string(near.size()) + " samples within " + fmt("%.1f", reach) + " mm";
    return std::nullopt;
  }

  // PCL RANSAC sphere (radius bounded near the marker's) picks the cap out of whatever else
  // lies near: the flank the marker sits on, a neighbouring finger. Coordinates relative to
  // the guess keep PCL's float arithmetic precise.
  pcl::PointCloud<pcl::PointXYZ>::Ptr local(new pcl::PointCloud<pcl::PointXYZ>);
  for (int k : near) {
    const Eigen::Vector3d d = s.points[k] - guess;
    local->push_back(pcl::PointXYZ(static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z())));
  }
  auto model = std::make_shared<pcl::SampleConsensusModelSphere<pcl::PointXYZ>>(local, false);
  model->setRadiusLimits(r * (1 - 2 * o.radius_tolerance), r * (1 + 2 * o.radius_tolerance));
  const SacFit sphere = ransac<pcl::PointXYZ>(model, o.inlier_mm, 400, false);
  std::vector<Eigen::Vector3d> starts = {guess};
  if (sphere.coefficients.size() == 4) starts.push_back(guess + sphere.coefficients.head<3>().cast<double>());

  // Every sample of a cap lies inside the outline the scanner can see, where the sphere's
  // slope n_z ≥ steep_floor (a test on X and Y, which carry no noise): beyond it a depth
  // error stands for a sideways one of any size (sphere_residual.hpp).
  const double outline2 = r * r * (1 - o.steep_floor * o.steep_floor);

  // Fixed-radius refinement from the guess and from the RANSAC sphere; the sample set is
  // re-selected by distance and by normal (a flank sample at the right distance but facing
  // elsewhere is not on the cap). The start that ends with more samples wins.
  Eigen::Vector3d c = guess;
  std::vector<int> in;
  for (const Eigen::Vector3d& start : starts) {
    Eigen::Vector3d cs = start;
    std::vector<int> ins;
    // Coarse to fine: the first rounds accept samples as far off as the start may be.
    // The last rounds repeat at the fine gate until the sample set settles, so that two
    // starts near the same cap end on the same samples.
    const double gates[] = {std::max(o.inlier_mm, search), std::max(o.inlier_mm, search / 2),
                            std::max(o.inlier_mm, search / 4), o.inlier_mm, o.inlier_mm, o.inlier_mm,
                            o.inlier_mm, o.inlier_mm};
    std::vector<int> previous;
    for (size_t g = 0; g < std::size(gates); ++g) {
      const double gate = gates[g];
      if (g >= 5 && ins == previous) break;
      previous = ins;
      ins.clear();
      for (size_t q = 0; q < near.size(); ++q) {
        const int k = near[q];
        const Eigen::Vector3d d = s.points[k] - cs;
        const double dist = d.norm();
        if (std::abs(dist - r) > gate || (gate <= o.inlier_mm && d.head<2>().squaredNorm() > outline2)) continue;
        if (s.has_normal(k) && s.normals[k].dot(d / dist) < std::cos(o.normal_gate_deg * M_PI / 180.0)) continue;
        ins.push_back(k);
      }
      if (static_cast<long>(ins.size()) < o.min_points) break;
      cs = fit_centre(s, ins, cs, r, o.steep_floor, gate > o.inlier_mm);
    }
    if (ins.size() > in.size()) {
      in = ins;
      c = cs;
    }
  }
  if (static_cast<long>(in.size()) < o.min_points) {
    *why = "only " + std::to_string(in.size()) + " samples on a sphere of radius " + fmt("%.2f", r) + " mm (need " +
           std::to_string(o.min_points) + ")";
    return std::nullopt;
  }
  SphereFit f;
  f.centre = c;
  f.inliers = in;
  double ss = 0;
  Eigen::Vector3d mean_dir = Eigen::Vector3d::Zero();
  for (int k : in) {
    const Eigen::Vector3d d = s.points[k] - c;
    ss += (d.norm() - r) * (d.norm() - r);
    mean_dir += d.normalized();
  }
  f.rms_mm = std::sqrt(ss / static_cast<double>(in.size()));
  mean_dir.normalize();
  for (int k : in)
    f.spread_deg = std::max(f.spread_deg, std::acos(std::clamp((s.points[k] - c).normalized().dot(mean_dir), -1.0, 1.0)) *
                                              180.0 / M_PI);
  // The free radius's samples (besides their distance to the sphere and the outline) have no
  // neighbouring return that rises above the sphere: there the skin the marker sits on meets
  // it, and that skin's samples within the distance gate are not on the sphere. On noise-free
  // scans of the family 1.3 % of the gated samples lay 0.13-0.3 mm above it, all next to such
  // skin; they scattered single caps' free radii by 0.03 mm, leaning large (0.001 without
  // them). The centre's samples keep the normal gate instead, which drops most of them: this
  // rule would also drop the whole rim of a marker set into the skin, which holds the
  // centre's X and Y (the family's rotation errors grew with it, 0.0144 -> 0.0169 deg mean).
  auto on_cap = [&](int k, const Eigen::Vector3d& centre) {
    if ((s.points[k] - centre).head<2>().squaredNorm() > outline2) return false;
    const int i = s.pixel[k] / s.cols, j = s.pixel[k] % s.cols;
    for (int a = std::max(0, i - 1); a <= std::min(s.rows - 1, i + 1); ++a)
      for (int b = std::max(0, j - 1); b <= std::min(s.cols - 1, j + 1); ++b) {
        const int q = s.point_of_pixel[static_cast<size_t>(a) * s.cols + b];
        if (q < 0 || q == k) continue;
        const Eigen::Vector3d d = s.points[q] - centre;
        if (std::abs(d.norm() - r) <= o.inlier_mm) continue;  // on the sphere itself
        if (d.z() > std::sqrt(std::max(0.0, r * r - d.head<2>().squaredNorm()))) return false;
      }
    return true;
  };

  // The normal gate is left out here: a cap's rim samples whose 5 x 5 window normals stray
  // (the window reaches the skin) are not random, and leaving them out made the free fits
  // small (docs/registration.md).
  for (int k : near)
    if (std::abs((s.points[k] - c).norm() - r) <= o.inlier_mm && on_cap(k, c)) f.shell.push_back(k);
  f.radius_free = fit_free_radius(s, f.shell, c, r, o.steep_floor);
  if (std::abs(f.radius_free - r) > o.radius_tolerance * r) {
    *why = fmt("a free fit gives radius %.2f mm, not %.2f mm", f.radius_free, r);
    return std::nullopt;
  }
  if (f.rms_mm > o.max_rms_mm) {
    *why = fmt("fit residual %.3f mm exceeds %.3f mm", f.rms_mm, o.max_rms_mm);
    return std::nullopt;
  }
  if (f.spread_deg < o.min_spread_deg) {
    *why = fmt("the samples span only %.0f deg of the sphere (need %.0f)", f.spread_deg, o.min_spread_deg);
    return std::nullopt;
  }
  if ((c - guess).norm() > search + o.inlier_mm) {
    *why = fmt("the fitted centre is %.2f mm from the starting position (allowed %.2f)", (c - guess).norm(), search);
    return std::nullopt;
  }
  return f;
}

double fit_shared_radius(const std::vector<SharedRadiusCap>& caps, double r, double floor, double* sd) {
  if (sd) *sd = 0;
  if (caps.empty()) return r;
  double radius = r;
  std::vector<std::array<double, 3>> c(caps.size());
  ceres::Problem problem;
  for (size_t i = 0; i < caps.size(); ++i) {
    const SphereFit& f = *caps[i].fit;
    c[i] = {f.centre.x(), f.centre.y(), f.centre.z()};
    for (int k : f.shell)
      problem.AddResidualBlock(FreeRadiusResidual::Create(caps[i].scan->points[k], floor), nullptr, c[i].data(), &radius);
  }
  problem.SetParameterLowerBound(&radius, 0, 0.5 * r);
  problem.SetParameterUpperBound(&radius, 0, 2.0 * r);
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_SCHUR;  // independent centres, one shared radius
  o.max_num_iterations = 50;
  o.logging_type = ceres::SILENT;
  o.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  double var = 0, sigma = 0;
  if (sd && residual_scaled_covariance(&problem, &radius, 1, &var, &sigma)) *sd = std::sqrt(std::max(0.0, var));
  return radius;
}

namespace {

// The Hough search's vote grid (detect_spheres): cells of a fixed size, named by their integer
// coordinates. The occupied cells in bricks of 8 x 8 x 8 (a brick made when a vote first falls in it),
// found through a small open-addressing table of the bricks. Each vote is looked up ~30 times
// by the neighbour tests below, and those of one cell lie in one brick or its neighbours:
// a table of single cells (until 2026-12-01, 16-byte slots of key, votes and index) took a
// cache miss per lookup, most of this search's time (docs/performance.md). A cell holds its
// votes and the index of its vote sum, which is kept densely, in the order the cells were
// first voted for; the peaks are sorted below, so no order reaches the result.
struct Cell {
  int votes = 0;
  int index = -1;  // into `sums`
};
struct BrickGrid {
  static constexpr int kShift = 3, kSide = 1 << kShift, kMask = kSide - 1;
  std::vector<long> slot_key;  // per slot of the brick table: its brick's key, -1 empty
  std::vector<int> slot_brick;
  size_t mask = 0;
  std::vector<std::array<Cell, kSide * kSide * kSide>> bricks;
  std::vector<std::array<long, 3>> origin;  // per brick, its coordinates (a cell's, divided by kSide)
  std::vector<Eigen::Vector3d> sums;    // dense, the sum of a cell's votes
  mutable long last_key = -1;           // the brick looked up last (most lookups repeat it)
  mutable int last_brick = -1;
  void reset(size_t expected_bricks, size_t votes) {
    size_t cap = 256;
    while (cap < 2 * expected_bricks) cap <<= 1;
    slot_key.assign(cap, -1);
    slot_brick.assign(cap, -1);
    mask = cap - 1;
    bricks.clear();
    origin.clear();
    sums.clear();
    // At most one cell and sum per vote, and bricks as many as a 2 mm marker's search spreads
    // its votes over (a 512² scan: 2 900 bricks for 73 000 votes): reserved, so that they are
    // not copied as they grow, up to a bound (64 MB of bricks, 24 MB of sums: a 4096 × 1024
    // scan's votes would have reserved 1 GB); their pages are touched only as they fill.
    bricks.reserve(std::min<size_t>(votes / 16, 1 << 14));
    origin.reserve(std::min<size_t>(votes / 16, 1 << 14));
    sums.reserve(std::min<size_t>(votes, 1 << 20));
    last_key = last_brick = -1;
  }
  static long brick_key(long a, long b, long c) {
    return (((a >> kShift) + (1L << 20)) << 42) | (((b >> kShift) + (1L << 20)) << 21) | ((c >> kShift) + (1L << 20));
  }
  static int within(long a, long b, long c) {
    return static_cast<int>(((a & kMask) << (2 * kShift)) | ((b & kMask) << kShift) | (c & kMask));
  }
  static size_t slot_of(long k) {
    std::uint64_t x = static_cast<std::uint64_t>(k);
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    return static_cast<size_t>(x);
  }
  int brick(long bk) const {  // -1: none
    if (bk == last_key) return last_brick;
    size_t i = slot_of(bk) & mask;
    while (slot_key[i] != -1 && slot_key[i] != bk) i = (i + 1) & mask;
    last_key = bk;
    return last_brick = slot_key[i] == -1 ? -1 : slot_brick[i];
  }
  void grow() {
    const std::vector<long> old_key = std::move(slot_key);
    const std::vector<int> old_brick = std::move(slot_brick);
    slot_key.assign(2 * old_key.size(), -1);
    slot_brick.assign(2 * old_key.size(), -1);
    mask = slot_key.size() - 1;
    for (size_t j = 0; j < old_key.size(); ++j) {
      if (old_key[j] == -1) continue;
      size_t i = slot_of(old_key[j]) & mask;
      while (slot_key[i] != -1) i = (i + 1) & mask;
      slot_key[i] = old_key[j], slot_brick[i] = old_brick[j];
    }
  }
  void vote(long a, long b, long c, const Eigen::Vector3d& v) {
    const long bk = brick_key(a, b, c);
    int id = brick(bk);
    if (id < 0) {
      if (2 * (bricks.size() + 1) > slot_key.size()) grow();
      size_t i = slot_of(bk) & mask;
      while (slot_key[i] != -1) i = (i + 1) & mask;
      id = static_cast<int>(bricks.size());
      slot_key[i] = bk, slot_brick[i] = id;
      bricks.emplace_back();
      origin.push_back({a >> kShift, b >> kShift, c >> kShift});
      last_key = bk, last_brick = id;
    }
    Cell& cl = bricks[static_cast<size_t>(id)][static_cast<size_t>(within(a, b, c))];
    if (cl.votes == 0) {
      cl.index = static_cast<int>(sums.size());
      sums.push_back(Eigen::Vector3d::Zero());
    }
    ++cl.votes;
    sums[static_cast<size_t>(cl.index)] += v;
  }
  const Cell* find(long a, long b, long c) const {
    const int id = brick(brick_key(a, b, c));
    if (id < 0) return nullptr;
    const Cell& cl = bricks[static_cast<size_t>(id)][static_cast<size_t>(within(a, b, c))];
    return cl.votes > 0 ? &cl : nullptr;
  }
};

}  // namespace

std::vector<SphereFit> detect_spheres(const PreparedScan& s, const SphereOptions& o,
                                      std::vector<SphereCandidateReport>* report, size_t max_found) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("marker options", err);
  const double r = o.radius_mm;
  // Hough voting with the radius known: a sample on a sphere of radius r votes at its centre
  // p − r·n, so a marker's votes gather in one small cluster; samples of other curvature
  // spread theirs over a surface (a plane's over a plane r below it). A peak is a candidate
  // when its votes are many and concentrated: most of those in a 3.5 mm cube lie in the
  // central 1.5 mm one.
  const double cell = r / 6.0;
  auto key = [](long a, long b, long c) {
    return ((a + (1L << 20)) << 42) | ((b + (1L << 20)) << 21) | (c + (1L << 20));
  };
  BrickGrid grid;
  grid.reset(s.points.size() / 64, s.points.size());
  for (size_t k = 0; k < s.points.size(); ++k) {
    if (!s.has_normal(k)) continue;
    const Eigen::Vector3d v = s.points[k] - r * s.normals[k];
    const long a = std::lround(std::floor(v.x() / cell)), b = std::lround(std::floor(v.y() / cell)),
               c = std::lround(std::floor(v.z() / cell));
    grid.vote(a, b, c, v);
  }
  // Whether the central cube's votes are at least `share` of the 7 x 7 x 7 cube's about
  // cell (a, b, c): the shell around the central 3 x 3 x 3 is summed onto `central` and the
  // sum stops as soon as it is too large (most local maxima are on a surface's spread of
  // votes and fail within a few cells; the full 316 lookups were the search's costliest step).
  auto concentrated = [&](long a, long b, long c, long central, double share) {
    long wide = central;
    for (long da = -3; da <= 3; ++da)
      for (long db = -3; db <= 3; ++db)
        for (long dc = -3; dc <= 3; ++dc) {
          if (std::abs(da) <= 1 && std::abs(db) <= 1 && std::abs(dc) <= 1) continue;  // counted in `central`
          if (const Cell* g = grid.find(a + da, b + db, c + dc)) {
            wide += g->votes;
            if (static_cast<double>(central) < share * static_cast<double>(wide)) return false;
          }
        }
    return true;
  };
  struct Peak {
    long votes;
    long k;
    Eigen::Vector3d centre;
  };
  std::vector<Peak> peaks;
  // Brick by brick (the peaks are sorted below): a cell's neighbours lie in its brick or the 26
  // about it, found once per brick.
  constexpr int kShift = BrickGrid::kShift, kMask = BrickGrid::kMask, kCells = BrickGrid::kSide * BrickGrid::kSide * BrickGrid::kSide;
  for (size_t brick = 0; brick < grid.bricks.size(); ++brick) {
    const std::array<long, 3>& at = grid.origin[brick];
    std::array<const Cell*, 27> around;
    for (int i = 0; i < 27; ++i) {
      const int id = grid.brick(BrickGrid::brick_key((at[0] + i / 9 - 1) * BrickGrid::kSide, (at[1] + i / 3 % 3 - 1) * BrickGrid::kSide,
                                                     (at[2] + i % 3 - 1) * BrickGrid::kSide));
      around[static_cast<size_t>(i)] = id < 0 ? nullptr : grid.bricks[static_cast<size_t>(id)].data();
    }
    const Cell* cells = grid.bricks[brick].data();
    for (int q = 0; q < kCells; ++q) {
      const long votes = cells[q].votes;
      if (votes == 0) continue;
      const int x = q >> (2 * kShift), y = (q >> kShift) & kMask, z = q & kMask;
      const long a = at[0] * BrickGrid::kSide + x, b = at[1] * BrickGrid::kSide + y, c = at[2] * BrickGrid::kSide + z;
      const long k = key(a, b, c);
      // The occupied cell (a + da, b + db, c + dc), |d| <= 1, or none.
      const auto neighbour = [&](int da, int db, int dc) -> const Cell* {
        const int nx = x + da, ny = y + db, nz = z + dc;
        const Cell* in = around[static_cast<size_t>(9 * ((nx >> kShift) + 1) + 3 * ((ny >> kShift) + 1) + ((nz >> kShift) + 1))];
        if (!in) return nullptr;
        const Cell& n = in[((nx & kMask) << (2 * kShift)) | ((ny & kMask) << kShift) | (nz & kMask)];
        return n.votes > 0 ? &n : nullptr;
      };
      // A local maximum of the votes (a tie goes to the smaller key), and its central cube's
      // votes; their sum only for a maximum.
      bool is_max = true;
      long central = 0;
      for (long da = -1; da <= 1 && is_max; ++da)
        for (long db = -1; db <= 1 && is_max; ++db)
          for (long dc = -1; dc <= 1; ++dc) {
            const Cell* n = neighbour(static_cast<int>(da), static_cast<int>(db), static_cast<int>(dc));
            if (!n) continue;
            if (n->votes > votes || (n->votes == votes && key(a + da, b + db, c + dc) < k)) {
              is_max = false;
              break;
            }
            central += n->votes;
          }
      if (!is_max) continue;
      if (central < o.min_votes) continue;
      if (!concentrated(a, b, c, central, o.min_vote_concentration)) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();  // in the same order as before: da, db, dc
      for (long da = -1; da <= 1; ++da)
        for (long db = -1; db <= 1; ++db)
          for (long dc = -1; dc <= 1; ++dc)
            if (const Cell* n = neighbour(static_cast<int>(da), static_cast<int>(db), static_cast<int>(dc)))
              sum += grid.sums[static_cast<size_t>(n->index)];
      peaks.push_back({central, k, sum / static_cast<double>(central)});
    }
  }
  std::sort(peaks.begin(), peaks.end(), [](const Peak& x, const Peak& y) {
    return x.votes != y.votes ? x.votes > y.votes : x.k < y.k;
  });

  std::vector<SphereFit> found;
  const size_t max_candidates = 100;
  for (size_t p = 0; p < peaks.size() && p < max_candidates && found.size() < max_found; ++p) {
    const Peak& pk = peaks[p];
    bool near_found = false;
    for (const auto& f : found)
      if ((f.centre - pk.centre).norm() < 1.5 * r) near_found = true;
    if (near_found) continue;
    std::string why;
    auto fit = fit_sphere_near(s, pk.centre, cell * 2, o, &why);
    if (fit) {
      for (const auto& f : found)
        if ((f.centre - fit->centre).norm() < 1.5 * r) {
          fit.reset();
          why = "the same sphere as a stronger candidate";
          break;
        }
    }
    if (report) report->push_back({pk.centre, pk.votes, fit ? "" : why});
    if (fit) found.push_back(std::move(*fit));
  }
  return found;
}

}  // namespace handskin
