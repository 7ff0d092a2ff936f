#include "skin/skin_steps.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "skin/profile.hpp"

namespace handskin::skin_steps {

using profile::kTwoPi;
using profile::Profile;
using profile::segment_distance2;
using profile::wrap;

namespace {
// A ring whose samples cover less than min_coverage_deg but at least this much of the circle
// corrects its filled radii (resample_rings).
constexpr double kMinPartialCoverageDeg = 60;

// Real spherical harmonics to degree 2 of a unit direction (local x, y, z).
Eigen::Matrix<double, 9, 1> sh9(const Eigen::Vector3d& d) {
  Eigen::Matrix<double, 9, 1> r;
  r << 1, d.x(), d.y(), d.z(), d.x() * d.y(), d.x() * d.z(), d.y() * d.z(), d.x() * d.x() - d.y() * d.y(),
      3 * d.z() * d.z() - 1;
  return r;
}

}  // namespace

// Give each point of a tube to the station whose plane is nearest (within its slab); points
// past the last plane go to `beyond` when the tube ends in a dome.
void fill_slabs(TubeBuild* t, const std::vector<Eigen::Vector3d>& pts, double h, bool dome) {
  const size_t K = t->st.size();
  t->slab.assign(K, {});
  std::vector<int> where(pts.size(), -1);  // station, K: beyond the last, -1: none
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(pts.size()); ++i) {
    const Eigen::Vector3d& q = pts[i];
    // The planes are ordered along the tube and never cross within it, so the signed
    // distance falls along the stations: bisect for its sign change.
    auto dist = [&](size_t k) { return t->st[k].n.dot(q - t->st[k].o); };
    size_t a = 0, b = K;  // first station with a negative distance lies in [a, b]
    while (a < b) {
      const size_t m = (a + b) / 2;
      if (dist(m) >= 0) a = m + 1;
      else b = m;
    }
    size_t best = a;
    double bsigned = a < K ? dist(a) : 1e300;
    if (a > 0 && (a == K || std::abs(dist(a - 1)) < std::abs(bsigned))) best = a - 1, bsigned = dist(a - 1);
    const double bd = std::abs(bsigned);
    if (best + 1 == K && bsigned > 0.5 * h) where[i] = dome ? static_cast<int>(K) : -1;
    else if ((best == 0 && bsigned < -0.5 * h) || bd > 0.75 * h) where[i] = -1;
    else where[i] = static_cast<int>(best);
  }
  for (size_t i = 0; i < pts.size(); ++i) {
    if (where[i] < 0) continue;
    if (where[i] == static_cast<int>(K)) {
      t->beyond.push_back(pts[i]);
      continue;
    }
    const Station& s = t->st[where[i]];
    const Eigen::Vector3d r = pts[i] - s.o;
    t->slab[where[i]].emplace_back(r.dot(s.u), r.dot(s.v));
  }
}

// Resample every station's ring: polar profile about the station's centre, a fixed number of
// angles on the station's ellipse, smoothing over neighbouring stations, and rings without
// enough samples filled from their measured neighbours (roots shrink into the palm).
void resample_rings(TubeBuild* t, int M, const SkinOptions& o, bool shrink_root) {
  const size_t K = t->st.size();
  const double window = o.window_deg * kDeg, bridge = 0.2;
  std::vector<std::optional<std::vector<double>>> rho(K);
  std::vector<std::vector<double>> phi(K);
  // Rings whose samples cover too little of the circle to stand alone (a curled fingertip's
  // last sections, seen on the pad and the nail only) keep them: they correct the ring
  // filled from the neighbours (below).
  std::vector<std::optional<Profile>> partial(K);
#pragma omp parallel for schedule(dynamic)
  for (long kk = 0; kk < static_cast<long>(K); ++kk) {
    const size_t k = static_cast<size_t>(kk);
    const Station& s = t->st[k];
    for (int j = 0; j < M; ++j) {
      const double psi = kTwoPi * j / M;
      phi[k].push_back(wrap(std::atan2(s.b * std::sin(psi), s.a * std::cos(psi))));
    }
    const auto& g = t->slab[k];
    if (static_cast<long>(g.size()) < std::max<long>(o.slicing.min_points, 10)) continue;
    // Samples more than 2.5 times the median radius out are not this tube's section (a
    // neighbouring digit's skin that reached the slab, where a curled finger passes near).
    std::vector<double> radii;
    for (const auto& p : g) radii.push_back(p.norm());
    std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
    const double ceiling = 2.5 * radii[radii.size() / 2];
    std::vector<std::pair<double, double>> pr;
    for (const auto& p : g)
      if (p.norm() <= ceiling) pr.emplace_back(wrap(std::atan2(p.y(), p.x())), p.norm());
    std::sort(pr.begin(), pr.end());
    Profile P;
    for (const auto& [a, r] : pr) P.phi.push_back(a), P.rho.push_back(r);
    double unseen = 0;
    for (size_t i = 0; i < P.phi.size(); ++i) {
      const double gap = i + 1 < P.phi.size() ? P.phi[i + 1] - P.phi[i] : P.phi.front() + kTwoPi - P.phi.back();
      if (gap > bridge) unseen += gap;
    }
    if (kTwoPi - unseen < o.min_coverage_deg * kDeg) {
      if (kTwoPi - unseen >= kMinPartialCoverageDeg * kDeg && P.phi.size() >= 20) partial[k] = std::move(P);
      continue;
    }
    std::vector<double> r;
    std::vector<double> sorted_rho = P.rho;
    std::nth_element(sorted_rho.begin(), sorted_rho.begin() + sorted_rho.size() / 2, sorted_rho.end());
    const double floor = 0.3 * sorted_rho[sorted_rho.size() / 2];
    // A bridge across an unseen gap never reaches beyond 1.2 times the farthest sample: a
    // circle through a nearly straight arc (a curled finger cut at a slant) would bulge far.
    const double roof = 1.2 * *std::max_element(P.rho.begin(), P.rho.end());
    for (int j = 0; j < M; ++j) r.push_back(std::clamp(P.at_bridged(phi[k][j], window, bridge), floor, roof));
    rho[k] = std::move(r);
  }
  // Wrinkles: per angle index, a quadratic least-squares fit over ± m neighbouring rings
  // (Savitzky–Golay) predicts each radius; one that strays from it by more than wrinkle_mm
  // is replaced by the fit. Radii the neighbours agree with are kept as measured (a plain
  // average would shrink every profile curved along the tube). Rings without all their
  // neighbours measured keep their own radii.
  const int m = o.smoothing_rings;
  std::vector<double> w;
  for (int i = -m; i <= m; ++i)
    w.push_back((3.0 * (3 * m * m + 3 * m - 1) - 15.0 * i * i) / ((2 * m + 1) * (4.0 * m * m + 4 * m - 3)));
  std::vector<std::optional<std::vector<double>>> smooth(K);
  for (size_t k = 0; k < K; ++k) {
    if (!rho[k]) continue;
    bool all = m > 0;
    for (int d = -m; d <= m && all; ++d) {
      const long kk = static_cast<long>(k) + d;
      all = kk >= 0 && kk < static_cast<long>(K) && rho[kk].has_value();
    }
    if (!all) {
      smooth[k] = rho[k];
      continue;
    }
    std::vector<double> r = *rho[k];
    for (int j = 0; j < M; ++j) {
      double fit = 0;
      for (int d = -m; d <= m; ++d) fit += w[d + m] * (*rho[k + d])[j];
      if (std::abs(fit - r[j]) > o.wrinkle_mm) r[j] = std::max(fit, 0.3 * r[j]);
    }
    smooth[k] = std::move(r);
  }
  // Fill: between measured rings by linear interpolation, beyond them by copying the
  // nearest (shrinking toward a digit's root so that it stays inside the palm).
  std::vector<size_t> measured;
  for (size_t k = 0; k < K; ++k)
    if (smooth[k]) measured.push_back(k);
  t->report.rings = static_cast<int>(K);
  t->report.measured = static_cast<int>(measured.size());
  t->report.filled = static_cast<int>(K - measured.size());
  t->report.present = !measured.empty();
  if (measured.empty()) return;
  // A finger's section shape: per angle, the median over its measured rings of the radius
  // over the ring's median radius. A partial ring past the last measured one (a curled
  // finger's phalanges, seen from the back only) takes it across its unseen arc, scaled to its
  // seen arc. The last measured ring alone, which the fill copies, lies at the bent joint
  // before them, its palmar side in the joint's crease: copied beyond it, it flattened the
  // phalanges' palmar halves (a hand with its PIPs bent 55-60 deg: the skin 3-6 mm inside the
  // true skin). Not the thumb's: its measured rings run from the thenar's wide sections to
  // the tip, and on the WebXR hand with its thumb bent the median shape was 0.001 mm worse.
  std::vector<double> shape;
  if (shrink_root && t->id >= 2 && measured.size() >= 3) {
    std::vector<std::vector<double>> per_angle(M);
    for (size_t k : measured) {
      std::vector<double> r = *smooth[k];
      std::nth_element(r.begin(), r.begin() + M / 2, r.end());
      const double mid = r[M / 2];
      if (!(mid > 0)) continue;
      for (int j = 0; j < M; ++j) per_angle[j].push_back((*smooth[k])[j] / mid);
    }
    if (per_angle[0].size() >= 3) {
      shape.resize(M);
      for (int j = 0; j < M; ++j) {
        auto& v = per_angle[j];
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        shape[j] = v[v.size() / 2];
      }
    }
  }
  for (size_t k = 0; k < K; ++k) {
    if (smooth[k]) continue;
    std::vector<double> r(M);
    const auto hi = std::lower_bound(measured.begin(), measured.end(), k);
    if (hi == measured.begin()) {
      const double f = shrink_root ? std::max(0.7, 1.0 - 0.05 * static_cast<double>(*hi - k)) : 1.0;
      for (int j = 0; j < M; ++j) r[j] = f * (*smooth[*hi])[j];
    } else if (hi == measured.end()) {
      r = *smooth[measured.back()];
      if (partial[k] && !shape.empty()) {  // the shape at the last ring's size; the seen arc scales it (below)
        std::vector<double> last = r;
        std::nth_element(last.begin(), last.begin() + M / 2, last.end());
        for (int j = 0; j < M; ++j) r[j] = shape[j] * last[M / 2];
      }
    } else {
      const size_t a = *(hi - 1), b = *hi;
      const double u = static_cast<double>(k - a) / static_cast<double>(b - a);
      for (int j = 0; j < M; ++j) r[j] = (1 - u) * (*smooth[a])[j] + u * (*smooth[b])[j];
    }
    if (partial[k]) {
      // Measured radii where the partial ring has samples; across its unseen arc the filled
      // radii scaled by the median ratio of the two where both exist. Copying the last full
      // ring instead made a curled fingertip a cylinder: 1.5 mm out where the tip tapers.
      const Profile& P = *partial[k];
      std::vector<double> ratio;
      std::vector<std::optional<double>> seen(M);
      for (int j = 0; j < M; ++j) {
        double v = 0;
        size_t lo = 0, hi = 0;
        if (!P.near_estimate(wrap(phi[k][j]), window, bridge, &v, &lo, &hi) || r[j] <= 0) continue;
        seen[j] = v;
        ratio.push_back(v / r[j]);
      }
      if (ratio.size() >= 3) {
        std::nth_element(ratio.begin(), ratio.begin() + ratio.size() / 2, ratio.end());
        const double scale = std::clamp(ratio[ratio.size() / 2], 0.5, 1.5);
        for (int j = 0; j < M; ++j) r[j] = seen[j] ? *seen[j] : scale * r[j];
        ++t->report.partial;
      }
    }
    smooth[k] = std::move(r);
  }
  t->rings.clear();
  t->ring_station.clear();
  t->ring_centre.clear();
  for (size_t k = 0; k < K; ++k) {
    const Station& s = t->st[k];
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < M; ++j)
      ring.push_back(s.o + (*smooth[k])[j] * (std::cos(phi[k][j]) * s.u + std::sin(phi[k][j]) * s.v));
    t->rings.push_back(std::move(ring));
    t->ring_station.push_back(static_cast<int>(k));
    t->ring_centre.push_back(s.o);
  }
}

// A fingertip's dome: rings at decreasing polar angles about the last station's centre, and
// the pole. Radii from the points around each direction; where the tip was not seen, from a
// degree-2 spherical-harmonic fit of the radius to the tip's points.
void add_dome(TubeBuild* t, int M, int rings, const SkinOptions& o) {
  const Station& s = t->st.back();
  std::vector<Eigen::Vector3d> dir_pts;  // local (u, v, n) directions and radii
  std::vector<double> rad;
  Eigen::Matrix<double, 9, 9> N = Eigen::Matrix<double, 9, 9>::Zero();
  Eigen::Matrix<double, 9, 1> rhs = Eigen::Matrix<double, 9, 1>::Zero();
  auto local = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector3d r = q - s.o;
    return Eigen::Vector3d(r.dot(s.u), r.dot(s.v), r.dot(s.n));
  };
  // The rim: the tube's last ring, and its largest radius. A copy: the rings pushed below may
  // move t->rings' elements (a tube whose rings filled their capacity exactly: the little
  // finger of a family pair with the automatic skeleton, 16 of 16), and a reference to the rim
  // would then read freed memory (it crashed once in a family study, a general protection
  // fault).
  const std::vector<Eigen::Vector3d> last = t->rings.back();
  double rim = 0;
  for (const auto& p : last) rim = std::max(rim, (p - s.o).norm());
  // The last slab's points too: they pin the dome's rim. Points beyond 1.6 times the rim's
  // largest radius are another digit's (a curled neighbour's tip), not this dome's.
  const double reach = 1.6 * rim;
  for (const auto& p2 : t->slab.back()) {
    const Eigen::Vector3d l(p2.x(), p2.y(), 0);
    if (l.norm() > 1e-6 && l.norm() <= reach) dir_pts.push_back(l.normalized()), rad.push_back(l.norm());
  }
  for (const auto& q : t->beyond) {
    const Eigen::Vector3d l = local(q);
    if (l.norm() > 1e-6 && l.norm() <= reach) dir_pts.push_back(l.normalized()), rad.push_back(l.norm());
  }
  for (size_t i = 0; i < rad.size(); ++i) {
    const auto y = sh9(dir_pts[i]);
    N += y * y.transpose();
    rhs += y * rad[i];
  }
  for (int k = 1; k < 9; ++k) N(k, k) += 1e-3 * static_cast<double>(rad.size()) + 1e-9;
  N(0, 0) += 1e-9;
  const Eigen::Matrix<double, 9, 1> c = N.ldlt().solve(rhs);
  const double cos_win = std::cos(3.0 * o.window_deg * kDeg);
  // A fingertip is about as wide as its last ring: the dome's radius stays within 0.3–1.3
  // times the rim's largest (the harmonic fit, unconstrained where a curled tip was not
  // seen, can otherwise throw a spike far out).
  auto radius = [&](const Eigen::Vector3d& d) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < rad.size(); ++i)
      if (dir_pts[i].dot(d) >= cos_win) sum += rad[i], ++n;
    const double r = n >= 3 ? sum / n : c.dot(sh9(d));
    return std::clamp(r, std::max(0.3 * rim, 0.5), std::max(1.3 * rim, 0.5));
  };
  for (int i = 1; i <= rings; ++i) {
    const double theta = 0.5 * M_PI * (1.0 - static_cast<double>(i) / (rings + 1));
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < M; ++j) {
      const Eigen::Vector3d r = last[j] - s.o;
      const double phi = std::atan2(r.dot(s.v), r.dot(s.u));
      const Eigen::Vector3d d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      ring.push_back(s.o + radius(d) * (d.x() * s.u + d.y() * s.v + d.z() * s.n));
    }
    t->rings.push_back(std::move(ring));
    t->ring_station.push_back(-1);
    t->ring_centre.push_back(s.o + std::cos(theta) * radius(Eigen::Vector3d::UnitZ()) * s.n);
  }
  t->pole = s.o + radius(Eigen::Vector3d::UnitZ()) * s.n;
}

void keep_apart(TubeBuild* tp, const HandFrame& H, int f) {
  TubeBuild& t = *tp;
  const auto& J = H.J;
    // Neighbouring fingers' tubes meet in the webs. Where a ring point lies nearer the
  // neighbour's phalanges than its own (less a margin) it is pulled back along its ray,
  // so that two tubes never touch — near-tangent contacts would make the stitching
  // fragile — and the web between them is the palm's.
  if (f >= 1) {
    auto chain_distance = [&](int finger, const Eigen::Vector3d& p) {
      const auto c = finger_chain(static_cast<Finger>(finger));
      double best = 1e300;
      for (size_t k = 1; k + 1 < c.size(); ++k) best = std::min(best, segment_distance2(p, J[c[k]], J[c[k + 1]]));
      return std::sqrt(best);
    };
    const double margin = 0.5;
    for (size_t k = 0; k < t.rings.size(); ++k)
      for (auto& p : t.rings[k])
        for (int g : {f - 1, f + 1}) {
          if (g < 1 || g >= kFingerCount) continue;
          auto clear = [&](const Eigen::Vector3d& x) { return chain_distance(g, x) - chain_distance(f, x) >= margin; };
          if (clear(p)) continue;
          const Eigen::Vector3d c = t.ring_centre[k];
          double lo = 0.3, hi = 1.0;  // fraction of the radius: lo clear (checked), hi not
          if (!clear(c + lo * (p - c))) continue;
          for (int it = 0; it < 12; ++it) {
            const double mid = 0.5 * (lo + hi);
            (clear(c + mid * (p - c)) ? lo : hi) = mid;
          }
          p = c + lo * (p - c);
        }
  }
}

}  // namespace handskin::skin_steps
