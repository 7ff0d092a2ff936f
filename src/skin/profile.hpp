#pragma once
/// Internal to the skin library: a measured radial profile ρ(φ) of one cross-section and its
/// resampling (thesis eqs. 4.1–4.2, with a window mean and a Fourier bridge across unseen
/// flanks). Shared by the thesis slicing (slices.cpp) and the skin's strips (skin_mesh.cpp).
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
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
  /// data are dense, linear interpolation across a narrow gap, and across a wider one the
  /// circle fitted (Kåsa) to the samples on both of its sides — the rounded flank neither
  /// scan saw — unless that circle bulges out by more than `max_bulge` of the gap's chord;
  /// then the chord itself (e.g. where another tube's points were taken out).
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
    Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
    Eigen::Vector3d r = Eigen::Vector3d::Zero();
    int used = 0;
    auto take = [&](size_t start, int step) {
      const Eigen::Vector2d E = xy(start);
      for (size_t k = 0, i = start; k < n / 2; ++k, i = (i + n + step) % n) {
        const Eigen::Vector2d q = xy(i);
        if ((q - E).norm() > reach) break;
        const Eigen::Vector3d row(q.x(), q.y(), 1.0);
        N += row * row.transpose();
        r += row * -q.squaredNorm();
        ++used;
      }
    };
    take(lo, -1);
    const int before = used;
    take(hi, +1);
    if (before < 3 || used - before < 3) return t_chord;
    const Eigen::Vector3d c = N.ldlt().solve(r);  // x² + y² + D x + E y + F = 0
    const double b = c(0) * d.x() + c(1) * d.y(), disc = b * b - 4 * c(2);
    if (!c.allFinite() || disc < 0) return t_chord;
    const double t = 0.5 * (-b + std::sqrt(disc));
    if (t < t_chord - max_bulge * chord || t > t_chord + max_bulge * chord) return t_chord;
    return t;
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
