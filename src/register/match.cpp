#include "register/match.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>

namespace handskin {

Eigen::Isometry3d fit_rigid(const std::vector<Eigen::Vector3d>& back, const std::vector<Eigen::Vector3d>& palm,
                            const std::vector<std::pair<int, int>>& pairs) {
  Eigen::Matrix3Xd src(3, pairs.size()), dst(3, pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    src.col(k) = back[pairs[k].first];
    dst.col(k) = palm[pairs[k].second];
  }
  // Eigen::umeyama corrects the SVD's sign so the result is a rotation, never a reflection.
  Eigen::Isometry3d T;
  T.matrix() = Eigen::umeyama(src, dst, false);
  return T;
}

namespace {

struct Scored {
  std::vector<std::pair<int, int>> pairs;
  Eigen::Isometry3d T;
  double rms = 0, max = 0;
};

// Extend a hypothesis: each back marker goes to the nearest palm marker within tolerance,
// one-to-one (closest pairs first), then refit; twice, so the fit can settle.
Scored grow(const std::vector<Eigen::Vector3d>& back, const std::vector<Eigen::Vector3d>& palm, Eigen::Isometry3d T,
            double tol) {
  Scored s;
  for (int round = 0; round < 2; ++round) {
    std::vector<std::tuple<double, int, int>> cand;
    for (size_t b = 0; b < back.size(); ++b)
      for (size_t p = 0; p < palm.size(); ++p) {
        const double d = (T * back[b] - palm[p]).norm();
        if (d < tol) cand.emplace_back(d, static_cast<int>(b), static_cast<int>(p));
      }
    std::sort(cand.begin(), cand.end());
    std::vector<char> used_b(back.size(), 0), used_p(palm.size(), 0);
    s.pairs.clear();
    for (const auto& [d, b, p] : cand)
      if (!used_b[b] && !used_p[p]) {
        used_b[b] = used_p[p] = 1;
        s.pairs.emplace_back(b, p);
      }
    std::sort(s.pairs.begin(), s.pairs.end());
    if (s.pairs.size() < 3) break;
    T = fit_rigid(back, palm, s.pairs);
  }
  s.T = T;
  double ss = 0;
  for (const auto& [b, p] : s.pairs) {
    const double d = (T * back[b] - palm[p]).norm();
    ss += d * d;
    s.max = std::max(s.max, d);
  }
  s.rms = s.pairs.empty() ? 0 : std::sqrt(ss / static_cast<double>(s.pairs.size()));
  return s;
}

bool better(const Scored& a, const Scored& b) {
  return a.pairs.size() != b.pairs.size() ? a.pairs.size() > b.pairs.size() : a.rms < b.rms;
}

}  // namespace

MarkerMatch match_markers(const std::vector<Eigen::Vector3d>& back, const std::vector<Eigen::Vector3d>& palm,
                          double tol) {
  MarkerMatch out;
  const int nb = static_cast<int>(back.size()), np = static_cast<int>(palm.size());
  // Distinct pair sets reached, with their best score.
  std::map<std::vector<std::pair<int, int>>, Scored> reached;
  auto dist = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return (a - b).norm(); };
  for (int a = 0; a < nb; ++a)
    for (int b = a + 1; b < nb; ++b)
      for (int c = b + 1; c < nb; ++c) {
        const double dab = dist(back[a], back[b]), dac = dist(back[a], back[c]), dbc = dist(back[b], back[c]);
        // A near-degenerate triangle fixes no rotation about its long side.
        const double area2 = (back[b] - back[a]).cross(back[c] - back[a]).norm();
        if (area2 / std::max({dab, dac, dbc}) < 4 * tol) continue;
        for (int p = 0; p < np; ++p)
          for (int q = 0; q < np; ++q) {
            if (q == p || std::abs(dist(palm[p], palm[q]) - dab) > tol) continue;
            for (int r = 0; r < np; ++r) {
              if (r == p || r == q) continue;
              if (std::abs(dist(palm[p], palm[r]) - dac) > tol || std::abs(dist(palm[q], palm[r]) - dbc) > tol) continue;
              ++out.hypotheses;
              const Eigen::Isometry3d T = fit_rigid(back, palm, {{a, p}, {b, q}, {c, r}});
              Scored s = grow(back, palm, T, tol);
              if (s.pairs.size() < 3) continue;
              auto it = reached.find(s.pairs);
              if (it == reached.end() || s.rms < it->second.rms) reached[s.pairs] = s;
            }
          }
      }
  if (reached.empty()) return out;
  std::vector<const Scored*> order;
  for (const auto& kv : reached) order.push_back(&kv.second);
  std::sort(order.begin(), order.end(), [](const Scored* x, const Scored* y) { return better(*x, *y); });
  const Scored& best = *order.front();
  out.pairs = best.pairs;
  out.back_to_palm = best.T;
  out.rms_mm = best.rms;
  out.max_mm = best.max;
  // Runner-up: the best matching that is not a subset of the chosen one (a subset is the
  // same answer with a marker left out).
  for (size_t k = 1; k < order.size(); ++k) {
    const auto& ps = order[k]->pairs;
    const bool subset = std::all_of(ps.begin(), ps.end(), [&](const std::pair<int, int>& x) {
      return std::binary_search(best.pairs.begin(), best.pairs.end(), x);
    });
    if (subset) continue;
    out.runner_up_pairs = ps.size();
    out.runner_up_rms_mm = order[k]->rms;
    break;
  }
  return out;
}

}  // namespace handskin
