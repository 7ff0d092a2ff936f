#pragma once
/// Quality gates: figures measured on the outputs as written (skin.ply read back, the patch
/// net as patches.json holds it), each against a documented limit, with a verdict. `run`,
/// `skin`, `register` and `patches` put them in their report (value / limit / pass) and print a
/// warning line for each failed gate; with --strict a failed gate writes nothing and the
/// command exits 3 (docs/architecture.md "Quality gates").
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "mesh/mesh_check.hpp"
#include "mesh/mesh_distance.hpp"
#include "pipeline/options.hpp"

namespace handskin {

struct Registration;
struct PatchStageResult;

struct QualityGate {
  std::string name;     ///< e.g. "skin.self_intersections"
  std::string measure;  ///< what was measured, on what
  double value = 0, limit = 0;
  std::string unit;     ///< "mm", "deg", "pairs", ...
  std::string key;      ///< the pipeline key that sets the limit; empty: fixed (the skin's structure)
  bool pass = true;
};

struct QualityGates {
  std::vector<QualityGate> gates;
  std::optional<WrittenMeshCheck> skin;        ///< skin.ply read back
  std::optional<OneWayDistance> cloud_to_skin; ///< the cloud to the skin as read back
  bool all_pass() const;
  std::vector<std::string> failed() const;     ///< names of the failed gates
  std::string failed_list() const;             ///< the same, joined by ", "
};

/// What to check; every part optional.
struct GateInputs {
  std::string skin_file;                          ///< a written skin mesh (the staged skin.ply)
  std::string skin_name;                          ///< how messages name it (its final path)
  const std::vector<Eigen::Vector3d>* cloud = nullptr;  ///< the merged cloud (cloud → skin)
  double cloud_noise_mm = 0;                      ///< run --cloud: the cloud's measured noise (PreparedCloud::noise_mm), 0 unknown
  const Registration* registration = nullptr;     ///< its own error estimate (1σ)
  const PatchStageResult* patches = nullptr;      ///< patches → skin, G0 gap
};

QualityGates check_gates(const GateInputs& in, const PipelineOptions& options);

/// One line for a failed gate: "quality gate <name> failed: <value> <unit> (limit <limit>): <measure>".
std::string gate_warning(const QualityGate& g);

/// The gates as the reports hold them: [{name, measure, value, limit, unit, key, pass}, ...].
Json to_json(const QualityGates& g);
/// `report`'s "gates" (to_json) and "gates_passed".
void put_gates(const QualityGates& g, Json* report);

/// The skin stage's report entries ("mesh", "cloud_to_skin_mm") replaced by what was measured
/// on the written file, with "written_file" naming it.
void describe_written_skin(const QualityGates& g, Json* skin_stage_json);

}  // namespace handskin
