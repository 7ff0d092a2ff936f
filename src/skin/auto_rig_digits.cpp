// Steps 2-4 of the automatic skeleton (auto_rig_steps.hpp): the silhouette, the digits beyond
// its opening, their points, and the hand's orientation and side.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <queue>
#include <unordered_map>

#include "core/errors.hpp"
#include "skin/auto_rig_steps.hpp"

namespace handskin::auto_rig_steps {

namespace {

// Digits overlapping in the silhouette are parted by the scans' sheets: points within
// kSheetLinkMm of each other connect (a sheet's samples lie 0.5 mm apart across the scanlines
// and up to 1.6 mm apart on a flank at the scanner's 72 deg), and a piece of at least
// kSheetPoints points is a digit's (smaller ones are flank fragments).
constexpr double kSheetLinkMm = 2.0;
constexpr size_t kSheetPoints = 200;


// The grid's cells are only looked up, never walked in order: a hash map (std::map's ordered
// search over ~20 000 cells, 27 lookups a point, was most of the sheets' parting, which runs
// for each of up to ~40 distances: 0.45 s of a random hand's automatic run, R04 of
// `scripts/random_hands_study.py --draw 73`). Each cell's points are in idx's order either way,
// so the labels are the same. (mesh/point_grid.hpp's PointGrid is such a grid, flatter, but
// it visits a point's own cell before the 26 round it: another order of the neighbours, which
// in the spread from many labels at once can give a contested point the other label.)
struct CellHash {
  size_t operator()(const std::array<long, 3>& k) const {
    std::uint64_t x = static_cast<std::uint64_t>(k[0]) * 0x9E3779B97F4A7C15ull;
    x ^= static_cast<std::uint64_t>(k[1]) * 0xC2B2AE3D27D4EB4Full + (x << 6) + (x >> 2);
    x ^= static_cast<std::uint64_t>(k[2]) * 0x165667B19E3779F9ull + (x << 6) + (x >> 2);
    return static_cast<size_t>(x ^ (x >> 29));
  }
};

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
  std::unordered_map<std::array<long, 3>, std::vector<size_t>, CellHash> cells;
  cells.reserve(idx.size() / 2 + 1);
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

long count_digits(const std::vector<std::vector<int>>& cs) {
  return std::count_if(cs.begin(), cs.end(), [&](const auto& cc) { return cc.size() >= kDigitCells; });
}

// 4-connected components of a cell mask, in scan order.
std::vector<std::vector<int>> components(const Grid& g, const std::vector<std::uint8_t>& mask) {
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
}

// The silhouette's cells farther than t from the opened palm.
std::vector<std::uint8_t> beyond(const DigitCells& dc, double t) {
  std::vector<std::uint8_t> mask(dc.g.on.size(), 0);
  for (size_t k = 0; k < dc.g.on.size(); ++k) mask[k] = dc.g.on[k] && dc.to_core[k] > t;
  return mask;
}

// Two digits can still join beyond the opening (below): the pieces (of at least
// kDigitCells) farther out are grown back over the digits' cells, breadth first from all of
// them at once: each cell goes to the piece it is nearest through them.
std::vector<std::vector<int>> grow_back(const DigitCells& dc, const std::vector<std::vector<int>>& seeds) {
  const Grid& g = dc.g;
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
      if (g.in(x, y) && dc.digit_cell[g.idx(x, y)] && owner[g.idx(x, y)] < 0) {
        owner[g.idx(x, y)] = owner[cidx];
        qu.push(g.idx(x, y));
      }
    }
  }
  return grown;
}

// Each digit's points from the scans' sheets: beyond a distance t from the opened palm,
// the back scan's points fall into pieces that points within kSheetLinkMm of each other
// connect — one per digit, however the digits overlap in the silhouette, as two fingers
// lie a gap apart in height where one runs under the other's edge — and so do the palm
// scan's (a digit's two sheets do not meet: neither scan sees its flanks). From the first
// t that gives five pieces of at least kSheetPoints on each side, the pieces spread over
// their side's points in the digits' cells, and the two sides' pieces pair up in their
// order round the palm's centre. Empty when a side never gives five.
std::vector<std::vector<size_t>> sheet_digits(const DigitCells& dc, const std::vector<Eigen::Vector3d>& h,
                                              const std::vector<std::uint32_t>& sides) {
  std::array<std::vector<std::vector<size_t>>, 2> side_groups;
  for (const std::uint32_t side : {1u, 0u}) {
    std::vector<size_t> all;
    for (size_t i = 0; i < h.size(); ++i)
      if (sides[i] == side && dc.digit_cell[dc.cell_of[i]]) all.push_back(i);
    for (double t = dc.r0; t <= 2 * dc.r0 && side_groups[side].empty(); t += 1) {
      std::vector<size_t> far;
      for (size_t i : all)
        if (dc.to_core[dc.cell_of[i]] > t) far.push_back(i);
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
    return Eigen::Vector2d(m / static_cast<double>(grp.size()) - dc.pc);
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
}

// One pass of the search in the frame (X, Z): h, the silhouette (closed or only its holes
// filled), the palm's centre and radius, the opening, and the digits' cells beyond it.
void silhouette_pass(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides, Silhouette mode,
                     HandFrame* f, std::vector<Eigen::Vector3d>* hp, DigitCells* dc) {
  std::vector<Eigen::Vector3d>& h = *hp;
  Grid& g = dc->g;
  f->Y = f->Z.cross(f->X);
  const Eigen::Vector3d &c = f->c, &X = f->X, &Y = f->Y, &Z = f->Z;
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
    dc->cell_of[i] = g.idx(g.ci(h[i].x()), g.cj(h[i].y()));
    g.on[dc->cell_of[i]] = 1;
  }
  if (mode == Silhouette::Closed)
    g.morph(true), g.morph(true), g.morph(false), g.morph(false);
  else
    g.fill_holes();
  dc->dist = g.distance();
  const int best = static_cast<int>(std::max_element(dc->dist.begin(), dc->dist.end()) - dc->dist.begin());
  dc->R = dc->dist[best] * g.cell;
  dc->pc = Eigen::Vector2d(g.u0 + (best % g.nx + 0.5) * g.cell, g.v0 + (best / g.nx + 0.5) * g.cell);
  // Digits: what a morphological opening with a disc of 0.45 R removes (fingers are far
  // narrower than the palm and the wrist stub, which survive it).
  dc->r0 = 0.45 * dc->R / g.cell;
  Grid core = g;
  for (size_t k = 0; k < g.on.size(); ++k) core.on[k] = !(dc->dist[k] >= dc->r0);
  dc->to_core = core.distance();
  dc->digit_cell = beyond(*dc, dc->r0);
  if (mode == Silhouette::Sheets) {
    // The digits' cells for the count: those of each group's points.
    dc->sheet_groups = sheet_digits(*dc, h, sides);
    dc->comps.clear();
    for (const auto& grp : dc->sheet_groups) {
      std::vector<int> cells;
      for (size_t i : grp) cells.push_back(dc->cell_of[i]);
      std::sort(cells.begin(), cells.end());
      cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
      dc->comps.push_back(std::move(cells));
    }
  } else {
    dc->comps = components(g, dc->digit_cell);
  }
}

// The palm's mid-surface (a plane halfway between the back's and the palm's samples over the
// cells the opening keeps) as the frame's new Z, or none when too little of the palm is seen
// from both sides or it turns Z by less than 2 deg.
std::optional<Eigen::Vector3d> mid_surface_normal(const std::vector<Eigen::Vector3d>& h,
                                                  const std::vector<std::uint32_t>& sides, const DigitCells& dc,
                                                  const HandFrame& f) {
  const Grid& g = dc.g;
  std::vector<double> zlo(g.on.size(), 1e300), zhi(g.on.size(), -1e300);
  std::vector<std::uint8_t> seen(g.on.size(), 0);
  for (size_t i = 0; i < h.size(); ++i) {
    const int k = dc.cell_of[i];
    if (!(dc.dist[k] >= dc.r0)) continue;
    zlo[k] = std::min(zlo[k], h[i].z()), zhi[k] = std::max(zhi[k], h[i].z());
    if (sides[i] <= 1) seen[k] |= sides[i] == 1 ? 1 : 2;
  }
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < g.on.size(); ++k) {
    if (seen[k] != 3) continue;
    const Eigen::Vector3d row(g.u0 + (k % g.nx + 0.5) * g.cell, g.v0 + (k / g.nx + 0.5) * g.cell, 1.0);
    A += row * row.transpose();
    rhs += row * 0.5 * (zlo[k] + zhi[k]);
  }
  if (A(2, 2) < 500) return std::nullopt;  // too little of the palm seen from both sides
  const Eigen::Vector3d plane = A.ldlt().solve(rhs);  // mid-surface z = a u + b v + c
  const Eigen::Vector3d Zp = (f.Z - plane(0) * f.X - plane(1) * f.Y).normalized();
  if (!Zp.allFinite() || Zp.dot(f.Z) > std::cos(2 * M_PI / 180)) return std::nullopt;
  return Zp;
}

}  // namespace

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
// sheets (sheet_digits). With DigitParting::Sheets, only that third try is made: the skin
// stage asks for it when it refuses the skeleton the silhouette gave (a finger that touches
// its neighbour along most of its length leaves only its tip beyond the opening, and a line
// through that tip's middles, carried into the palm, misses the finger: H12 of the family
// as a cloud, its little finger's PIP 17.7 mm off).
DigitCells find_digit_cells(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides,
                            DigitParting parting, HandFrame* frame, std::vector<Eigen::Vector3d>* h, AutoRig* out) {
  DigitCells dc;
  dc.cell_of.resize(h->size());
  const Eigen::Vector3d X0 = frame->X, Z0 = frame->Z;
  for (const Silhouette mode : {Silhouette::Closed, Silhouette::Unclosed, Silhouette::Sheets}) {
    if (parting == DigitParting::Sheets && mode != Silhouette::Sheets) continue;
    frame->X = X0, frame->Z = Z0;
    for (int pass = 0;; ++pass) {
      silhouette_pass(pts, sides, mode, frame, h, &dc);
      if (count_digits(dc.comps) >= 5 || pass == 8) break;
      const std::optional<Eigen::Vector3d> Zp = mid_surface_normal(*h, sides, dc, *frame);
      if (!Zp) break;
      frame->Z = *Zp;
      frame->X = (frame->X - frame->X.dot(frame->Z) * frame->Z).normalized();
    }
    out->palm_radius_mm = dc.R;
    // Two digits can still join beyond the opening: a little finger whose web lies far
    // proximal of the ring finger's leaves a band along the palm's edge, outside the opening,
    // that links their bases. Farther from the palm they part: the pieces found beyond the
    // first distance that gives five digits are grown back over the digits' cells (breadth
    // first from all of them at once: each cell goes to the piece it is nearest through them).
    // (Not for the sheets' try: its silhouette is the unclosed one, already tried so.)
    if (count_digits(dc.comps) < 5 && mode != Silhouette::Sheets) {
      const long before = count_digits(dc.comps);
      for (double t = dc.r0 + 1; t <= 2 * dc.r0; t += 1) {
        const std::vector<std::vector<int>> seeds = components(dc.g, beyond(dc, t));
        const long n = count_digits(seeds);
        if (n < before) break;  // a digit ends before the joined ones part
        if (n != 5) continue;
        dc.comps = grow_back(dc, seeds);
        break;
      }
    }
    if (count_digits(dc.comps) == 5) {
      if (mode == Silhouette::Unclosed)
        out->notes.push_back("digits found in the silhouette left unclosed (two fingers lie within ~4 mm)");
      if (mode == Silhouette::Sheets && parting != DigitParting::Sheets)  // asked for: the asker says why
        out->notes.push_back("digits parted by the scans' sheets (two fingers overlap in the silhouette)");
      dc.parted_by = mode;
      break;
    }
  }
  return dc;
}

std::vector<Digit> collect_digits(const DigitCells& dc, const std::vector<Eigen::Vector3d>& h) {
  const Grid& g = dc.g;
  std::vector<Digit> digits;
  for (size_t k = 0; k < dc.comps.size(); ++k) {
    if (dc.comps[k].size() < kDigitCells) continue;
    Digit dg;
    Eigen::Vector2d m = Eigen::Vector2d::Zero();
    for (int cidx : dc.comps[k]) m += Eigen::Vector2d(g.u0 + (cidx % g.nx + 0.5) * g.cell, g.v0 + (cidx / g.nx + 0.5) * g.cell);
    m /= static_cast<double>(dc.comps[k].size());
    dg.angle = std::atan2(m.y() - dc.pc.y(), m.x() - dc.pc.x());
    if (dc.parted_by == Silhouette::Sheets && dc.sheet_groups.size() == dc.comps.size()) {
      dg.points = dc.sheet_groups[k];
      digits.push_back(dg);
      continue;
    }
    digits.push_back(dg);
    std::vector<std::uint8_t> mine(g.on.size(), 0);
    for (int cidx : dc.comps[k]) mine[cidx] = 1;
    for (size_t i = 0; i < h.size(); ++i)
      if (mine[dc.cell_of[i]]) digits.back().points.push_back(i);
  }
  if (digits.size() != 5)
    throw InputError("merged cloud", "automatic skeleton placement found " + std::to_string(digits.size()) +
                                         " digits beyond the palm, not 5 (fingers touching or missing?); give a rig");
  return digits;
}

void orient_digits(HandFrame* frame, std::vector<Eigen::Vector3d>* h, Eigen::Vector2d* pc, std::vector<Digit>* dp,
                   AutoRig* out) {
  std::vector<Digit>& digits = *dp;
  // The digits lie beyond the palm's centre toward the fingers' end. If most lie the other
  // way, the end taken for the wrist's (the thicker) was the fingers' (a short forearm stub,
  // curled fingers, a hanging thumb): turn the frame half round about Z.
  double toward = 0;
  for (const Digit& dg : digits) toward += std::cos(dg.angle);
  if (toward < 0) {
    frame->X = -frame->X, frame->Y = -frame->Y;
    for (auto& q : *h) q.x() = -q.x(), q.y() = -q.y();
    *pc = -*pc;
    for (Digit& dg : digits) dg.angle = dg.angle > 0 ? dg.angle - M_PI : dg.angle + M_PI;
  }
  std::sort(digits.begin(), digits.end(), [](const Digit& a, const Digit& b) { return a.angle < b.angle; });
  // Back up, a right hand's thumb lies on +Y (Y = Z × X), a left hand's on −Y: the thumb is
  // the digit beyond the widest angular gap. A left hand is worked on in mirrored
  // coordinates (Y flipped), where it is a right hand; the joints go back through the same Y.
  const double gap_top = digits[4].angle - digits[3].angle, gap_bottom = digits[1].angle - digits[0].angle;
  out->side = HandSide::Right;
  if (gap_bottom > gap_top) {
    out->side = HandSide::Left;
    frame->Y = -frame->Y;
    for (auto& q : *h) q.y() = -q.y();
    pc->y() = -pc->y();
    for (Digit& dg : digits) dg.angle = -dg.angle;
    std::sort(digits.begin(), digits.end(), [](const Digit& a, const Digit& b) { return a.angle < b.angle; });
  }
}

}  // namespace handskin::auto_rig_steps
