#pragma once
/// The posture solver (thesis §3.2): springs K on every DOF about the relaxed posture θ̄,
/// linear pair constraints J = ½(Aθ+b)ᵀW(Aθ+b), instructed torques τ̂, pinned angles, soft
/// targets, joint limits, optional non-linear grid potentials (§3.2.3) and an optional
/// mixture of Gaussians over postures (the calibrated non-linear mode).
///
/// Linear model: the equilibrium (K + AᵀWA)θ = τ̂ − AᵀWb (eq. 3.17, θ measured from θ̄),
/// solved over the unpinned DOFs as a box-constrained quadratic programme (active set): the
/// limits hold at the solution, not by clamping afterwards. Factorisations are cached per
/// set of fixed DOFs, so a model solves many postures cheaply.
/// Non-linear model: Gauss–Newton on the total potential with each grid term a spring to the
/// nearest measured sample, each step a box QP, a backtracking line search that never lets
/// the potential increase.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "posture/model.hpp"

namespace handskin {

struct PostureInputs {
  std::vector<std::pair<int, double>> pins;     ///< DOF, angle (deg): hard
  std::vector<std::pair<int, double>> torques;  ///< DOF, instructed input τ̂ (deg-equivalents: K = 1 turns 1 into 1°)
  struct Target {
    int dof;
    double angle, weight;  ///< soft: ½·weight·(θ − angle)²
  };
  std::vector<Target> targets;
};

struct PostureSolution {
  Angles angles{};             ///< every DOF, absolute degrees (mm for wrist.t*)
  double energy = 0;           ///< total potential (springs + pairs + grids + targets − torque work)
  int iterations = 0;          ///< active-set rounds (linear) or Gauss–Newton steps (non-linear)
  double last_step_deg = 0;    ///< non-linear: size of the last accepted step
  std::vector<double> energy_trace;  ///< non-linear: the potential after each step
  std::vector<int> at_limit;   ///< DOFs held at a limit
  int clamped_inputs = 0;      ///< pins or targets outside the limits, moved onto them
  bool converged = true;
  std::vector<double> component_weights;  ///< mixture: each component's posterior weight
};

class PostureSolver {
 public:
  explicit PostureSolver(const PostureModel& model);
  ~PostureSolver();
  const PostureModel& model() const { return model_; }
  bool has_grids() const { return !grids_.empty(); }

  /// Linear model only (grids ignored). Throws InputError on a NaN or unknown input.
  PostureSolution solve_linear(const PostureInputs& in) const;
  /// Linear model plus the grid potentials.
  PostureSolution solve_nonlinear(const PostureInputs& in, int max_iterations = 50) const;
  /// The mixture's conditional mean (docs/posture.md, "Mixture"); solve_linear without one.
  PostureSolution solve_mixture(const PostureInputs& in) const;
  /// solve_mixture if the model has a mixture, else solve_nonlinear if it has grids, else
  /// solve_linear.
  PostureSolution solve(const PostureInputs& in) const;
  bool has_mixture() const { return !components_.empty(); }

  /// The total potential of a posture for these inputs (what the solvers minimise).
  double energy(const Angles& x, const PostureInputs& in, bool with_grids) const;

  /// The matrix and vector of eq. 3.17 in θ̄-relative angles (for tests): K + AᵀWA, −AᵀWb.
  Eigen::MatrixXd system_matrix() const;
  Eigen::VectorXd system_rhs() const;
  /// The linear model's potential in absolute angles, without inputs: ½xᵀHx − gᵀx + c, with
  /// H = system_matrix(); this is g (for a page that solves the linear model itself).
  Eigen::VectorXd absolute_rhs() const { return g0_; }

 private:
  using Vec = Eigen::Matrix<double, kDofCount, 1>;
  using Mat = Eigen::Matrix<double, kDofCount, kDofCount>;
  struct Grid {
    int a, b;
    double w, lo_a, hi_a, lo_b, hi_b;
    int n;
    std::vector<float> sa, sb;  ///< nearest sample per node, n × n, row = a index
    double d2_at(double xa, double xb, double* s_a, double* s_b) const;
  };
  struct Factor;
  struct Problem;

  void prepare(const PostureInputs& in, Problem* p) const;
  void box_qp(Problem& p, const Vec& g, const Mat& H, int cache_id, Vec* x, int* rounds) const;
  const Factor& factor(const Mat& H, int cache_id, std::uint64_t fixed_mask) const;
  double grid_energy(const Vec& x, std::vector<std::array<double, 2>>* anchors) const;
  PostureSolution checked(PostureSolution s) const;

  PostureModel model_;
  Vec relaxed_, lo_, hi_, g0_;
  Mat H0_, Hgrid_;
  Eigen::MatrixXd A_;
  Eigen::VectorXd b_, w_;
  std::vector<Grid> grids_;
  mutable std::unordered_map<std::uint64_t, std::unique_ptr<Factor>> cache_[3];  ///< H0, H0+grids, other
  // Mixture: one linear solver per component, log π_c and ½ log det H_c.
  std::vector<std::unique_ptr<PostureSolver>> components_;
  std::vector<double> log_weight_, half_logdet_;
  double half_logdet_free(std::uint64_t pinned) const;  ///< ½ log det of H0 over the unpinned DOFs (cached)
  mutable std::unordered_map<std::uint64_t, double> logdet_cache_;
};

/// A fist as pins: finger MCP 85°, PIP 100°, DIP 60°; thumb MCP 40°, IP 50° (the report's
/// and the folding test's fist, docs/rigging.md). The model fills in the other joints.
PostureInputs fist_inputs();

/// Parse "name=value" (a --set / --torque argument) or "name=value@weight" (a --target).
void parse_assignment(const std::string& text, const std::string& option, int* dof, double* value,
                      double* weight = nullptr);

}  // namespace handskin
