#include "patches/patches.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <future>
#include <optional>
#include <map>
#include <limits>
#include <memory>
#include <set>
#include <tuple>

#include "core/errors.hpp"
#include "core/threads.hpp"
#include "mesh/mesh_check.hpp"
#include "mesh/mesh_distance.hpp"
#include "mesh/point_grid.hpp"
#include "patches/patch_steps.hpp"

namespace handskin {

namespace patch_steps {

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

Net build_net(const PatchLayout& L, const LayoutTopology& T) {
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
  N.derived.assign(N.count, {});
  if (T.conforming()) return N;
  // Each long side's halves by de Casteljau at 1/2, in its four control points L0…L3 (from its
  // start): half 0 is [L0, (L0+L1)/2, (L0+2L1+L2)/4, M], half 1 [M, (L1+2L2+L3)/4, (L2+L3)/2, L3],
  // M = (L0+3L1+3L2+L3)/8 the hanging corner. A short side runs its half the other way.
  std::vector<std::vector<std::pair<int, double>>> direct(N.count);
  for (const auto& [long_side, pieces] : T.halves) {
    std::array<std::array<int, 2>, 4> on, in;
    border(long_side.second, &on, &in);
    int Lid[4];
    for (int k = 0; k < 4; ++k) Lid[k] = N.ids[long_side.first][4 * on[k][0] + on[k][1]];
    for (int h = 0; h < 2; ++h) {
      const auto [g, gs] = pieces[h];
      border(gs, &on, &in);
      for (int k = 0; k < 4; ++k) {
        const int id = N.ids[g][4 * on[k][0] + on[k][1]];
        const double* w = kHalfCurve[h][3 - k];
        if (std::count(w, w + 4, 1.0) == 1) continue;  // the long side's own corner
        std::vector<std::pair<int, double>> combo;
        for (int j = 0; j < 4; ++j)
          if (w[j] != 0) combo.push_back({Lid[j], w[j]});
        direct[id] = std::move(combo);
      }
    }
  }
  // In the unknowns: a long side's corner can hang on another long side in turn.
  std::vector<char> state(N.count, 0);  // 0 not resolved, 1 resolving, 2 resolved
  std::function<void(int)> resolve = [&](int id) {
    if (state[id] == 2) return;
    if (state[id] == 1) throw InputError("patch layout", "its T-junctions hang on one another in a loop");
    state[id] = 1;
    std::map<int, double> sum;
    for (const auto& [j, w] : direct[id]) {
      if (direct[j].empty()) {
        sum[j] += w;
        continue;
      }
      resolve(j);
      for (const auto& [k, wk] : N.derived[j]) sum[k] += w * wk;
    }
    N.derived[id].assign(sum.begin(), sum.end());
    state[id] = 2;
  };
  for (int id = 0; id < N.count; ++id)
    if (!direct[id].empty()) resolve(id);
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

}  // namespace patch_steps

using namespace patch_steps;

namespace {

constexpr double kSettledRms = 0.005;  // a round that takes less off the RMS ends the correction
constexpr double kRecheckMm = 0.3;  // a final distance past this is checked against the other patches near
constexpr size_t kFitPoints = 15000;  // measured points in the least squares (at least 16 per control point)

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

// --- 1. the control net of the layout, started on its bilinear faces (or on a seed: a split
// surface's control points, a shared one the same from every face on it) ---
Net start_net(const PatchLayout& layout, const LayoutTopology& T, PatchSkin* out,
              const std::vector<std::array<Eigen::Vector3d, 16>>* seed) {
  Net net = build_net(layout, T);
  out->patch_control = net.ids;
  out->control_derived = net.derived;
  out->control.assign(net.count, Eigen::Vector3d::Zero());
  out->patches.resize(layout.faces.size());
  for (size_t f = 0; f < layout.faces.size(); ++f) {
    const auto& c = layout.faces[f];
    const auto& V = layout.vertices;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        const double s = i / 3.0, t = j / 3.0;
        out->control[net.ids[f][4 * i + j]] =
            seed ? (*seed)[f][4 * i + j]
                 : Eigen::Vector3d((1 - s) * (1 - t) * V[c[0]] + s * (1 - t) * V[c[1]] + s * t * V[c[2]] + (1 - s) * t * V[c[3]]);
      }
    out->patches[f].name = f < layout.names.size() ? layout.names[f] : "face" + std::to_string(f);
  }
  rebuild_patches(out);
  return net;
}

// --- 2. data: the measured points near the skin, and samples of the polygon skin as weak
// data. `in_fit`: per point, its datum, -1 measured at the end only, -2 stray; `refined`: the
// layout was refined to a tolerance (its faces halved) ---
constexpr double kSeenMm = 2.0, kRefinedSeenMm = 5.0;
std::vector<Datum> gather_data(const std::vector<Eigen::Vector3d>& points, const std::vector<std::uint32_t>& sides,
                               const std::vector<Eigen::Vector3d>& support, int net_count, const PatchOptions& o,
                               bool refined, std::vector<int>* in_fit) {
  std::vector<Datum> data;
  in_fit->assign(points.size(), -2);
  constexpr double kFarMm = 5.0;  // farther from the skin's every sample: not the skin (a stray sample)
  const PointGrid near_skin(support, 2.0);
  std::vector<char> keep(points.size(), 1);
  if (!support.empty()) {
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(points.size()); ++k) keep[k] = near_skin.any_within(points[k], kFarMm);
  }
  const size_t measured = static_cast<size_t>(std::count(keep.begin(), keep.end(), 1));
  const size_t wanted = std::max<size_t>(kFitPoints, 16 * static_cast<size_t>(net_count));
  const size_t stride = std::max<size_t>(1, measured / wanted);
  size_t m = 0;
  for (size_t k = 0; k < points.size(); ++k) {
    if (!keep[k]) continue;
    if (m++ % stride == 0) {
      (*in_fit)[k] = static_cast<int>(data.size());
      data.push_back({points[k], static_cast<double>(stride), sides[k] == 1 ? 1 : 0});
    } else {
      (*in_fit)[k] = -1;
    }
  }
  // The skin's samples only where the scans saw nothing: within seen_mm of a fitted measured
  // point they weigh little beside it (0.5 against the stride's ~9) but cost as much in every
  // round's foot points and blocks (on the fixture they were 56 % of the data). A refined
  // layout's small patches follow the samples closely: where the polygon skin's guess over an
  // unseen rim (a spread thumb's web) leaves the data by millimetres, they bent to it within
  // 2 mm of the data's last points and missed those by ~1 mm, whatever the splits; 5 mm gives
  // the surface room to turn (docs/patches.md, refinement step 5). The default layout's large
  // patches are held better by the nearer samples (at 4 mm the family's surfaces came out
  // farther from the truth on 95 of 96 runs, by up to 0.007 mm).
  const double seen_mm = refined ? kRefinedSeenMm : kSeenMm;
  std::vector<Eigen::Vector3d> fitted;
  fitted.reserve(data.size());
  for (const Datum& d : data) fitted.push_back(d.p);
  const PointGrid seen(fitted, seen_mm);
  for (const auto& p : support)
    if (!seen.any_within(p, seen_mm)) data.push_back({p, o.skin_weight, -1});
  return data;
}

// --- 3. each datum's first foot point on the started surface ---
void place_data(const std::vector<BezierPatch>& P, const LayoutTopology& T, std::vector<Datum>* data) {
  // 4 mm cells: many points lie millimetres off the layout's bilinear faces, and a search
  // from them crosses fewer large cells (the nearest sample is the same at any cell size;
  // this placement took 16 ms on the fixture with 2 mm cells, 7 with 4).
  const SurfaceSamples S(P, 8);
  const PointGrid grid(S.p, 4.0);
#pragma omp parallel for schedule(dynamic, 256)
  for (long k = 0; k < static_cast<long>(data->size()); ++k) locate_globally(P, T, S, grid, &(*data)[k]);
}

// The surface's unit normal at d's foot point into d.n (zero where it is degenerate); returns
// the foot point.
Eigen::Vector3d take_normal(const std::vector<BezierPatch>& P, Datum* d) {
  Eigen::Vector3d Sp, Su, Sv;
  P[d->patch].derivatives(d->s, d->t, &Sp, &Su, &Sv);
  const Eigen::Vector3d nn = Su.cross(Sv);
  d->n = nn.norm() > 1e-12 ? Eigen::Vector3d(nn.normalized()) : Eigen::Vector3d::Zero();
  return Sp;
}

// --- 5. parameter correction (eqs. 4.6–4.7): foot points on the current surface, refit ---
void correct_parameters(PatchSkin* out, const LayoutTopology& T, const PatchLayout& layout, std::vector<Datum>* data,
                        const PatchOptions& o, NetFit* net) {
  std::vector<std::vector<char>> touches(out->patches.size(), std::vector<char>(out->patches.size(), 0));
  {
    std::vector<std::vector<int>> at_corner(layout.vertices.size());
    for (size_t f = 0; f < layout.faces.size(); ++f)
      for (int c : layout.faces[f]) at_corner[c].push_back(static_cast<int>(f));
    for (const auto& fs : at_corner)
      for (int f : fs)
        for (int g : fs) touches[f][g] = 1;
    for (size_t f = 0; f < layout.faces.size(); ++f)  // a long side's face and the half away from its corner
      for (int g : T.faces_across(static_cast<int>(f))) touches[f][g] = touches[g][f] = 1;
  }
  std::vector<double> moved(data->size(), -1);
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
    std::vector<int> was(data->size());
    std::vector<Eigen::Vector3d> before(data->size());
    std::vector<char> lost(data->size(), 0);
#pragma omp parallel for schedule(dynamic, 256)
    for (long k = 0; k < static_cast<long>(data->size()); ++k) {
      Datum& d = (*data)[k];
      was[k] = d.patch;
      before[k] = out->patches[d.patch].eval(d.s, d.t);
      lost[k] = foot_point(out->patches, T, &d, 3);
    }
    if (std::find(lost.begin(), lost.end(), 1) != lost.end()) {
      const SurfaceSamples S(out->patches, 8);
      const PointGrid grid(S.p, 4.0);
#pragma omp parallel for schedule(dynamic, 16)
      for (long k = 0; k < static_cast<long>(data->size()); ++k)
        if (lost[k]) locate_globally(out->patches, T, S, grid, &(*data)[k]);
    }
    std::vector<double> r2(data->size(), -1);  // squared residuals, summed in order below (deterministic)
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(data->size()); ++k) {
      Datum& d = (*data)[k];
      const Eigen::Vector3d Sp = take_normal(out->patches, &d);
      moved[k] = -1;
      if (d.side < 0) continue;
      if (touches[was[k]][d.patch]) moved[k] = (Sp - before[k]).norm();
      r2[k] = (d.p - Sp).squaredNorm();
    }
    double sum2 = 0;
    long count = 0, reassigned = 0;
    for (size_t k = 0; k < data->size(); ++k)
      if (r2[k] >= 0) {
        sum2 += r2[k], ++count;
        if (moved[k] < 0) ++reassigned;
      }
    out->rms_per_round.push_back(std::sqrt(sum2 / std::max(count, 1L)));
    const bool rose = best.round >= 0 && out->rms_per_round.back() > best.rms;
    if (!rose) best.rms = out->rms_per_round.back(), best.round = round, best.control = out->control, best.patches = out->patches;
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
    out->max_update_per_round.push_back(largest);
    out->update_p999_per_round.push_back(p999);
    out->reassigned_per_round.push_back(static_cast<size_t>(reassigned));
    // Settled: 99.9 % of the points moved less than the tolerance, or the round took less than
    // 0.5 % off the RMS (the points still moving are sliding along a surface that no longer
    // comes nearer them). A round that raised it settles nothing: the refits are still
    // untangling parameters the first fit took from the layout.
    const size_t nr = out->rms_per_round.size();
    const bool settled = p999 < o.correction_tolerance ||
                         (nr >= 2 && !rose && out->rms_per_round[nr - 1] > (1 - kSettledRms) * out->rms_per_round[nr - 2]);
    if (settled) break;  // this round's foot points are the final surface's
    net->fit(out, T, *data, o);
  }
  if (best.round >= 0 && best.round + 1 < static_cast<int>(out->rms_per_round.size())) {
    out->control = std::move(best.control), out->patches = std::move(best.patches);
  } else {
    // The last solve's surface is kept: its least squares to kCgTolerance. (An earlier round's
    // surface, kept when a later one raised the RMS, stays as its round solved it.)
    net->polish(out);
  }
  out->kept_round = best.round;

}

// --- 6. every measured point's foot point on the final surface: the exact distances ---
void measure_points(PatchSkin* out, const LayoutTopology& T, const std::vector<Eigen::Vector3d>& points,
                    const std::vector<std::uint32_t>& sides, const std::vector<int>& in_fit,
                    const std::vector<Datum>& data) {
  const SurfaceSamples S(out->patches, 16);
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
      if (foot_point(out->patches, T, &d, 8)) locate_globally(out->patches, T, S, grid, &d);
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
      if (!start || foot_point(out->patches, T, &d, 6)) locate_globally(out->patches, T, S, grid, &d);
    }
    r[k] = (out->patches[d.patch].eval(d.s, d.t) - d.p).norm();
    if (r[k] > kRecheckMm) r[k] = nearest_sheet(out->patches, T, S, grid, &d, r[k]);
  }
  std::vector<double> residual[2];
  double worst[2] = {-1, -1};
  out->samples.reserve(out->samples.size() + static_cast<size_t>(std::count_if(in_fit.begin(), in_fit.end(), [](int i) { return i != -2; })));
  for (size_t k = 0; k < points.size(); ++k) {
    if (in_fit[k] == -2) continue;
    const Datum& d = all[k];
    if (r[k] > worst[d.side]) worst[d.side] = r[k], out->worst_patch[d.side] = out->patches[d.patch].name;
    residual[d.side].push_back(r[k]);
    out->samples.push_back({d.p, static_cast<float>(r[k]), static_cast<std::uint8_t>(d.side), d.patch,
                           static_cast<float>(d.s), static_cast<float>(d.t)});
  }
  out->side = {figures_of(residual[0]), figures_of(residual[1])};
}

// --- 7. the binding, the patches' links, continuity figures ---
void bind_and_check(PatchSkin* out, const LayoutTopology& T, const PatchLayout& layout, const std::vector<Bone>& bones) {
  out->control_link.resize(out->control.size());
  for (size_t k = 0; k < out->control.size(); ++k) out->control_link[k] = nearest_link(out->control[k], bones);
  rebuild_patches(out);
  for (auto& P : out->patches) P.link = nearest_link(P.eval(0.5, 0.5), bones);
  out->control_points = out->control.size();
  std::vector<double> g1, g1_near;
  double worst_jump = -1;
  for (size_t f = 0; f < out->patches.size(); ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      // Each border once: a shared one from the face with the lower index, a T-junction's from
      // its short sides (the long side's face is sampled where each lies along it).
      const bool short_side = T.half[f][s] >= 0;
      if (!short_side && (g < static_cast<int>(f) || (g == static_cast<int>(f) && gs < s))) continue;
      if (layout.is_crease(layout.faces[f][s], layout.faces[f][(s + 1) % 4])) continue;
      const bool irregular_start = !T.regular(layout.faces[f][s]), irregular_end = !T.regular(layout.faces[f][(s + 1) % 4]);
      for (int q = 1; q <= 9; ++q) {
        int g_at, gs_at;  // g and gs (a shared side's or a short side's long one)
        double along;
        T.across(static_cast<int>(f), s, q / 10.0, &g_at, &gs_at, &along);
        const Eigen::Vector2d a = on_side(s, q / 10.0), b = on_side(gs_at, along);
        Eigen::Vector3d Sa, Sau, Sav, Sb, Sbu, Sbv;
        out->patches[f].derivatives(a.x(), a.y(), &Sa, &Sau, &Sav);
        out->patches[g_at].derivatives(b.x(), b.y(), &Sb, &Sbu, &Sbv);
        out->g0_gap_mm = std::max(out->g0_gap_mm, (Sa - Sb).norm());
        const Eigen::Vector3d na = Sau.cross(Sav), nb = Sbu.cross(Sbv);
        if (na.norm() < 1e-12 || nb.norm() < 1e-12) continue;
        const double jump = std::acos(std::clamp(na.normalized().dot(nb.normalized()), -1.0, 1.0)) * 180 / M_PI;
        const bool near = (q <= 2 && irregular_start) || (q >= 8 && irregular_end);
        (near ? g1_near : g1).push_back(jump);
        if (!near && jump > worst_jump) worst_jump = jump, out->g1_max_where = out->patches[f].name + " | " + out->patches[g].name;
      }
    }
  auto median_of = [](std::vector<double>& v) { return v.empty() ? 0.0 : v[v.size() / 2]; };
  std::sort(g1.begin(), g1.end());
  std::sort(g1_near.begin(), g1_near.end());
  if (!g1.empty()) {
    out->g1_median_deg = median_of(g1);
    out->g1_p95_deg = g1[static_cast<size_t>(0.95 * (g1.size() - 1))];
    out->g1_max_deg = g1.back();
  }
  if (!g1_near.empty()) out->g1_near_median_deg = median_of(g1_near), out->g1_near_max_deg = g1_near.back();
}

}  // namespace

void rebuild_patches(PatchSkin* s) {
  for (size_t k = 0; k < s->control_derived.size(); ++k)
    if (!s->control_derived[k].empty()) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (const auto& [j, w] : s->control_derived[k]) p += w * s->control[j];
      s->control[k] = p;
    }
  for (size_t f = 0; f < s->patches.size(); ++f)
    for (int k = 0; k < 16; ++k) {
      const int id = s->patch_control[f][k];
      s->patches[f].P[k] = s->control[id];
      s->patches[f].cp_link[k] = s->control_link.empty() ? -1 : s->control_link[id];
    }
}

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
  if (subdivision < 1 || subdivision > 8) return invalid(error, "subdivision must be in [1, 8]");
  if (!(fairness >= 0 && fairness <= 10)) return invalid(error, "fairness must be in [0, 10]");
  if (!(c1_weight >= 0 && c1_weight <= 1e4)) return invalid(error, "c1_weight must be in [0, 1e4]");
  if (!(corner_weight >= 0 && corner_weight <= 1e4)) return invalid(error, "corner_weight must be in [0, 1e4]");
  if (!(skin_weight > 0 && skin_weight <= 10)) return invalid(error, "skin_weight must be in (0, 10]");
  if (max_corrections < 0 || max_corrections > 100) return invalid(error, "max_corrections must be in [0, 100]");
  if (!(correction_tolerance > 0)) return invalid(error, "correction_tolerance must be > 0");
  if (tessellation < 1 || tessellation > 64) return invalid(error, "tessellation must be in [1, 64]");
  if (!(tolerance_mm >= 0 && tolerance_mm <= 100)) return invalid(error, "tolerance_mm must be in [0, 100] (0: none)");
  if (max_patches < 1 || max_patches > 20000) return invalid(error, "max_patches must be in [1, 20000]");
  if (refine_rounds < 0 || refine_rounds > 20) return invalid(error, "refine_rounds must be in [0, 20]");
  if (rough_rounds < 0 || rough_rounds > 20) return invalid(error, "rough_rounds must be in [0, 20]");
  return true;
}

PatchSkin patch_steps::fit_patches_unmeasured(const PatchLayout& layout, const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<std::uint32_t>& sides, const std::vector<Eigen::Vector3d>& support,
                                 const std::vector<Bone>& bones, const PatchOptions& o,
                                 const std::vector<std::array<Eigen::Vector3d, 16>>* seed,
                                 const std::vector<Separation>& separations) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("patch options", err);
  HS_CHECK(points.size() == sides.size(), "points and sides differ in length");
  HS_CHECK(!seed || seed->size() == layout.faces.size(), "one seed per face");
  const auto t0 = std::chrono::steady_clock::now();
  PatchSkin out;
  out.layout = layout;
  out.skin_weight_used = o.skin_weight;
  out.fairness_used = o.fairness;
  HS_CHECK(separations.empty() || seed, "separations act in the rounds along the normals: a seed is needed");
  out.separations = separations;
  auto pending = std::make_shared<PendingMeasure>();
  pending->topology = layout_topology(layout, "patch layout");
  const LayoutTopology& T = pending->topology;
  for (const auto& b : bones) out.bones.push_back(b.name());
  for (int v : T.valence) out.irregular_corners += v != 4;

  const Net net = start_net(layout, T, &out, seed);
  std::vector<int>& in_fit = pending->in_fit;
  std::vector<Datum>& data = pending->data;
  data = gather_data(points, sides, support, net.count, o, !layout.levels.empty(), &in_fit);
  if (data.size() < 16 * out.patches.size())
    throw InputError("patches", "too few points (" + std::to_string(data.size()) + ") for " +
                                    std::to_string(out.patches.size()) + " patches");
  place_data(out.patches, T, &data);
  if (seed) {
    // A seed is a fitted surface (split_layout): its foot points' normals are good already, so
    // the first least squares is a correction round (the normal error, G1 where C1 cannot
    // hold) and not a fresh start. A point-to-point first fit, with no G1 rows next to the
    // corners where other than four patches meet, folded the flanks of two fingers at their
    // web on the fixture (175° between their normals), and nothing after it unfolded them.
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(data.size()); ++k) take_normal(out.patches, &data[k]);
  }
  NetFit net_fit;  // --- 4. the least squares ---
  net_fit.fit(&out, T, data, o);
  correct_parameters(&out, T, layout, &data, o, &net_fit);
  for (const auto& c : out.control)
    if (!c.allFinite())
      throw InputError("patches", "the fit gave non-finite control points; the layout does not fit these points");
  bind_and_check(&out, T, layout, bones);
  out.pending_measure = std::move(pending);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

void patch_steps::measure_pending(PatchSkin* s, const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<std::uint32_t>& sides) {
  if (!s->pending_measure) return;
  const auto t0 = std::chrono::steady_clock::now();
  const PendingMeasure& m = *s->pending_measure;
  measure_points(s, m.topology, points, sides, m.in_fit, m.data);
  s->pending_measure.reset();
  s->seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

PatchSkin fit_patches(const PatchLayout& layout, const std::vector<Eigen::Vector3d>& points,
                      const std::vector<std::uint32_t>& sides, const std::vector<Eigen::Vector3d>& support,
                      const std::vector<Bone>& bones, const PatchOptions& o,
                      const std::vector<std::array<Eigen::Vector3d, 16>>* seed,
                      const std::vector<Separation>& separations) {
  PatchSkin out = fit_patches_unmeasured(layout, points, sides, support, bones, o, seed, separations);
  measure_pending(&out, points, sides);  // --- 6. every measured point's distance ---
  return out;
}

std::string patch_steps::finger_of(const std::string& name) {
  const std::string f = name.substr(0, name.find('.'));
  return f == "index" || f == "middle" || f == "ring" || f == "little" ? f : std::string();
}

namespace {

// Where two fingers' patches that share a border (the web's, between their tubes) cross, the
// fingers are pressed together and both patches follow the crease between them (the family's
// H04 and H12: the true section two overlapping circles, each tube's inner wall within a
// fraction of a millimetre of the other's). The plane they are held apart by holds that
// border (through its control points' mean, along it) and is turned about it to pass nearest
// where the two crossed (below). A refined layout's faces are taken by the layout's face they were split from (their name up
// to the first '/'), so that the two sides are every patch split from the two that crossed.
std::vector<Separation> finger_separations(const PatchSkin& s, const PatchCrossings& c) {
  const auto root = [&](int f) { const std::string& n = s.patches[f].name; return n.substr(0, n.find('/')); };
  std::set<std::pair<std::string, std::string>> done;
  std::vector<Separation> out;
  for (const auto& [fa, fb] : c.patch_pairs) {
    const std::string ra = root(fa), rb = root(fb);
    const std::string a = finger_of(ra), b = finger_of(rb);
    if (a.empty() || b.empty() || a == b || !done.insert(std::minmax(ra, rb)).second) continue;
    std::vector<Eigen::Vector3d> lens;  // where the two tubes' patches cross: about the crease
    for (size_t k = 0; k < c.patch_pairs.size(); ++k)
      if (std::minmax(root(c.patch_pairs[k].first), root(c.patch_pairs[k].second)) == std::minmax(ra, rb))
        lens.insert(lens.end(), c.where[k].begin(), c.where[k].end());
    std::array<std::vector<int>, 2> faces;
    std::array<std::set<int>, 2> ids;
    std::array<Eigen::Vector3d, 2> centre = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    for (size_t f = 0; f < s.patches.size(); ++f)
      for (int side = 0; side < 2; ++side)
        if (root(static_cast<int>(f)) == (side == 0 ? ra : rb)) {
          faces[side].push_back(static_cast<int>(f));
          ids[side].insert(s.patch_control[f].begin(), s.patch_control[f].end());
        }
    // The shared border's control points, and its two ends: the pair farthest apart.
    std::vector<Eigen::Vector3d> border;
    for (int id : ids[0])
      if (ids[1].count(id)) border.push_back(s.control[id]);
    if (border.size() < 2) continue;  // a corner only: no border to hold them apart along
    for (int side = 0; side < 2; ++side) {
      for (int id : ids[side]) centre[side] += s.control[id];
      centre[side] /= static_cast<double>(ids[side].size());
    }
    Eigen::Vector3d mid = Eigen::Vector3d::Zero(), along = Eigen::Vector3d::Zero();
    for (const auto& p : border) mid += p / static_cast<double>(border.size());
    for (const auto& p : border)
      for (const auto& q : border)
        if ((q - p).norm() > along.norm()) along = q - p;
    // The plane holds the border; turned about it to pass nearest the lens where the two
    // crossed (the crease lies there, and the tubes' mean direction away from the border
    // missed it by up to 1.3 mm on H04), the tubes' direction counting as one point 10 mm out.
    const Eigen::Vector3d e = along.normalized();
    const Eigen::Vector3d tube = (centre[0] - mid).normalized() + (centre[1] - mid).normalized();
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    const auto add = [&](const Eigen::Vector3d& x, double w) {
      const Eigen::Vector3d q = (x - mid) - (x - mid).dot(e) * e;
      M += w * q * q.transpose();
    };
    if (tube.norm() > 1e-9) add(mid + 10 * tube.normalized(), static_cast<double>(std::max<size_t>(lens.size(), 1)));
    for (const auto& x : lens) add(x, 1.0);
    // The normal: across the border, the direction the points spread least in.
    Eigen::Vector3d u = e.unitOrthogonal(), v = e.cross(u);
    Eigen::Matrix2d m;
    m << u.dot(M * u), u.dot(M * v), v.dot(M * u), v.dot(M * v);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(m);
    Eigen::Vector3d n = eig.eigenvectors()(0, 0) * u + eig.eigenvectors()(1, 0) * v;
    if (!(n.norm() > 1e-9) || !n.allFinite()) continue;
    n.normalize();
    if (n.dot(centre[1] - centre[0]) < 0) n = -n;
    Separation sep;
    sep.normal = n;
    sep.offset = n.dot(mid);
    sep.faces = std::move(faces);
    sep.between = std::min(ra, rb) + " | " + std::max(ra, rb);
    out.push_back(std::move(sep));
  }
  return out;
}

}  // namespace

void check_layout_on_skin(const PatchLayout& layout, const Mesh& skin) {
  // Every corner within 20 mm of the skin's surface, not of its vertices: a refined layout has
  // corners in the middle of the wrist cut's cap, whose vertices are its rim only (the family's
  // H04, 300 mm long: 24–30 mm from the nearest vertex, on the cap; refused as "not from this
  // skin" until 2026-11-30).
  const MeshDistance to_skin(skin);
  for (size_t k = 0; k < layout.vertices.size(); ++k)
    if (!layout.vertices[k].allFinite() || !(to_skin.distance(layout.vertices[k]) <= 20.0))
      throw InputError("patch layout", "corner " + std::to_string(k) + " lies more than 20 mm from the skin; is the layout from this skin?");
}

PatchSkin fit_patch_skin(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<std::uint32_t>& sides, const PatchOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("patch options", err);
  const auto t0 = std::chrono::steady_clock::now();
  if (o.layout) check_layout_on_skin(*o.layout, skin.mesh);
  // The skin as weak data, one sample per 2 mm², so that it holds the surface where the scans saw
  // nothing (the flanks between the fingers, the wrist cut) and nowhere outweighs them.
  const std::vector<Eigen::Vector3d> support = sample_surface(skin.mesh, 0.5);
  auto fit = [&](int shift, double turn) {
    const PatchLayout layout =
        o.layout ? *o.layout : subdivide_layout(hand_patch_layout(skin, rig, points, sides, shift, turn), o.subdivision);
    return fit_patches_unmeasured(layout, points, sides, support, skin.bones, o);
  };
  // The skin's distance tree for the check below, built beside the first fit (~2 ms, which
  // the fit's single-threaded factorisations leave room for).
  std::future<std::unique_ptr<MeshDistance>> skin_tree;
  if (!o.layout)
    skin_tree = std::async(side_launch(), [&skin] { return std::make_unique<MeshDistance>(skin.mesh); });
  PatchSkin s = fit(0, 0);
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
    std::vector<double> turns = {0.0};
    // A surface that passes through itself at the thumb's base, the palm or the wrist (not
    // between two fingers, which another thumb ring does not part) is tried again too: on the
    // WebXR hand model (scripts/webxr_study.py) the thumb's first row crossed the thenar's
    // patch on 4 of 29 runs (13-119 pairs of triangles) whose patches strayed 0.65-0.70 mm at
    // the 95th percentile, and the layout with that ring 2 rings toward the wrist crossed
    // nowhere and lay nearer the skin.
    s.crossings = crossings(s, o.tessellation);
    std::vector<size_t> crossed = {s.crossings->pairs};
    std::vector<std::pair<double, std::string>> folds = {{s.g1_max_deg, s.g1_max_where}};
    const auto at_base = [](const std::string& w) {
      return w.find("thumb.") != std::string::npos || w.find("palm.") != std::string::npos ||
             w.find("wrist.") != std::string::npos;
    };
    const bool crossed_at_base = std::any_of(s.crossings->patches.begin(), s.crossings->patches.end(), at_base);
    // And one that folds: a jump between two patches' normals over the gate's 30 deg
    // (gates.g1_kink_deg). On the WebXR hand with its thumb bent (left, second pair) the first
    // layout crossed itself at the thumb's base in 53 pairs, or, its skin a few micrometres
    // otherwise, in none but folded there by 42 deg with its patches 3.1 mm from the skin; the
    // layout with that ring 2 rings toward the wrist did neither. (Until 2026-11-30 a fold
    // counted at the thumb's, the palm's or the wrist's borders only: the WebXR fixed hand,
    // its forearm cut 5 mm beyond the wrist, folded by 160 deg at its middle finger's first
    // row and no other layout was tried.)
    constexpr double kFoldDeg = 30;
    const auto folded = [&](const PatchSkin& p) { return p.g1_max_deg > kFoldDeg; };
    if (tries[0].second > kStrayP95Mm || crossed_at_base || folded(s)) {
      // The other layouts are fitted two at a time, each on a thread of its own (a fit's
      // factorisations leave most of the second core idle), and compared in a fixed order:
      // the same choice with any number of threads.
      auto other = [&](int shift, double turn) -> std::optional<PatchSkin> {
        try {
          return fit(shift, turn);
        } catch (const InputError&) {
          return std::nullopt;  // a corner that cannot be placed there: the layout stays as it was
        }
      };
      // Kept: the fewest crossings, then one not folded over the G1 gate's 30 deg anywhere (a
      // ring moved for the thumb's sake can fold a finger's first row: the WebXR fixed hand's
      // middle finger, 34-47 deg at its web with the index), then the nearest the skin.
      std::tuple<size_t, bool, double> best = {crossed[0], folded(s), tries[0].second};
      const auto at_thumb = [](const std::string& w) { return w.find("thumb.") != std::string::npos; };
      const auto thumb_in_trouble = [&](const PatchSkin& p) {
        return std::any_of(p.crossings->patches.begin(), p.crossings->patches.end(), at_thumb) ||
               (folded(p) && at_thumb(p.g1_max_where));
      };
      bool thumb_trouble = thumb_in_trouble(s);
      const auto compare = [&](std::array<std::tuple<int, double, std::optional<PatchSkin>>, 2>& others) {
        for (auto& [shift, turn, t] : others) {
          if (!t) continue;
          tries.push_back({shift, stray(*t)});
          turns.push_back(turn);
          t->crossings = crossings(*t, o.tessellation);
          crossed.push_back(t->crossings->pairs);
          folds.push_back({t->g1_max_deg, t->g1_max_where});
          thumb_trouble = thumb_trouble || thumb_in_trouble(*t);
          const std::tuple<size_t, bool, double> mine = {crossed.back(), folded(*t), tries.back().second};
          if (mine < best) best = mine, s = std::move(*t), s.thumb_ring_shift = shift, s.thumb_turn_deg = turn;
        }
      };
      {
        std::future<std::optional<PatchSkin>> toward_webs = std::async(side_launch(), other, 2, 0.0);
        std::array<std::tuple<int, double, std::optional<PatchSkin>>, 2> shifted = {
            std::tuple<int, double, std::optional<PatchSkin>>{-2, 0.0, other(-2, 0.0)}, {2, 0.0, toward_webs.get()}};
        compare(shifted);
      }
      // A thumb turned under the hand grows from the palm's side, not from the radial flank the
      // layout puts its base on: the patches beside its base then fold over (the WebXR
      // "generic-fixed-hand", a relaxed hand with its thumb under the fingers, without a rig:
      // 86-189 pairs of crossing triangles with the ring moved either way). Where the kept
      // layout still crosses or folds, and a layout tried so far crossed or folded at the thumb
      // (a thumb patch in a crossing pair, or at the largest fold), the base is turned
      // kThumbTurnDeg round the palm's section toward the palm and toward the back, with the
      // ring where it was and where it was kept, and compared in the same order. That hand:
      // every gate passes turned toward the palm. (Turned wherever the kept layout crossed, a
      // hand whose pressed fingers cross each other — the unusual hands' P03 — kept a turn that
      // crossed 7 pairs less before its fingers were held apart and 104 more after.)
      constexpr double kThumbTurnDeg = 20;
      if (thumb_trouble && (std::get<0>(best) > 0 || std::get<1>(best))) {
        std::vector<int> shifts = {0};
        if (s.thumb_ring_shift != 0) shifts.push_back(s.thumb_ring_shift);
        for (const int shift : shifts) {
          std::future<std::optional<PatchSkin>> toward_back = std::async(side_launch(), other, shift, -kThumbTurnDeg);
          std::array<std::tuple<int, double, std::optional<PatchSkin>>, 2> turned = {
              std::tuple<int, double, std::optional<PatchSkin>>{shift, kThumbTurnDeg, other(shift, kThumbTurnDeg)},
              {shift, -kThumbTurnDeg, toward_back.get()}};
          compare(turned);
        }
      }
    }
    s.layout_tries = std::move(tries);
    s.layout_try_turns = std::move(turns);
    s.layout_try_crossings = std::move(crossed);
    s.layout_try_folds = std::move(folds);
  }
  // Neighbouring fingers pressed together: their tubes' patches either side of the web can
  // pass through each other (finger_separations). The net is fitted again from this surface
  // with them held apart, and kept when it crosses itself less (on the family's H04 and H12,
  // whose fingers touch at their roots: 0.2-0.35 s more). Held apart, two tubes can push a
  // third finger's into its neighbour (H12's second pair: index–middle and middle–ring held,
  // ring–little then crossed in 4 pairs): the crossings left are looked at again, up to
  // kSeparationFits fits. A refined surface is looked at too (its splits can bring together
  // two tubes that did not cross).
  const auto hold_fingers_apart = [&](PatchSkin* s, const PatchOptions& o) {
    if (!s->crossings) s->crossings = crossings(*s, o.tessellation);
    constexpr int kSeparationFits = 3;
    const size_t crossed_first = s->crossings_before_separation > 0 ? s->crossings_before_separation : s->crossings->pairs;
    for (int fit_count = 0; fit_count < kSeparationFits && s->crossings->pairs > 0; ++fit_count) {
      std::vector<Separation> seps = s->separations;
      for (Separation& sep : finger_separations(*s, *s->crossings))
        if (std::none_of(seps.begin(), seps.end(), [&](const Separation& x) { return x.between == sep.between; }))
          seps.push_back(std::move(sep));
      if (seps.size() == s->separations.size()) break;  // none new: the crossings left are not between two fingers' tubes
      std::vector<std::array<Eigen::Vector3d, 16>> seed(s->patches.size());
      for (size_t f = 0; f < seed.size(); ++f) seed[f] = s->patches[f].P;
      PatchSkin t = fit_patches_unmeasured(s->layout, points, sides, support, skin.bones, o, &seed, seps);
      t.crossings = crossings(t, o.tessellation);
      if (t.crossings->pairs >= s->crossings->pairs) break;
      t.crossings_before_separation = crossed_first;
      carry_fit_choices(s, &t);
      if ((t.refinement = std::move(s->refinement))) {  // after a refinement: its figures of the surface kept
        measure_pending(&t, points, sides);
        const std::vector<double> err = patch_max_error(t);
        PatchSkin::Refinement& R = *t.refinement;
        R.patches.push_back(static_cast<int>(t.patches.size()));
        R.over.push_back(static_cast<int>(std::count_if(err.begin(), err.end(), [&](double e) { return e > o.tolerance_mm; })));
        R.worst_mm.push_back(err.empty() ? 0.0 : *std::max_element(err.begin(), err.end()));
        R.seconds.push_back(t.seconds);
        R.held = R.over.back() == 0;
      }
      *s = std::move(t);
    }
  };
  hold_fingers_apart(&s, o);
  // The polygon skin's samples hold the surface where the scans saw nothing (skin_weight 0.5
  // of a measured point). Where they pull a patch into a fold of the skin that it then
  // crosses (on the family's H12-s3 with the automatic skeleton, between two pressed fingers;
  // on the WebXR hand's bent thumb, its base: 4 pairs of triangles each), the net is fitted
  // again with them at kLightSkinWeight, the weight before 2026-11-29, under which neither
  // crossed; kept when it crosses less.
  PatchOptions used = o;
  constexpr double kLightSkinWeight = 0.05;
  if (s.crossings && s.crossings->pairs > 0 && o.skin_weight > kLightSkinWeight) {
    PatchOptions light = o;
    light.skin_weight = kLightSkinWeight;
    PatchSkin t = fit_patches_unmeasured(s.layout, points, sides, support, skin.bones, light);
    hold_fingers_apart(&t, light);  // measures its crossings first
    if (t.crossings->pairs < s.crossings->pairs) {
      carry_fit_choices(&s, &t);
      s = std::move(t);
      used = light;
    }
  }
  // A fit that still passes through itself, not where two fingers press together (those are
  // held apart above) but within a finger, the thumb or the palm, folds a patch into a crease
  // of the skin (a finger flexed at its MCP beside a straight neighbour: on random hands of
  // scripts/random_hands_study.py the middle finger's first row, its back against its radial
  // side, 3 pairs of triangles; a ring finger's back against its ulnar side, 5 pairs). The
  // fairness term (second differences inside each patch) is what holds a patch to a smooth
  // shape: it is raised 1.5, 2 and 3 times in turn, the net fitted again each time, and the
  // first fit that crosses itself nowhere is kept (`fairness_used` in report.json); a fit
  // that still crosses is not (one that crossed less but kinked at a web was worse). The
  // price is accuracy in the crease: the surface's mean distance to the true skin 0.176 ->
  // 0.186 mm and 0.204 -> 0.234 mm on those two hands (docs/patches.md).
  // (With patches.fairness 0 there is nothing to raise.)
  static constexpr double kFairnessRaises[] = {1.5, 2.0, 3.0};
  if (o.fairness > 0 && s.crossings && s.crossings->pairs > 0 &&
      crossings_not_between_fingers(s, *s.crossings) == s.crossings->patch_pairs.size())
    for (const double raise : kFairnessRaises) {
      PatchOptions fairer = used;
      fairer.fairness = raise * o.fairness;
      PatchSkin t = fit_patches_unmeasured(s.layout, points, sides, support, skin.bones, fairer);
      hold_fingers_apart(&t, fairer);
      if (t.crossings->pairs > 0) continue;
      carry_fit_choices(&s, &t);
      t.crossings_before_fairness = s.crossings->pairs;
      s = std::move(t);
      used = fairer;
      break;
    }
  if (used.tolerance_mm > 0) {
    measure_pending(&s, points, sides);  // the refinement cuts by the points' distances
    refine_to_tolerance(
        &s, used,
        [&](const LayoutSplit& split) {
          // s: the fit being refined.
          return fit_patches(split.layout, points, sides, support, skin.bones, used, &split.seed,
                             separations_after_split(s.separations, split));
        },
        [&](PatchSkin* refined) { hold_fingers_apart(refined, used); });
  }
  // Only the fit kept is measured (every measured point's foot point: ~65-100 ms).
  measure_pending(&s, points, sides);
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return s;
}

namespace {
// The tessellation's vertex of each patch's (n + 1)² grid point: a layout corner's and a
// shared border's points are one vertex for every patch on them. A border point is named by
// its edge and its step along it in halves of a grid step, so that at a T-junction a short
// side's points are the long side's at every other half step, and the points between (made by
// the short sides' patches) are in `mids`: per face and side, on a long side, the vertex
// halfway along each of its n grid steps.
struct TessellationIndex {
  std::vector<std::vector<int>> index;
  std::vector<std::array<std::vector<int>, 4>> mids;
};
TessellationIndex tessellation_index(const PatchSkin& s, int n, std::vector<std::array<int, 3>>* made) {
  HS_CHECK(n >= 1, "tessellation needs at least one quad per patch side");
  TessellationIndex X;
  X.index.assign(s.patches.size(), std::vector<int>(static_cast<size_t>(n + 1) * (n + 1), -1));
  X.mids.resize(s.patches.size());
  std::vector<int> corner(s.layout.vertices.size(), -1);
  std::map<std::tuple<int, int, int>, int> on_edge;
  const bool conforming = s.control_derived.empty() ||
                          std::all_of(s.control_derived.begin(), s.control_derived.end(), [](const auto& d) { return d.empty(); });
  const LayoutTopology T = conforming ? LayoutTopology{} : layout_topology(s.layout, "patch layout");
  // The slot of the point `k` grid steps along side `side` of face f (0 < k < n).
  const auto border_slot = [&](size_t f, int side, int k) -> int* {
    const auto& c = s.layout.faces[f];
    int p = c[side], q = c[(side + 1) % 4], fine = 2 * k;
    if (!conforming) {
      if (const int h = T.half[f][side]; h >= 0) {
        const auto& g = s.layout.faces[T.neighbour[f][side]];
        const int gs = T.neighbour_side[f][side];
        p = g[gs], q = g[(gs + 1) % 4], fine = h * n + (n - k);
      } else if (T.neighbour[f][side] < 0 && fine == n) {
        return &corner[T.hanging.at({static_cast<int>(f), side})];
      }
    }
    if (p > q) std::swap(p, q), fine = 2 * n - fine;
    return &on_edge.emplace(std::make_tuple(p, q, fine), -1).first->second;
  };
  made->clear();
  for (size_t f = 0; f < s.patches.size(); ++f) {
    const auto& c = s.layout.faces[f];
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        int* slot = nullptr;
        if ((i == 0 || i == n) && (j == 0 || j == n)) {
          slot = &corner[c[i == 0 ? (j == 0 ? 0 : 3) : (j == 0 ? 1 : 2)]];
        } else if (j == 0) {
          slot = border_slot(f, 0, i);
        } else if (i == n) {
          slot = border_slot(f, 1, j);
        } else if (j == n) {
          slot = border_slot(f, 2, n - i);
        } else if (i == 0) {
          slot = border_slot(f, 3, n - j);
        }
        int id;
        if (slot && *slot >= 0) {
          id = *slot;
        } else {
          id = static_cast<int>(made->size());
          made->push_back({static_cast<int>(f), i, j});
          if (slot) *slot = id;
        }
        X.index[f][i * (n + 1) + j] = id;
      }
  }
  if (!conforming)
    for (const auto& [long_side, pieces] : T.halves) {
      const auto [f, side] = long_side;
      const auto& c = s.layout.faces[f];
      for (int k = 0; k < n; ++k) {
        int p = c[side], q = c[(side + 1) % 4], fine = 2 * k + 1;
        int id = -1;
        if (fine == n) {
          id = corner[T.hanging.at(long_side)];
        } else {
          if (p > q) std::swap(p, q), fine = 2 * n - fine;
          const auto it = on_edge.find(std::make_tuple(p, q, fine));
          if (it != on_edge.end()) id = it->second;
        }
        HS_CHECK(id >= 0, "tessellation: a T-junction's short side made no point halfway along a grid step");
        X.mids[f][side].push_back(id);
      }
    }
  return X;
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

Mesh tessellate(const PatchSkin& s, int n, std::vector<int>* face_patch) {
  std::vector<std::array<int, 3>> made;
  const TessellationIndex X = tessellation_index(s, n, &made);
  std::vector<Eigen::Vector3d> points;
  evaluate_made(s, n, made, &points);
  std::vector<std::array<int, 3>> tris;
  if (face_patch) face_patch->clear();
  for (size_t f = 0; f < s.patches.size(); ++f) {
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const auto& index = X.index[f];
        const int a = index[i * (n + 1) + j], b = index[(i + 1) * (n + 1) + j];
        const int c = index[(i + 1) * (n + 1) + j + 1], d = index[i * (n + 1) + j + 1];
        // The points halfway along the quad's edges on a long side (-1: none), edge ab, bc, cd, da.
        const auto& M = X.mids[f];
        const int mid[4] = {j == 0 && !M[0].empty() ? M[0][i] : -1, i + 1 == n && !M[1].empty() ? M[1][j] : -1,
                            j + 1 == n && !M[2].empty() ? M[2][n - i - 1] : -1, i == 0 && !M[3].empty() ? M[3][n - j - 1] : -1};
        if (mid[0] < 0 && mid[1] < 0 && mid[2] < 0 && mid[3] < 0) {
          // (u, v) counter-clockwise: Su × Sv points out of the hand.
          tris.push_back({a, b, c});
          tris.push_back({a, c, d});
          continue;
        }
        // A quad on a long side: the polygon of its corners and those points, fanned from a
        // corner neither of whose edges has one (else from such a point), so that no triangle
        // lies along a side.
        const int corners[4] = {a, b, c, d};
        std::vector<int> poly;
        int start = -1;
        for (int e = 0; e < 4; ++e) {
          if (start < 0 && mid[e] < 0 && mid[(e + 3) % 4] < 0) start = static_cast<int>(poly.size());
          poly.push_back(corners[e]);
          if (mid[e] >= 0) poly.push_back(mid[e]);
        }
        if (start < 0) start = 1;  // the point halfway along ab (every edge has one)
        std::rotate(poly.begin(), poly.begin() + start, poly.end());
        for (size_t k = 1; k + 1 < poly.size(); ++k) tris.push_back({poly[0], poly[k], poly[k + 1]});
      }
    if (face_patch) face_patch->resize(tris.size(), static_cast<int>(f));
  }
  return Mesh{std::move(points), std::move(tris)};
}

PatchCrossings tessellation_crossings(const PatchSkin& s, const Mesh& tessellation, const std::vector<int>& face_patch) {
  HS_CHECK(face_patch.size() == tessellation.faces.size(), "one patch per triangle");
  std::vector<Eigen::Vector3d> stored(tessellation.vertices.size());
  for (size_t k = 0; k < stored.size(); ++k) stored[k] = tessellation.vertices[k].cast<float>().cast<double>();
  const auto pairs = crossing_face_pairs(stored, tessellation.faces);
  std::set<std::string> names;
  std::map<std::pair<int, int>, std::vector<Eigen::Vector3d>> which;
  const auto centroid = [&](int f) {
    const auto& t = tessellation.faces[f];
    return ((stored[t[0]] + stored[t[1]] + stored[t[2]]) / 3).eval();
  };
  for (const auto& [f, g] : pairs) {
    std::string a = s.patches[face_patch[f]].name, b = s.patches[face_patch[g]].name;
    if (b < a) std::swap(a, b);
    names.insert(a == b ? a : a + " | " + b);
    auto& at = which[std::minmax(face_patch[f], face_patch[g])];
    at.push_back(centroid(f));
    at.push_back(centroid(g));
  }
  PatchCrossings c{pairs.size(), std::vector<std::string>(names.begin(), names.end()), {}, {}};
  for (auto& [pair, at] : which) c.patch_pairs.push_back(pair), c.where.push_back(std::move(at));
  return c;
}

PatchCrossings crossings(const PatchSkin& s, int n) {
  std::vector<int> face_patch;
  const Mesh m = tessellate(s, n, &face_patch);
  return tessellation_crossings(s, m, face_patch);
}

}  // namespace handskin
