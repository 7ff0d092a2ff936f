#include "patches/patches.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/CholmodSupport>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <limits>
#include <memory>
#include <tuple>

#include "core/errors.hpp"
#include "mesh/mesh_distance.hpp"
#include "mesh/point_grid.hpp"

namespace handskin {

namespace {

void bernstein(double t, double B[4], double D[4]) {
  const double s = 1 - t;
  B[0] = s * s * s, B[1] = 3 * t * s * s, B[2] = 3 * t * t * s, B[3] = t * t * t;
  if (D) D[0] = -3 * s * s, D[1] = 3 * s * s - 6 * t * s, D[2] = 6 * t * s - 3 * t * t, D[3] = 3 * t * t;
}

int nearest_link(const Eigen::Vector3d& p, const std::vector<Bone>& bones) {
  int best = -1;
  double bd = 1e300;
  for (size_t k = 0; k < bones.size(); ++k) {
    const double d = distance_to_bone(p, bones[k]);
    if (d < bd) bd = d, best = static_cast<int>(k);
  }
  return best;
}

// The control net of a layout: one control point per corner, two per edge, four inside each
// face. Patch f's P(i, j) (i along corner 0 → 1, j along corner 0 → 3) is ids[f][4 i + j].
struct Net {
  std::vector<std::array<int, 16>> ids;
  int count = 0;
};

Net build_net(const PatchLayout& L) {
  Net N;
  N.count = static_cast<int>(L.vertices.size());
  std::map<std::pair<int, int>, int> edge_base;
  auto edge = [&](int a, int b, int near) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    auto it = edge_base.find(key);
    if (it == edge_base.end()) it = edge_base.emplace(key, N.count).first, N.count += 2;
    return it->second + (near == key.first ? 0 : 1);
  };
  for (const auto& c : L.faces) {
    std::array<int, 16> id{};
    auto P = [&](int i, int j) -> int& { return id[4 * i + j]; };
    P(0, 0) = c[0], P(3, 0) = c[1], P(3, 3) = c[2], P(0, 3) = c[3];
    P(1, 0) = edge(c[0], c[1], c[0]), P(2, 0) = edge(c[0], c[1], c[1]);
    P(3, 1) = edge(c[1], c[2], c[1]), P(3, 2) = edge(c[1], c[2], c[2]);
    P(2, 3) = edge(c[2], c[3], c[2]), P(1, 3) = edge(c[2], c[3], c[3]);
    P(0, 2) = edge(c[3], c[0], c[3]), P(0, 1) = edge(c[3], c[0], c[0]);
    P(1, 1) = N.count++, P(2, 1) = N.count++, P(1, 2) = N.count++, P(2, 2) = N.count++;
    N.ids.push_back(id);
  }
  return N;
}

// Side s of a patch (from its corner s to corner s + 1): the border's control points in that
// order, as (i, j), and each one's inner neighbour.
void border(int s, std::array<std::array<int, 2>, 4>* on, std::array<std::array<int, 2>, 4>* in) {
  for (int k = 0; k < 4; ++k) {
    switch (s) {
      case 0: (*on)[k] = {k, 0}, (*in)[k] = {k, 1}; break;
      case 1: (*on)[k] = {3, k}, (*in)[k] = {2, k}; break;
      case 2: (*on)[k] = {3 - k, 3}, (*in)[k] = {3 - k, 2}; break;
      default: (*on)[k] = {0, 3 - k}, (*in)[k] = {1, 3 - k}; break;
    }
  }
}
// The parameters of the point a fraction q along side s.
Eigen::Vector2d on_side(int s, double q) {
  switch (s) {
    case 0: return {q, 0};
    case 1: return {1, q};
    case 2: return {1 - q, 1};
    default: return {0, 1 - q};
  }
}

struct Datum {
  Eigen::Vector3d p;
  double w = 1;
  int side = -1;  ///< 0 palm, 1 back; -1 a sample of the polygon skin (weak data)
  bool fit = true;  ///< in the least squares (the measured points are thinned for it)
  int patch = -1;
  double s = 0.5, t = 0.5;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();  ///< the surface's unit normal at the foot point (after the first fit)
};

// Newton (Gauss–Newton) foot point of d.p on the surface from (d.patch, d.s, d.t), at most
// `iterations` steps. A step that leaves the patch goes on in the patch across the side it
// crossed, from the point where it crossed (at most 4 such crossings, so that a point between
// two patches that both pull it back cannot cycle). Returns true when it ends pushing out of
// its patch still (a corner, or the crossings spent): then it is looked for on the whole
// surface.
bool foot_point(const std::vector<BezierPatch>& P, const LayoutTopology& T, Datum* d, int iterations,
                bool across = true) {
  int crossings = 0;
  for (int it = 0; it < iterations; ++it) {
    Eigen::Vector3d S, Su, Sv;
    P[d->patch].derivatives(d->s, d->t, &S, &Su, &Sv);
    const Eigen::Vector3d r = d->p - S;
    Eigen::Matrix2d J;
    J << Su.dot(Su), Su.dot(Sv), Su.dot(Sv), Sv.dot(Sv);
    const Eigen::Vector2d g(Su.dot(r), Sv.dot(r));
    const double det = J(0, 0) * J(1, 1) - J(0, 1) * J(1, 0);
    if (std::abs(det) < 1e-12) break;
    // The 2 × 2 normal equations by Cramer's rule (an LDLᵀ object per step cost ~2 % of the fit).
    Eigen::Vector2d step((J(1, 1) * g(0) - J(0, 1) * g(1)) / det, (J(0, 0) * g(1) - J(1, 0) * g(0)) / det);
    const double len = step.norm();
    if (len > 0.5) step *= 0.5 / len;  // at most half a patch per step
    const double s = d->s + step(0), t = d->t + step(1);
    // The side crossed first along the step, if any.
    int side = -1;
    double first = 2;
    auto consider = [&](int k, double at) {
      if (at >= 0 && at < first) first = at, side = k;
    };
    if (t < 0) consider(0, d->t / (d->t - t));
    if (s > 1) consider(1, (1 - d->s) / (s - d->s));
    if (t > 1) consider(2, (1 - d->t) / (t - d->t));
    if (s < 0) consider(3, d->s / (d->s - s));
    if (side < 0) {
      d->s = s, d->t = t;
      if (step.norm() < 1e-7) break;
      continue;
    }
    const double cs = std::clamp(d->s + first * step(0), 0.0, 1.0), ct = std::clamp(d->t + first * step(1), 0.0, 1.0);
    if (crossings >= 2 && (side == 0 || side == 2 ? d->t : d->s) == (side == 0 || side == 3 ? 0.0 : 1.0)) {
      // Already on this side, and pushed out across it again after crossing back and forth:
      // the foot point lies on the border curve (a ridge or a valley between two patches).
      // Newton along the side alone.
      const bool along_s = side == 0 || side == 2;
      const double h = along_s ? J(0, 0) : J(1, 1);
      if (h < 1e-12) break;
      const double ds = std::clamp((along_s ? g(0) : g(1)) / h, -0.5, 0.5);
      if (along_s) d->s = std::clamp(d->s + ds, 0.0, 1.0);
      else d->t = std::clamp(d->t + ds, 0.0, 1.0);
      if (std::abs(ds) < 1e-7) break;
      continue;
    }
    const int g2 = T.neighbour[d->patch][side];
    if (g2 < 0 || crossings == 4) {
      d->s = cs, d->t = ct;
      return true;
    }
    ++crossings;
    // Where along the side (from its corner `side` to the next) the step crossed; the
    // neighbour runs the side the other way.
    const double q = side == 0 ? cs : side == 1 ? ct : side == 2 ? 1 - cs : 1 - ct;
    const Eigen::Vector2d at = on_side(T.neighbour_side[d->patch][side], 1 - q);
    d->patch = g2, d->s = at.x(), d->t = at.y();
  }
  // Settled on a side: where two patches meet at a sharp fold (the wrist cut) the residual can
  // stand square to this patch there while the neighbour comes nearer; look across once.
  constexpr double kNearSide = 0.01;
  const int on = d->t < kNearSide ? 0 : d->s > 1 - kNearSide ? 1 : d->t > 1 - kNearSide ? 2 : d->s < kNearSide ? 3 : -1;
  if (across && on >= 0 && T.neighbour[d->patch][on] >= 0) {
    const double q = on == 0 ? d->s : on == 1 ? d->t : on == 2 ? 1 - d->s : 1 - d->t;
    const Eigen::Vector2d at = on_side(T.neighbour_side[d->patch][on], 1 - q);
    Datum e = *d;
    e.patch = T.neighbour[d->patch][on], e.s = at.x(), e.t = at.y();
    if (!foot_point(P, T, &e, iterations, false) &&
        (P[e.patch].eval(e.s, e.t) - e.p).squaredNorm() < (P[d->patch].eval(d->s, d->t) - d->p).squaredNorm() - 1e-12)
      *d = e;
  }
  return false;
}

// The whole surface sampled on an m × m grid per patch, for the nearest-point search that
// (re)assigns a point to its patch.
struct SurfaceSamples {
  std::vector<Eigen::Vector3d> p;
  std::vector<std::array<float, 3>> at;  ///< patch, s, t
  /// Per patch, how far a point of it can lie from its nearest sample: the largest distance
  /// from a cell's middle to the nearest of its four corners, with a margin (a bicubic cell
  /// bulges little between its corners and middle).
  std::vector<double> cover;
  double widest = 0;  ///< the largest cover
  SurfaceSamples(const std::vector<BezierPatch>& P, int m) {
    const size_t row = static_cast<size_t>(m) + 1;
    cover.assign(P.size(), 0.0);
    p.resize(P.size() * row * row);
    at.resize(p.size());
#pragma omp parallel for schedule(static)
    for (long f = 0; f < static_cast<long>(P.size()); ++f) {
      const size_t first = static_cast<size_t>(f) * row * row;
      for (int i = 0; i <= m; ++i)
        for (int j = 0; j <= m; ++j) {
          const double s = static_cast<double>(i) / m, t = static_cast<double>(j) / m;
          p[first + i * row + j] = P[f].eval(s, t);
          at[first + i * row + j] = {static_cast<float>(f), static_cast<float>(s), static_cast<float>(t)};
        }
      double c = 0;
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
          const Eigen::Vector3d mid = P[f].eval((i + 0.5) / m, (j + 0.5) / m);
          const size_t k = first + static_cast<size_t>(i) * row + static_cast<size_t>(j);
          c = std::max(c, std::min({(mid - p[k]).norm(), (mid - p[k + 1]).norm(), (mid - p[k + row]).norm(),
                                    (mid - p[k + row + 1]).norm()}));
        }
      cover[f] = 1.25 * c + 0.05;
    }
    for (double c : cover) widest = std::max(widest, c);
  }
};

// Place d on the surface: the nearest sample, then Newton in its patch.
void locate_globally(const std::vector<BezierPatch>& P, const LayoutTopology& T, const SurfaceSamples& S,
                     const PointGrid& grid, Datum* d) {
  const int k = grid.nearest(d->p, 1e3);
  HS_CHECK(k >= 0, "patch fit: no surface sample near a point");
  d->patch = static_cast<int>(S.at[k][0]), d->s = S.at[k][1], d->t = S.at[k][2];
  foot_point(P, T, d, 8);
}

// Newton finds a foot point, not always the nearest: a point in a web's groove can settle on
// the far sheet, with no sample of the near one nearer than it. From the nearest sample of
// every patch that can hold a nearer point (one of its samples within r + its cover), and from
// its nearest sample off its sides, Newton starts again; the nearest foot point is kept.
// Returns its distance (r when none is nearer).
double nearest_sheet(const std::vector<BezierPatch>& P, const LayoutTopology& T, const SurfaceSamples& S,
                     const PointGrid& grid, Datum* d, double r) {
  // Per patch, its nearest sample and its nearest sample off its sides: a side's samples are
  // two patches', and Newton from one can run back into the patch the point came from while
  // this one holds a nearer sheet further in (on the fixture a point 0.91 mm from its foot
  // point had one 0.87 mm away so).
  struct Start {
    int patch;
    double any_d2 = std::numeric_limits<double>::infinity(), inner_d2 = std::numeric_limits<double>::infinity();
    int any = -1, inner = -1;
  };
  std::vector<Start> starts;
  grid.within(d->p, r + S.widest, [&](int q) {
    const int f = static_cast<int>(S.at[q][0]);
    const double dist = (S.p[q] - d->p).squaredNorm();
    if (dist > (r + S.cover[f]) * (r + S.cover[f])) return;
    Start* st = nullptr;
    for (auto& x : starts)
      if (x.patch == f) st = &x;
    if (!st) starts.push_back({f}), st = &starts.back();
    if (dist < st->any_d2) st->any_d2 = dist, st->any = q;
    const float s = S.at[q][1], t = S.at[q][2];
    if (s > 0 && s < 1 && t > 0 && t < 1 && dist < st->inner_d2) st->inner_d2 = dist, st->inner = q;
  });
  for (const Start& st : starts)
    for (const int q : {st.any, st.inner == st.any ? -1 : st.inner}) {
      if (q < 0) continue;
      Datum e = *d;
      e.patch = st.patch, e.s = S.at[q][1], e.t = S.at[q][2];
      foot_point(P, T, &e, 8);
      const double re = (P[e.patch].eval(e.s, e.t) - e.p).norm();
      if (re < r - 1e-9) *d = e, r = re;
    }
  return r;
}

DistanceFigures figures_of(std::vector<double> r) {
  DistanceFigures f;
  f.points = r.size();
  if (r.empty()) return f;
  double s = 0, s2 = 0;
  for (double x : r) s += x, s2 += x * x, f.max = std::max(f.max, x);
  f.mean = s / r.size();
  f.rms = std::sqrt(s2 / r.size());
  const size_t k = static_cast<size_t>(0.95 * (r.size() - 1));
  std::nth_element(r.begin(), r.begin() + k, r.end());
  f.p95 = r[k];
  return f;
}

// The control point on the layout edge (v, w) next to corner v.
int net_edge_near(const PatchSkin& s, int v, int w) {
  const auto& faces = s.layout.faces;
  for (size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 4; ++k)
      if (faces[f][k] == v && faces[f][(k + 1) % 4] == w) {
        std::array<std::array<int, 2>, 4> on, in;
        border(k, &on, &in);
        return s.patch_control[f][4 * on[1][0] + on[1][1]];
      }
  HS_CHECK(false, "patch net: no face runs an edge of the layout");
  return -1;
}

}  // namespace

void rebuild_patches(PatchSkin* s) {
  for (size_t f = 0; f < s->patches.size(); ++f)
    for (int k = 0; k < 16; ++k) {
      const int id = s->patch_control[f][k];
      s->patches[f].P[k] = s->control[id];
      s->patches[f].cp_link[k] = s->control_link.empty() ? -1 : s->control_link[id];
    }
}

namespace {

// The least squares' weights (fit_net says what each term is).
constexpr double kTangentWeight = 0.005;
constexpr double kSettledRms = 0.005;  // a round that takes less off the RMS ends the correction
constexpr double kRecheckMm = 0.3;  // a final distance past this is checked against the other patches near
constexpr size_t kFitPoints = 15000;  // measured points in the least squares (at least 16 per control point)
// The G1 rows' weight against a C1 row's. On 12 hands of the family at 0.1 the G1 p95 is
// 0.41–0.62° (8.4–9.5° without), the surface → true skin mean as before (median 0.1643 →
// 0.1633 mm). On one of them 0.03 leaves the p95 at 1.27°, 0.3 takes it to 0.33° with the
// surface → true skin mean 1.6 % larger than at 0.1.
constexpr double kG1Weight = 0.1;

// G1 along the borders that end where other than four patches meet, where C1 cannot hold (it
// is left out next to such a corner). At samples along the border, with n the mean of the two
// patches' normals and D_f, D_g their derivatives across it (each into its own patch), the kink
// is sin α_f + sin α_g = n·D_f/|D_f| + n·D_g/|D_g|: zero when the two cross directions are
// one line, whatever the plane's tilt (to first order a turn of both about the border leaves
// it zero, so the penalty does not pin the tangent plane where the last round left it). With
// n and the lengths from the last round the rows are linear; they couple the border's control
// points with both inner rows (12 control points, 36 unknowns).
struct G1Border {
  int f, s, g, gs;
  std::array<int, 12> ids;  ///< the border (f's order), f's inner row, g's inner row (g's order)
};
std::vector<G1Border> g1_borders(const PatchSkin& out, const LayoutTopology& T) {
  std::vector<G1Border> list;
  const auto& faces = out.layout.faces;
  for (int f = 0; f < static_cast<int>(out.patches.size()); ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      if (g < f || (g == f && gs < s)) continue;  // each border once
      if (out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) continue;
      if (T.regular(faces[f][s]) && T.regular(faces[f][(s + 1) % 4])) continue;
      G1Border b{f, s, g, gs, {}};
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(gs, &on_g, &in_g);
      for (int k = 0; k < 4; ++k) {
        b.ids[k] = out.patch_control[f][4 * on_f[k][0] + on_f[k][1]];
        b.ids[4 + k] = out.patch_control[f][4 * in_f[k][0] + in_f[k][1]];
        b.ids[8 + k] = out.patch_control[g][4 * in_g[k][0] + in_g[k][1]];
      }
      list.push_back(b);
    }
  return list;
}
// The border's kink penalty, Σ over samples of w·(L·kink)² (L the cross derivatives' mean
// length / 3, so that it weighs like a C1 row in mm²), as a 36 × 36 matrix on its ids.
Eigen::Matrix<double, 36, 36> g1_block(const PatchSkin& out, const G1Border& b, double w) {
  constexpr int kSamples = 9;
  Eigen::Matrix<double, 36, 36> M = Eigen::Matrix<double, 36, 36>::Zero();
  for (int q = 1; q <= kSamples; ++q) {
    const double t = q / (kSamples + 1.0);
    const Eigen::Vector2d a = on_side(b.s, t), c = on_side(b.gs, 1 - t);
    Eigen::Vector3d Sa, Sau, Sav, Sc, Scu, Scv;
    out.patches[b.f].derivatives(a.x(), a.y(), &Sa, &Sau, &Sav);
    out.patches[b.g].derivatives(c.x(), c.y(), &Sc, &Scu, &Scv);
    const Eigen::Vector3d na = Sau.cross(Sav), nc = Scu.cross(Scv);
    if (na.norm() < 1e-12 || nc.norm() < 1e-12) continue;
    const Eigen::Vector3d nm = na.normalized() + nc.normalized();
    if (nm.norm() < 1e-6) continue;
    const Eigen::Vector3d n = nm.normalized();
    double Bf[4], Bg[4];
    bernstein(t, Bf, nullptr);
    bernstein(1 - t, Bg, nullptr);
    Eigen::Vector3d Df = Eigen::Vector3d::Zero(), Dg = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) {
      Df += 3 * Bf[k] * (out.control[b.ids[4 + k]] - out.control[b.ids[k]]);
      Dg += 3 * Bg[k] * (out.control[b.ids[8 + k]] - out.control[b.ids[3 - k]]);  // g runs the border the other way
    }
    const double lf = Df.norm(), lg = Dg.norm();
    if (lf < 1e-9 || lg < 1e-9) continue;
    const double L = (lf + lg) / 6;
    Eigen::Matrix<double, 36, 1> row = Eigen::Matrix<double, 36, 1>::Zero();
    for (int k = 0; k < 4; ++k) {
      row.segment<3>(3 * (4 + k)) += 3 * Bf[k] * L / lf * n;
      row.segment<3>(3 * k) -= 3 * Bf[k] * L / lf * n;
      row.segment<3>(3 * (8 + k)) += 3 * Bg[k] * L / lg * n;
      row.segment<3>(3 * (3 - k)) -= 3 * Bg[k] * L / lg * n;
    }
    M.noalias() += w * row * row.transpose();
  }
  return M;
}

// The normal equations' solver, kept from round to round. The matrix's pattern is the same
// every round (the same net, blocks and penalties), and so are the penalties' values: the
// first round builds the pattern, keeps the penalties' share of the values and where each
// patch's 48 × 48 block lands; later rounds copy the one and add the others there.
//
// Sparse Cholesky of the normal equations; never an inverse. CHOLMOD's supernodal Cholesky
// (SuiteSparse, through Eigen): 6–8 times faster here than Eigen's simplicial LDLᵀ. A
// correction round changes the matrix only a little (the points' parameters and normals move),
// so a round first tries conjugate gradients preconditioned by the last factor, from the last
// round's control points (`preconditioned_cg`): iterations of one sparse product and two
// triangular solves (~0.26 ms each on the fixture) against a new factorisation (~17 ms). Where
// they would not converge within kCgBudget iterations the round factors its own matrix, which
// later rounds then use. The G1 rows and the normals change most in the early rounds, which
// factor; the later ones converge so as the surface settles.
constexpr int kCgBudget = 40;  // iterations; a factorisation costs about 65 on the fixture (a budget of 60 took as long)
constexpr int kCgCheck = 6;    // iterations between two predictions of the iterations still needed
constexpr int kCgStalled = 12;  // given up within this many: the next round factors at once
constexpr double kCgTolerance = 1e-7;  // relative residual; the control points then agree with direct solves within ~3e-4 mm
// The correction rounds' solves stop at a relative residual of 1e-4: each is one step of the
// alternation between foot points and control points, whose next round moves the parameters
// again, and a solve to 1e-7 there bought nothing. On the fixture and five family pairs (H01,
// H02, H05, H07, H10) every figure of the report stayed within 0.001 mm (means) and 0.02 mm
// (maxima) of solves to 1e-7, the G1 p95 within 0.07° (with G0 alone, c1_weight 0, 0.002–0.006 mm
// farther from the truth); the fit took 10–25 % less time (392
// patches on the fixture, with the final solve below: 1.67 → 1.27 s). The surface kept is then solved again to kCgTolerance
// (polish_net): the least squares of the final parameters, exactly.
constexpr double kCgRoundTolerance = 1e-4;

// Conjugate gradients on A x = b (A holding both halves) from x, preconditioned by M (the
// Cholesky factor of an earlier round's matrix). Written out rather than Eigen's
// ConjugateGradient so that it can give up early and deterministically: every kCgCheck
// iterations the residual's rate of decrease over the last ones predicts how many more
// convergence needs, and when the total would pass kCgBudget it stops (the caller then
// factors). Returns true when the relative residual reached `tolerance`.
bool preconditioned_cg(const Eigen::SparseMatrix<double>& A,
                       const Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>& M, const Eigen::VectorXd& b,
                       double tolerance, Eigen::VectorXd* x, int* iterations) {
  *iterations = 0;
  const double bn = b.norm();
  if (bn == 0) {
    x->setZero();
    return true;
  }
  Eigen::VectorXd r = b - A * *x;
  double err = r.norm() / bn, err_checked = err;
  Eigen::VectorXd z = M.solve(r);
  Eigen::VectorXd p = z, Ap(b.size());
  double rz = r.dot(z);
  for (int it = 1; it <= kCgBudget && err > tolerance; ++it) {
    Ap.noalias() = A.transpose() * p;  // A is symmetric: its transpose is row-major, whose product Eigen runs on every thread
    const double pAp = p.dot(Ap);
    if (!(pAp > 0)) return false;  // not positive definite to working precision: factor
    const double alpha = rz / pAp;
    *x += alpha * p;
    r -= alpha * Ap;
    err = r.norm() / bn;
    *iterations = it;
    if (err <= tolerance) break;
    if (it % kCgCheck == 0) {
      const double rate = std::pow(err / err_checked, 1.0 / kCgCheck);
      if (!(rate < 1) || it + std::log(tolerance / err) / std::log(rate) > kCgBudget) return false;
      err_checked = err;
    }
    z = M.solve(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return err <= tolerance;
}

struct NetSolver {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
  bool factored = false;  ///< llt holds a factor (of a round with normals: the first fit solves its own)
  bool stalled = false;  ///< the last round's conjugate gradients gave up early
  Eigen::SparseMatrix<double> A;  ///< the normal equations (both halves)
  std::vector<double> penalty_values;  ///< the penalties' share of A's values
  std::vector<int> block_slot;  ///< per patch, its 48 × 48 block's entries' indices in A's values
  std::vector<G1Border> g1;  ///< the borders held G1 (their kink rows change every round)
  std::vector<int> g1_slot;  ///< per such border, its 36 × 36 block's entries' indices in A's values
  Eigen::VectorXd x;  ///< the last solution
  Eigen::VectorXd rhs;  ///< the last right-hand side (A x = rhs)
  bool exact = false;  ///< x solves the last system directly or to kCgTolerance
};

// A direct solve of A x = b with A the solver's matrix; the factor is kept (later rounds'
// conjugate gradients are preconditioned by it).
Eigen::VectorXd solve_directly(NetSolver* solver, const Eigen::VectorXd& b) {
  solver->llt.factorize(solver->A);
  HS_CHECK(solver->llt.info() == Eigen::Success, "patch fit: the normal equations could not be factored");
  solver->factored = true;
  return solver->llt.solve(b);
}

// A solution of the solver's system (`exact`: directly or to kCgTolerance) into the net's
// control points and the patches.
void take_solution(PatchSkin* out, NetSolver* solver, Eigen::VectorXd X, bool exact) {
  solver->x = std::move(X);
  solver->exact = exact;
  for (size_t k = 0; k < out->control.size(); ++k) out->control[k] = solver->x.segment<3>(3 * static_cast<long>(k));
  rebuild_patches(out);
}

// The penalties that are the same every round, as triplets: fairness, C1 across borders, G1
// at the corners where other than four patches meet.
std::vector<Eigen::Triplet<double>> net_penalties(const PatchSkin& out, const LayoutTopology& T, const PatchOptions& o,
                                                  double per_point) {
  const int patches = static_cast<int>(out.patches.size());
  std::vector<Eigen::Triplet<double>> A;
  // A penalty row Σ w_k e_k on control points (the same for x, y and z): its normal-equation entries.
  auto penalty = [&](std::initializer_list<int> ids, std::initializer_list<double> coef, double w) {
    const int* id = ids.begin();
    const double* cf = coef.begin();
    const size_t m = ids.size();
    for (size_t x = 0; x < m; ++x)
      for (size_t y = 0; y < m; ++y)
        for (int c = 0; c < 3; ++c) A.emplace_back(3 * id[x] + c, 3 * id[y] + c, w * cf[x] * cf[y]);
  };
  auto triple = [&](int i0, int i1, int i2, double w) { penalty({i0, i1, i2}, {1, -2, 1}, w); };
  // Fairness: second differences along both directions inside each patch.
  for (int f = 0; f < patches; ++f) {
    const auto& id = out.patch_control[f];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 2; ++b) {
        triple(id[4 * a + b], id[4 * a + b + 1], id[4 * a + b + 2], per_point * o.fairness);
        triple(id[4 * b + a], id[4 * (b + 1) + a], id[4 * (b + 2) + a], per_point * o.fairness);
      }
  }
  // C1: each border's control points midway between their inner neighbours on either side.
  const auto& faces = out.layout.faces;
  for (int f = 0; f < patches; ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      if (g < f || (g == f && gs < s)) continue;  // each border once
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(gs, &on_g, &in_g);
      const auto& idf = out.patch_control[f];
      const auto& idg = out.patch_control[g];
      for (int k = 0; k < 4; ++k) {
        const auto& b = on_f[k];
        const auto& a = in_f[k];
        const auto& c = in_g[3 - k];  // g runs the border the other way
        HS_CHECK(idf[4 * b[0] + b[1]] == idg[4 * on_g[3 - k][0] + on_g[3 - k][1]], "patch net: a border not shared");
        if (out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) break;
        // Next to a corner where other than four patches meet C1 cannot hold; from the second
        // round the border is held G1 instead (g1_block), and only the row at a regular end
        // keeps its C1 condition.
        if (k <= 2 && !T.regular(faces[f][s])) continue;
        if (k >= 1 && !T.regular(faces[f][(s + 1) % 4])) continue;
        triple(idf[4 * a[0] + a[1]], idf[4 * b[0] + b[1]], idg[4 * c[0] + c[1]], per_point * (o.c1_weight + o.fairness));
      }
    }
  // Where other than four patches meet, the control points next to the corner along its
  // edges, taken in turn round it (v_i = e_i − corner), are held to an affine image of a
  // regular n-gon: v_{i−1} + v_{i+1} = 2 cos(2π/n) v_i. They then lie in one plane — one
  // tangent plane for all the patches there (G1 at the corner) — and the condition is linear
  // and the same for x, y and z (for n = 4 it is the C1 condition above). Corners on a crease
  // are left free.
  for (size_t v = 0; v < T.valence.size(); ++v) {
    if (T.regular(static_cast<int>(v)) || T.around[v].empty()) continue;
    bool on_crease = false;
    for (int w : T.around[v]) on_crease = on_crease || out.layout.is_crease(static_cast<int>(v), w);
    if (on_crease) continue;
    const int m = static_cast<int>(T.around[v].size());
    const double c = std::cos(2 * M_PI / m);
    std::vector<int> e(m);
    for (int i = 0; i < m; ++i) e[i] = net_edge_near(out, static_cast<int>(v), T.around[v][i]);
    for (int i = 0; i < m; ++i) {
      penalty({e[(i + m - 1) % m], e[(i + 1) % m], e[i], static_cast<int>(v)}, {1, 1, -2 * c, -2 * (1 - c)},
              per_point * o.corner_weight);
    }
  }
  return A;
}

// The unknowns (x, y, z of each) of `count` control points, in that order.
std::vector<int> unknowns_of(const int* ids, int count) {
  std::vector<int> u(3 * static_cast<size_t>(count));
  for (int a = 0; a < 3 * count; ++a) u[a] = 3 * ids[a / 3] + a % 3;
  return u;
}

// Where the entries (u[a], u[b]) of a dense block on the distinct unknowns u sit in A's values:
// slot[|u| a + b]. One walk down each of the block's columns (A's row indices are sorted in
// each column) instead of a binary search per entry: the first round's pattern took 9 ms so.
void block_slots(const Eigen::SparseMatrix<double>& A, const std::vector<int>& u, int* slot) {
  const int m = static_cast<int>(u.size());
  std::vector<int> order(m);
  for (int a = 0; a < m; ++a) order[a] = a;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return u[a] < u[b]; });
  const int* inner = A.innerIndexPtr();
  for (int b = 0; b < m; ++b) {
    int p = A.outerIndexPtr()[u[b]];
    const int end = A.outerIndexPtr()[u[b] + 1];
    for (int a : order) {
      while (p < end && inner[p] < u[a]) ++p;
      HS_CHECK(p < end && inner[p] == u[a], "patch fit: a block entry is missing from the matrix's pattern");
      slot[m * a + b] = p;
    }
  }
}

// Least squares for every control point at once (eq. 4.5): the data, C1 across every border
// but next to a corner where other than four patches meet (there it would flatten the corner's
// tangents): those borders are held G1 (g1_block) from the second round on, the corner itself
// by its own condition (net_penalties); fairness inside each patch. The normal equations are
// assembled from per-patch blocks.
//
// Once the points have foot points with normals, each point's error is measured the way
// squared-distance minimisation does (Wang, Pottmann & Liu 2006): its distance along the
// surface's normal there in full, its offset along the surface at kTangentWeight. The
// thesis's point-to-point error (eq. 4.5 with the parameters held) makes the fit drag the
// surface along with the points' old parameters: the parameter correction then creeps (on an
// ellipsoid the RMS still fell by a third from the tenth round to the thirtieth); with the
// normal error the correction settles in a few rounds. The normal term couples x, y and z,
// so the system has three unknowns per control point.
void fit_net(PatchSkin* out, const LayoutTopology& T, const std::vector<Datum>& data, const PatchOptions& o,
             NetSolver* solver) {
  const int n = static_cast<int>(out->control.size());
  const int patches = static_cast<int>(out->patches.size());
  std::vector<std::vector<int>> of_patch(patches);
  double wsum = 0;
  bool normals = false;
  for (size_t k = 0; k < data.size(); ++k)
    if (data[k].fit) {
      of_patch[data[k].patch].push_back(static_cast<int>(k)), wsum += data[k].w;
      normals = normals || data[k].n.squaredNorm() > 0.5;
    }
  // Per patch: the point term's 16 × 16 block (the same for x, y, z) and the normal term's
  // 48 × 48 block, each one product C·Cᵀ of its data's columns.
  std::vector<Eigen::Matrix<double, 16, 16>> block(patches);
  std::vector<Eigen::Matrix<double, 16, 3>> rhs(patches);
  std::vector<Eigen::Matrix<double, 48, 48>> nblock(patches);
  std::vector<Eigen::Matrix<double, 48, 1>> nrhs(patches);
#pragma omp parallel for schedule(dynamic)
  for (int f = 0; f < patches; ++f) {
    const std::vector<int>& ids = of_patch[f];
    if (ids.empty()) {  // no point on it (a small patch over a hole): the penalties alone hold it
      block[f].setZero(), rhs[f].setZero(), nblock[f].setZero(), nrhs[f].setZero();
      continue;  // (and Eigen's product blocking divides by the empty depth)
    }
    Eigen::Matrix<double, 16, Eigen::Dynamic> C(16, ids.size());
    Eigen::Matrix<double, Eigen::Dynamic, 3> Y(ids.size(), 3);
    Eigen::Matrix<double, 48, Eigen::Dynamic> Cn = Eigen::Matrix<double, 48, Eigen::Dynamic>::Zero(48, ids.size());
    Eigen::Matrix<double, Eigen::Dynamic, 1> Yn = Eigen::Matrix<double, Eigen::Dynamic, 1>::Zero(ids.size());
    for (size_t q = 0; q < ids.size(); ++q) {
      const Datum& d = data[ids[q]];
      double Bu[4], Bv[4];
      bernstein(d.s, Bu, nullptr);
      bernstein(d.t, Bv, nullptr);
      const bool with_normal = d.n.squaredNorm() > 0.5;
      const double sp = std::sqrt(d.w * (with_normal ? kTangentWeight : 1.0)), sn = std::sqrt(d.w);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
          const double b = Bu[i] * Bv[j];
          C(4 * i + j, q) = sp * b;
          if (with_normal) Cn.block<3, 1>(3 * (4 * i + j), q) = sn * b * d.n;
        }
      Y.row(q) = sp * d.p.transpose();
      if (with_normal) Yn(q) = sn * d.n.dot(d.p);
    }
    block[f].noalias() = C * C.transpose();
    rhs[f].noalias() = C * Y;
    // Cn·Cnᵀ is symmetric: its lower half by a rank update (half the products), mirrored.
    nblock[f].setZero();
    nblock[f].selfadjointView<Eigen::Lower>().rankUpdate(Cn);
    nblock[f].triangularView<Eigen::StrictlyUpper>() = nblock[f].transpose();
    // The point term's block on the diagonal of each control point pair's 3 × 3.
    for (int x = 0; x < 16; ++x)
      for (int y = 0; y < 16; ++y)
        for (int c = 0; c < 3; ++c) nblock[f](3 * x + c, 3 * y + c) += block[f](x, y);
    nrhs[f].noalias() = Cn * Yn;
  }
  Eigen::VectorXd R = Eigen::VectorXd::Zero(3 * n);
  for (int f = 0; f < patches; ++f) {
    const auto& idx = out->patch_control[f];
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c) R(3 * idx[x] + c) += rhs[f](x, c) + nrhs[f](3 * x + c);
  }
  Eigen::SparseMatrix<double>& As = solver->A;
  if (solver->block_slot.empty()) {
    // The pattern: every patch's 48 × 48 block (as zeros) and the penalties.
    // Each dense block's unknowns: every patch's 48, then every G1 border's 36.
    solver->g1 = g1_borders(*out, T);
    std::vector<std::vector<int>> blocks;
    for (int f = 0; f < patches; ++f) blocks.push_back(unknowns_of(out->patch_control[f].data(), 16));
    for (const G1Border& g : solver->g1) blocks.push_back(unknowns_of(g.ids.data(), 12));
    std::vector<Eigen::Triplet<double>> A = net_penalties(*out, T, o, wsum / n);
    A.reserve(A.size() + static_cast<size_t>(patches) * 48 * 48 + solver->g1.size() * 36 * 36);
    for (const auto& u : blocks)
      for (int a : u)
        for (int b : u) A.emplace_back(a, b, 0.0);
    As.resize(3 * n, 3 * n);
    As.setFromTriplets(A.begin(), A.end());  // sums duplicates, keeps the zeros
    As.makeCompressed();
    solver->penalty_values.assign(As.valuePtr(), As.valuePtr() + As.nonZeros());
    solver->block_slot.resize(static_cast<size_t>(patches) * 48 * 48);
    solver->g1_slot.resize(solver->g1.size() * 36 * 36);
    for (size_t k = 0; k < blocks.size(); ++k)
      block_slots(As, blocks[k],
                  k < static_cast<size_t>(patches) ? &solver->block_slot[k * 48 * 48]
                                                   : &solver->g1_slot[(k - patches) * 36 * 36]);
    solver->llt.analyzePattern(As);
  }
  std::copy(solver->penalty_values.begin(), solver->penalty_values.end(), As.valuePtr());
  for (int f = 0; f < patches; ++f) {
    const int* slot = &solver->block_slot[static_cast<size_t>(f) * 48 * 48];
    for (int a = 0; a < 48; ++a)
      for (int b = 0; b < 48; ++b) As.valuePtr()[slot[48 * a + b]] += nblock[f](a, b);
  }
  if (normals) {
    const double w = wsum / n * (o.c1_weight + o.fairness) * kG1Weight;
    std::vector<Eigen::Matrix<double, 36, 36>> gb(solver->g1.size());
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(gb.size()); ++k) gb[k] = g1_block(*out, solver->g1[k], w);
    for (size_t k = 0; k < gb.size(); ++k) {
      const int* slot = &solver->g1_slot[k * 36 * 36];
      for (int a = 0; a < 36; ++a)
        for (int b = 0; b < 36; ++b) As.valuePtr()[slot[36 * a + b]] += gb[k](a, b);
    }
  }
  Eigen::VectorXd X;
  bool exact = true;  // the first fit and a factored round are direct solves
  if (!normals) {
    // The first fit (no foot point normals yet, no G1 rows) is the same system for x, y and z:
    // A = A₁ ⊗ I₃ (the unknowns interleaved). One factorisation of A₁ (n × n, ~1 ms on the
    // fixture) serves the three coordinates instead of one of A (3n × 3n, ~17 ms).
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(static_cast<size_t>(As.nonZeros()) / 9 + 1);
    for (int c = 0; c < As.outerSize(); c += 3)
      for (Eigen::SparseMatrix<double>::InnerIterator it(As, c); it; ++it)
        if (it.row() % 3 == 0) t.emplace_back(it.row() / 3, c / 3, it.value());
    Eigen::SparseMatrix<double> A1(n, n);
    A1.setFromTriplets(t.begin(), t.end());
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt1(A1);
    HS_CHECK(llt1.info() == Eigen::Success, "patch fit: the normal equations could not be factored");
    const Eigen::MatrixXd X1 = llt1.solve(Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(R.data(), n, 3));
    X.resize(3 * n);
    for (int k = 0; k < n; ++k) X.segment<3>(3 * k) = X1.row(k).transpose();
  } else {
    bool direct = !solver->factored || solver->stalled;
    solver->stalled = false;
    if (!direct) {
      X = solver->x;
      int iterations = 0;
      direct = !preconditioned_cg(As, solver->llt, R, kCgRoundTolerance, &X, &iterations);
      // Given up within kCgStalled iterations: the matrices still change fast from round to
      // round (the early rounds), so the next round factors without trying.
      solver->stalled = direct && iterations <= kCgStalled;
    }
    if (direct) X = solve_directly(solver, R);
    exact = direct;
  }
  solver->rhs = std::move(R);
  take_solution(out, solver, std::move(X), exact);
}

// The last system solved again to kCgTolerance (the correction rounds stop theirs at
// kCgRoundTolerance): conjugate gradients from the last solution, else a factorisation.
void polish_net(PatchSkin* out, NetSolver* solver) {
  if (solver->exact) return;
  Eigen::VectorXd X = solver->x;
  int iterations = 0;
  if (!preconditioned_cg(solver->A, solver->llt, solver->rhs, kCgTolerance, &X, &iterations))
    X = solve_directly(solver, solver->rhs);
  take_solution(out, solver, std::move(X), true);
}

}  // namespace

Eigen::Vector3d BezierPatch::eval(double u, double v) const {
  double Bu[4], Bv[4];
  bernstein(u, Bu, nullptr);
  bernstein(v, Bv, nullptr);
  // Contracted along v first, in registers (as derivatives below).
  double s[3] = {0, 0, 0};
  for (int i = 0; i < 4; ++i) {
    double q[3] = {0, 0, 0};
    for (int j = 0; j < 4; ++j) {
      const double* c = P[4 * i + j].data();
      for (int k = 0; k < 3; ++k) q[k] += Bv[j] * c[k];
    }
    for (int k = 0; k < 3; ++k) s[k] += Bu[i] * q[k];
  }
  return {s[0], s[1], s[2]};
}

void BezierPatch::derivatives(double u, double v, Eigen::Vector3d* S, Eigen::Vector3d* Su, Eigen::Vector3d* Sv) const {
  double Bu[4], Du[4], Bv[4], Dv[4];
  bernstein(u, Bu, Du);
  bernstein(v, Bv, Dv);
  // Contracted along v first (each row's point and v-derivative), then along u: 44 vector
  // multiply-adds instead of 48, in locals the compiler keeps in registers (the foot points'
  // Newton steps spend most of their time here: the correction rounds' foot points went ~52 →
  // ~34 ms on the fixture).
  double s[3] = {0, 0, 0}, su[3] = {0, 0, 0}, sv[3] = {0, 0, 0};
  for (int i = 0; i < 4; ++i) {
    double q[3] = {0, 0, 0}, qv[3] = {0, 0, 0};
    for (int j = 0; j < 4; ++j) {
      const double* c = P[4 * i + j].data();
      for (int k = 0; k < 3; ++k) q[k] += Bv[j] * c[k], qv[k] += Dv[j] * c[k];
    }
    for (int k = 0; k < 3; ++k) s[k] += Bu[i] * q[k], su[k] += Du[i] * q[k], sv[k] += Bu[i] * qv[k];
  }
  *S = Eigen::Vector3d(s[0], s[1], s[2]);
  *Su = Eigen::Vector3d(su[0], su[1], su[2]);
  *Sv = Eigen::Vector3d(sv[0], sv[1], sv[2]);
}

bool PatchOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (subdivision < 1 || subdivision > 8) return bad("subdivision must be in [1, 8]");
  if (!(fairness >= 0 && fairness <= 10)) return bad("fairness must be in [0, 10]");
  if (!(c1_weight >= 0 && c1_weight <= 1e4)) return bad("c1_weight must be in [0, 1e4]");
  if (!(corner_weight >= 0 && corner_weight <= 1e4)) return bad("corner_weight must be in [0, 1e4]");
  if (!(skin_weight > 0 && skin_weight <= 10)) return bad("skin_weight must be in (0, 10]");
  if (max_corrections < 0 || max_corrections > 100) return bad("max_corrections must be in [0, 100]");
  if (!(correction_tolerance > 0)) return bad("correction_tolerance must be > 0");
  if (tessellation < 1 || tessellation > 64) return bad("tessellation must be in [1, 64]");
  return true;
}

PatchSkin fit_patches(const PatchLayout& layout, const std::vector<Eigen::Vector3d>& points,
                      const std::vector<std::uint32_t>& sides, const std::vector<Eigen::Vector3d>& support,
                      const std::vector<Bone>& bones, const PatchOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("patch options", err);
  HS_CHECK(points.size() == sides.size(), "points and sides differ in length");
  const auto t0 = std::chrono::steady_clock::now();
  PatchSkin out;
  out.layout = layout;
  const LayoutTopology T = layout_topology(layout, "patch layout");
  for (const auto& b : bones) out.bones.push_back(b.name());
  for (int v : T.valence) out.irregular_corners += v != 4;

  // --- the net, started on the layout's bilinear faces ---
  const Net net = build_net(layout);
  out.patch_control = net.ids;
  out.control.assign(net.count, Eigen::Vector3d::Zero());
  out.patches.resize(layout.faces.size());
  for (size_t f = 0; f < layout.faces.size(); ++f) {
    const auto& c = layout.faces[f];
    const auto& V = layout.vertices;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        const double s = i / 3.0, t = j / 3.0;
        out.control[net.ids[f][4 * i + j]] =
            (1 - s) * (1 - t) * V[c[0]] + s * (1 - t) * V[c[1]] + s * t * V[c[2]] + (1 - s) * t * V[c[3]];
      }
    out.patches[f].name = f < layout.names.size() ? layout.names[f] : "face" + std::to_string(f);
  }
  rebuild_patches(&out);

  // --- data: the measured points near the skin, and samples of the polygon skin as weak data ---
  // The least squares and the correction rounds take every `stride`-th measured point (each
  // weighing `stride`): some 16 per control point are plenty for 16 unknowns a patch, and the
  // fit's time goes with them. Every measured point is placed and measured at the end.
  std::vector<Datum> data;
  std::vector<int> in_fit(points.size(), -2);  // per point: its datum, -1 measured at the end only, -2 stray
  {
    constexpr double kFarMm = 5.0;  // farther from the skin's every sample: not the skin (a stray sample)
    const PointGrid near_skin(support, 2.0);
    std::vector<char> keep(points.size(), 1);
    if (!support.empty()) {
#pragma omp parallel for schedule(static)
      for (long k = 0; k < static_cast<long>(points.size()); ++k) keep[k] = near_skin.any_within(points[k], kFarMm);
    }
    const size_t measured = static_cast<size_t>(std::count(keep.begin(), keep.end(), 1));
    const size_t wanted = std::max<size_t>(kFitPoints, 16 * static_cast<size_t>(net.count));
    const size_t stride = std::max<size_t>(1, measured / wanted);
    size_t m = 0;
    for (size_t k = 0; k < points.size(); ++k) {
      if (!keep[k]) continue;
      if (m++ % stride == 0) {
        in_fit[k] = static_cast<int>(data.size());
        data.push_back({points[k], static_cast<double>(stride), sides[k] == 1 ? 1 : 0});
      } else {
        in_fit[k] = -1;
      }
    }
    // The skin's samples only where the scans saw nothing: within kSeenMm of a fitted measured
    // point they weigh nothing beside it (0.05 against the stride's ~9) but cost as much in
    // every round's foot points and blocks (on the fixture they were 56 % of the data).
    constexpr double kSeenMm = 2.0;
    std::vector<Eigen::Vector3d> fitted;
    fitted.reserve(data.size());
    for (const Datum& d : data) fitted.push_back(d.p);
    const PointGrid seen(fitted, kSeenMm);
    for (const auto& p : support)
      if (!seen.any_within(p, kSeenMm)) data.push_back({p, o.skin_weight, -1});
  }
  if (data.size() < 16 * out.patches.size())
    throw InputError("patches", "too few points (" + std::to_string(data.size()) + ") for " +
                                    std::to_string(out.patches.size()) + " patches");
  {
    // 4 mm cells: many points lie millimetres off the layout's bilinear faces, and a search
    // from them crosses fewer large cells (the nearest sample is the same at any cell size;
    // this placement took 16 ms on the fixture with 2 mm cells, 7 with 4).
    const SurfaceSamples S(out.patches, 8);
    const PointGrid grid(S.p, 4.0);
#pragma omp parallel for schedule(dynamic, 256)
    for (long k = 0; k < static_cast<long>(data.size()); ++k) locate_globally(out.patches, T, S, grid, &data[k]);
  }
  NetSolver solver;
  fit_net(&out, T, data, o, &solver);

  // --- parameter correction (eqs. 4.6–4.7): foot points on the current surface, refit ---
  // A point whose Newton step leaves its patch goes on in its neighbour (or is looked for
  // again on the whole surface). The round's update is how far the foot points moved on the
  // surface; a point whose foot point went to a patch that does not touch its last one
  // (between two sheets of skin: a web, the thumb over the palm) is counted as reassigned
  // rather than moved. The rounds stop when 99.9 % of the points moved less than the
  // tolerance: the few largest moves are points the surface does not reach (a web's fold, a
  // knuckle's crease at 98 patches), which slide on from round to round.
  std::vector<std::vector<char>> touches(out.patches.size(), std::vector<char>(out.patches.size(), 0));
  {
    std::vector<std::vector<int>> at_corner(layout.vertices.size());
    for (size_t f = 0; f < layout.faces.size(); ++f)
      for (int c : layout.faces[f]) at_corner[c].push_back(static_cast<int>(f));
    for (const auto& fs : at_corner)
      for (int f : fs)
        for (int g : fs) touches[f][g] = 1;
  }
  std::vector<double> moved(data.size(), -1);
  // The surface of the round with the lowest RMS: a round whose refit raised the RMS (the
  // first fit's parameters, taken from the layout's bilinear faces, lie far from the skin where
  // a raised thumb leaves the palm: the WebXR hand model) does not end the correction, and the
  // best surface is the one kept. (Its foot points are not kept: the final distances below look
  // for every point's again, from the last round's parameters, the far ones on the whole surface.)
  struct Kept {
    double rms = std::numeric_limits<double>::infinity();
    int round = -1;
    std::vector<Eigen::Vector3d> control;
    std::vector<BezierPatch> patches;
  } best;
  for (int round = 0; round <= o.max_corrections; ++round) {
    // Newton from each point's last foot point; the few that leave the surface's reach (a
    // corner, the crossings spent) are looked for on the whole surface, whose samples are
    // made only when some point needs them.
    std::vector<int> was(data.size());
    std::vector<Eigen::Vector3d> before(data.size());
    std::vector<char> lost(data.size(), 0);
#pragma omp parallel for schedule(dynamic, 256)
    for (long k = 0; k < static_cast<long>(data.size()); ++k) {
      Datum& d = data[k];
      was[k] = d.patch;
      before[k] = out.patches[d.patch].eval(d.s, d.t);
      lost[k] = foot_point(out.patches, T, &d, 3);
    }
    if (std::find(lost.begin(), lost.end(), 1) != lost.end()) {
      const SurfaceSamples S(out.patches, 8);
      const PointGrid grid(S.p, 4.0);
#pragma omp parallel for schedule(dynamic, 16)
      for (long k = 0; k < static_cast<long>(data.size()); ++k)
        if (lost[k]) locate_globally(out.patches, T, S, grid, &data[k]);
    }
    std::vector<double> r2(data.size(), -1);  // squared residuals, summed in order below (deterministic)
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(data.size()); ++k) {
      Datum& d = data[k];
      Eigen::Vector3d Sp, Su, Sv;
      out.patches[d.patch].derivatives(d.s, d.t, &Sp, &Su, &Sv);
      const Eigen::Vector3d nn = Su.cross(Sv);
      d.n = nn.norm() > 1e-12 ? Eigen::Vector3d(nn.normalized()) : Eigen::Vector3d::Zero();
      moved[k] = -1;
      if (d.side < 0) continue;
      if (touches[was[k]][d.patch]) moved[k] = (Sp - before[k]).norm();
      r2[k] = (d.p - Sp).squaredNorm();
    }
    double sum2 = 0;
    long count = 0, reassigned = 0;
    for (size_t k = 0; k < data.size(); ++k)
      if (r2[k] >= 0) {
        sum2 += r2[k], ++count;
        if (moved[k] < 0) ++reassigned;
      }
    out.rms_per_round.push_back(std::sqrt(sum2 / std::max(count, 1L)));
    const bool rose = best.round >= 0 && out.rms_per_round.back() > best.rms;
    if (!rose) best.rms = out.rms_per_round.back(), best.round = round, best.control = out.control, best.patches = out.patches;
    if (round == o.max_corrections) break;
    std::vector<double> m;
    for (double x : moved)
      if (x >= 0) m.push_back(x);
    double p999 = 0, largest = 0;
    if (!m.empty()) {
      const size_t q = static_cast<size_t>(0.999 * (m.size() - 1));
      std::nth_element(m.begin(), m.begin() + q, m.end());
      p999 = m[q];
      largest = *std::max_element(m.begin(), m.end());
    }
    out.max_update_per_round.push_back(largest);
    out.update_p999_per_round.push_back(p999);
    out.reassigned_per_round.push_back(static_cast<size_t>(reassigned));
    // Settled: 99.9 % of the points moved less than the tolerance, or the round took less than
    // 0.5 % off the RMS (the points still moving are sliding along a surface that no longer
    // comes nearer them). A round that raised it settles nothing: the refits are still
    // untangling parameters the first fit took from the layout.
    const size_t nr = out.rms_per_round.size();
    const bool settled = p999 < o.correction_tolerance ||
                         (nr >= 2 && !rose && out.rms_per_round[nr - 1] > (1 - kSettledRms) * out.rms_per_round[nr - 2]);
    if (settled) break;  // this round's foot points are the final surface's
    fit_net(&out, T, data, o, &solver);
  }
  if (best.round >= 0 && best.round + 1 < static_cast<int>(out.rms_per_round.size())) {
    out.control = std::move(best.control), out.patches = std::move(best.patches);
  } else {
    // The last solve's surface is kept: its least squares to kCgTolerance. (An earlier round's
    // surface, kept when a later one raised the RMS, stays as its round solved it.)
    polish_net(&out, &solver);
  }
  out.kept_round = best.round;

  // --- every measured point's foot point on the final surface: the exact distances ---
  // Denser samples than the rounds' (16 × 16 per patch): every point that lands farther than
  // kRecheckMm is looked for again from every patch with a sample within its distance + that
  // patch's cover (about half a cell), and smaller cells leave fewer patches to try (on the
  // fixture this pass took 60 ms with 8 × 8 samples, 50 with 16 × 16, 46 with the grid's 3 mm
  // cells, 40 with each point started from its neighbour's foot point).
  {
    const SurfaceSamples S(out.patches, 16);
    const PointGrid grid(S.p, 3.0);
    std::vector<Datum> all(points.size());
    std::vector<double> r(points.size(), -1);
    constexpr long kChunk = 256;
#pragma omp parallel for schedule(dynamic, kChunk)
    for (long k = 0; k < static_cast<long>(points.size()); ++k) {
      if (in_fit[k] == -2) continue;
      Datum& d = all[k];
      if (in_fit[k] >= 0) {
        d = data[in_fit[k]];
        if (foot_point(out.patches, T, &d, 8)) locate_globally(out.patches, T, S, grid, &d);
      } else {
        // From the foot point of the point before it in scan order (its neighbour on the range
        // image's row) when this thread has placed it already (the same chunk of the loop's:
        // the same start whatever the threads), else of the fitted point before it, else from
        // the whole surface.
        long from = k - 1;
        const Datum* start = nullptr;
        if (k % kChunk != 0 && in_fit[from] != -2 && (points[from] - points[k]).norm() < 3) {
          start = &all[from];
        } else {
          while (from >= 0 && in_fit[from] < 0) --from;
          if (from >= 0 && k - from < 64 && (data[in_fit[from]].p - points[k]).norm() < 3) start = &data[in_fit[from]];
        }
        if (start) d = *start;
        d.p = points[k], d.side = sides[k] == 1 ? 1 : 0;
        if (!start || foot_point(out.patches, T, &d, 6)) locate_globally(out.patches, T, S, grid, &d);
      }
      r[k] = (out.patches[d.patch].eval(d.s, d.t) - d.p).norm();
      if (r[k] > kRecheckMm) r[k] = nearest_sheet(out.patches, T, S, grid, &d, r[k]);
    }
    std::vector<double> residual[2];
    double worst[2] = {-1, -1};
    for (size_t k = 0; k < points.size(); ++k) {
      if (in_fit[k] == -2) continue;
      const Datum& d = all[k];
      if (r[k] > worst[d.side]) worst[d.side] = r[k], out.worst_patch[d.side] = out.patches[d.patch].name;
      residual[d.side].push_back(r[k]);
      out.samples.push_back({d.p, static_cast<float>(r[k]), static_cast<std::uint8_t>(d.side), d.patch,
                             static_cast<float>(d.s), static_cast<float>(d.t)});
    }
    out.side = {figures_of(residual[0]), figures_of(residual[1])};
  }

  for (const auto& c : out.control)
    if (!c.allFinite())
      throw InputError("patches", "the fit gave non-finite control points; the layout does not fit these points");
  // --- the binding, the patches' links, continuity figures ---
  out.control_link.resize(out.control.size());
  for (size_t k = 0; k < out.control.size(); ++k) out.control_link[k] = nearest_link(out.control[k], bones);
  rebuild_patches(&out);
  for (auto& P : out.patches) P.link = nearest_link(P.eval(0.5, 0.5), bones);
  out.control_points = out.control.size();
  std::vector<double> g1, g1_near;
  double worst_jump = -1;
  for (size_t f = 0; f < out.patches.size(); ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      if (g < static_cast<int>(f) || (g == static_cast<int>(f) && gs < s)) continue;
      if (layout.is_crease(layout.faces[f][s], layout.faces[f][(s + 1) % 4])) continue;
      const bool irregular_start = !T.regular(layout.faces[f][s]), irregular_end = !T.regular(layout.faces[f][(s + 1) % 4]);
      for (int q = 1; q <= 9; ++q) {
        const Eigen::Vector2d a = on_side(s, q / 10.0), b = on_side(gs, 1 - q / 10.0);
        Eigen::Vector3d Sa, Sau, Sav, Sb, Sbu, Sbv;
        out.patches[f].derivatives(a.x(), a.y(), &Sa, &Sau, &Sav);
        out.patches[g].derivatives(b.x(), b.y(), &Sb, &Sbu, &Sbv);
        out.g0_gap_mm = std::max(out.g0_gap_mm, (Sa - Sb).norm());
        const Eigen::Vector3d na = Sau.cross(Sav), nb = Sbu.cross(Sbv);
        if (na.norm() < 1e-12 || nb.norm() < 1e-12) continue;
        const double jump = std::acos(std::clamp(na.normalized().dot(nb.normalized()), -1.0, 1.0)) * 180 / M_PI;
        const bool near = (q <= 2 && irregular_start) || (q >= 8 && irregular_end);
        (near ? g1_near : g1).push_back(jump);
        if (!near && jump > worst_jump) worst_jump = jump, out.g1_max_where = out.patches[f].name + " | " + out.patches[g].name;
      }
    }
  auto median_of = [](std::vector<double>& v) { return v.empty() ? 0.0 : v[v.size() / 2]; };
  std::sort(g1.begin(), g1.end());
  std::sort(g1_near.begin(), g1_near.end());
  if (!g1.empty()) {
    out.g1_median_deg = median_of(g1);
    out.g1_p95_deg = g1[static_cast<size_t>(0.95 * (g1.size() - 1))];
    out.g1_max_deg = g1.back();
  }
  if (!g1_near.empty()) out.g1_near_median_deg = median_of(g1_near), out.g1_near_max_deg = g1_near.back();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

PatchSkin fit_patch_skin(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<std::uint32_t>& sides, const PatchOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("patch options", err);
  const auto t0 = std::chrono::steady_clock::now();
  if (o.layout) {  // a layout given back must lie on this skin: every corner within 20 mm of it
    const std::vector<Eigen::Vector3d> v = mesh_vertices(skin.mesh);
    const PointGrid grid(v, 4.0);
    for (size_t k = 0; k < o.layout->vertices.size(); ++k)
      if (!o.layout->vertices[k].allFinite() || !grid.any_within(o.layout->vertices[k], 20.0))
        throw InputError("patch layout", "corner " + std::to_string(k) +
                                             " lies more than 20 mm from the skin; is the layout from this skin?");
  }
  // The skin as weak data, one sample per 2 mm², so that it holds the surface where the scans saw
  // nothing (the flanks between the fingers, the wrist cut) and nowhere outweighs them.
  const std::vector<Eigen::Vector3d> support = sample_surface(skin.mesh, 0.5);
  auto fit = [&](int shift) {
    const PatchLayout layout = o.layout ? *o.layout : subdivide_layout(hand_patch_layout(skin, rig, points, sides, shift), o.subdivision);
    return fit_patches(layout, points, sides, support, skin.bones, o);
  };
  // The skin's distance tree for the check below, built beside the first fit (~2 ms, which
  // the fit's single-threaded factorisations leave room for).
  std::future<std::unique_ptr<MeshDistance>> skin_tree;
  if (!o.layout)
    skin_tree = std::async(std::launch::async, [&skin] { return std::make_unique<MeshDistance>(skin.mesh); });
  PatchSkin s = fit(0);
  if (!o.layout) {
    // Where the patches stray from the polygon skin they were laid on, one bridges what the skin
    // follows: on the WebXR hand model (scripts/webxr_study.py) a patch of the thumb's first row
    // spanned the fold of the thumb-index web on 4 of 16 pairs, 12-16 mm inside the flesh, and
    // moving the palm ring the thumb's base ends at by two of the skin's rings either way took
    // it out on every one of them. So: the surface's 5 x 5 samples per patch against the skin;
    // over kStrayP95Mm at the 95th percentile (the family's 12 pairs: 0.38-0.63 mm; the WebXR
    // pairs without the fold 0.44-0.65; with it 0.83-1.03), the layout is tried again with
    // that ring moved 2 rings toward the wrist, then toward the webs, and the fit whose samples
    // lie nearest the skin is kept.
    constexpr double kStrayP95Mm = 0.75;
    const std::unique_ptr<MeshDistance> tree = skin_tree.get();
    const MeshDistance& to_skin = *tree;
    auto stray = [&](const PatchSkin& p) {  // ~3 ms on one thread for the fixture's 2450 samples
      std::vector<double> d(p.patches.size() * 25);
#pragma omp parallel for schedule(static)
      for (long k = 0; k < static_cast<long>(d.size()); ++k)
        d[k] = to_skin.distance(p.patches[k / 25].eval((k % 25) / 5 / 4.0, (k % 5) / 4.0));
      const size_t q = static_cast<size_t>(0.95 * static_cast<double>(d.size() - 1));
      std::nth_element(d.begin(), d.begin() + static_cast<long>(q), d.end());
      return d[q];
    };
    std::vector<std::pair<int, double>> tries = {{0, stray(s)}};
    if (tries[0].second > kStrayP95Mm) {
      double best = tries[0].second;
      for (int shift : {-2, 2}) {
        PatchSkin t;
        try {
          t = fit(shift);
        } catch (const InputError&) {
          continue;  // a corner that cannot be placed there: the layout stays as it was
        }
        tries.push_back({shift, stray(t)});
        if (tries.back().second < best) best = tries.back().second, s = std::move(t), s.thumb_ring_shift = shift;
      }
    }
    s.layout_tries = std::move(tries);
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return s;
}

namespace {
// The tessellation's vertex of each patch's (n + 1)² grid point: a layout corner's and a
// shared border's points are one vertex for every patch on them.
std::vector<std::vector<int>> tessellation_index(const PatchSkin& s, int n, std::vector<std::array<int, 3>>* made) {
  HS_CHECK(n >= 1, "tessellation needs at least one quad per patch side");
  std::vector<std::vector<int>> index(s.patches.size(), std::vector<int>(static_cast<size_t>(n + 1) * (n + 1), -1));
  std::vector<int> corner(s.layout.vertices.size(), -1);
  std::map<std::tuple<int, int, int>, int> on_edge;
  made->clear();
  for (size_t f = 0; f < s.patches.size(); ++f) {
    const auto& c = s.layout.faces[f];
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        int* slot = nullptr;
        if ((i == 0 || i == n) && (j == 0 || j == n)) {
          slot = &corner[c[i == 0 ? (j == 0 ? 0 : 3) : (j == 0 ? 1 : 2)]];
        } else if (i == 0 || i == n || j == 0 || j == n) {
          int a, b, step;
          if (j == 0) a = c[0], b = c[1], step = i;
          else if (i == n) a = c[1], b = c[2], step = j;
          else if (j == n) a = c[3], b = c[2], step = i;
          else a = c[0], b = c[3], step = j;
          if (a > b) std::swap(a, b), step = n - step;
          slot = &on_edge.emplace(std::make_tuple(a, b, step), -1).first->second;
        }
        int id;
        if (slot && *slot >= 0) {
          id = *slot;
        } else {
          id = static_cast<int>(made->size());
          made->push_back({static_cast<int>(f), i, j});
          if (slot) *slot = id;
        }
        index[f][i * (n + 1) + j] = id;
      }
  }
  return index;
}

// Each vertex the index made, evaluated once on the patch that made it.
void evaluate_made(const PatchSkin& s, int n, const std::vector<std::array<int, 3>>& made, std::vector<Eigen::Vector3d>* out) {
  out->resize(made.size());
  for (size_t k = 0; k < made.size(); ++k)
    (*out)[k] = s.patches[made[k][0]].eval(static_cast<double>(made[k][1]) / n, static_cast<double>(made[k][2]) / n);
}
}  // namespace

void tessellation_vertices(const PatchSkin& s, int n, std::vector<Eigen::Vector3d>* out) {
  std::vector<std::array<int, 3>> made;
  tessellation_index(s, n, &made);
  evaluate_made(s, n, made, out);
}

TriMesh tessellate(const PatchSkin& s, int n) {
  std::vector<std::array<int, 3>> made;
  const auto index = tessellation_index(s, n, &made);
  std::vector<Eigen::Vector3d> points;
  evaluate_made(s, n, made, &points);
  std::vector<std::array<int, 3>> tris;
  for (size_t f = 0; f < s.patches.size(); ++f)
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const int a = index[f][i * (n + 1) + j], b = index[f][(i + 1) * (n + 1) + j];
        const int c = index[f][(i + 1) * (n + 1) + j + 1], d = index[f][i * (n + 1) + j + 1];
        // (u, v) counter-clockwise: Su × Sv points out of the hand.
        tris.push_back({a, b, c});
        tris.push_back({a, c, d});
      }
  return mesh_from_arrays(points, tris);
}

}  // namespace handskin
