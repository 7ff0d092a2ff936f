#include "skin/auto_rig.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <queue>

#include <Eigen/Geometry>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/hand_proportions.hpp"
#include "skin/principal_axes.hpp"

namespace handskin {

namespace {

using namespace proportions;

// The palm widens into the thenar and hypothenar eminences this far (nominal mm) beyond the
// wrist joint (measured on the proportions' hand: the knee of its breadth along the hand).
constexpr double kKneeBeyondWrist = 12.0;

// A finger's bones lie this far (nominal mm) dorsal of the middle of its cross-sections.
constexpr double kDorsalOffset = 1.0;

// A digit's section middle more than this (mm) beside the line through those beyond it
// toward the tip is not across the digit.
constexpr double kLateralStrayMm = 1.5;
// Digits overlapping in the silhouette are parted by the scans' sheets: points within
// kSheetLinkMm of each other connect (a sheet's samples lie 0.5 mm apart across the scanlines
// and up to 1.6 mm apart on a flank at the scanner's 72 deg), and a piece of at least
// kSheetPoints points is a digit's (smaller ones are flank fragments).
constexpr double kSheetLinkMm = 2.0;
constexpr size_t kSheetPoints = 200;

// In the palm, the joints' depth as a share of the palm's local thickness from its back: the
// metacarpals lie nearer the back than the palm (the palmar soft tissue is the thicker).
// Measured at the true joints of the synthetic family (12 hands, 160-215 mm, thin to thick):
// MCPs and metacarpal bases 0.39-0.42, the wrist 0.45-0.47, the thumb's base 0.56. Before,
// the MCPs took the height of their finger's centre line carried into the palm along its end
// tangent; on close or arched fingers that line is short and the heights strayed 9-12 mm (the
// metacarpal bases with them).
constexpr double kMetacarpalDepth = 0.41, kWristDepth = 0.46, kThumbBaseDepth = 0.56;

// The silhouette of the hand on its plane: a 1 mm grid of occupied cells. Written here rather
// than with an image library: a few dozen lines (closing, a chamfer distance transform,
// 4-connected labelling) on a grid of ~50 000 cells.
struct Grid {
  int nx = 0, ny = 0;
  double u0 = 0, v0 = 0, cell = 1.0;
  std::vector<std::uint8_t> on;
  int idx(int i, int j) const { return j * nx + i; }
  bool in(int i, int j) const { return i >= 0 && j >= 0 && i < nx && j < ny; }
  int ci(double u) const { return static_cast<int>(std::floor((u - u0) / cell)); }
  int cj(double v) const { return static_cast<int>(std::floor((v - v0) / cell)); }
  void morph(bool dilate) {
    std::vector<std::uint8_t> out = on;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        bool any = false, all = true;
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const bool v = in(i + di, j + dj) && on[idx(i + di, j + dj)];
            any = any || v;
            all = all && v;
          }
        out[idx(i, j)] = dilate ? any : all;
      }
    on = out;
  }
  // Empty cells that the grid's border cannot reach through empty cells (4-connected) become
  // set: holes in the silhouette, not the gaps between fingers, which open to the outside.
  void fill_holes() {
    std::vector<std::uint8_t> outside(on.size(), 0);
    std::queue<int> qu;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        if ((i == 0 || j == 0 || i == nx - 1 || j == ny - 1) && !on[idx(i, j)]) outside[idx(i, j)] = 1, qu.push(idx(i, j));
    while (!qu.empty()) {
      const int k = qu.front();
      qu.pop();
      const int a = k % nx, b = k / nx;
      for (auto [da, db] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
        if (in(a + da, b + db) && !on[idx(a + da, b + db)] && !outside[idx(a + da, b + db)])
          outside[idx(a + da, b + db)] = 1, qu.push(idx(a + da, b + db));
    }
    for (size_t k = 0; k < on.size(); ++k) on[k] = !outside[k];
  }
  // Distance (in cells) to the nearest empty cell: two-pass 3-4 chamfer.
  std::vector<double> distance() const {
    std::vector<double> d(on.size());
    for (size_t k = 0; k < on.size(); ++k) d[k] = on[k] ? 1e9 : 0;
    auto relax = [&](int i, int j, int di, int dj, double w) {
      if (in(i + di, j + dj)) d[idx(i, j)] = std::min(d[idx(i, j)], d[idx(i + di, j + dj)] + w);
    };
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) relax(i, j, -1, 0, 3), relax(i, j, 0, -1, 3), relax(i, j, -1, -1, 4), relax(i, j, 1, -1, 4);
    for (int j = ny - 1; j >= 0; --j)
      for (int i = nx - 1; i >= 0; --i) relax(i, j, 1, 0, 3), relax(i, j, 0, 1, 3), relax(i, j, 1, 1, 4), relax(i, j, -1, 1, 4);
    for (double& x : d) x /= 3.0;
    return d;
  }
};

// The silhouette's breadth (across Yh) in 1 mm steps along Xh from the cut to the MCPs,
// fitted with a continuous two-piece line (a hinge); the hinge where the breadth starts to
// grow fast. Empty when the fit shows no such knee (the slope must at least double).
std::optional<double> breadth_knee(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector3d& Xh,
                                   const Eigen::Vector3d& Yh, double cut, double mcp_x, double s) {
  // Searched from the cut (or 170 nominal mm before the MCPs) to 60 before them: the knee
  // lies ~85 before them, and further into the palm the breadth grows slower again. The
  // forearm stub before the knee is the hinge's flat piece: a window that began 120 mm
  // before the MCPs lost most of it when the scale of the last round was too large (a 40 mm
  // stub, the knee not yet found), and the knee with it.
  const double x0 = std::max(cut + 1.5, mcp_x - 170 * s), x1 = mcp_x - 60 * s;
  const int n = static_cast<int>(x1 - x0);
  if (n < 8) return std::nullopt;
  std::vector<double> lo(n, 1e300), hi(n, -1e300);
  for (const auto& q : h) {
    const int b = static_cast<int>(std::floor(q.dot(Xh) - x0));
    if (b < 0 || b >= n) continue;
    lo[b] = std::min(lo[b], q.dot(Yh)), hi[b] = std::max(hi[b], q.dot(Yh));
  }
  std::vector<Eigen::Vector2d> xw;
  for (int b = 0; b < n; ++b)
    if (hi[b] > lo[b]) xw.emplace_back(x0 + b + 0.5, hi[b] - lo[b]);
  if (xw.size() < 8) return std::nullopt;
  double best = 1e300, best_k = 0, b1 = 0, b2 = 0;
  for (double k = x0 + 1; k <= x1 - 4; k += 0.5) {
    Eigen::MatrixXd A(xw.size(), 3);
    Eigen::VectorXd y(xw.size());
    for (size_t i = 0; i < xw.size(); ++i) {
      A.row(i) << 1, std::min(xw[i].x() - k, 0.0), std::max(xw[i].x() - k, 0.0);
      y(i) = xw[i].y();
    }
    const Eigen::Vector3d c = A.colPivHouseholderQr().solve(y);
    const double sse = (A * c - y).squaredNorm();
    if (sse < best) best = sse, best_k = k, b1 = c(1), b2 = c(2);
  }
  if (!(b2 > 0.3 && b2 > 2 * std::max(b1, 0.0))) return std::nullopt;
  return best_k;
}

// The middle of the cloud's section through `at` square to `a` (the points within 1.5 mm of
// that plane and within `window` of `at` along e1 and e2): the midpoint of their extents
// along e1 and e2, moved to and measured again, three times. Empty when the section does not
// close inside the window (it runs on into the palm or a neighbour) or holds < 30 points.
std::optional<Eigen::Vector3d> section_middle(const std::vector<Eigen::Vector3d>& h, Eigen::Vector3d at,
                                              const Eigen::Vector3d& a, const Eigen::Vector3d& e1,
                                              const Eigen::Vector3d& e2, double window) {
  for (int it = 0; it < 3; ++it) {
    double lo1 = 1e300, hi1 = -1e300, lo2 = 1e300, hi2 = -1e300;
    int n = 0;
    for (const auto& p : h) {
      const Eigen::Vector3d d = p - at;
      if (std::abs(d.dot(a)) > 1.5) continue;
      const double x1 = d.dot(e1), x2 = d.dot(e2);
      if (std::abs(x1) > window || std::abs(x2) > window) continue;
      lo1 = std::min(lo1, x1), hi1 = std::max(hi1, x1), lo2 = std::min(lo2, x2), hi2 = std::max(hi2, x2);
      ++n;
    }
    const double edge = 0.9 * window;
    if (n < 30 || lo1 < -edge || hi1 > edge || lo2 < -edge || hi2 > edge) return std::nullopt;
    at += 0.5 * (lo1 + hi1) * e1 + 0.5 * (lo2 + hi2) * e2;
  }
  return at;
}

// Points linked through points within `link` mm of each other, over a hash grid of
// `link`-sized cells: labels spread breadth first from every labelled point of `idx` (indices
// into h; label[i] >= 0) at once to the unlabelled ones (-1), each taking the label of the
// point it is reached from. Points no label reaches keep -1. With no label given, `fresh`
// starts a new label at each point not yet reached (in idx's order): the pieces the links
// connect.
void spread_labels(const std::vector<Eigen::Vector3d>& h, const std::vector<size_t>& idx, double link,
                   std::vector<int>* label, bool fresh = false) {
  auto key = [link](const Eigen::Vector3d& p) {
    return std::array<long, 3>{static_cast<long>(std::floor(p.x() / link)), static_cast<long>(std::floor(p.y() / link)),
                               static_cast<long>(std::floor(p.z() / link))};
  };
  std::map<std::array<long, 3>, std::vector<size_t>> cells;
  std::queue<size_t> qu;
  for (size_t i : idx) {
    cells[key(h[i])].push_back(i);
    if ((*label)[i] >= 0) qu.push(i);
  }
  int next = 0;
  for (size_t i : idx) next = std::max(next, (*label)[i] + 1);
  auto drain = [&] {
    while (!qu.empty()) {
      const size_t i = qu.front();
      qu.pop();
      const auto c = key(h[i]);
      for (long dx = -1; dx <= 1; ++dx)
        for (long dy = -1; dy <= 1; ++dy)
          for (long dz = -1; dz <= 1; ++dz) {
            const auto it = cells.find({c[0] + dx, c[1] + dy, c[2] + dz});
            if (it == cells.end()) continue;
            for (size_t m : it->second)
              if ((*label)[m] < 0 && (h[m] - h[i]).squaredNorm() <= link * link) (*label)[m] = (*label)[i], qu.push(m);
          }
    }
  };
  drain();
  if (!fresh) return;
  for (size_t i : idx)
    if ((*label)[i] < 0) (*label)[i] = next++, qu.push(i), drain();
}

// A finger's section centres carried toward the palm from its first one (at t = lateral's
// front), through the whole cloud `h`: every 3 mm, the finger lies between the lowest points
// of the back's profile across it (the grooves between it and its neighbours), or the gaps
// where nothing was seen, on either side of where the centres so far put it. Stops at the
// second section where no groove 1 mm deep bounds it on both sides or its width is not within
// 0.6-1.5 times the measured sections' median (the knuckles flatten into the palm's back),
// or 60 mm on. Centres are added at the front (t ascending), as (t, lateral offset, 0).
void extend_proximally(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& m2, const Eigen::Vector2d& d2,
                       const Eigen::Vector2d& n2, std::vector<double> widths, std::vector<Eigen::Vector3d>* lateral) {
  constexpr double kBin = 0.5, kReach = 60, kStep = 3, kGroove = 1.0;
  std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
  const double wd = widths[widths.size() / 2], half = 1.5 * wd;
  const double t_start = lateral->front().x();
  struct Local {
    double t, l, z;
  };
  std::vector<Local> near;
  for (const auto& q : h) {
    const Eigen::Vector2d d = q.head<2>() - m2;
    const double t = d.dot(d2);
    if (t < t_start - kReach - 2 || t > t_start) continue;
    near.push_back({t, d.dot(n2), q.z()});
  }
  const int nb = static_cast<int>(std::ceil(2 * half / kBin)), inner = static_cast<int>(std::round(0.25 * wd / kBin));
  if (nb < 8) return;
  std::vector<double> top(nb);
  int misses = 0;
  for (double t = t_start - kStep; t > t_start - kReach && misses < 2; t -= kStep) {
    // The line through the centres so far predicts where the finger lies.
    double st = 0, sl = 0, stt = 0, stl = 0;
    for (const auto& c : *lateral) st += c.x(), sl += c.y(), stt += c.x() * c.x(), stl += c.x() * c.y();
    const double n = static_cast<double>(lateral->size()), den = n * stt - st * st;
    const double slope = std::abs(den) > 1e-9 ? (n * stl - st * sl) / den : 0;
    const double cp = (sl - slope * st) / n + slope * t, l0 = cp - half;
    std::fill(top.begin(), top.end(), -1e300);  // the back's height per bin; -1e300: nothing seen
    for (const Local& q : near) {
      if (std::abs(q.t - t) > 1.5 || std::abs(q.l - cp) >= half) continue;
      const int b = std::clamp(static_cast<int>((q.l - l0) / kBin), 0, nb - 1);
      top[b] = std::max(top[b], q.z);
    }
    const int cb = nb / 2;
    // The groove (or gap) on each side: the lowest bin; among empty ones, the nearest.
    auto valley = [&](int from, int to, int step) {
      int best = -1;
      for (int b = from; b != to; b += step)
        if (best < 0 || top[b] < top[best]) best = b;
      return best;
    };
    const int left = valley(cb - inner, -1, -1), right = valley(cb + inner, nb, +1);
    bool ok = left >= 0 && right >= 0;
    double ridge = -1e300;
    for (int b = left + 1; ok && b < right; ++b) ridge = std::max(ridge, top[b]);
    ok = ok && ridge > -1e299 && ridge - top[left] >= kGroove && ridge - top[right] >= kGroove;
    const double width = (right - left) * kBin;
    ok = ok && width >= 0.6 * wd && width <= 1.5 * wd;
    if (!ok) {
      ++misses;
      continue;
    }
    misses = 0;
    lateral->insert(lateral->begin(), Eigen::Vector3d(t, l0 + 0.5 * (left + right + 1) * kBin, 0));
  }
}
}  // namespace

AutoRig place_skeleton(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides) {
  if (pts.size() < 1000 || sides.size() != pts.size())
    throw InputError("merged cloud", "too few points (or no side labels) to place a skeleton in");
  AutoRig out;
  // --- the hand's frame: long axis, thickness axis toward the back, the wrist's end ---
  Eigen::Matrix3d axes;
  Eigen::Vector3d c;
  principal_axes<3>(pts, &axes, &c);
  Eigen::Vector3d X = axes.col(0), Z = axes.col(2);
  Eigen::Vector3d back = Eigen::Vector3d::Zero(), palm = Eigen::Vector3d::Zero();
  size_t nb = 0, np = 0;
  for (size_t i = 0; i < pts.size(); ++i) (sides[i] == 1 ? (++nb, back) : (++np, palm)) += pts[i];
  if (nb == 0 || np == 0) throw InputError("merged cloud", "needs points of both scans (back and palm) to place a skeleton");
  if ((back / nb - palm / np).dot(Z) < 0) Z = -Z;
  double umin = 1e300, umax = -1e300;
  for (const auto& p : pts) umin = std::min(umin, (p - c).dot(X)), umax = std::max(umax, (p - c).dot(X));
  auto end_thickness = [&](bool low) {
    double lo = 1e300, hi = -1e300;
    for (const auto& p : pts) {
      const double u = (p - c).dot(X);
      if (low ? u < umin + 15 : u > umax - 15) lo = std::min(lo, (p - c).dot(Z)), hi = std::max(hi, (p - c).dot(Z));
    }
    return hi - lo;
  };
  if (end_thickness(false) > end_thickness(true)) X = -X;  // the wrist's cut end is the thicker (checked below)
  Eigen::Vector3d Y = Z.cross(X);  // flipped below for a left hand
  std::vector<Eigen::Vector3d> h(pts.size());  // hand coordinates (u, v, w)
  // The height (Z, toward the back) at `share` of the cloud's thickness from its back, over a
  // disc of `radius` about (x, y); nothing where fewer than 5 points lie there.
  auto depth_at = [&h](const Eigen::Vector3d& at, double share, double radius) -> std::optional<double> {
    double lo = 1e300, hi = -1e300;
    int n = 0;
    for (const auto& q : h)
      if ((q.head<2>() - at.head<2>()).squaredNorm() < radius * radius) lo = std::min(lo, q.z()), hi = std::max(hi, q.z()), ++n;
    if (n < 5) return std::nullopt;
    return hi - share * (hi - lo);
  };
  // (A lambda of Y by reference: it maps back through the mirrored Y for a left hand.)
  auto to_cloud = [&](const Eigen::Vector3d& q) { return Eigen::Vector3d(c + q.x() * X + q.y() * Y + q.z() * Z); };

  // --- silhouette, palm centre (largest inscribed circle), digits beyond an opening of it ---
  Grid g;
  std::vector<int> cell_of(h.size());
  std::vector<double> dist, to_core;
  double R = 0, r0 = 0;
  Eigen::Vector2d pc;
  std::vector<std::uint8_t> digit_cell;
  std::vector<std::vector<int>> comps;
  constexpr size_t kDigitCells = 150;  // smaller pieces are specks the opening left
  auto count_digits = [&](const std::vector<std::vector<int>>& cs) {
    return std::count_if(cs.begin(), cs.end(), [&](const auto& cc) { return cc.size() >= kDigitCells; });
  };
  // 4-connected components of a cell mask, in scan order.
  auto components = [&g](const std::vector<std::uint8_t>& mask) {
    std::vector<int> comp(mask.size(), -1);
    std::vector<std::vector<int>> found;
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        if (!mask[g.idx(i, j)] || comp[g.idx(i, j)] >= 0) continue;
        std::vector<int> cells;
        std::queue<std::pair<int, int>> qu;
        qu.push({i, j});
        comp[g.idx(i, j)] = static_cast<int>(found.size());
        while (!qu.empty()) {
          auto [a, b] = qu.front();
          qu.pop();
          cells.push_back(g.idx(a, b));
          for (auto [da, db] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
            const int x = a + da, y = b + db;
            if (g.in(x, y) && mask[g.idx(x, y)] && comp[g.idx(x, y)] < 0) {
              comp[g.idx(x, y)] = static_cast<int>(found.size());
              qu.push({x, y});
            }
          }
        }
        found.push_back(std::move(cells));
      }
    return found;
  };
  auto beyond = [&](double t) {  // the silhouette's cells farther than t from the opened palm
    std::vector<std::uint8_t> mask(g.on.size(), 0);
    for (size_t k = 0; k < g.on.size(); ++k) mask[k] = g.on[k] && to_core[k] > t;
    return mask;
  };
  // The silhouette is made square to the cloud's thinnest axis. That is the palm's normal
  // while the digits lie near the palm's plane; a raised thumb and arched fingers tilt it
  // (21 deg on the WebXR hand model, fixtures/webxr-hand), and two neighbouring fingers at
  // different heights then overlap in the silhouette and make one digit. Only then (fewer
  // than five digits found) the frame is refitted to the palm's mid-surface — a plane halfway
  // between the back's and the palm's samples over the cells the opening keeps — until it
  // turns by less than 2 deg (at most 8 times). Hands whose five digits the first silhouette
  // finds keep it: on the family's 48 pairs the refit always was no better on the whole.
  // The silhouette is closed (2 cells) against the scans' small gaps. Fingers that lie within
  // ~4 mm of each other in it are closed into one digit too; when five digits are not found
  // that way, the search starts again from the principal frame with the silhouette unclosed
  // (only its enclosed holes filled): the WebXR hand model with its PIPs curled 25-32 deg
  // (scripts/webxr_study.py, one pair of four) brings its ring and little fingers ~2 mm
  // apart in the silhouette. Where two fingers at different heights overlap in it (the same
  // hand's other pairs, and arched: its little finger runs under the ring finger's edge),
  // no silhouette parts them: the third try takes each digit's points from the scans'
  // sheets (below).
  enum class Silhouette { Closed, Unclosed, Sheets };
  // Two digits can still join beyond the opening (below): the pieces (of at least
  // kDigitCells) farther out are grown back over the digits' cells, breadth first from all of
  // them at once: each cell goes to the piece it is nearest through them.
  auto grow_back = [&](const std::vector<std::vector<int>>& seeds) {
    std::vector<int> owner(g.on.size(), -1);
    std::queue<int> qu;
    std::vector<std::vector<int>> grown;
    for (const auto& sd : seeds) {
      if (sd.size() < kDigitCells) continue;
      for (int cidx : sd) owner[cidx] = static_cast<int>(grown.size()), qu.push(cidx);
      grown.emplace_back();
    }
    while (!qu.empty()) {
      const int cidx = qu.front();
      qu.pop();
      grown[owner[cidx]].push_back(cidx);
      const int a = cidx % g.nx, b = cidx / g.nx;
      for (auto [da, db] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int x = a + da, y = b + db;
        if (g.in(x, y) && digit_cell[g.idx(x, y)] && owner[g.idx(x, y)] < 0) {
          owner[g.idx(x, y)] = owner[cidx];
          qu.push(g.idx(x, y));
        }
      }
    }
    return grown;
  };
  // Each digit's points from the scans' sheets: beyond a distance t from the opened palm,
  // the back scan's points fall into pieces that points within kSheetLinkMm of each other
  // connect — one per digit, however the digits overlap in the silhouette, as two fingers
  // lie a gap apart in height where one runs under the other's edge — and so do the palm
  // scan's (a digit's two sheets do not meet: neither scan sees its flanks). From the first
  // t that gives five pieces of at least kSheetPoints on each side, the pieces spread over
  // their side's points in the digits' cells, and the two sides' pieces pair up in their
  // order round the palm's centre. Empty when a side never gives five.
  std::vector<std::vector<size_t>> sheet_groups;
  auto sheet_digits = [&]() {
    std::array<std::vector<std::vector<size_t>>, 2> side_groups;
    for (const std::uint32_t side : {1u, 0u}) {
      std::vector<size_t> all;
      for (size_t i = 0; i < h.size(); ++i)
        if (sides[i] == side && digit_cell[cell_of[i]]) all.push_back(i);
      for (double t = r0; t <= 2 * r0 && side_groups[side].empty(); t += 1) {
        std::vector<size_t> far;
        for (size_t i : all)
          if (to_core[cell_of[i]] > t) far.push_back(i);
        std::vector<int> label(h.size(), -1);
        spread_labels(h, far, kSheetLinkMm, &label, true);
        std::map<int, size_t> size;
        for (size_t i : far) ++size[label[i]];
        std::map<int, int> big;  // label -> digit
        for (const auto& [l, n] : size)
          if (n >= kSheetPoints) big.emplace(l, static_cast<int>(big.size()));
        if (big.size() != 5) continue;
        std::vector<int> digit(h.size(), -1);
        for (size_t i : far)
          if (const auto it = big.find(label[i]); it != big.end()) digit[i] = it->second;
        spread_labels(h, all, kSheetLinkMm, &digit);
        side_groups[side].assign(5, {});
        for (size_t i : all)
          if (digit[i] >= 0) side_groups[side][digit[i]].push_back(i);
      }
      if (side_groups[side].empty()) return std::vector<std::vector<size_t>>{};
    }
    // Each side's pieces in their order round the palm's centre (angles about the mean
    // direction of the ten, so that none wraps round).
    auto centre = [&](const std::vector<size_t>& grp) {
      Eigen::Vector2d m = Eigen::Vector2d::Zero();
      for (size_t i : grp) m += h[i].head<2>();
      return Eigen::Vector2d(m / static_cast<double>(grp.size()) - pc);
    };
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& sg : side_groups)
      for (const auto& grp : sg) mean += centre(grp).normalized();
    const double phi0 = std::atan2(mean.y(), mean.x());
    for (auto& sg : side_groups)
      std::sort(sg.begin(), sg.end(), [&](const auto& x, const auto& y) {
        auto angle = [&](const std::vector<size_t>& grp) {
          const Eigen::Vector2d d = centre(grp);
          return std::remainder(std::atan2(d.y(), d.x()) - phi0, 2 * M_PI);
        };
        return angle(x) < angle(y);
      });
    std::vector<std::vector<size_t>> groups(5);
    for (int k = 0; k < 5; ++k) {
      groups[k] = side_groups[1][k];
      groups[k].insert(groups[k].end(), side_groups[0][k].begin(), side_groups[0][k].end());
    }
    return groups;
  };
  const Eigen::Vector3d X0 = X, Z0 = Z;
  Silhouette parted_by = Silhouette::Closed;
  for (const Silhouette mode : {Silhouette::Closed, Silhouette::Unclosed, Silhouette::Sheets}) {
    X = X0, Z = Z0;
    for (int pass = 0;; ++pass) {
      Y = Z.cross(X);
      for (size_t i = 0; i < pts.size(); ++i) h[i] = Eigen::Vector3d((pts[i] - c).dot(X), (pts[i] - c).dot(Y), (pts[i] - c).dot(Z));
      Eigen::Vector3d lo = h.front(), hi = h.front();
      for (const auto& q : h) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
      g = Grid{};
      g.u0 = lo.x() - 3, g.v0 = lo.y() - 3;
      g.nx = static_cast<int>((hi.x() - lo.x()) / g.cell) + 7;
      g.ny = static_cast<int>((hi.y() - lo.y()) / g.cell) + 7;
      if (static_cast<long>(g.nx) * g.ny > 4000000) throw InputError("merged cloud", "spans more than 2 m; not a hand in mm");
      g.on.assign(static_cast<size_t>(g.nx) * g.ny, 0);
      for (size_t i = 0; i < h.size(); ++i) {
        cell_of[i] = g.idx(g.ci(h[i].x()), g.cj(h[i].y()));
        g.on[cell_of[i]] = 1;
      }
      if (mode == Silhouette::Closed)
        g.morph(true), g.morph(true), g.morph(false), g.morph(false);
      else
        g.fill_holes();
      dist = g.distance();
      const int best = static_cast<int>(std::max_element(dist.begin(), dist.end()) - dist.begin());
      R = dist[best] * g.cell;
      pc = Eigen::Vector2d(g.u0 + (best % g.nx + 0.5) * g.cell, g.v0 + (best / g.nx + 0.5) * g.cell);
      // Digits: what a morphological opening with a disc of 0.45 R removes (fingers are far
      // narrower than the palm and the wrist stub, which survive it).
      r0 = 0.45 * R / g.cell;
      Grid core = g;
      for (size_t k = 0; k < g.on.size(); ++k) core.on[k] = !(dist[k] >= r0);
      to_core = core.distance();
      digit_cell = beyond(r0);
      if (mode == Silhouette::Sheets) {
        // The digits' cells for the count: those of each group's points.
        sheet_groups = sheet_digits();
        comps.clear();
        for (const auto& grp : sheet_groups) {
          std::vector<int> cells;
          for (size_t i : grp) cells.push_back(cell_of[i]);
          std::sort(cells.begin(), cells.end());
          cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
          comps.push_back(std::move(cells));
        }
      } else {
        comps = components(digit_cell);
      }
      if (count_digits(comps) >= 5 || pass == 8) break;
      std::vector<double> zlo(g.on.size(), 1e300), zhi(g.on.size(), -1e300);
      std::vector<std::uint8_t> seen(g.on.size(), 0);
      for (size_t i = 0; i < h.size(); ++i) {
        const int k = cell_of[i];
        if (!(dist[k] >= r0)) continue;
        zlo[k] = std::min(zlo[k], h[i].z()), zhi[k] = std::max(zhi[k], h[i].z());
        seen[k] |= sides[i] == 1 ? 1 : 2;
      }
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      for (size_t k = 0; k < g.on.size(); ++k) {
        if (seen[k] != 3) continue;
        const Eigen::Vector3d row(g.u0 + (k % g.nx + 0.5) * g.cell, g.v0 + (k / g.nx + 0.5) * g.cell, 1.0);
        A += row * row.transpose();
        rhs += row * 0.5 * (zlo[k] + zhi[k]);
      }
      if (A(2, 2) < 500) break;  // too little of the palm seen from both sides
      const Eigen::Vector3d plane = A.ldlt().solve(rhs);  // mid-surface z = a u + b v + c
      const Eigen::Vector3d Zp = (Z - plane(0) * X - plane(1) * Y).normalized();
      if (!Zp.allFinite() || Zp.dot(Z) > std::cos(2 * M_PI / 180)) break;
      Z = Zp;
      X = (X - X.dot(Z) * Z).normalized();
    }
    out.palm_radius_mm = R;
    // Two digits can still join beyond the opening: a little finger whose web lies far
    // proximal of the ring finger's leaves a band along the palm's edge, outside the opening,
    // that links their bases. Farther from the palm they part: the pieces found beyond the
    // first distance that gives five digits are grown back over the digits' cells (breadth
    // first from all of them at once: each cell goes to the piece it is nearest through them).
    // (Not for the sheets' try: its silhouette is the unclosed one, already tried so.)
    if (count_digits(comps) < 5 && mode != Silhouette::Sheets) {
      const long before = count_digits(comps);
      for (double t = r0 + 1; t <= 2 * r0; t += 1) {
        const std::vector<std::vector<int>> seeds = components(beyond(t));
        const long n = count_digits(seeds);
        if (n < before) break;  // a digit ends before the joined ones part
        if (n != 5) continue;
        comps = grow_back(seeds);
        break;
      }
    }
    if (count_digits(comps) == 5) {
      if (mode == Silhouette::Unclosed)
        out.notes.push_back("digits found in the silhouette left unclosed (two fingers lie within ~4 mm)");
      if (mode == Silhouette::Sheets)
        out.notes.push_back("digits parted by the scans' sheets (two fingers overlap in the silhouette)");
      parted_by = mode;
      break;
    }
  }
  struct Digit {
    std::vector<size_t> points;
    double angle = 0;
    double width = 0;  // the median width of its measured sections (across it, in the silhouette)
    // Centre line (hand coordinates) from well inside the palm to the skin's tip, sampled
    // every 0.25 mm, with its arc length: a curled or arched digit's axis is a curve.
    std::vector<Eigen::Vector3d> curve;
    std::vector<double> arc;
    Eigen::Vector3d tip_skin = Eigen::Vector3d::Zero();
    // The point at arc length `a` (clamped to the curve).
    Eigen::Vector3d at(double a) const {
      const size_t i = std::clamp<size_t>(std::lower_bound(arc.begin(), arc.end(), a) - arc.begin(), 1, arc.size() - 1);
      const double u = std::clamp((a - arc[i - 1]) / std::max(arc[i] - arc[i - 1], 1e-9), 0.0, 1.0);
      return curve[i - 1] + u * (curve[i] - curve[i - 1]);
    }
    double length() const { return arc.back(); }
    // The arc length, before `a_from`, of the point `chord` (straight line) from `from`: the
    // next joint back along the centre line (a bent chain's corners are a bone's length apart).
    double chord_back(const Eigen::Vector3d& from, double chord, double a_from) const {
      double lo = 0, hi = a_from;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        ((at(mid) - from).norm() > chord ? lo : hi) = mid;
      }
      return 0.5 * (lo + hi);
    }
  };
  // The centre line's direction at the curve point nearest q.
  auto tangent_near = [](const Digit& dg, const Eigen::Vector3d& q) {
    size_t best = 1;
    double bd = 1e300;
    for (size_t k = 1; k < dg.curve.size(); ++k)
      if (const double d = (dg.curve[k] - q).squaredNorm(); d < bd) bd = d, best = k;
    return Eigen::Vector3d((dg.curve[best] - dg.curve[best - 1]).normalized());
  };
  std::vector<Digit> digits;
  for (size_t k = 0; k < comps.size(); ++k) {
    if (comps[k].size() < kDigitCells) continue;
    Digit dg;
    Eigen::Vector2d m = Eigen::Vector2d::Zero();
    for (int cidx : comps[k]) m += Eigen::Vector2d(g.u0 + (cidx % g.nx + 0.5) * g.cell, g.v0 + (cidx / g.nx + 0.5) * g.cell);
    m /= static_cast<double>(comps[k].size());
    dg.angle = std::atan2(m.y() - pc.y(), m.x() - pc.x());
    if (parted_by == Silhouette::Sheets && sheet_groups.size() == comps.size()) {
      dg.points = sheet_groups[k];
      digits.push_back(dg);
      continue;
    }
    digits.push_back(dg);
    std::vector<std::uint8_t> mine(g.on.size(), 0);
    for (int cidx : comps[k]) mine[cidx] = 1;
    for (size_t i = 0; i < h.size(); ++i)
      if (mine[cell_of[i]]) digits.back().points.push_back(i);
  }
  if (digits.size() != 5)
    throw InputError("merged cloud", "automatic skeleton placement found " + std::to_string(digits.size()) +
                                         " digits beyond the palm, not 5 (fingers touching or missing?); give a rig");
  // The digits lie beyond the palm's centre toward the fingers' end. If most lie the other
  // way, the end taken for the wrist's (the thicker) was the fingers' (a short forearm stub,
  // curled fingers, a hanging thumb): turn the frame half round about Z.
  double toward = 0;
  for (const Digit& dg : digits) toward += std::cos(dg.angle);
  if (toward < 0) {
    X = -X, Y = -Y;
    for (auto& q : h) q.x() = -q.x(), q.y() = -q.y();
    pc = -pc;
    for (Digit& dg : digits) dg.angle = dg.angle > 0 ? dg.angle - M_PI : dg.angle + M_PI;
  }
  std::sort(digits.begin(), digits.end(), [](const Digit& a, const Digit& b) { return a.angle < b.angle; });
  // Back up, a right hand's thumb lies on +Y (Y = Z × X), a left hand's on −Y: the thumb is
  // the digit beyond the widest angular gap. A left hand is worked on in mirrored
  // coordinates (Y flipped), where it is a right hand; the joints go back through the same Y.
  const double gap_top = digits[4].angle - digits[3].angle, gap_bottom = digits[1].angle - digits[0].angle;
  out.side = HandSide::Right;
  if (gap_bottom > gap_top) {
    out.side = HandSide::Left;
    Y = -Y;
    for (auto& q : h) q.y() = -q.y();
    pc.y() = -pc.y();
    for (Digit& dg : digits) dg.angle = -dg.angle;
    std::sort(digits.begin(), digits.end(), [](const Digit& a, const Digit& b) { return a.angle < b.angle; });
  }

  // --- each digit's axis: a line through its section centres ---
  for (Digit& dg : digits) {
    std::vector<Eigen::Vector2d> p2;
    for (size_t i : dg.points) p2.push_back(h[i].head<2>());
    Eigen::Matrix2d ax;
    Eigen::Vector2d m2;
    principal_axes<2>(p2, &ax, &m2);
    Eigen::Vector2d d2 = ax.col(0);
    if (d2.dot(m2 - pc) < 0) d2 = -d2;
    const Eigen::Vector2d n2(-d2.y(), d2.x());
    double t0 = 1e300, t1 = -1e300;
    for (const auto& q : p2) t0 = std::min(t0, (q - m2).dot(d2)), t1 = std::max(t1, (q - m2).dot(d2));
    std::vector<Eigen::Vector3d> centres;  // (t, lateral offset, z)
    std::vector<double> widths;            // each section's width across the digit
    for (double t = t0 + 2; t < t1 - 6; t += 3) {
      double a = 1e300, b = -1e300, zl = 1e300, zh = -1e300;
      int n = 0;
      for (size_t i : dg.points) {
        const Eigen::Vector2d q = h[i].head<2>() - m2;
        if (std::abs(q.dot(d2) - t) > 1.5) continue;
        a = std::min(a, q.dot(n2)), b = std::max(b, q.dot(n2));
        zl = std::min(zl, h[i].z()), zh = std::max(zh, h[i].z());
        ++n;
      }
      if (n < 20) continue;
      centres.emplace_back(t, 0.5 * (a + b), 0.5 * (zl + zh));
      widths.push_back(b - a);
    }
    // Sections much narrower or wider than the digit's median are not across it: the
    // opening's remnant ends in a thin sliver along its boundary between the digits' roots,
    // and those sections' middles drew a short digit's line 20-30 deg aside (H12's little
    // finger: its PIP 11 mm off).
    if (widths.size() >= 4) {
      std::vector<double> ws = widths;
      std::nth_element(ws.begin(), ws.begin() + ws.size() / 2, ws.end());
      const double wm = ws[ws.size() / 2];
      std::vector<Eigen::Vector3d> kept_c;
      std::vector<double> kept_w;
      for (size_t k = 0; k < widths.size(); ++k)
        if (widths[k] >= 0.6 * wm && widths[k] <= 1.4 * wm) kept_c.push_back(centres[k]), kept_w.push_back(widths[k]);
      if (kept_c.size() >= 4) centres.swap(kept_c), widths.swap(kept_w);
      dg.width = wm;
    }
    // A digit does not bend sideways: from the tip's end, the centres that keep to one line.
    // The opening's remnant can carry on past the finger's root as a sliver along its
    // neighbour's boundary, of a finger's width but beside the finger's line (H12's close
    // little finger: the sliver's middles turned its line 20 deg and put its PIP 9.6 mm off).
    // The distal four start the line; each centre toward the palm joins it while it lies
    // within kLateralStrayMm of the line through those kept; the first that strays ends it.
    if (centres.size() > 4) {
      auto stray = [&](size_t first, size_t k) {  // distance of centre k from the line fitted to first..end
        double st = 0, sl = 0, stt = 0, stl = 0;
        const double n = static_cast<double>(centres.size() - first);
        for (size_t i = first; i < centres.size(); ++i) {
          st += centres[i].x(), sl += centres[i].y();
          stt += centres[i].x() * centres[i].x(), stl += centres[i].x() * centres[i].y();
        }
        const double den = n * stt - st * st;
        const double b = std::abs(den) > 1e-12 ? (n * stl - st * sl) / den : 0.0, a = (sl - b * st) / n;
        return std::abs(centres[k].y() - (a + b * centres[k].x()));
      };
      size_t first = centres.size() - 4;
      while (first > 0 && stray(first, first - 1) <= kLateralStrayMm) --first;
      if (first > 0) {
        centres.erase(centres.begin(), centres.begin() + static_cast<long>(first));
        widths.erase(widths.begin(), widths.begin() + static_cast<long>(first));
      }
    }
    if (centres.size() < 4) throw InputError("merged cloud", "a digit is too short to find its axis; give a rig");
    // The lateral line is fitted to these centres and to more toward the palm: the opening
    // leaves only the distal part of fingers that lie close together, and a short line
    // carried 40-60 mm into the palm strayed 5-10 mm sideways at the MCPs (H12).
    std::vector<Eigen::Vector3d> lateral = centres;
    if (&dg - digits.data() < 4) extend_proximally(h, m2, d2, n2, widths, &lateral);
    // Lateral offset and height as polynomials of t (least squares). Fingers flex, they do
    // not bend sideways between their joints: the lateral offset is a line; the height a
    // quadratic where the measured span is long enough to show a curl (a flexed digit arches
    // out of the hand's plane). Beyond the measured centres the curve goes on along its end
    // tangents (straight into the palm, straight to the tip).
    const double tm = 0.5 * (centres.front().x() + centres.back().x());
    const bool curl = centres.size() >= 6 && centres.back().x() - centres.front().x() >= 25;
    auto fit = [&](const std::vector<Eigen::Vector3d>& cs, int coordinate, bool quadratic) {
      // coefficients of 1, u, u² (u = t − tm)
      const int n = quadratic ? 3 : 2;
      Eigen::MatrixXd A(cs.size(), n);
      Eigen::VectorXd b(cs.size());
      for (size_t k = 0; k < cs.size(); ++k) {
        const double u = cs[k].x() - tm;
        A(k, 0) = 1, A(k, 1) = u;
        if (quadratic) A(k, 2) = u * u;
        b(k) = cs[k](coordinate);
      }
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      c.head(n) = A.colPivHouseholderQr().solve(b);
      return c;
    };
    const Eigen::Vector3d cl = fit(lateral, 1, false), cz = fit(centres, 2, curl);
    const double ta = centres.front().x(), tb = centres.back().x();
    auto point = [&](double t) {
      const double u = std::clamp(t, ta, tb) - tm, e = t - std::clamp(t, ta, tb);
      const double l = cl(0) + cl(1) * u + cl(2) * u * u + e * (cl(1) + 2 * cl(2) * u);
      const double z = cz(0) + cz(1) * u + cz(2) * u * u + e * (cz(1) + 2 * cz(2) * u);
      const Eigen::Vector2d q = m2 + t * d2 + l * n2;
      return Eigen::Vector3d(q.x(), q.y(), z);
    };
    // The tip: the digit's farthest point along the curve's end direction.
    const Eigen::Vector3d end = point(tb), end_dir = (point(tb + 1) - end).normalized();
    double reach = -1e300;
    for (size_t i : dg.points) reach = std::max(reach, (h[i] - end).dot(end_dir));
    dg.tip_skin = end + reach * end_dir;
    for (double t = ta - 80; t < tb; t += 0.25) dg.curve.push_back(point(t));
    dg.curve.push_back(end);
    dg.curve.push_back(dg.tip_skin);
    dg.arc.assign(1, 0.0);
    for (size_t k = 1; k < dg.curve.size(); ++k) dg.arc.push_back(dg.arc.back() + (dg.curve[k] - dg.curve[k - 1]).norm());
  }

  // --- scale from the middle fingertip and the wrist cut; joints by the proportions ---
  // The rig's hand frame (X from the wrist to the middle MCP) is only approximated by the
  // principal axes, and the wrist, the scale and the MCPs depend on one another: three
  // rounds of wrist → scale → digit joints → frame.
  const Digit& middle = digits[2];
  Eigen::Vector3d Xh = Eigen::Vector3d::UnitX(), W = Eigen::Vector3d::Zero();
  double s = 1;
  std::array<std::vector<Eigen::Vector3d>, 5> chains;  // hand coordinates, MCP ... tip
  double thumb_mcp_arc = 0;                            // the thumb's MCP along its centre line
  for (int round = 0; round < 3; ++round) {
    const Eigen::Vector3d Yh = Eigen::Vector3d::UnitZ().cross(Xh);
    double cut = 1e300;
    for (const auto& q : h) cut = std::min(cut, q.dot(Xh));
    // The hand's length along the middle finger's centre line (a curled finger is longer
    // than its shadow): to the middle MCP (where the last round put it), then along the curve.
    const double a_mcp_guess =
        std::max(0.0, middle.length() - (kTipInset + kFingers[2].distal + kFingers[2].middle + kFingers[2].proximal) * s);
    const double mcp_x = middle.at(a_mcp_guess).dot(Xh), to_tip = middle.length() - a_mcp_guess;
    // The wrist: where the palm starts to widen into the thenar and hypothenar eminences, a
    // knee in the silhouette's breadth along the hand, kKneeBeyondWrist beyond the joint.
    // The cut is where the replica was sawn off (a forearm stub of any length): only a
    // fallback when no knee shows.
    const std::optional<double> knee = breadth_knee(h, Xh, Yh, cut, mcp_x, s);
    double wrist_x;
    if (knee) {
      s = (mcp_x - *knee + to_tip) / (kNominalHandLength - kKneeBeyondWrist);
      wrist_x = *knee - kKneeBeyondWrist * s;
    } else {
      s = (mcp_x - cut + to_tip) / (kNominalHandLength + kWristCut);
      wrist_x = cut + kWristCut * s;
    }
    double vl = 1e300, vh = -1e300, wl = 1e300, wh = -1e300;
    for (const auto& q : h)
      if (q.dot(Xh) < cut + 10) vl = std::min(vl, q.dot(Yh)), vh = std::max(vh, q.dot(Yh)), wl = std::min(wl, q.z()), wh = std::max(wh, q.z());
    W = wrist_x * Xh + 0.5 * (vl + vh) * Yh + 0.5 * (wl + wh) * Eigen::Vector3d::UnitZ();
    // Its height from the thickness a disc's radius inside the cut: a disc at the cut itself
    // (a cast sawn off at the wrist, no stub) holds the rim only, often one scan's side, and
    // put the wrist 10 mm toward the palm (H03).
    const Eigen::Vector3d W_in = W + std::max(0.0, cut + 3 * s - wrist_x) * Xh;
    if (const auto z = depth_at(W_in, kWristDepth, 3 * s)) W.z() = *z;
    // digits sorted little, ring, middle, index, thumb → fingers 4, 3, 2, 1, 0; joints back
    // from the tip along the centre line by the proportions' lengths.
    for (int k = 0; k < 5; ++k) {
      const int fi = 4 - k;
      const Digit& dg = digits[k];
      const FingerSpec& f = kFingers[fi];
      const std::vector<double> lengths = fi == 0 ? std::vector<double>{f.distal, f.proximal}
                                                  : std::vector<double>{f.distal, f.middle, f.proximal};
      double a = dg.length() - kTipInset * s;
      std::vector<Eigen::Vector3d> js = {dg.at(a)};
      for (size_t li = 0; li < lengths.size(); ++li) {
        const double L = lengths[li];
        // Chord, not arc: the joints are the corners of the bent chain.
        const Eigen::Vector3d from = js.back();
        a = dg.chord_back(from, L * s, a);
        Eigen::Vector3d j = dg.at(a);
        if (fi != 0 && fi != 2 && li + 1 == lengths.size()) {
          // A finger's MCP is its metacarpal's head: a spread finger turns there, so the
          // phalanx's line, carried on into the palm, passes beside it. The joint is put
          // the proximal phalanx's length from the PIP toward where the proportions put
          // the metacarpal's head across the hand (its height from the centre line). Not the
          // middle finger's: its MCP sets the frame's X (and its phalanges point along it).
          // (The proportions' frame turned so that the middle finger's head lies on X, as the
          // rig's hand frame has it.)
          auto head_of = [](const FingerSpec& g) {
            const double h = g.angle_deg * M_PI / 180.0;
            return Eigen::Vector2d(g.cmc.x() + g.metacarpal * std::cos(h), g.cmc.y() + g.metacarpal * std::sin(h));
          };
          const Eigen::Vector2d mid = head_of(kFingers[2]);
          const Eigen::Vector2d hd = Eigen::Rotation2Dd(-std::atan2(mid.y(), mid.x())) * head_of(f);
          const Eigen::Vector3d head = W + s * hd.x() * Xh + s * hd.y() * Yh;
          Eigen::Vector3d target = j;
          target.head<2>() = head.head<2>();
          const Eigen::Vector3d aim = target - from;
          j = from + L * s * aim.normalized();
        }
        js.push_back(j);
      }
      // A finger's MCP lies in the palm: its height from the palm's thickness there.
      std::optional<double> mcp_z;
      if (fi != 0) mcp_z = depth_at(js.back(), kMetacarpalDepth, 3 * s);
      // The bones lie dorsal of a digit's section middle (the palmar pad is the thicker
      // side): the joints are lifted by kDorsalOffset, square to the centre line.
      for (Eigen::Vector3d& j : js) {
        Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d tl = tangent_near(dg, j);
        up = (up - up.dot(tl) * tl).normalized();
        j += kDorsalOffset * s * up;
      }
      if (mcp_z) js.back().z() = *mcp_z;
      std::reverse(js.begin(), js.end());
      chains[fi] = js;
      if (fi == 0) thumb_mcp_arc = a;
    }
    Xh = chains[2].front() - W;
    Xh.z() = 0;
    Xh.normalize();
  }
  // The thumb's MCP and IP on the middle of the cloud's sections through them. The centre
  // line's height is a quadratic fitted to the part beyond the palm's opening and carried on
  // straight; a raised thumb bent at its MCP (the WebXR hand model posed about parallel axes,
  // ~25 deg out of the palm's plane and flexed 10 deg) had its MCP there 5.4 mm below the
  // thumb's middle. On the family the skins' mean went 0.0748 -> 0.0746 mm with it.
  if (const double dg_thumb_width = digits[4].width; dg_thumb_width > 0) {
    std::vector<Eigen::Vector3d>& js = chains[0];  // MCP, IP, tip
    // Each joint moves as the middle of the section at `along` of the way from it to the
    // next joint out: the IP's own section is free of the palm; at the MCP the thenar runs
    // on below the thumb, but a third of the way out along its proximal phalanx it is clear.
    for (const auto& [k, along] : {std::pair{1, 0.0}, std::pair{0, 0.35}}) {
      const Eigen::Vector3d a = (js[k + 1] - js[k]).normalized(), q = js[k] + along * (js[k + 1] - js[k]);
      Eigen::Vector3d e1 = Eigen::Vector3d::UnitZ() - a.z() * a;
      if (e1.norm() < 0.3) continue;  // a thumb pointing up or down out of the hand: no height to centre
      e1.normalize();
      const Eigen::Vector3d e2 = a.cross(e1), up = kDorsalOffset * s * e1;
      if (const auto m = section_middle(h, q - up, a, e1, e2, dg_thumb_width)) js[k] += *m + up - q;
    }
  }
  out.scale = s;
  Rig& rig = out.rig;
  rig.frame = "palm";
  rig.joints[0] = to_cloud(W);
  // The metacarpal bases at their nominal places in that frame.
  const Eigen::Vector3d Yh = Eigen::Vector3d::UnitZ().cross(Xh);
  for (int fi = 0; fi < 5; ++fi) {
    const FingerSpec& f = kFingers[fi];
    const auto chain = finger_chain(static_cast<Finger>(fi));
    Eigen::Vector3d cmc = W + s * (f.cmc.x() * Xh + f.cmc.y() * Yh);
    cmc.z() = fi == 0 ? W.z() - 6.0 * s : chains[fi].front().z();
    if (const auto z = depth_at(cmc, fi == 0 ? kThumbBaseDepth : kMetacarpalDepth, 3 * s)) cmc.z() = *z;
    rig.joints[chain[0]] = to_cloud(cmc);
    for (size_t k2 = 0; k2 < chains[fi].size(); ++k2) rig.joints[chain[k2 + 1]] = to_cloud(chains[fi][k2]);
  }
  // The palm's normal from the placed joints, square to the wrist -> middle MCP line and to
  // the index -> little MCP line (toward the back, as Z): the frame the skin stage slices in.
  // Z itself, the cloud's thinnest axis (or the palm's mid-surface), can lie 20 deg off it
  // in roll on an arched hand (the WebXR hand flexed 8-14 deg at the MCPs: 21 deg), and in
  // that frame the little finger ran under the ring finger's edge: the ring-little web was
  // found beyond the little finger's PIP and the palm's last ring folded.
  {
    const auto at = [&](const char* n) { return rig.joints[joint_index(n).value()]; };
    const Eigen::Vector3d x = (at("middle-finger-phalanx-proximal") - at("wrist")).normalized();
    Eigen::Vector3d n = x.cross(at("index-finger-phalanx-proximal") - at("pinky-finger-phalanx-proximal"));
    n -= n.dot(x) * x;
    rig.palm_normal = n.norm() > 1e-9 ? Eigen::Vector3d((n.dot(Z) < 0 ? -n : n).normalized()) : Z;
  }
  {
    // The thumb's base on its own centre line: the metacarpal's length (chord) back from the
    // MCP along the curve, which runs on into the palm; straight on along its first chord
    // where it ends sooner.
    const Digit& dg = digits[4];
    const Eigen::Vector3d& mcp = chains[0].front();
    const double L = kFingers[0].metacarpal * s;
    const Eigen::Vector3d base = (dg.curve.front() - mcp).norm() >= L
                                     ? dg.at(dg.chord_back(mcp, L, thumb_mcp_arc))
                                     : Eigen::Vector3d(mcp - L * (mcp - dg.curve.front()).normalized());
    out.thumb_base_on_line = rig;
    out.thumb_base_on_line.joints[finger_chain(Finger::Thumb)[0]] = to_cloud(base);
  }
  if (out.side == HandSide::Left) out.notes.push_back("a left hand (the thumb lies on the other side of the middle finger)");
  out.notes.push_back("joints along the measured digit centre lines with the proportions of Buryanov & Kotiuk (2010), scale " +
                      std::to_string(s).substr(0, 5) + " from the middle fingertip and the wrist cut");
  return out;
}

JointError joint_error(const Rig& a, const Rig& b) {
  JointError e;
  for (int j = 0; j < kJointCount; ++j) {
    const double d = (a.joints[j] - b.joints[j]).norm();
    e.mean_mm += d / kJointCount;
    if (d > e.max_mm) e.max_mm = d, e.worst_joint = joints()[j].name;
  }
  return e;
}

}  // namespace handskin
