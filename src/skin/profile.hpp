#pragma once
/// Internal to the skin library: a measured radial profile ρ(φ) of one cross-section and its
/// resampling (thesis eqs. 4.1–4.2, with a window mean and a Fourier bridge across unseen
/// flanks). Shared by the thesis slicing (slices.cpp) and the skin's strips (skin_mesh.cpp).
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

namespace handskin::profile {

constexpr double kTwoPi = 2 * M_PI;

inline double wrap(double a) {  // to [0, 2π)
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

// A plane's measured profile of one link: radius against angle, sorted.
struct Profile {
  std::vector<double> phi, rho;  ///< sorted by phi in [0, 2π)
  bool closed = false;
  std::vector<std::pair<double, double>> arcs;  ///< covered arcs: start, length (counter-clockwise)
  double largest_gap = 0;
  bool has(double p) const {
    if (closed) return true;
    for (const auto& [a, l] : arcs)
      if (wrap(p - a) <= l + 1e-12) return true;
    return false;
  }
  /// Closed profiles: a second-order Fourier fit ρ(φ) = a0 + Σ ak cos kφ + bk sin kφ — an
  /// off-centre ellipse — to bridge the gaps neither scan saw (the flanks).
  Eigen::Matrix<double, 5, 1> fourier = Eigen::Matrix<double, 5, 1>::Zero();
  bool has_fourier = false;
  double fourier_at(double p) const {
    return fourier(0) + fourier(1) * std::cos(p) + fourier(2) * std::sin(p) + fourier(3) * std::cos(2 * p) +
           fourier(4) * std::sin(2 * p);
  }
  // The radius at angle p: the mean of the measured radii within ±window of p where the data
  // are dense (a scan gives many points per angle and plane, so one neighbour pair would
  // pick noise); else linear interpolation between the measured neighbours (eqs. 4.1–4.2);
  // across a gap wider than `bridge` a closed profile takes its Fourier fit instead.
  double at(double p, double window = 0.035, double bridge = 0.2) const {
    p = wrap(p);
    double r = 0;
    size_t lo = 0, hi = 0;
    if (near_estimate(p, window, bridge, &r, &lo, &hi)) return r;
    return has_fourier ? fourier_at(p) : linear(p, lo, hi);
  }

  /// What both estimators share: the window mean where the data are dense, else linear
  /// interpolation between the measured neighbours of p (in [0, 2π)) when their gap is at most
  /// `bridge`. Across a wider gap it returns false with the neighbours, for the caller to bridge.
  bool near_estimate(double p, double window, double bridge, double* r, size_t* lo, size_t* hi) const {
    if (window_mean(p, window, r)) return true;
    std::tie(*lo, *hi) = neighbours(p);
    const double span = wrap(phi[*hi] - phi[*lo]);
    if (span > 0 && span > bridge) return false;
    *r = linear(p, *lo, *hi);
    return true;
  }
  /// Linear interpolation in angle between samples lo and hi (eqs. 4.1–4.2).
  double linear(double p, size_t lo, size_t hi) const {
    const double span = wrap(phi[hi] - phi[lo]);
    if (span == 0) return rho[lo];
    return rho[lo] + wrap(p - phi[lo]) / span * (rho[hi] - rho[lo]);
  }

  /// The mean of the radii within ±window of angle p (in [0, 2π)), when at least 3 lie there.
  bool window_mean(double p, double window, double* mean) const {
    double sum = 0;
    int count = 0;
    auto add_range = [&](double a, double b) {  // [a, b] within [0, 2π)
      for (auto it = std::lower_bound(phi.begin(), phi.end(), a); it != phi.end() && *it <= b; ++it)
        sum += rho[static_cast<size_t>(it - phi.begin())], ++count;
    };
    if (p - window < 0) add_range(0, p + window), add_range(p - window + kTwoPi, kTwoPi);
    else if (p + window >= kTwoPi) add_range(p - window, kTwoPi), add_range(0, p + window - kTwoPi);
    else add_range(p - window, p + window);
    if (count < 3) return false;
    *mean = sum / count;
    return true;
  }
  /// The measured samples just below and above angle p (wrapping round).
  std::pair<size_t, size_t> neighbours(double p) const {
    const size_t n = phi.size();
    const size_t hi = static_cast<size_t>(std::upper_bound(phi.begin(), phi.end(), p) - phi.begin()) % n;
    return {(hi + n - 1) % n, hi};
  }

  /// The radius at angle p for a closed ring of the skin's strips: the window mean where the
  /// data are dense, linear interpolation across a narrow gap, and across a wider one (the
  /// rounded flank neither scan saw) the mean of two guesses that err on opposite sides:
  ///  - the circle fitted (Kåsa) to the samples on both sides of the gap follows the curvature
  ///    at its ends: it bulges too far where the curvature is highest at the ends and the
  ///    unseen middle is flatter (a thumb turned about its axis, whose nail and pad face
  ///    sideways; the WebXR hand: up to 0.6 mm out);
  ///  - the circular arc through the gap's two ends that turns as the sides' tangents there
  ///    do (each end's tangent from a circle fitted to that side alone) follows the turning
  ///    across the gap: it falls short where the curvature peaks inside the gap (the edge of
  ///    a section wider than it is thick).
  /// A guess that bulges out by more than `max_bulge` of the gap's chord is dropped (e.g.
  /// where another tube's points were taken out), unless it bulges less than 1.25 times what
  /// a circle's arc across the gap's angle does (wider gaps than ~120°). With neither guess,
  /// the chord itself, or across more than a quarter turn the radii interpolated linearly in
  /// angle.
  double at_bridged(double p, double window, double bridge, double max_bulge = 0.35) const {
    const size_t n = phi.size();
    p = wrap(p);
    double near = 0;
    size_t lo = 0, hi = 0;
    if (near_estimate(p, window, bridge, &near, &lo, &hi)) return near;
    auto xy = [&](size_t i) { return Eigen::Vector2d(rho[i] * std::cos(phi[i]), rho[i] * std::sin(phi[i])); };
    const Eigen::Vector2d A = xy(lo), B = xy(hi), d(std::cos(p), std::sin(p));
    // Chord: A + s (B - A) = t d.
    Eigen::Matrix2d Mx;
    Mx.col(0) = d;
    Mx.col(1) = A - B;
    const double det = Mx.determinant();
    const double t_chord = std::abs(det) > 1e-12 ? Mx.inverse().row(0).dot(A) : std::min(rho[lo], rho[hi]);
    const double chord = (B - A).norm(), reach = std::max(3.0, chord);
    // A circle's arc across a gap of angle θ about its centre bulges tan(θ/4)/2 of its chord
    // (0.21 at 90°, 0.5 at 180°): the bound grows with the gap where that exceeds it.
    const double span = wrap(phi[hi] - phi[lo]);
    const double allowed = std::max(max_bulge, 1.25 * 0.5 * std::tan(std::min(span, 1.9 * M_PI) / 4));
    auto plausible = [&](double t) { return t >= t_chord - allowed * chord && t <= t_chord + allowed * chord; };
    // Kåsa's circle x² + y² + D x + E y + F = 0 over the samples within `reach` of the gap's
    // end `start`, walking away from the gap (step −1 below it, +1 above it).
    struct Side {
      Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
      Eigen::Vector3d r = Eigen::Vector3d::Zero();
      int used = 0;
      Eigen::Vector2d far;  ///< the sample farthest from the gap's end
    };
    auto side = [&](size_t start, int step) {
      Side S;
      const Eigen::Vector2d E = xy(start);
      S.far = E;
      for (size_t k = 0, i = start; k < n / 2; ++k, i = (i + n + step) % n) {
        const Eigen::Vector2d q = xy(i);
        if ((q - E).norm() > reach) break;
        const Eigen::Vector3d row(q.x(), q.y(), 1.0);
        S.N += row * row.transpose();
        S.r += row * -q.squaredNorm();
        ++S.used;
        S.far = q;
      }
      return S;
    };
    const Side below = side(lo, -1), above = side(hi, +1);
    // The circle through both sides' samples, where the ray meets it.
    std::optional<double> circle;
    if (below.used >= 3 && above.used >= 3) {
      const Eigen::Vector3d c = (below.N + above.N).ldlt().solve(below.r + above.r);
      const double b = c(0) * d.x() + c(1) * d.y(), disc = b * b - 4 * c(2);
      const double t = 0.5 * (-b + std::sqrt(disc));
      if (c.allFinite() && disc >= 0 && plausible(t)) circle = t;
    }
    // The tangent arc. Each end's tangent, pointing counter-clockwise (the way φ grows): from
    // its side's own circle, or along the side's samples where they are nearly straight.
    auto tangent = [&](const Side& S, const Eigen::Vector2d& E, int step) -> std::optional<Eigen::Vector2d> {
      if (S.used < 5) return std::nullopt;
      Eigen::Vector2d along = step < 0 ? Eigen::Vector2d(E - S.far) : Eigen::Vector2d(S.far - E);
      if (!(along.norm() > 1e-9)) return std::nullopt;
      along.normalize();
      const Eigen::Vector3d c = S.N.ldlt().solve(S.r);
      const Eigen::Vector2d C(-0.5 * c(0), -0.5 * c(1));
      const double R2 = C.squaredNorm() - c(2);
      if (!c.allFinite() || !(R2 > 0) || R2 > 400 * reach * reach) return along;
      Eigen::Vector2d t(-(E - C).y(), (E - C).x());
      t.normalize();
      return t.dot(along) < 0 ? Eigen::Vector2d(-t) : t;
    };
    std::optional<double> arc;
    const auto tA = tangent(below, A, -1), tB = tangent(above, B, +1);
    if (tA && tB && chord > 1e-9) {
      const double turn = std::atan2(tA->x() * tB->y() - tA->y() * tB->x(), tA->dot(*tB));  // > 0: convex
      if (turn > 1e-3) {
        const double th = std::min(turn, M_PI - 1e-3), R = chord / (2 * std::sin(th / 2));
        const Eigen::Vector2d mid = 0.5 * (A + B), u = (B - A) / chord;
        Eigen::Vector2d out(u.y(), -u.x());  // away from the ring's centre
        if (out.dot(mid) < 0) out = -out;
        const Eigen::Vector2d C = mid - out * std::sqrt(std::max(0.0, R * R - 0.25 * chord * chord));
        const double dc = d.dot(C), disc = dc * dc - C.squaredNorm() + R * R;
        if (disc >= 0 && plausible(dc + std::sqrt(disc))) arc = dc + std::sqrt(disc);
      }
    }
    if (circle && arc) return 0.5 * (*circle + *arc);
    if (circle) return *circle;
    if (arc) return *arc;
    // Across more than a quarter turn the chord runs near the centre (through it at half a
    // turn): the radii's linear interpolation in angle instead (eqs. 4.1–4.2).
    return span > M_PI / 2 ? linear(p, lo, hi) : t_chord;
  }
};

inline double segment_distance2(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (a + t * ab - p).squaredNorm();
}

/// Fit the profile's Fourier bridge (needs ≥ 10 samples), by least squares.
inline void fit_fourier(Profile* P) {
  const size_t m = P->phi.size();
  if (m < 10) return;
  Eigen::Matrix<double, 5, 5> N = Eigen::Matrix<double, 5, 5>::Zero();
  Eigen::Matrix<double, 5, 1> r = Eigen::Matrix<double, 5, 1>::Zero();
  for (size_t i = 0; i < m; ++i) {
    const double a = P->phi[i];
    Eigen::Matrix<double, 5, 1> row;
    row << 1, std::cos(a), std::sin(a), std::cos(2 * a), std::sin(2 * a);
    N += row * row.transpose();
    r += row * P->rho[i];
  }
  P->fourier = N.ldlt().solve(r);
  P->has_fourier = P->fourier.allFinite();
}

}  // namespace handskin::profile
