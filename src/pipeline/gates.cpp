#include "pipeline/gates.hpp"

#include <cstdio>

#include "mesh/mesh_distance.hpp"
#include "pipeline/patch_stage.hpp"
#include "register/registration.hpp"
#include "pipeline/figures_json.hpp"
#include "pipeline/skin_stage.hpp"
#include "skin/baseline.hpp"

namespace handskin {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}
}  // namespace

bool QualityGates::all_pass() const {
  for (const auto& g : gates)
    if (!g.pass) return false;
  return true;
}

std::vector<std::string> QualityGates::failed() const {
  std::vector<std::string> f;
  for (const auto& g : gates)
    if (!g.pass) f.push_back(g.name);
  return f;
}

std::string QualityGates::failed_list() const {
  std::string s;
  for (const auto& n : failed()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

QualityGates check_gates(const GateInputs& in, const PipelineOptions& o) {
  QualityGates R;
  auto at_most = [&](std::string name, std::string measure, double value, double limit, std::string unit, std::string key) {
    R.gates.push_back({std::move(name), std::move(measure), value, limit, std::move(unit), std::move(key), value <= limit});
  };
  if (!in.skin_file.empty()) {
    R.skin = check_written_mesh(in.skin_file);
    const WrittenMeshCheck& c = *R.skin;
    const std::string file = in.skin_name.empty() ? in.skin_file : in.skin_name;
    at_most("skin.closed", "boundary edges of " + file + " (and faces its reader could not add)",
            static_cast<double>(c.health.boundary_edges + c.faces_dropped), 0, "edges", "");
    at_most("skin.manifold", "non-manifold vertices of " + file,
            static_cast<double>(c.health.nonmanifold_vertices + c.vertices_split + c.faces_dropped), 0, "vertices", "");
    at_most("skin.one_component", "face-connected components of " + file + " beyond the first",
            static_cast<double>(c.health.components > 0 ? c.health.components - 1 : 1), 0, "components", "");
    R.gates.push_back({"skin.outward", "enclosed volume of " + file + " (positive: faces oriented outward)",
                       c.health.volume_mm3, 0, "mm3", "", c.health.volume_mm3 > 0});
    at_most("skin.self_intersections", "pairs of crossing triangles in " + file + " (CGAL, exact predicates)",
            static_cast<double>(c.crossing_pairs), 0, "pairs", "");
    if (in.cloud && !in.cloud->empty()) {
      const MeshDistance to_skin(c.mesh);
      R.cloud_to_skin = one_way_distance(thinned_points(*in.cloud, kCloudToSkinPoints), to_skin);  // as the skin stage
      // A noisy scanner's points scatter about any skin by their noise: where the gate fails and
      // the cloud's measured noise is over a CUBIST scan's, the measure says so and what to do
      // (a depth camera's σ 0.6 mm: p95 1.02 mm against 0.35, the skin 0.18 mm from the true one).
      std::string noisy;
      if (in.cloud_noise_mm > 0.1 && R.cloud_to_skin->p95 > o.gates.cloud_to_skin_p95_mm)
        noisy = " (the cloud's own noise is " + num(in.cloud_noise_mm) +
                " mm, measured after the voxel grid: a scanner this noisy scatters its points about any skin; set "
                "gates.cloud_to_skin_p95_mm for it in a pipeline, as pipelines/handheld.json does for 0.3 mm)";
      at_most("cloud_to_skin.p95", "merged cloud's points to " + file + ", 95th percentile" + noisy, R.cloud_to_skin->p95,
              o.gates.cloud_to_skin_p95_mm, "mm", "gates.cloud_to_skin_p95_mm");
      at_most("cloud_to_skin.max", "merged cloud's points to " + file + ", largest", R.cloud_to_skin->max,
              o.gates.cloud_to_skin_max_mm, "mm", "gates.cloud_to_skin_max_mm");
    }
  }
  if (in.patches) {
    const PatchStageResult& p = *in.patches;
    at_most("patches_to_skin.p95", "the patch surface (as patches.json holds it) to the polygon skin, 95th percentile",
            p.surface_to_skin.p95, o.gates.patches_to_skin_p95_mm, "mm", "gates.patches_to_skin_p95_mm");
    at_most("patches_to_skin.max", "the patch surface to the polygon skin, largest", p.surface_to_skin.max,
            o.gates.patches_to_skin_max_mm, "mm", "gates.patches_to_skin_max_mm");
    std::string crossing_where;
    for (size_t k = 0; k < p.crossings.patches.size() && k < 3; ++k)
      crossing_where += (k ? "; " : "") + p.crossings.patches[k];
    if (p.crossings.patches.size() > 3) crossing_where += "; …";
    at_most("patches.self_intersections",
            "pairs of crossing triangles in patches.ply (the patch surface passing through itself; CGAL, exact predicates)" +
                (crossing_where.empty() ? std::string() : " at " + crossing_where),
            static_cast<double>(p.crossings.pairs), 0, "pairs", "");
    at_most("patches.g0_gap", "largest gap between neighbouring patches along their shared borders", p.patches.g0_gap_mm,
            o.gates.g0_gap_mm, "mm", "gates.g0_gap_mm");
    at_most("patches.g1_kink",
            "largest angle between neighbouring patches' normals along their borders, away from the corners where "
            "other than four patches meet (at " + p.patches.g1_max_where + ")",
            p.patches.g1_max_deg, o.gates.g1_kink_deg, "deg", "gates.g1_kink_deg");
    if (const auto& r = p.patches.refinement)
      at_most("patches.tolerance",
              "the measured points' largest distance to the refined patches" +
                  (r->stopped.empty() ? std::string() : " (the refinement stopped: " + r->stopped + ")"),
              r->worst_mm.back(), r->tolerance_mm, "mm", "patches.tolerance_mm");
  }
  if (in.registration) {
    const RegistrationFigures& f = in.registration->figures;
    if (f.rotation_sigma_deg > 0) {
      at_most("registration.rotation_1sigma", "the registration's own error estimate (1 sigma), rotation",
              f.rotation_sigma_deg, o.registration.warn_rotation_deg, "deg", "registration.warn_rotation_deg");
      at_most("registration.displacement_1sigma",
              "the registration's own error estimate (1 sigma), mean displacement of the back scan's skin",
              f.displacement_sigma_mm, o.registration.warn_displacement_mm, "mm", "registration.warn_displacement_mm");
    }
  }
  return R;
}

std::string gate_warning(const QualityGate& g) {
  return "quality gate " + g.name + " failed: " + num(g.value) + " " + g.unit + " (limit " + num(g.limit) +
         (g.key.empty() ? "" : ", " + g.key) + "): " + g.measure;
}

Json to_json(const QualityGates& g) {
  Json a = Json::array();
  for (const auto& q : g.gates)
    a.push_back({{"name", q.name}, {"measure", q.measure}, {"value", q.value}, {"limit", q.limit},
                 {"unit", q.unit}, {"key", q.key.empty() ? Json(nullptr) : Json(q.key)}, {"pass", q.pass}});
  return a;
}

void put_gates(const QualityGates& g, Json* report) {
  (*report)["gates"] = to_json(g);
  (*report)["gates_passed"] = g.all_pass();
}

void describe_written_skin(const QualityGates& g, Json* j) {
  if (!g.skin) return;
  const WrittenMeshCheck& c = *g.skin;
  Json& m = (*j)["mesh"];
  m["vertices"] = c.mesh.n_vertices();
  m["triangles"] = c.mesh.n_faces();
  m["closed"] = c.closed();
  m["manifold"] = c.manifold();
  m["components"] = c.health.components;
  m["outward"] = c.outward();
  m["volume_mm3"] = c.health.volume_mm3;
  m["area_mm2"] = c.health.area_mm2;
  m["self_intersections"] = c.self_intersects();
  m["crossing_pairs"] = c.crossing_pairs;
  m["watertight"] = c.watertight();
  m["measured_on"] = "the written file";
  if (g.cloud_to_skin) (*j)["cloud_to_skin_mm"] = to_json(*g.cloud_to_skin);
}

}  // namespace handskin
