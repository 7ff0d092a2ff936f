#pragma once
/// The automatic skeleton's named steps (auto_rig.hpp: place_skeleton runs them in order),
/// internal to the skin library. Hand coordinates `h`: a point's offsets from the cloud's
/// centroid along the frame's X (toward the fingers), Y and Z (toward the back), mm.
///   1. principal_frame     the hand's frame: long axis, thickness axis toward the back, the
///                          wrist's (thicker) end
///   2. find_digit_cells    silhouette, palm centre (largest inscribed circle), the digits
///                          beyond an opening of it: the silhouette closed, unclosed, or the
///                          digits parted by the scans' sheets (auto_rig_digits.cpp)
///   3. collect_digits      each digit's points; five, or an error (auto_rig_digits.cpp)
///   4. orient_digits       the fingers' end and the hand's side (a left hand is mirrored)
///                          (auto_rig_digits.cpp)
///   5. digit_directions    each digit's piece's axis; a finger curled to a stub takes its
///                          neighbours' direction (auto_rig_axes.cpp)
///      trace_centre_line   each digit's centre line through its sections' middles
///                          (auto_rig_axes.cpp)
///   6. place_chains        scale, wrist and every digit's joints by the proportions, in three
///                          rounds of wrist → scale → joints → frame
///   7. centre_thumb_joints the thumb's MCP and IP on the middles of its sections
///   8. assemble_rig        the rig in the cloud's frame, its palm normal, and the variant with
///                          the thumb's base on the thumb's own centre line
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <queue>
#include <vector>

#include "skin/auto_rig.hpp"

namespace handskin::auto_rig_steps {

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

/// The hand's frame in the cloud: centroid c, X toward the fingers, Z toward the back, Y = Z × X
/// (mirrored for a left hand, which is then worked on as a right hand).
struct HandFrame {
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                  Z = Eigen::Vector3d::UnitZ();
  /// Hand coordinates back to the cloud's frame (through the mirrored Y for a left hand).
  Eigen::Vector3d to_cloud(const Eigen::Vector3d& q) const { return Eigen::Vector3d(c + q.x() * X + q.y() * Y + q.z() * Z); }
};

/// How the digits were told apart in the silhouette.
enum class Silhouette { Closed, Unclosed, Sheets };

/// The silhouette and the digits beyond its opening.
struct DigitCells {
  Grid g;
  std::vector<int> cell_of;            ///< per point: its cell
  std::vector<double> dist, to_core;   ///< per cell: distance (cells) to the outside, to the opened palm
  double R = 0, r0 = 0;                ///< the palm's inscribed radius (mm); the opening's radius (cells)
  Eigen::Vector2d pc = Eigen::Vector2d::Zero();  ///< the palm's centre (h's first two coordinates)
  std::vector<std::uint8_t> digit_cell;          ///< cells beyond the opening
  std::vector<std::vector<int>> comps;           ///< the digits' cells (pieces of kDigitCells or more)
  std::vector<std::vector<size_t>> sheet_groups; ///< the sheets' try: each digit's points
  Silhouette parted_by = Silhouette::Closed;
};
constexpr size_t kDigitCells = 150;  ///< smaller pieces are specks the opening left

struct Digit {
  std::vector<size_t> points;
  double angle = 0;
  double width = 0;  // the median width of its measured sections (across it, in the silhouette)
  // Its piece's mean and principal axis (away from the palm's centre) in the silhouette (h's
  // first two coordinates), and its direction there when that axis does not give it
  // (digit_directions).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero(), axis = Eigen::Vector2d::UnitX();
  std::optional<Eigen::Vector2d> along;
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

/// The rounds' result: the hand frame's X in h, the wrist, the scale, and each finger's
/// joints (hand coordinates, MCP … tip; index 0 the thumb).
struct Chains {
  Eigen::Vector3d Xh = Eigen::Vector3d::UnitX(), W = Eigen::Vector3d::Zero();
  double s = 1;
  std::array<std::vector<Eigen::Vector3d>, 5> joints;
  double thumb_mcp_arc = 0;  ///< the thumb's MCP along its centre line
};

HandFrame principal_frame(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides);
DigitCells find_digit_cells(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides,
                            DigitParting parting, HandFrame* frame, std::vector<Eigen::Vector3d>* h, AutoRig* out);
std::vector<Digit> collect_digits(const DigitCells& dc, const std::vector<Eigen::Vector3d>& h);
void orient_digits(HandFrame* frame, std::vector<Eigen::Vector3d>* h, Eigen::Vector2d* pc, std::vector<Digit>* digits,
                   AutoRig* out);
void digit_directions(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& pc, std::vector<Digit>* digits);
void trace_centre_line(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& pc, bool finger, bool trace_curled,
                       Digit* dg, double step = 3);
Chains place_chains(const std::vector<Eigen::Vector3d>& h, const std::vector<Digit>& digits);
void centre_thumb_joints(const std::vector<Eigen::Vector3d>& h, const Digit& thumb, double s,
                         std::vector<Eigen::Vector3d>* js);
void assemble_rig(const HandFrame& frame, const std::vector<Eigen::Vector3d>& h, const Chains& ch, const Digit& thumb,
                  AutoRig* out);

/// The height (Z, toward the back) at `share` of the cloud's thickness from its back, over a
/// disc of `radius` about (x, y); nothing where fewer than 5 points lie there.
std::optional<double> depth_at(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector3d& at, double share,
                               double radius);

}  // namespace handskin::auto_rig_steps
