// run, register, skin: the pipeline's commands.
#include <filesystem>
#include <memory>

#include "cli/commands.hpp"
#include "core/errors.hpp"
#include "core/output_set.hpp"
#include "pipeline/layout_json.hpp"
#include "pipeline/options.hpp"
#include "pipeline/patch_stage.hpp"
#include "pipeline/stage_options.hpp"
#include "pipeline/registration_stage.hpp"
#include "pipeline/run.hpp"
#include "pipeline/run_folder.hpp"
#include "pipeline/skin_stage.hpp"
#include "scan/cubist_io.hpp"

namespace handskin::cli {

namespace {

// ---------------- run ----------------
struct RunArgs {
  RunInputs in;
  std::optional<double> patch_tolerance;
  std::string units = "mm", hand;
  std::string out_dir;
  bool force = false, strict = false;
};

void run_command(RunArgs a, const Progress& progress) {
  RunInputs& in = a.in;
  in.units = *parse_length_unit(a.units);  // checked by the parser
  if (!a.hand.empty()) in.hand = a.hand == "left" ? HandSide::Left : HandSide::Right;
  if (a.out_dir.empty()) throw UsageError("--out", "no output folder given");
  if (!in.pipeline_path.empty()) in.options = load_pipeline(in.pipeline_path);
  if (a.patch_tolerance) in.options.patches.tolerance_mm = *a.patch_tolerance;  // range checked by the parser
  const RunWritten w = run_into_folder(
      in, a.out_dir, output_options(a.force), [&](const std::string& m) { progress("run", m); },
      [&](const QualityGates& g) { settle_gates(g, a.strict, a.out_dir); });
  const Json& report = w.report;
  progress("run", "done in " + std::to_string(report["total_seconds"].get<double>()).substr(0, 5) + " s");
  std::printf("outputs in %s (report: %s)\n", a.out_dir.c_str(), (std::filesystem::path(a.out_dir) / "report.json").c_str());
  print_gates(w.gates);
}

// ---------------- skin ----------------
struct SkinArgs {
  std::string merged, rig, out = "skin", pipeline, truth;
  bool auto_rig = false, baseline = false, force = false, strict = false;
};

void skin_command(const SkinArgs& a, const Progress& progress) {
  OutputSet out(a.out, output_options(a.force));
  PipelineOptions po;
  if (!a.pipeline.empty()) po = load_pipeline(a.pipeline);
  {
    std::vector<std::string> plan = skin_output_plan(a.auto_rig || a.rig.empty(), po.skin.slices_json,
                                                     a.baseline || po.skin.baseline);
    plan.push_back("skin_report.json");
    std::vector<std::string> all = skin_output_names();
    all.push_back("skin_report.json");
    out.claim(plan, all);
  }
  SkinStageInputs in;
  if (!a.rig.empty()) {
    in.rig = load_palm_rig(a.rig);
    in.rig_name = a.rig;
  }
  in.auto_rig = a.auto_rig;
  in.baseline = a.baseline || po.skin.baseline;
  in.slices = po.skin.slices_json;
  if (!a.truth.empty()) in.truth = load_truth_skin(a.truth);  // before any work, so a bad file fails early
  progress("skin", "reading " + a.merged);
  MergedArrays m = read_merged(a.merged);
  in.points = std::move(m.points);
  in.normals = std::move(m.normals);
  in.sides = std::move(m.sides);
  in.cloud_name = a.merged;
  const SkinStageResult r = run_skin_stage(in, po, [&](const std::string& msg) { progress("skin", msg); });
  Json report = to_json(r);
  report["format"] = "handskin-skin-report/1";
  report["inputs"] = {{"merged", a.merged}, {"rig", a.rig.empty() ? "(placed automatically)" : a.rig},
                      {"pipeline", a.pipeline.empty() ? "(built-in defaults)" : a.pipeline}};
  relativise_input_paths(&report["inputs"], out.out_dir(), &report["inputs_absolute"]);
  report["outputs"] = write_skin_outputs(out, r, skin_preview_png(r));
  report["outputs"]["report"] = out.final_path("skin_report.json");
  relativise_output_paths(&report["outputs"], out.out_dir());
  GateInputs gi;
  gi.skin_file = out.staged_path("skin.ply");
  gi.skin_name = out.final_path("skin.ply");
  gi.cloud = &in.points;
  const QualityGates gates = check_gates(gi, po);
  describe_written_skin(gates, &report);
  put_gates(gates, &report);
  save_json(out.stage("skin_report.json"), report);
  settle_gates(gates, a.strict, a.out);
  out.commit();
  const MeshHealth& h = r.skin.health;
  std::printf("skin: %zu vertices, %zu triangles, watertight %s, cloud to skin mean %.3f p95 %.3f max %.2f mm, %.0f ms -> %s\n",
              h.vertices, h.faces, r.skin.watertight() ? "yes" : "no", r.cloud_to_skin.mean, r.cloud_to_skin.p95,
              r.cloud_to_skin.max, 1000 * r.build_seconds, out.final_path("skin_report.json").c_str());
  if (r.against_given)
    std::printf("automatic skeleton: mean joint error %.2f mm (max %.2f, %s) against %s\n", r.against_given->mean_mm,
                r.against_given->max_mm, r.against_given->worst_joint.c_str(), a.rig.c_str());
  if (r.truth)
    std::printf("against the truth: skin->truth mean %.3f p95 %.3f mm; truth->skin within 1 mm %.2f %%\n",
                r.truth->skin_to_truth.mean, r.truth->skin_to_truth.p95, 100 * r.truth->truth_to_skin.within_1mm);
  print_gates(gates);
}

// ---------------- register ----------------
struct RegisterArgs {
  std::string back, palm, out = "registration", markers, pipeline, truth;
  bool no_refine = false, force = false, strict = false;
};

void register_command(const RegisterArgs& a, const Progress& progress) {
  OutputSet out(a.out, output_options(a.force));
  PipelineOptions po;
  if (!a.pipeline.empty()) po = load_pipeline(a.pipeline);
  out.claim(registration_output_names());
  RegistrationOptions ro = registration_options(po);
  if (a.no_refine) ro.refine_enabled = false;
  const RangeScan back = load_scan_side(a.back, ScanSide::Back, "--back");
  const RangeScan palm = load_scan_side(a.palm, ScanSide::Palm, "--palm");
  MarkerHints hints;
  if (!a.markers.empty()) hints = load_marker_hints(a.markers);
  std::optional<TruthSkin> truth;  // read before any work so a bad file fails early
  if (!a.truth.empty()) truth = load_truth_skin(a.truth);
  const Registration reg = register_scans(back, palm, a.back + ".png", a.palm + ".png", ro,
                                          a.markers.empty() ? nullptr : &hints,
                                          [&](const std::string& m) { progress("register", m); });
  for (const auto& w : reg.warnings) progress("register", "warning: " + w);
  Json report = registration_to_json(reg);
  if (truth) report["against_truth"] = registration_against_truth(reg, *truth);
  GateInputs gi;
  gi.registration = &reg;
  const QualityGates gates = check_gates(gi, po);
  put_gates(gates, &report);
  write_registration_outputs(out, reg, report, merged_preview_png(reg));
  settle_gates(gates, a.strict, a.out);
  out.commit();
  const RegistrationFigures& f = reg.figures;
  std::printf("%s: %s, %zu of %zu/%zu markers matched (radius %.3f mm, %s), marker rms %.4f mm (refined %.4f mm), %zu "
              "merged points\n",
              reg.warnings.empty() ? "ok" : "ok_with_warnings", reg.refined ? "refined" : "markers", f.markers_matched,
              f.markers_back, f.markers_palm, reg.marker_radius_mm, f.radius_estimated ? "estimated" : "given",
              f.marker_only_rms_mm, f.refined_rms_mm, f.merged_points);
  if (f.rotation_sigma_deg > 0)
    std::printf("its own error estimate (1 sigma): rotation %.4f deg, skin displacement %.4f mm\n", f.rotation_sigma_deg,
                f.displacement_sigma_mm);
  const Json& r = report;
  if (r.contains("against_truth"))
    std::printf("against truth: rotation %.5f deg, skin mean %.4f mm, max %.4f mm\n",
                r["against_truth"]["chosen"]["rotation_deg"].get<double>(),
                r["against_truth"]["chosen"]["skin_mean_mm"].get<double>(),
                r["against_truth"]["chosen"]["skin_max_mm"].get<double>());
}

// ---------------- patches ----------------
struct PatchesArgs {
  std::string skin_dir, rig, out, pipeline, truth, layout;
  std::optional<long> count;
  std::optional<double> patch_tolerance;
  bool force = false, strict = false;
};

void patches_command(const PatchesArgs& a, const Progress& progress) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(a.skin_dir))
    throw InputError(a.skin_dir, fs::exists(a.skin_dir) ? "is not a folder (--skin-dir takes a run's output folder)"
                                                        : "no such folder (--skin-dir takes a run's output folder)");
  // Its own folder by default: report.json there is the patches' report, not the run's.
  const std::string out_dir = a.out.empty() ? (fs::path(a.skin_dir) / "patches").string() : a.out;
  OutputSet out(out_dir, output_options(a.force));
  PipelineOptions po;
  if (!a.pipeline.empty()) po = load_pipeline(a.pipeline);
  {
    std::vector<std::string> names = patch_output_names();
    names.push_back("report.json");
    out.claim(names);
  }
  if (a.patch_tolerance) po.patches.tolerance_mm = *a.patch_tolerance;  // range checked by the parser
  if (a.count) {
    po.patches.count = *a.count;
    std::string err;
    if (!po.IsValid(&err)) throw UsageError("--count", err);
  }
  const std::string rig_path = run_folder_rig(a.skin_dir, a.rig);
  const Rig rig = load_palm_rig(rig_path);
  std::optional<TruthSkin> truth;
  if (!a.truth.empty()) truth = load_truth_skin(a.truth);
  std::optional<PatchLayout> layout;
  if (!a.layout.empty()) layout = parse_patch_layout(load_json_object(a.layout), a.layout);
  const RunFolderPatches p = patches_for_run_folder(a.skin_dir, rig, rig_path, po, layout, a.layout, truth ? &*truth : nullptr,
                                                    [&](const std::string& m) { progress("patches", m); });
  const PatchStageResult& r = p.result;
  const std::string& merged = p.merged;
  Json report = to_json(r);
  report["format"] = "handskin-patches-report/1";
  report["inputs"] = {{"merged", merged}, {"rig", rig_path}, {"pipeline", a.pipeline.empty() ? "(built-in defaults)" : a.pipeline}};
  relativise_input_paths(&report["inputs"], out.out_dir(), &report["inputs_absolute"]);
  GateInputs gi;
  gi.patches = &r;
  const QualityGates gates = check_gates(gi, po);
  put_gates(gates, &report);
  Json step;
  report["outputs"] = write_patch_outputs(out, r, Json{{"gates", report["gates"]}}, {}, &step);
  report["patches_step"] = step;
  report["outputs"]["report"] = out.final_path("report.json");
  relativise_output_paths(&report["outputs"], out.out_dir());
  save_json(out.stage("report.json"), report);
  settle_gates(gates, a.strict, out_dir);
  out.commit();
  const PatchSkin& s = r.patches;
  std::printf("patches: %zu bicubic patches, %zu control points; data to surface: palm mean %.3f max %.2f mm, back mean "
              "%.3f max %.2f mm; G0 gap %.1e mm, G1 jump median %.2f deg; %zu correction rounds, %.0f ms -> %s\n",
              s.patches.size(), s.control_points, s.side[0].mean, s.side[0].max, s.side[1].mean, s.side[1].max,
              s.g0_gap_mm, s.g1_median_deg, s.max_update_per_round.size(), 1000 * s.seconds,
              out.final_path("report.json").c_str());
  std::printf("against the polygon skin: surface->skin mean %.3f p95 %.3f max %.2f mm\n", r.surface_to_skin.mean,
              r.surface_to_skin.p95, r.surface_to_skin.max);
  if (const auto note = layout_note(s)) std::printf("%s\n", note->c_str());
  if (const auto note = separation_note(s)) std::printf("patches: %s\n", note->c_str());
  if (const auto note = fairness_note(s)) std::printf("patches: %s\n", note->c_str());
  if (r.surface_to_truth)
    std::printf("against the truth: surface->truth mean %.3f p95 %.3f mm; truth->surface within 1 mm %.2f %%\n",
                r.surface_to_truth->mean, r.surface_to_truth->p95, 100 * r.truth_to_surface->within_1mm);
  print_gates(gates);
}

}  // namespace

void add_pipeline_commands(CLI::App& app, const Progress& progress, Commands* out) {
  auto ra = std::make_shared<RunArgs>();
  RunInputs* in = &ra->in;
  auto* run = app.add_subcommand("run", "Run the pipeline on a back/palm scan pair, or on a cloud from any scanner (and a "
                                        "rig, or none)");
  auto* back = run->add_option("--back", in->back_stem, "Back scan: its stem (<stem>.png + <stem>.json) or either file")
                   ->transform(scan_stem_option());
  auto* palm = run->add_option("--palm", in->palm_stem, "Palm scan: its stem or either file")
                   ->transform(scan_stem_option());
  auto* cloud = run->add_option("--cloud", in->clouds,
                                "Instead of --back/--palm: a hand's cloud from any scanner (.ply, .pcd, .obj, .stl, .off, "
                                ".xyz, .pts, .txt; docs/clouds.md): one merged scan, or given twice, two halves (e.g. the "
                                "back views and the palm views), the first registered into the second without markers")
                    ->expected(1)
                    ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  run->add_option("--units", ra->units, "--cloud: the cloud's units (mm, cm, m or in)")
      ->check(CLI::IsMember({"mm", "cm", "m", "in"}))
      ->capture_default_str();
  run->add_option("--hand", ra->hand, "--cloud: which hand it is (left or right), when the fingers are too straight to tell "
                                      "the palm from the back and there is no --rig")
      ->check(CLI::IsMember({"left", "right"}));
  run->add_option("--rig", in->rig_path, "hand-rig/1 file, joints in the palm frame (default: placed automatically)");
  run->add_flag("--auto-rig", in->auto_rig, "Place the skeleton automatically even with --rig, and report its joint error");
  run->add_option("--out", ra->out_dir, "Output folder (created if needed; only files handskin wrote there and that are unchanged "
                                        "are replaced, all at once when every stage succeeded)")
      ->required();
  run->add_option("--pipeline", in->pipeline_path, "Pipeline parameters (default: built-in = pipelines/cubist.json)");
  run->add_option("--markers", in->markers_path,
                  "Manual marker positions (handskin-markers/1) for scans whose bumps the detector misses");
  run->add_option("--truth", in->truth_path, "truth.json of a synthetic pair: add the errors against it to the report");
  run->add_option("--posture-model", in->posture_model,
                  "Posture model skin.glb carries (hand-posture/1 file or builtin:<name>)")
      ->capture_default_str();
  run->add_option("--back-photo", in->back_photo,
                  "The back scan's photo (8-bit RGB PNG on the scan's grid) for the texture (default: <back stem>.photo.png if "
                  "both photos are there)");
  run->add_option("--palm-photo", in->palm_photo, "The palm scan's photo (default: <palm stem>.photo.png)");
  run->add_flag("--force", ra->force, "Move things of yours in the way of an output (same name, not written by "
                                      "handskin) aside into <out>/handskin-backup-<date>/ instead of refusing");
  run->add_flag("--strict", ra->strict, "A failed quality gate (report.json \"gates\") writes nothing and exits 3");
  run->add_option("--patch-tolerance", ra->patch_tolerance,
                  "Split the patches whose measured points lie farther than this (mm, [0.001, 100]), locally with exact "
                  "T-junctions, and fit again, up to patches.max_patches (300) patches (default: patches.tolerance_mm, "
                  "none: the thesis's layout)")
      ->check(CLI::Range(1e-3, 100.0));
  run->add_flag("--baseline", in->baseline, "Also a Poisson reconstruction of the cloud (baseline.ply and its figures, for comparison; ~0.5 s)");
  run->add_flag("--scan-clouds", in->scan_clouds,
                "Also back.ply and palm.ply: each scan's measured points in its own scanner frame (6 MB; `convert` makes them too)");
  run->parse_complete_callback([run, back, palm, cloud] {
    if (cloud->count() > 2) throw CLI::ValidationError("--cloud", "one merged cloud or two halves, not " + std::to_string(cloud->count()));
    if (cloud->count() > 0) {
      for (const char* scan_only : {"--back", "--palm", "--markers", "--back-photo", "--palm-photo", "--scan-clouds"})
        if (run->count(scan_only) > 0) throw CLI::ValidationError(scan_only, "is for a scan pair, not with --cloud");
    } else {
      for (const char* cloud_only : {"--units", "--hand"})
        if (run->count(cloud_only) > 0) throw CLI::ValidationError(cloud_only, "is for --cloud");
      if (back->count() == 0 || palm->count() == 0)
        throw CLI::RequiredError("--back and --palm (a scan pair), or --cloud (any scanner's cloud),");
    }
  });
  out->push_back({run, [ra, &progress] { run_command(*ra, progress); }});

  auto rg = std::make_shared<RegisterArgs>();
  auto* regc = app.add_subcommand("register", "Register the back scan into the palm scan's frame and merge them");
  regc->add_option("--back", rg->back, "Back scan: its stem (<stem>.png + <stem>.json) or either file")
      ->transform(scan_stem_option())
      ->required();
  regc->add_option("--palm", rg->palm, "Palm scan: its stem or either file")->transform(scan_stem_option())->required();
  regc->add_option("--out", rg->out, "Output folder: registration.json, merged.ply, merged.png")->capture_default_str();
  regc->add_option("--markers", rg->markers, "Manual marker positions (handskin-markers/1), replacing detection");
  regc->add_option("--pipeline", rg->pipeline, "Pipeline parameters (markers, registration sections)");
  regc->add_option("--truth", rg->truth, "truth.json of a synthetic pair: add the errors against it to the report");
  regc->add_flag("--force", rg->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  regc->add_flag("--strict", rg->strict, "A failed quality gate (the registration's own 1 sigma over its limit) writes nothing and exits 3");
  regc->add_flag("--no-refine", rg->no_refine, "Keep the marker-only fit (no joint sphere/ICP refinement)");
  out->push_back({regc, [rg, &progress] { register_command(*rg, progress); }});

  auto sk = std::make_shared<SkinArgs>();
  auto* skinc = app.add_subcommand("skin", "Skin mesh from a merged cloud and a rig: strips between planes, closed (thesis §4.1.2-4.1.3)");
  skinc->add_option("--merged", sk->merged, "Merged cloud (merged.ply from handskin register)")->required();
  skinc->add_option("--rig", sk->rig, "hand-rig/1 file, joints in the palm frame (default: placed automatically)");
  skinc->add_flag("--auto-rig", sk->auto_rig, "Place the skeleton automatically even with --rig, and report its joint error");
  skinc->add_option("--out", sk->out, "Output folder: skin.ply, skin.obj, skin.png, slices.json, skin_report.json "
                                      "(+ rig_auto.json, baseline.ply)")
      ->capture_default_str();
  skinc->add_option("--pipeline", sk->pipeline, "Pipeline parameters (slicing, skin sections)");
  skinc->add_option("--truth", sk->truth, "truth.json of a synthetic pair: add the errors against its true skin");
  skinc->add_flag("--force", sk->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  skinc->add_flag("--strict", sk->strict, "A failed quality gate (skin_report.json \"gates\") writes nothing and exits 3");
  skinc->add_flag("--baseline", sk->baseline, "Also a Poisson reconstruction of the cloud (baseline.ply and its figures, for comparison; ~0.5 s)");
  out->push_back({skinc, [sk, &progress] { skin_command(*sk, progress); }});

  auto pa = std::make_shared<PatchesArgs>();
  auto* pc = app.add_subcommand("patches", "Bicubic Bezier patches over a closed quad layout of the whole skin, and the fitting-error report (thesis §4.1.4)");
  pc->add_option("--skin-dir", pa->skin_dir, "Output folder of run (or of register + skin): merged.ply, the rig, and the skin fitted (skin.ply with skin_grid.json; built again on the rig without them)")->required();
  pc->add_option("--rig", pa->rig, "The skin's rig (default: rig_auto.json there, else the rig its report.json names)");
  pc->add_option("--out", pa->out, "Output folder: patches.json, patches.obj, patches.ply, report.json, report.html "
                                   "(default: <skin-dir>/patches)");
  pc->add_option("--pipeline", pa->pipeline, "Pipeline parameters (the patches section; slicing and skin when the skin is built again)");
  pc->add_option("--patch-tolerance", pa->patch_tolerance,
                 "Split the patches whose measured points lie farther than this (mm, [0.001, 100]), locally with exact "
                 "T-junctions, and fit again, up to patches.max_patches (300) patches (default: patches.tolerance_mm, none)")
      ->check(CLI::Range(1e-3, 100.0));
  pc->add_option("--count", pa->count, "Patches wanted, [24, 1500] (default: patches.count, 96); the hand's layout has 98, split k x k: 98 k^2 nearest");
  pc->add_option("--layout", pa->layout,
                 "A layout given back: a patches.json (or handskin-patch-layout/1) whose 'layout' (corners, four-sided faces) is fitted on instead of the hand's; --count is then ignored");
  pc->add_flag("--strict", pa->strict, "A failed quality gate (report.json \"gates\") writes nothing and exits 3");
  pc->add_flag("--force", pa->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  pc->add_option("--truth", pa->truth, "truth.json of a synthetic pair: add the surface's distances to the true skin");
  out->push_back({pc, [pa, &progress] { patches_command(*pa, progress); }});
}

}  // namespace handskin::cli
