#include "pipeline/stage_options.hpp"

#include <algorithm>
#include <cmath>

namespace handskin {

RegistrationOptions registration_options(const PipelineOptions& o) {
  RegistrationOptions r;
  r.expected_markers = o.markers.count;
  r.estimate_radius = !o.markers.radius_mm;
  if (o.markers.radius_mm) r.spheres.radius_mm = *o.markers.radius_mm;
  r.prepare.table_margin_mm = o.registration.table_margin_mm;
  r.match_tolerance_mm = o.registration.match_tolerance_mm;
  r.marker_clearance_mm = o.registration.marker_clearance_mm;
  r.refine_enabled = o.registration.refine;
  r.refine.gate_mm = o.registration.icp_gate_mm;
  r.refine.normal_deg = o.registration.icp_normal_deg;
  r.refine.trim = o.registration.icp_trim;
  r.refine.max_iterations = static_cast<int>(o.registration.icp_max_iterations);
  r.warn_rotation_sigma_deg = o.registration.warn_rotation_deg;
  r.warn_displacement_sigma_mm = o.registration.warn_displacement_mm;
  return r;
}

SkinOptions skin_options(const PipelineOptions& o) {
  // Values are range-checked by the table (IsValid) before a stage uses them; the clamps
  // only keep the narrowing defined for an unchecked object.
  auto to_int = [](long v) { return static_cast<int>(std::clamp(v, -1000000000L, 1000000000L)); };
  SkinOptions s;
  s.slicing.planes = to_int(o.slicing.planes);
  s.slicing.points_per_segment = to_int(o.slicing.points_per_segment);
  s.thumb_overlap_mm = o.skin.thumb_overlap_mm;
  s.smoothing_rings = to_int(o.skin.smoothing_rings);
  s.wrinkle_mm = o.skin.wrinkle_mm;
  s.cap_rings = to_int(o.skin.cap_rings);
  s.max_triangles = to_int(o.skin.max_triangles);
  s.decimation_tolerance_mm = o.skin.decimation_tolerance_mm;
  s.data_fit.enabled = o.skin.fit_to_data;
  s.data_fit.max_move_mm = o.skin.fit_max_move_mm;
  s.fair_unseen.enabled = o.skin.fair_unseen;
  return s;
}

PatchOptions patch_options(const PipelineOptions& o) {
  // The hand's layout has 98 faces; split k × k it has 98 k²: the k nearest the count.
  PatchOptions p;
  p.subdivision = patch_subdivision(o.patches.count);
  p.c1_weight = o.patches.c1_weight;
  p.fairness = o.patches.fairness;
  p.skin_weight = o.patches.skin_weight;
  p.tolerance_mm = o.patches.tolerance_mm;
  p.max_patches = static_cast<int>(o.patches.max_patches);
  return p;
}

BindingOptions binding_options(const PipelineOptions& o) {
  BindingOptions b;
  b.mode = o.rigging.smooth ? "smooth" : "rigid";
  return b;
}

}  // namespace handskin
