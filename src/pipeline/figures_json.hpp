#pragma once
/// The reports' form of a one-way distance between surfaces (mm), shared by every stage's
/// report and the quality gates.
#include "core/json_util.hpp"
#include "mesh/mesh_distance.hpp"

namespace handskin {

inline Json to_json(const OneWayDistance& d) {
  return {{"mean", d.mean}, {"median", d.median}, {"p95", d.p95}, {"max", d.max},
          {"within_1mm", d.within_1mm}, {"samples", d.samples}};
}

}  // namespace handskin
