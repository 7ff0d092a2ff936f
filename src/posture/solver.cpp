#include "posture/solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "core/errors.hpp"

namespace handskin {

struct PostureSolver::Factor {
  std::vector<int> free;  ///< DOFs solved for
  Eigen::MatrixXd inv;    ///< (H restricted to them)⁻¹
};

struct PostureSolver::Problem {
  Mat H;
  Vec g;
  Vec x;                       ///< pinned values (others: scratch)
  std::uint64_t pinned = 0;
  std::uint64_t at_bound = 0;  ///< DOFs the last box QP held at a limit
  bool targets = false;
  int clamped = 0;
};

namespace {
constexpr std::uint64_t bit(int i) { return std::uint64_t{1} << i; }
}  // namespace

PostureSolver::PostureSolver(const PostureModel& model) : model_(model) {
  // Rows of A, b, W: the pair lines, then the general constraint rows.
  const int np = static_cast<int>(model.pairs.size()), m = np + static_cast<int>(model.constraints.size());
  A_ = Eigen::MatrixXd::Zero(m, kDofCount);
  b_ = Eigen::VectorXd::Zero(m);
  w_ = Eigen::VectorXd::Zero(m);
  for (int k = 0; k < np; ++k) {
    const PairLine& l = model.pairs[k];
    A_(k, l.a) = l.alpha;
    A_(k, l.b) = l.beta;
    b_(k) = l.gamma;
    w_(k) = l.weight;
  }
  for (int k = np; k < m; ++k) {
    const LinearConstraint& c = model.constraints[k - np];
    for (const auto& [d, v] : c.terms) A_(k, d) += v;
    b_(k) = c.offset;
    w_(k) = c.weight;
  }
  Mat K = Mat::Zero();
  for (int d = 0; d < kDofCount; ++d) {
    relaxed_(d) = model.dof[d].relaxed;
    lo_(d) = model.dof[d].lo;
    hi_(d) = model.dof[d].hi;
    K(d, d) = model.dof[d].stiffness;
    if (!(model.dof[d].stiffness >= kMinStiffness && model.dof[d].stiffness <= kMaxStiffness))
      throw InputError(model.name.empty() ? "model" : model.name,
                       "DOF " + dofs()[d].name + ": stiffness must be in [1e-3, 1e3] (docs/posture.md)");
  }
  // Energy ½(x−θ̄)ᵀK(x−θ̄) + ½(Ax+b)ᵀW(Ax+b) − τ̂ᵀx  =  ½xᵀH0x − g0ᵀx + const.
  H0_ = K + A_.transpose() * w_.asDiagonal() * A_;
  g0_ = K * relaxed_ - A_.transpose() * (w_.asDiagonal() * b_);
  Hgrid_ = H0_;
  for (const PairGrid& pg : model.grids) {
    Grid g{pg.a, pg.b, pg.weight, pg.lo_a, pg.hi_a, pg.lo_b, pg.hi_b, pg.cells, {}, {}};
    g.sa.resize(static_cast<size_t>(g.n) * g.n);
    g.sb.resize(g.sa.size());
    // Nearest sample per node, by brute force: grids are small (100²) and the samples are
    // thinned by calibration to a few hundred, so this is milliseconds and needs no index.
    for (int i = 0; i < g.n; ++i)
      for (int j = 0; j < g.n; ++j) {
        const double xa = g.lo_a + (g.hi_a - g.lo_a) * i / (g.n - 1), xb = g.lo_b + (g.hi_b - g.lo_b) * j / (g.n - 1);
        double best = 1e300;
        std::array<double, 2> s{};
        for (const auto& q : pg.samples) {
          const double d = (q[0] - xa) * (q[0] - xa) + (q[1] - xb) * (q[1] - xb);
          if (d < best) best = d, s = q;
        }
        g.sa[static_cast<size_t>(i) * g.n + j] = static_cast<float>(s[0]);
        g.sb[static_cast<size_t>(i) * g.n + j] = static_cast<float>(s[1]);
      }
    Hgrid_(g.a, g.a) += g.w;
    Hgrid_(g.b, g.b) += g.w;
    grids_.push_back(std::move(g));
  }
  for (const MixtureComponent& c : model.mixture.components) {
    const PostureModel cm = component_model(model, c);
    components_.push_back(std::make_unique<PostureSolver>(cm));
    log_weight_.push_back(std::log(c.weight));
    // ½ log det of the component's full system (the Gaussian's precision, up to the scale).
    Eigen::LLT<Eigen::MatrixXd> llt(components_.back()->H0_);
    HS_CHECK(llt.info() == Eigen::Success, "mixture component is not positive definite");
    half_logdet_.push_back(Eigen::MatrixXd(llt.matrixL()).diagonal().array().log().sum());
  }
}

PostureSolver::~PostureSolver() = default;

double PostureSolver::Grid::d2_at(double xa, double xb, double* s_a, double* s_b) const {
  // Bilinear interpolation of the nearest-sample field at the point clamped into the grid.
  const double u = std::clamp((xa - lo_a) / (hi_a - lo_a), 0.0, 1.0) * (n - 1);
  const double v = std::clamp((xb - lo_b) / (hi_b - lo_b), 0.0, 1.0) * (n - 1);
  const int i = std::min(static_cast<int>(u), n - 2), j = std::min(static_cast<int>(v), n - 2);
  const double fu = u - i, fv = v - j;
  auto at = [&](const std::vector<float>& t, int ii, int jj) { return static_cast<double>(t[static_cast<size_t>(ii) * n + jj]); };
  auto lerp2 = [&](const std::vector<float>& t) {
    return (1 - fu) * ((1 - fv) * at(t, i, j) + fv * at(t, i, j + 1)) + fu * ((1 - fv) * at(t, i + 1, j) + fv * at(t, i + 1, j + 1));
  };
  *s_a = lerp2(sa);
  *s_b = lerp2(sb);
  return (xa - *s_a) * (xa - *s_a) + (xb - *s_b) * (xb - *s_b);
}

double PostureSolver::grid_energy(const Vec& x, std::vector<std::array<double, 2>>* anchors) const {
  double e = 0;
  if (anchors) anchors->resize(grids_.size());
  for (size_t k = 0; k < grids_.size(); ++k) {
    double sa, sb;
    e += 0.5 * grids_[k].w * grids_[k].d2_at(x(grids_[k].a), x(grids_[k].b), &sa, &sb);
    if (anchors) (*anchors)[k] = {sa, sb};
  }
  return e;
}

double PostureSolver::energy(const Angles& xa, const PostureInputs& in, bool with_grids) const {
  const Vec x = Eigen::Map<const Vec>(xa.data());
  const Vec dx = x - relaxed_;
  double e = 0;
  for (int d = 0; d < kDofCount; ++d) e += 0.5 * model_.dof[d].stiffness * dx(d) * dx(d);
  const Eigen::VectorXd r = A_ * x + b_;  // pair lines and constraint rows
  e += 0.5 * r.dot(w_.asDiagonal() * r);
  for (const auto& t : in.targets) e += 0.5 * t.weight * (x(t.dof) - t.angle) * (x(t.dof) - t.angle);
  for (const auto& [d, tau] : in.torques) e -= tau * x(d);
  if (with_grids) e += grid_energy(x, nullptr);
  return e;
}

Eigen::MatrixXd PostureSolver::system_matrix() const { return H0_; }
Eigen::VectorXd PostureSolver::system_rhs() const {
  // In θ̄-relative angles the pair constraints read Aθ + (b + Aθ̄) = 0.
  return -A_.transpose() * (w_.asDiagonal() * (b_ + A_ * relaxed_));
}

void PostureSolver::prepare(const PostureInputs& in, Problem* p) const {
  p->H = H0_;
  p->g = g0_;
  p->x = relaxed_;
  p->pinned = 0;
  p->targets = !in.targets.empty();
  p->clamped = 0;
  for (const auto& [d, v] : in.pins) {
    if (d < 0 || d >= kDofCount) throw InputError("inputs", "DOF index out of range");
    if (!std::isfinite(v)) throw InputError(dofs()[d].name, "pinned angle is not a finite number");
    const double c = std::clamp(v, lo_(d), hi_(d));
    if (c != v) ++p->clamped;
    p->x(d) = c;
    p->pinned |= bit(d);
  }
  for (const auto& [d, tau] : in.torques) {
    if (d < 0 || d >= kDofCount) throw InputError("inputs", "DOF index out of range");
    if (!(std::abs(tau) <= kMaxTorque))
      throw InputError(dofs()[d].name, "the input must be a number within ±" + std::to_string(static_cast<int>(kMaxTorque)));
    p->g(d) += tau;
  }
  for (const auto& t : in.targets) {
    if (t.dof < 0 || t.dof >= kDofCount) throw InputError("inputs", "DOF index out of range");
    if (!std::isfinite(t.angle) || !(t.weight > 0 && t.weight <= kMaxTargetWeight))
      throw InputError(dofs()[t.dof].name, "a target needs a finite angle and a weight in (0, 1e6]");
    const double c = std::clamp(t.angle, lo_(t.dof), hi_(t.dof));
    if (c != t.angle) ++p->clamped;
    p->H(t.dof, t.dof) += t.weight;
    p->g(t.dof) += t.weight * c;
  }
}

const PostureSolver::Factor& PostureSolver::factor(const Mat& H, int cache_id, std::uint64_t fixed) const {
  thread_local Factor scratch;
  auto build = [&](Factor* f) {
    f->free.clear();
    for (int d = 0; d < kDofCount; ++d)
      if (!(fixed & bit(d))) f->free.push_back(d);
    const int n = static_cast<int>(f->free.size());
    Eigen::MatrixXd Hff(n, n);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) Hff(r, c) = H(f->free[r], f->free[c]);
    Eigen::LLT<Eigen::MatrixXd> llt(Hff);
    HS_CHECK(llt.info() == Eigen::Success, "posture system is not positive definite");
    f->inv = llt.solve(Eigen::MatrixXd::Identity(n, n));
  };
  if (cache_id < 2) {
    auto& cache = cache_[cache_id];
    const auto it = cache.find(fixed);
    if (it != cache.end()) return *it->second;
    if (cache.size() < 4096) {
      auto f = std::make_unique<Factor>();
      build(f.get());
      return *cache.emplace(fixed, std::move(f)).first->second;
    }
  }
  build(&scratch);
  return scratch;
}

void PostureSolver::box_qp(Problem& p, const Vec& g, const Mat& H, int cache_id, Vec* xo, int* rounds) const {
  Vec& x = *xo;
  for (int d = 0; d < kDofCount; ++d)
    if (p.pinned & bit(d)) x(d) = p.x(d);
  std::uint64_t fixed = p.pinned;
  std::array<signed char, kDofCount> side{};
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kDofCount, 1> rhs;
  for (int round = 1; round <= 4 * kDofCount; ++round) {
    *rounds = round;
    const Factor& f = factor(H, cache_id, fixed);
    const int n = static_cast<int>(f.free.size());
    rhs.resize(n);
    for (int r = 0; r < n; ++r) {
      const int i = f.free[r];
      double v = g(i);
      for (int j = 0; j < kDofCount; ++j)
        if (fixed & bit(j)) v -= H(i, j) * x(j);
      rhs(r) = v;
    }
    for (int r = 0; r < n; ++r) x(f.free[r]) = f.inv.row(r).dot(rhs);
    // Free DOFs beyond a limit join the active set at that limit.
    bool added = false;
    for (int r = 0; r < n; ++r) {
      const int i = f.free[r];
      if (x(i) < lo_(i) - 1e-9) side[i] = -1, x(i) = lo_(i), fixed |= bit(i), added = true;
      else if (x(i) > hi_(i) + 1e-9) side[i] = 1, x(i) = hi_(i), fixed |= bit(i), added = true;
    }
    if (added) continue;
    // KKT: a DOF held at a limit must be pushed against it; release the worst one that is not.
    int worst = -1;
    double worst_v = 1e-9;
    for (int i = 0; i < kDofCount; ++i) {
      if (!side[i]) continue;
      const double grad = H.row(i).dot(x) - g(i);  // ∂E/∂x_i
      const double v = side[i] < 0 ? -grad : grad;
      if (v > worst_v) worst_v = v, worst = i;
    }
    if (worst < 0) {
      p.at_bound = fixed & ~p.pinned;
      return;
    }
    side[worst] = 0;
    fixed &= ~bit(worst);
  }
  HS_CHECK(false, "posture active set did not settle");
}

PostureSolution PostureSolver::solve_linear(const PostureInputs& in) const {
  thread_local Problem p;
  prepare(in, &p);
  PostureSolution s;
  Vec x = relaxed_;
  box_qp(p, p.g, p.H, p.targets ? 2 : 0, &x, &s.iterations);
  Eigen::Map<Vec>(s.angles.data()) = x;
  s.clamped_inputs = p.clamped;
  for (int d = 0; d < kDofCount; ++d)
    if (p.at_bound & bit(d)) s.at_limit.push_back(d);
  s.energy = energy(s.angles, in, false);
  return checked(std::move(s));
}

PostureSolution PostureSolver::solve_nonlinear(const PostureInputs& in, int max_iterations) const {
  if (grids_.empty()) return solve_linear(in);
  thread_local Problem p;
  prepare(in, &p);
  Mat Hg = p.H;
  for (const Grid& g : grids_) Hg(g.a, g.a) += g.w, Hg(g.b, g.b) += g.w;
  PostureSolution s;
  Vec x = relaxed_;
  int rounds = 0;
  box_qp(p, p.g, p.H, p.targets ? 2 : 0, &x, &rounds);  // start: the linear model's posture
  Angles xa;
  Eigen::Map<Vec>(xa.data()) = x;
  double e = energy(xa, in, true);
  s.energy_trace.push_back(e);
  std::vector<std::array<double, 2>> anchors;
  s.converged = false;
  for (int it = 1; it <= max_iterations; ++it) {
    s.iterations = it;
    // Gauss–Newton model: each grid term is a spring of its weight to the current nearest
    // sample; the model's minimiser within the limits gives the step direction.
    grid_energy(x, &anchors);
    Vec g = p.g;
    for (size_t k = 0; k < grids_.size(); ++k) {
      g(grids_[k].a) += grids_[k].w * anchors[k][0];
      g(grids_[k].b) += grids_[k].w * anchors[k][1];
    }
    Vec y = x;
    box_qp(p, g, Hg, p.targets ? 2 : 1, &y, &rounds);
    const Vec step = y - x;
    // Backtracking: the limits are a box, so every point between x and y is feasible.
    double alpha = 1.0, e_new = e;
    Vec x_new = x;
    bool accepted = false;
    for (int ls = 0; ls < 30; ++ls, alpha *= 0.5) {
      x_new = x + alpha * step;
      Eigen::Map<Vec>(xa.data()) = x_new;
      e_new = energy(xa, in, true);
      if (e_new <= e) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {  // no descent along the model's step: stationary
      s.converged = true;
      break;
    }
    s.last_step_deg = (alpha * step).cwiseAbs().maxCoeff();
    x = x_new;
    e = e_new;
    s.energy_trace.push_back(e);
    if (s.last_step_deg < 1e-6) {
      s.converged = true;
      break;
    }
  }
  Eigen::Map<Vec>(s.angles.data()) = x;
  s.energy = e;
  s.clamped_inputs = p.clamped;
  for (int d = 0; d < kDofCount; ++d)  // held at a limit by the last step's QP, or sitting on one
    if (!(p.pinned & bit(d)) && ((p.at_bound & bit(d)) || x(d) <= lo_(d) + 1e-9 || x(d) >= hi_(d) - 1e-9) &&
        std::abs(x(d) - relaxed_(d)) > 1e-9)
      s.at_limit.push_back(d);
  return checked(std::move(s));
}

PostureSolution PostureSolver::checked(PostureSolution s) const {
  // Bounded models and inputs keep the system well posed; this is the last guard that no
  // NaN or runaway angle is ever reported as a posture.
  bool ok = std::isfinite(s.energy);
  for (int d = 0; d < kDofCount; ++d) ok = ok && std::isfinite(s.angles[d]) && s.angles[d] >= lo_(d) - 1e-6 && s.angles[d] <= hi_(d) + 1e-6;
  if (!ok)
    throw InputError(model_.name.empty() ? "model" : model_.name,
                     "the solve gave no finite posture within the limits; the model's numbers are out of proportion");
  return s;
}

PostureSolution PostureSolver::solve(const PostureInputs& in) const {
  if (!components_.empty()) return solve_mixture(in);
  return grids_.empty() ? solve_linear(in) : solve_nonlinear(in);
}

PostureSolution PostureSolver::solve_mixture(const PostureInputs& in) const {
  if (components_.empty()) return solve_linear(in);
  // Each component c is a Gaussian with density ∝ exp(−E_c / s). With the pins fixed, its
  // constrained optimum x_c has the free energy E_c(x_c) − s·½ log det(H_c) + s·½ log det(H_c
  // over the unpinned DOFs): the negative log of the pinned values' marginal density. The
  // answer is the posterior-weighted mean of the x_c, the conditional mean of the mixture
  // (for pins alone exactly; torques and targets enter every component's energy alike).
  std::uint64_t pinned = 0;
  for (const auto& [d, v] : in.pins)
    if (d >= 0 && d < kDofCount) pinned |= bit(d);
  const double s = model_.mixture.energy_scale;
  const size_t C = components_.size();
  thread_local std::vector<PostureSolution> sols;
  thread_local std::vector<double> logp;
  sols.resize(C);
  logp.resize(C);
  double best = -1e300;
  for (size_t c = 0; c < C; ++c) {
    sols[c] = components_[c]->solve_linear(in);
    logp[c] = log_weight_[c] + half_logdet_[c] - components_[c]->half_logdet_free(pinned) - sols[c].energy / s;
    best = std::max(best, logp[c]);
  }
  double total = 0;
  for (size_t c = 0; c < C; ++c) total += (logp[c] = std::exp(logp[c] - best));
  PostureSolution out;
  Vec x = Vec::Zero();
  for (size_t c = 0; c < C; ++c) {
    out.component_weights.push_back(logp[c] / total);
    x += (logp[c] / total) * Eigen::Map<const Vec>(sols[c].angles.data());
    out.iterations = std::max(out.iterations, sols[c].iterations);
    out.clamped_inputs = std::max(out.clamped_inputs, sols[c].clamped_inputs);
  }
  // The weights are a convex combination of points inside the box: the result is too.
  for (int d = 0; d < kDofCount; ++d) x(d) = std::clamp(x(d), lo_(d), hi_(d));
  Eigen::Map<Vec>(out.angles.data()) = x;
  for (int d = 0; d < kDofCount; ++d)
    if (!(pinned & bit(d)) && (x(d) <= lo_(d) + 1e-9 || x(d) >= hi_(d) - 1e-9)) out.at_limit.push_back(d);
  out.energy = -s * (std::log(total) + best);  // the mixture's free energy at this input
  return checked(std::move(out));
}

double PostureSolver::half_logdet_free(std::uint64_t pinned) const {
  const auto it = logdet_cache_.find(pinned);
  if (it != logdet_cache_.end()) return it->second;
  std::vector<int> f;
  for (int d = 0; d < kDofCount; ++d)
    if (!(pinned & bit(d))) f.push_back(d);
  double v = 0;
  if (!f.empty()) {
    Eigen::MatrixXd H(f.size(), f.size());
    for (size_t r = 0; r < f.size(); ++r)
      for (size_t c = 0; c < f.size(); ++c) H(r, c) = H0_(f[r], f[c]);
    Eigen::LLT<Eigen::MatrixXd> llt(H);
    HS_CHECK(llt.info() == Eigen::Success, "posture system is not positive definite");
    v = Eigen::MatrixXd(llt.matrixL()).diagonal().array().log().sum();
  }
  if (logdet_cache_.size() < 4096) logdet_cache_.emplace(pinned, v);
  return v;
}

PostureInputs fist_inputs() {
  PostureInputs in;
  for (const char* f : {"index", "middle", "ring", "little"})
    for (const auto& [j, a] : {std::pair{".mcp.flex", 85.0}, {".pip.flex", 100.0}, {".dip.flex", 60.0}})
      in.pins.emplace_back(dof_index(std::string(f) + j).value(), a);
  in.pins.emplace_back(dof_index("thumb.mcp.flex").value(), 40.0);
  in.pins.emplace_back(dof_index("thumb.ip.flex").value(), 50.0);
  return in;
}

void parse_assignment(const std::string& text, const std::string& option, int* dof, double* value, double* weight) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw UsageError(option, "'" + text + "' is not of the form name=value" + (weight ? "[@weight]" : ""));
  try {
    *dof = require_dof(text.substr(0, eq), option);
  } catch (const InputError& e) {
    throw UsageError(e.where(), e.detail());  // a flag's value
  }
  std::string rest = text.substr(eq + 1);
  if (weight) {
    *weight = 1.0;
    const size_t at = rest.find('@');
    if (at != std::string::npos) {
      char* end = nullptr;
      const std::string w = rest.substr(at + 1);
      *weight = std::strtod(w.c_str(), &end);
      if (w.empty() || *end != '\0' || !(*weight > 0 && *weight <= kMaxTargetWeight))
        throw UsageError(option, "'" + text + "': the weight after @ must be a number in (0, 1e6]");
      rest = rest.substr(0, at);
    }
  }
  char* end = nullptr;
  *value = std::strtod(rest.c_str(), &end);
  if (rest.empty() || *end != '\0' || !(std::abs(*value) <= kMaxTorque))
    throw UsageError(option, "'" + text + "': the value must be a finite number within ±1e4");
}

}  // namespace handskin
