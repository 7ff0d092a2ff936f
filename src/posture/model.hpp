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

struct PostureModel {
  std::string name, description;
  std::array<DofParams, kDofCount> dof;
  std::vector<PairLine> pairs;
  std::vector<PairGrid> grids;
  std::vector<std::string> notes;  ///< e.g. limits widened by calibration
};

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
