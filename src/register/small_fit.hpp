#pragma once
/// Levenberg–Marquardt for the markers' small fits: a sphere's centre (3 parameters), or its
/// centre and radius (4), against tens to hundreds of samples' residuals — each cap's fits in
/// the marker search (spheres.cpp), and each marker's centre from both scans with the pose
/// held (refine.cpp's marker_sphere_rms; test `Refine.MarkerCentresWithThePoseHeldAreCeressSolve`).
///
/// Written here rather than solved by Ceres (which the registration's pose fits, the shared
/// radius and the covariances still use): a marker search makes ~1 000 of these fits a run,
/// and Ceres's work around each — building the problem and its program, the evaluator, the
/// dense QR of the n × N Jacobian, the summary — cost several times the residuals' own
/// evaluation (`perf`: 0.11 s of CPU a fixture run in `ceres::Solve` for the centre fits,
/// ~0.03 s of it in the residuals). Here the residuals and their derivatives are the same
/// functors evaluated on Ceres's Jets, the normal equations are N × N, and the steps and the
/// stopping rules are Ceres's trust-region Levenberg–Marquardt's (its default options: Jacobi
/// scaling, the step's damping from the trust radius, the function, gradient and parameter
/// tolerances, 50 iterations), so each iteration lands where Ceres's does, to 1e-12 mm
/// (test `SmallFit.TakesCeressStepsAndEndsWhereCeresEnds`).
#include <ceres/jet.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace handskin::small_fit {

struct Options {
  int max_iterations = 50;             ///< Ceres's max_num_iterations
  double function_tolerance = 1e-6;    ///< |Δcost| / cost (Ceres's default)
  double gradient_tolerance = 1e-10;   ///< max |x − Π(x − g)| (Ceres's default)
  double parameter_tolerance = 1e-8;   ///< |Δx| ≤ tol · (|x| + tol) (Ceres's default)
  double initial_trust_radius = 1e4;   ///< Ceres's default
  double max_trust_radius = 1e16;
  double min_relative_decrease = 1e-3;  ///< a step is taken when it achieves this much of the model's decrease
};

/// Minimises ½ Σ_k r_k(x)² over x (N parameters, `x` in and out), within [lo, hi] per parameter
/// (steps projected onto the box, as Ceres projects them). `residual(k, x, &r)` writes residual
/// k at x for T = double and T = ceres::Jet<double, N>; `count` residuals. Returns the
/// iterations made.
template <int N, typename Residual>
int minimise(double* x, int count, const Residual& residual, const std::array<double, N>& lo, const std::array<double, N>& hi,
             const Options& o = {}) {
  using Jet = ceres::Jet<double, N>;
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  const auto project = [&](Vec v) {
    for (int i = 0; i < N; ++i) v[i] = std::clamp(v[i], lo[i], hi[i]);
    return v;
  };
  // The cost ½ Σ r², the gradient Jᵀr and JᵀJ at `at`.
  const auto linearise = [&](const Vec& at, double* cost, Vec* g, Mat* H) {
    std::array<Jet, N> xj;
    for (int i = 0; i < N; ++i) xj[i] = Jet(at[i], i);
    double c = 0;
    g->setZero();
    Mat L = Mat::Zero();
    for (int k = 0; k < count; ++k) {
      Jet r;
      residual(k, xj.data(), &r);
      c += r.a * r.a;
      *g += r.a * r.v;
      L.template selfadjointView<Eigen::Lower>().rankUpdate(r.v);
    }
    *H = L.template selfadjointView<Eigen::Lower>();
    *cost = 0.5 * c;
  };
  const auto cost_at = [&](const Vec& at) {
    double c = 0;
    for (int k = 0; k < count; ++k) {
      double r;
      residual(k, at.data(), &r);
      c += r * r;
    }
    return 0.5 * c;
  };
  Vec X = project(Eigen::Map<const Vec>(x));
  double cost;
  Vec g;
  Mat H;
  linearise(X, &cost, &g, &H);
  if (!std::isfinite(cost)) return 0;
  // The columns of J scaled by 1 / (1 + |column|), from the start (Ceres's Jacobi scaling).
  Vec scale;
  for (int i = 0; i < N; ++i) scale[i] = 1.0 / (1.0 + std::sqrt(H(i, i)));
  double radius = o.initial_trust_radius, decrease_factor = 2.0;
  // |x| as Ceres's parameter tolerance has it: unset (−1, so no step is small enough) until a
  // step is taken, when the problem has no bounds.
  const bool bounded = [&] {
    for (int i = 0; i < N; ++i)
      if (std::isfinite(lo[i]) || std::isfinite(hi[i])) return true;
    return false;
  }();
  double x_norm = bounded ? X.norm() : -1.0;
  bool successful = true;  // the last iteration's step was taken (iteration 0: the start)
  int invalid_in_a_row = 0;
  int iteration = 0;
  for (;;) {
    // Ceres's checks after each iteration: the iterations, then (after a step taken) the
    // projected gradient, then the trust radius.
    if (iteration >= o.max_iterations) break;
    if (successful && (X - project(X - g)).template lpNorm<Eigen::Infinity>() <= o.gradient_tolerance) break;
    if (radius <= 1e-32) break;
    ++iteration;
    // The step: (S JᵀJ S + D² ) δ = −S Jᵀr, D² = diag(S JᵀJ S) clamped to [1e-6, 1e32] / radius.
    const Mat Hs = scale.asDiagonal() * H * scale.asDiagonal();
    const Vec gs = scale.cwiseProduct(g);
    Mat A = Hs;
    for (int i = 0; i < N; ++i) A(i, i) += std::clamp(Hs(i, i), 1e-6, 1e32) / radius;
    const Vec step = A.ldlt().solve(-gs);
    // The model's decrease −(J δ)ᵀ(r + J δ / 2) = −(gᵀδ + ½ δᵀ JᵀJ δ), in the scaled space.
    const double model = -(gs.dot(step) + 0.5 * step.dot(Hs * step));
    if (!(model > 0.0) || !step.allFinite()) {  // an invalid step: the radius shrinks
      successful = false;
      if (++invalid_in_a_row >= 5) break;
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      continue;
    }
    invalid_in_a_row = 0;
    const Vec candidate = project(X + scale.cwiseProduct(step));
    double candidate_cost = cost_at(candidate);
    if (!std::isfinite(candidate_cost)) candidate_cost = std::numeric_limits<double>::max();
    if ((X - candidate).norm() <= o.parameter_tolerance * (x_norm + o.parameter_tolerance)) break;
    const double change = cost - candidate_cost;
    if (std::abs(change) <= o.function_tolerance * cost) break;
    const double rho = change / model;
    if (rho > o.min_relative_decrease) {
      X = candidate;
      x_norm = X.norm();
      linearise(X, &cost, &g, &H);
      radius = std::min(o.max_trust_radius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      decrease_factor = 2.0;
      successful = true;
    } else {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      successful = false;
    }
  }
  for (int i = 0; i < N; ++i) x[i] = X[i];
  return iteration;
}

}  // namespace handskin::small_fit
