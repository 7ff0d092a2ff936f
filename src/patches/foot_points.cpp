// Foot points on the patch surface (patch_steps.hpp, steps 3, 5 and 6 of the fit): Newton
// from a start, the surface's samples for a global start, and the nearest of several sheets.
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.hpp"
#include "patches/patch_steps.hpp"

namespace handskin::patch_steps {

// Newton (Gauss–Newton) foot point of d.p on the surface from (d.patch, d.s, d.t), at most
// `iterations` steps. A step that leaves the patch goes on in the patch across the side it
// crossed, from the point where it crossed (at most 4 such crossings, so that a point between
// two patches that both pull it back cannot cycle). Returns true when it ends pushing out of
// its patch still (a corner, or the crossings spent): then it is looked for on the whole
// surface.
bool foot_point(const std::vector<BezierPatch>& P, const LayoutTopology& T, Datum* d, int iterations,
                bool across) {
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
    // Where along the side (from its corner `side` to the next) the step crossed, and where
    // that is on the face across (which runs the side the other way, or holds half of it).
    const double q = side == 0 ? cs : side == 1 ? ct : side == 2 ? 1 - cs : 1 - ct;
    int g2, gs2;
    double gq;
    T.across(d->patch, side, q, &g2, &gs2, &gq);
    if (g2 < 0 || crossings == 4) {
      d->s = cs, d->t = ct;
      return true;
    }
    ++crossings;
    const Eigen::Vector2d at = on_side(gs2, gq);
    d->patch = g2, d->s = at.x(), d->t = at.y();
  }
  // Settled on a side: where two patches meet at a sharp fold (the wrist cut) the residual can
  // stand square to this patch there while the neighbour comes nearer; look across once.
  constexpr double kNearSide = 0.01;
  const int on = d->t < kNearSide ? 0 : d->s > 1 - kNearSide ? 1 : d->t > 1 - kNearSide ? 2 : d->s < kNearSide ? 3 : -1;
  if (across && on >= 0) {
    const double q = on == 0 ? d->s : on == 1 ? d->t : on == 2 ? 1 - d->s : 1 - d->t;
    int g2, gs2;
    double gq;
    T.across(d->patch, on, q, &g2, &gs2, &gq);
    const Eigen::Vector2d at = on_side(gs2, gq);
    Datum e = *d;
    e.patch = g2, e.s = at.x(), e.t = at.y();
    if (!foot_point(P, T, &e, iterations, false) &&
        (P[e.patch].eval(e.s, e.t) - e.p).squaredNorm() < (P[d->patch].eval(d->s, d->t) - d->p).squaredNorm() - 1e-12)
      *d = e;
  }
  return false;
}

SurfaceSamples::SurfaceSamples(const std::vector<BezierPatch>& P, int m) {
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

}  // namespace handskin::patch_steps
