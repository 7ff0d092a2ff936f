#include "pipeline/patch_stage.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/parallel_jobs.hpp"
#include "pipeline/figures_json.hpp"
#include "pipeline/layout_json.hpp"
#include "pipeline/patch_report.hpp"

namespace handskin {

namespace {
Json figures_json(const DistanceFigures& f) {
  return {{"mean", f.mean}, {"rms", f.rms}, {"p95", f.p95}, {"max", f.max}, {"points", f.points}};
}
}  // namespace

std::optional<std::string> layout_note(const PatchSkin& s) {
  if (s.layout_tries.size() < 2) return std::nullopt;
  const auto crossed = [&](size_t k) { return k < s.layout_try_crossings.size() ? s.layout_try_crossings[k] : size_t{0}; };
  size_t kept = 0;
  const auto turn = [&](size_t k) { return k < s.layout_try_turns.size() ? s.layout_try_turns[k] : 0.0; };
  for (size_t k = 0; k < s.layout_tries.size(); ++k)
    if (s.layout_tries[k].first == s.thumb_ring_shift && turn(k) == s.thumb_turn_deg) kept = k;
  char first[160], buf[400];
  const double fold = s.layout_try_folds.empty() ? 0.0 : s.layout_try_folds[0].first;
  if (crossed(0) > 0)
    std::snprintf(first, sizeof first, "passed through themselves (%zu pairs of triangles; p95 %.2f mm from the skin)",
                  crossed(0), s.layout_tries[0].second);
  else if (fold > 30)
    std::snprintf(first, sizeof first, "folded by %.0f deg at %s (p95 %.2f mm from the skin)", fold,
                  s.layout_try_folds[0].second.c_str(), s.layout_tries[0].second);
  else
    std::snprintf(first, sizeof first, "strayed from the skin (p95 %.2f mm)", s.layout_tries[0].second);
  if (kept != 0) {
    char moved[120], shifted[40];
    std::snprintf(shifted, sizeof shifted, "moved %+d rings", s.thumb_ring_shift);
    if (s.thumb_turn_deg != 0)
      std::snprintf(moved, sizeof moved, "turned %.0f deg toward the %s%s%s", std::abs(s.thumb_turn_deg),
                    s.thumb_turn_deg > 0 ? "palm" : "back", s.thumb_ring_shift != 0 ? " and " : "",
                    s.thumb_ring_shift != 0 ? shifted : "");
    else
      std::snprintf(moved, sizeof moved, "%s", shifted);
    std::snprintf(buf, sizeof buf,
                  "layout: the first one's patches %s; the one with the thumb's base %s (%zu crossing pairs, p95 %.2f "
                  "mm) was kept (docs/patches.md)",
                  first, moved, crossed(kept), s.layout_tries[kept].second);
  }
  else
    std::snprintf(buf, sizeof buf, "warning: the patches %s and no other layout tried did better (docs/patches.md)", first);
  return std::string(buf);
}

std::optional<std::string> separation_note(const PatchSkin& s) {
  if (s.separations.empty()) return std::nullopt;
  std::string between;
  for (const Separation& sep : s.separations) between += (between.empty() ? "" : ", ") + sep.between;
  return "the fingers' tubes passed through each other at " + between + " (" +
         std::to_string(s.crossings_before_separation) +
         " pairs of triangles: fingers pressed together); fitted again held apart by the plane between them (docs/patches.md)";
}

std::optional<std::string> fairness_note(const PatchSkin& s) {
  if (s.crossings_before_fairness == 0) return std::nullopt;
  char b[300];
  std::snprintf(b, sizeof b,
                "the surface passed through itself within a digit or the palm (%zu pairs of triangles: a patch folded into "
                "a crease); fitted again with the fairness term raised to %g, which crossed nowhere (docs/patches.md)",
                s.crossings_before_fairness, s.fairness_used);
  return std::string(b);
}

PatchStageResult run_patch_stage(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<std::uint32_t>& sides, const PatchOptions& options,
                                 const TruthSkin* truth, int error_grid, bool pictures) {
  const auto t0 = std::chrono::steady_clock::now();
  PatchStageResult r;
  r.options = options;
  r.patches = fit_patch_skin(skin, rig, points, sides, options);
  r.tessellation = tessellate(r.patches, options.tessellation);
  // The surface's distance to the skin and Table 4.1's figures side by side (each half serial:
  // the skin's AABB tree, the samples' sort), each into its own field.
  parallel_jobs(2, [&](long k) {
    if (k == 0)
      r.surface_to_skin = one_way_distance(sample_surface(r.tessellation, 1.0), MeshDistance(skin.mesh));
    else
      r.figures = patch_report_figures(r.patches, error_grid);
  });
  if (truth) {
    const auto t_truth = std::chrono::steady_clock::now();
    const MeshDistance to_truth(truth->skin), to_surface(r.tessellation);
    r.truth_file = truth->skin_path;
    r.surface_to_truth = one_way_distance(sample_surface(r.tessellation, 4.0), to_truth, truth->markers, truth->exclude_mm);
    r.truth_to_surface = one_way_distance(sample_surface(truth->skin, 4.0), to_surface, truth->markers, truth->exclude_mm);
    r.truth_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_truth).count();
  }
  // The surface's own crossings: fit_patch_skin measured them on this tessellation (for the
  // layout's choice and the fingers held apart) on every path.
  HS_CHECK(r.patches.crossings.has_value(), "the fit measures its surface's crossings");
  r.crossings = *r.patches.crossings;
  if (pictures) r.pictures = patch_report_pictures(r.patches, rig);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

Json to_json(const PatchStageResult& r) {
  const PatchSkin& s = r.patches;
  Json j = {{"name", "patches"},
            {"seconds", r.seconds},
            {"fit_seconds", s.seconds},
            {"patches", s.patches.size()},
            {"control_points", s.control_points},
            {"layout", {{"faces", s.layout.faces.size()}, {"corners", s.layout.vertices.size()},
                        {"irregular_corners", s.irregular_corners}, {"subdivision", r.options.subdivision},
                        {"given", r.options.layout.has_value()}}},
            {"data_to_surface_mm", {{"palm", figures_json(s.side[0])}, {"back", figures_json(s.side[1])}}},
            {"farthest_point_patch", {{"palm", s.worst_patch[0]}, {"back", s.worst_patch[1]}}},
            {"surface_to_skin_mm", to_json(r.surface_to_skin)},
            {"self_intersections", {{"crossing_pairs", r.crossings.pairs}, {"patches", r.crossings.patches},
                                    {"measured_on", "patches.ply's triangles (float coordinates), CGAL exact predicates"}}},
            {"layout_tries", [&] {
               Json a = Json::array();
               for (size_t k = 0; k < s.layout_tries.size(); ++k) {
                 a.push_back({{"thumb_ring_shift", s.layout_tries[k].first},
                              {"thumb_turn_deg", k < s.layout_try_turns.size() ? s.layout_try_turns[k] : 0.0},
                              {"surface_to_skin_p95_mm", s.layout_tries[k].second}});
                 if (k < s.layout_try_crossings.size()) a.back()["crossing_pairs"] = s.layout_try_crossings[k];
                 if (k < s.layout_try_folds.size())
                   a.back()["g1_max_deg"] = s.layout_try_folds[k].first, a.back()["g1_max_at"] = s.layout_try_folds[k].second;
               }
               return a;
             }()},
            {"thumb_ring_shift", s.thumb_ring_shift},
            {"thumb_turn_deg", s.thumb_turn_deg},
            {"skin_weight_used", s.skin_weight_used},
            {"fairness_used", s.fairness_used},
            {"separations", [&] {
               Json a = Json::array();
               for (const Separation& sep : s.separations)
                 a.push_back({{"between", sep.between}, {"normal", to_json(sep.normal)}, {"offset_mm", sep.offset},
                              {"margin_mm", kSeparationMarginMm}});
               return a;
             }()},
            {"crossing_pairs_before_separation", s.crossings_before_separation},
            {"correction", {{"rounds", s.max_update_per_round.size()},
                            {"max_update_mm", s.max_update_per_round},
                            {"update_p999_mm", s.update_p999_per_round},
                            {"reassigned_points", s.reassigned_per_round},
                            {"rms_mm", s.rms_per_round},
                            {"kept_round", s.kept_round},
                            {"tolerance_mm", r.options.correction_tolerance}}},
            {"continuity", {{"g0_gap_mm", s.g0_gap_mm},
                            {"g1_normal_jump_deg", {{"median", s.g1_median_deg}, {"p95", s.g1_p95_deg}, {"max", s.g1_max_deg}, {"max_where", s.g1_max_where}}},
                            {"g1_near_irregular_corners_deg", {{"median", s.g1_near_median_deg}, {"max", s.g1_near_max_deg}}}}},
            {"table_4_1", to_json(r.figures)},
            {"options", {{"fairness", r.options.fairness}, {"c1_weight", r.options.c1_weight},
                         {"skin_weight", r.options.skin_weight}, {"tessellation", r.options.tessellation}}}};
  if (const auto& f = s.refinement) {
    Json rounds = Json::array();
    for (size_t k = 0; k < f->patches.size(); ++k)
      rounds.push_back({{"patches", f->patches[k]}, {"over_tolerance", f->over[k]}, {"worst_mm", f->worst_mm[k]},
                        {"fit_seconds", k < f->seconds.size() ? f->seconds[k] : 0.0}});
    j["refinement"] = {{"tolerance_mm", f->tolerance_mm}, {"max_patches", r.options.max_patches},
                       {"fits", rounds}, {"held", f->held}, {"stopped", f->stopped}, {"frozen_faces", f->frozen}};
  }
  if (r.surface_to_truth)
    j["truth"] = {{"file", r.truth_file},
                  {"seconds", r.truth_seconds},
                  {"surface_to_truth_mm", to_json(*r.surface_to_truth)},
                  {"truth_to_surface_mm", to_json(*r.truth_to_surface)}};
  return j;
}

Json patches_to_json(const PatchSkin& s) {
  // Per patch: the points whose foot point lies on it, by scan.
  std::vector<std::array<size_t, 2>> count(s.patches.size(), {0, 0});
  std::vector<double> sum(s.patches.size(), 0), worst(s.patches.size(), 0);
  for (const auto& q : s.samples) {
    ++count[q.patch][q.side];
    sum[q.patch] += q.error;
    worst[q.patch] = std::max(worst[q.patch], static_cast<double>(q.error));
  }
  Json patches = Json::array();
  for (size_t f = 0; f < s.patches.size(); ++f) {
    const BezierPatch& p = s.patches[f];
    Json cps = Json::array(), links = Json::array();
    for (const auto& c : p.P) cps.push_back(to_json(c));
    for (int l : p.cp_link) links.push_back(l >= 0 ? Json(s.bones[l]) : Json(nullptr));
    const size_t n = count[f][0] + count[f][1];
    const char* side = n == 0 ? "none" : count[f][1] > count[f][0] ? "back" : "palm";
    patches.push_back({{"name", p.name}, {"side", side},
                       {"link", p.link >= 0 ? Json(s.bones[p.link]) : Json(nullptr)}, {"control_points", cps},
                       {"control_point_ids", s.patch_control[f]}, {"control_point_links", links},
                       {"fit", {{"points", n}, {"palm_points", count[f][0]}, {"back_points", count[f][1]},
                                {"mean_mm", n ? sum[f] / n : 0.0}, {"max_mm", worst[f]}}}});
  }
  Json j = {{"format", "handskin-patches/1"},
            {"units", "mm"},
            {"frame", "palm"},
            {"bones", s.bones},
            {"binding", "rigid: each control point moves with its link (control_point_links)"},
            {"layout", layout_to_json(s.layout)},
            {"patches", patches}};
  if (!s.control_weights.empty()) {
    j["binding"] = "smooth: each control point blends its links' motions by its control_point_weights (indexed by "
                   "control_point_ids), the " + s.binding_mode + " weights of the polygon skin at its nearest point; "
                   "control_point_links is each one's nearest link (the thesis's rigid binding)";
    Json w = Json::array();
    for (const VertexWeights& v : s.control_weights) {
      Json one = Json::array();
      for (int k = 0; k < kMaxInfluences; ++k)
        if (v.link[k] >= 0) one.push_back({s.bones[v.link[k]], static_cast<double>(v.weight[k])});
      w.push_back(one);
    }
    j["control_point_weights"] = w;
  }
  return j;
}

std::string patches_obj(const PatchSkin& s) {
  std::string out = "# handskin Bezier patches (bicubic), palm frame, mm; shared control points listed once\n";
  char buf[160];
  for (const auto& p : s.control) {
    std::snprintf(buf, sizeof buf, "v %.6f %.6f %.6f\n", p.x(), p.y(), p.z());
    out += buf;
  }
  for (size_t f = 0; f < s.patches.size(); ++f) {
    out += "g " + s.patches[f].name + "\ncstype bezier\ndeg 3 3\nsurf 0 1 0 1";
    for (int j = 0; j < 4; ++j)  // OBJ lists a surface's control points u fastest
      for (int i = 0; i < 4; ++i) out += " " + std::to_string(s.patch_control[f][4 * i + j] + 1);
    out += "\nparm u 0 1\nparm v 0 1\nend\n";
  }
  return out;
}

const std::vector<std::string>& patch_output_names() {
  static const std::vector<std::string> names = {"patches.json", "patches.obj", "patches.ply", "patches.step", "report.html"};
  return names;
}

Json step_to_json(const StepSummary& s) {
  return {{"faces", s.faces},
          {"shells", s.shells},
          {"closed_shells", s.closed_shells},
          {"solids", s.solids},
          {"free_edges", s.free_edges},
          {"valid", s.valid},
          {"box_min_mm", {s.box.min().x(), s.box.min().y(), s.box.min().z()}},
          {"box_max_mm", {s.box.max().x(), s.box.max().y(), s.box.max().z()}}};
}

Json write_patch_files(OutputSet& out, const PatchStageResult& r, Json* step) {
  save_json(out.stage("patches.json"), patches_to_json(r.patches));
  write_file_atomic(out.stage("patches.obj"), patches_obj(r.patches));
  save_mesh(out.stage("patches.ply"), r.tessellation);
  // The STEP file, its figures read back by OCCT from the bytes written.
  const StepFile made = r.step ? StepFile{} : patches_step_file(r.patches.patches);
  const StepFile& file = r.step ? *r.step : made;
  write_file_atomic(out.stage("patches.step"), file.bytes);
  if (step) *step = step_to_json(file.shape);
  return {{"patches_json", out.final_path("patches.json")},
          {"patches_obj", out.final_path("patches.obj")},
          {"patches_ply", out.final_path("patches.ply")},
          {"patches_step", out.final_path("patches.step")}};
}

Json write_patch_report(OutputSet& out, const PatchStageResult& r, const Json& run_report,
                        const std::vector<ReportPicture>& posed) {
  write_file_atomic(out.stage("report.html"), patch_report_html(r, run_report, posed));
  return {{"report_html", out.final_path("report.html")}};
}

Json write_patch_outputs(OutputSet& out, const PatchStageResult& r, const Json& run_report,
                         const std::vector<ReportPicture>& posed, Json* step) {
  Json o = write_patch_files(out, r, step);
  o.update(write_patch_report(out, r, run_report, posed));
  return o;
}

}  // namespace handskin
