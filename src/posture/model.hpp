#pragma once
/// A posture model (`hand-posture/1`, docs/posture.md): per DOF a relaxed angle θ̄, a spring
/// stiffness and limits; linear pair constraints (rows of A, b and W, thesis eqs. 3.10–3.14);
/// optional non-linear data-driven potentials on joint pairs (thesis §3.2.3).
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "posture/skeleton.hpp"

namespace handskin {

/// Bounds on every number a model may hold (checked on load, by the solver and by
/// calibration): beyond them the linear system loses all precision and a solve returns
/// garbage (docs/posture.md, "Bounds").
constexpr double kMaxStiffness = 1e3, kMinStiffness = 1e-3;
constexpr double kMaxAngle = 1000;        ///< |limits|, grid ranges and samples (deg; mm for the wrist translations)
constexpr double kMaxCoefficient = 1e3;   ///< |alpha|, |beta| of a pair
constexpr double kMaxOffset = 1e5;        ///< |gamma| of a pair
constexpr double kMaxWeight = 1e3;        ///< a pair's or grid's weight
constexpr double kMaxTorque = 1e4;        ///< |instructed input|
constexpr double kMaxTargetWeight = 1e6;  ///< a soft target's weight

struct DofParams {
  double relaxed = 0;    ///< θ̄, degrees (mm for wrist translations)
  double stiffness = 1;  ///< spring K: input per degree
  double lo = -180, hi = 180;  ///< limits
};

/// α·θ_a + β·θ_b + γ = 0 on absolute angles (degrees), weight w (a diagonal entry of W).
struct PairLine {
  int a = -1, b = -1;
  double alpha = 0, beta = 0, gamma = 0, weight = 0;
  std::string source;  ///< where it came from: "thesis Table 3.2", "calibration r = 0.93", ...
};

/// Potential w·½·d² on the (θ_a, θ_b) plane, d = distance to the nearest measured sample,
/// tabulated on a cells × cells grid over [range_a] × [range_b] (the samples are kept, the
/// table is built on load).
struct PairGrid {
  int a = -1, b = -1;
  double weight = 0;
  double lo_a = 0, hi_a = 0, lo_b = 0, hi_b = 0;
  int cells = 100;
  std::vector<std::array<double, 2>> samples;
};

/// A constraint potential over any number of DOFs, ½·w·(Σ c_i θ_i + γ)² on absolute angles
/// (a row of A, b and W that is not limited to two joints). The Gaussian calibration writes
/// its precision as springs plus such rows: each row is a postural synergy, a direction of
/// joint space along which the measured hands hardly vary (docs/posture.md).
struct LinearConstraint {
  std::vector<std::pair<int, double>> terms;  ///< DOF, coefficient c_i
  double offset = 0, weight = 0;              ///< γ, w
  std::string source;
};
constexpr int kMaxConstraints = 256;  ///< rows a model (or a mixture component) may hold

/// One Gaussian of a posture mixture, written like a linear model: its rest posture, its
/// springs and its constraint rows. DOFs it does not list take the model's own values.
struct MixtureComponent {
  double weight = 0;  ///< prior probability π_c
  std::vector<std::pair<int, double>> relaxed, stiffness;
  std::vector<LinearConstraint> constraints;
};
/// A mixture of Gaussians over postures (the non-linear mode of docs/posture.md). Each
/// component's energy E_c is the negative log density times `energy_scale`; the solver gives
/// each component's constrained optimum the weight of its posterior probability.
struct PostureMixture {
  double energy_scale = 1;
  std::vector<MixtureComponent> components;
};
constexpr int kMaxMixtureComponents = 16;

struct PostureModel {
  std::string name, description;
  std::array<DofParams, kDofCount> dof;
  std::vector<PairLine> pairs;
  std::vector<LinearConstraint> constraints;
  std::vector<PairGrid> grids;
  PostureMixture mixture;          ///< empty: none
  std::vector<std::string> notes;  ///< e.g. limits widened by calibration
};

/// The model a mixture component stands for: `base` with the component's rest posture,
/// springs and constraint rows in place of its own pairs, constraints, grids and mixture.
PostureModel component_model(const PostureModel& base, const MixtureComponent& c);

/// Anatomical defaults per DOF: relaxed posture, stiffness, limits (sources in docs/posture.md).
std::array<DofParams, kDofCount> default_dof_params();
/// The shipped parameter sets: "anatomical" (DIP–PIP and neighbouring-finger couplings) and
/// "thesis" (Table 3.2 as read in docs/posture.md). Unknown name → InputError.
PostureModel builtin_model(const std::string& name);

PostureModel parse_model(const Json& j, const std::string& file);
PostureModel load_model(const std::string& file);  ///< a file, or "builtin:<name>"
Json model_to_json(const PostureModel& m);
void save_model(const std::string& file, const PostureModel& m);

/// A DOF by name or alias, or InputError(where, "unknown DOF '<name>'").
int require_dof(const std::string& name, const std::string& where);

}  // namespace handskin
