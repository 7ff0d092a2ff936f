#include "pipeline/run.hpp"

#include <chrono>
#include <filesystem>
#include <future>

#include "core/errors.hpp"
#include "core/atomic_file.hpp"
#include "core/png_io.hpp"
#include "core/rig.hpp"
#include "posture/solver.hpp"
#include "rigging/binding.hpp"
#include "rigging/pose.hpp"
#include "export/step.hpp"
#include "render/preview.hpp"
#include "pipeline/gates.hpp"
#include "pipeline/registration_stage.hpp"
#include "pipeline/run_folder.hpp"
#include "pipeline/stage_options.hpp"
#include "core/parallel_jobs.hpp"
#include "core/threads.hpp"

namespace handskin {

namespace {

// A stage's progress as the run's, its name before each line; a stage's warning stays one
// ("warning: skin: …"), so that -q still shows it.
ProgressFn staged(const ProgressFn& progress, const std::string& stage) {
  return [&progress, stage](const std::string& m) {
    if (m.rfind("warning: ", 0) == 0)
      progress("warning: " + stage + ": " + m.substr(9));
    else
      progress(stage + ": " + m);
  };
}
class StageTimer {
 public:
  StageTimer() : t0_(std::chrono::steady_clock::now()) {}
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count(); }

 private:
  std::chrono::steady_clock::time_point t0_;
};

ScanFigures scan_figures(const RangeScan& scan, const std::string& stem) {
  return {stem, scan.meta.side, scan.meta.scanlines, scan.meta.points, scan.count_valid()};
}

Json to_json(const ScanFigures& s) {
  const size_t total = static_cast<size_t>(s.scanlines) * s.points;
  return {{"stem", s.stem}, {"side", side_name(s.side)}, {"scanlines", s.scanlines}, {"points", s.points},
          {"returns", s.returns}, {"no_return", total - s.returns}};
}
}  // namespace

namespace {
// The rigged skin in the report's postures: open (the scan's), relaxed, a fist, and the
// solver's answer to a 75° little-finger MCP alone; the last two also with the thesis's rigid
// binding. Side views, 360 × 270: the captions, the posed meshes and how to draw them.
struct PosedShots {
  std::vector<std::string> captions;
  std::vector<Mesh> meshes;
  RenderOptions view;
};
PosedShots posed_shots(const RiggedSkin& s, float texture_weight) {
  const PostureSolver solver(s.model);
  BindingOptions rb;
  rb.mode = "rigid";
  const SkinBinding rigid = bind_skin(s.mesh, bones_from_rig(s.rig), rb);
  const SkinPoser smooth_poser(s.mesh.vertices, s.mesh.faces, s.binding, s.rig, true),
      rigid_poser(s.mesh.vertices, s.mesh.faces, rigid, s.rig, false);
  const PostureInputs fist = fist_inputs();
  PostureInputs l2;
  l2.pins.emplace_back(dof_index("little.mcp.flex").value(), 75.0);
  const Angles open{};
  const Angles relaxed = solver.solve(PostureInputs{}).angles, closed = solver.solve(fist).angles, little = solver.solve(l2).angles;
  RenderOptions ro;
  ro.width = 360;
  ro.height = 270;
  ro.view = named_view("side") * hand_frame_from_rig(s.rig).linear();
  if (!s.texture.empty()) ro.texture = &s.texture, ro.texture_weight = texture_weight;
  const std::vector<std::tuple<const char*, const Angles*, const SkinBinding*>> shown = {
      {"open (the scan posture)", &open, &s.binding},
      {"relaxed", &relaxed, &s.binding},
      {"fist", &closed, &s.binding},
      {"little MCP 75° alone: the solver fills in the rest", &little, &s.binding},
      {"fist, rigid binding (the thesis)", &closed, &rigid},
      {"little MCP 75°, rigid binding (the thesis)", &little, &rigid}};
  // On every thread, each into its own slot (the crease guard's untangling takes ~15 ms a
  // posture); the pictures are drawn with skin.png (run_pipeline). The scan's posture is the
  // skin as built: posed at zero angles it came back within 3e-7 mm of it, after the same
  // ~15 ms of untangling a skin the skin stage found free of crossings.
  std::vector<Mesh> posed(shown.size());
  posed[0] = Mesh{s.mesh.vertices, s.mesh.faces};
  parallel_jobs(static_cast<long>(shown.size()) - 1, [&](long j) {
    const long k = j + 1;
    const auto& [caption, angles, binding] = shown[static_cast<size_t>(k)];
    const bool is_rigid = binding == &rigid;
    posed[static_cast<size_t>(k)] = Mesh{
        (is_rigid ? rigid_poser : smooth_poser).pose(*angles, is_rigid ? Blend::Linear : Blend::DualQuaternion), s.mesh.faces};
  });
  PosedShots out;
  for (const auto& shot : shown) out.captions.push_back(std::get<0>(shot));
  out.meshes = std::move(posed);
  out.view = ro;
  return out;
}
}  // namespace

namespace {
// A scan pair read and checked (the first inputs read, so their errors come first).
std::pair<RangeScan, RangeScan> read_scans(const RunInputs& in) {
  RangeScan back = load_scan_side(in.back_stem, ScanSide::Back, "--back");
  RangeScan palm = load_scan_side(in.palm_stem, ScanSide::Palm, "--palm");
  for (const auto* s : {&back, &palm})
    if (static_cast<long>(s->count_valid()) < in.options.ingest.min_returns)
      throw InputError((s == &back ? in.back_stem : in.palm_stem) + ".png",
                       "only " + std::to_string(s->count_valid()) + " measured samples (ingest.min_returns is " +
                           std::to_string(in.options.ingest.min_returns) + ")");
  return {std::move(back), std::move(palm)};
}

// Registration of a scan pair: the back scan into the palm frame. Returns the merged arrays
// the skin takes.
MergedArrays register_pair(const RunInputs& in, const RangeScan& back, const RangeScan& palm, const MarkerHints& hints,
                           const std::optional<TruthSkin>& truth, RunResult* Rp, const ProgressFn& progress) {
  RunResult& R = *Rp;
  const StageTimer t_reg;
  R.registration =
      register_scans(back, palm, in.back_stem + ".png", in.palm_stem + ".png", registration_options(in.options),
                     in.markers_path.empty() ? nullptr : &hints,
                     staged(progress, "registration"));
  for (const auto& w : R.registration.warnings) progress("warning: " + w);
  if (truth) R.registration_truth = registration_against_truth(R.registration, *truth);
  MergedArrays merged = merged_arrays(*R.registration.merged);  // the preview's and the skin's
  R.registration_seconds = t_reg.seconds();
  return merged;
}
}  // namespace

RunResult run_pipeline(const RunInputs& in, const ProgressFn& progress) {
  const StageTimer total;
  RunResult R;
  R.inputs = in;
  const bool clouds = !in.clouds.empty();
  // Open CASCADE (for patches.step) loads beside the first stages. (The run's pictures are
  // drawn on the CPU: it loads no OpenGL.)
  if (thread_count() > 1 && in.options.patches.enabled) preload_step();

  // --- ingest: read and check every input before any work ---
  const StageTimer t_ingest;
  std::optional<std::pair<RangeScan, RangeScan>> scans;
  if (clouds) {
    progress("ingest: reading the rig");
  } else {
    progress("ingest: reading scans and rig");
    scans = read_scans(in);
  }
  SkinStageInputs si;
  if (!in.rig_path.empty()) {
    // A cloud's rig is in the cloud's own frame, whatever its `frame` label says (a `synth
    // hand` rig, "hand", serves a cloud sampled from its hand.ply); whether it fits the cloud
    // is checked against the cloud (skin stage). A scan pair's is in the palm scan's frame.
    si.rig = clouds ? load_rig(in.rig_path) : load_palm_rig(in.rig_path);
    si.rig_name = in.rig_path;
  }
  std::optional<TruthSkin> truth;
  if (!in.truth_path.empty()) truth = load_truth_skin(in.truth_path);
  MarkerHints hints;
  if (!in.markers_path.empty()) hints = load_marker_hints(in.markers_path);
  const PostureModel posture_model = load_model(in.posture_model);
  const PostureSolver model_check(posture_model);  // refused now, not after the stages
  MergedArrays merged;
  std::optional<ScanPhoto> back_photo, palm_photo;
  if (clouds) {
    // --- a cloud from any scanner: read, cleaned, oriented (docs/clouds.md) ---
    CloudStageInputs ci;
    ci.files = in.clouds;
    ci.units = in.units;
    ci.hand = in.hand;
    ci.rig = si.rig ? &*si.rig : nullptr;
    R.cloud = run_cloud_stage(ci, staged(progress, "cloud"));
    if (truth && R.cloud->halves) R.registration_truth = halves_against_truth(*R.cloud, *truth);
    merged = R.cloud->merged();
    si.sheets = R.cloud->sheets;
    R.texture_note = "no texture: a cloud has no photos";
    si.cloud_name = in.clouds.size() == 2 ? "the halves " + in.clouds[0] + " and " + in.clouds[1] + " merged" : in.clouds[0];
  } else {
    const auto& [back, palm] = *scans;
    // The photos: given, or found beside the scans.
    if (const auto photos = run_photo_paths(in, &R.texture_note)) {
      back_photo = load_scan_photo(photos->first, back);
      palm_photo = load_scan_photo(photos->second, palm);
    }
    R.back = scan_figures(back, in.back_stem);
    R.palm = scan_figures(palm, in.palm_stem);
    if (in.scan_clouds) {
      R.back_cloud = dense_copy(*scan_to_organized_cloud(back));
      R.palm_cloud = dense_copy(*scan_to_organized_cloud(palm));
    }
    R.ingest_seconds = t_ingest.seconds();
    merged = register_pair(in, back, palm, hints, truth, &R, progress);
    si.cloud_name = "merged cloud of " + in.back_stem + " and " + in.palm_stem;
  }

  // The merged cloud's picture (its 143 000 splats, render/splats.cpp, ~60 ms): with a rig
  // given, beside the skin's first steps (SkinStageInputs::beside_build); with the skeleton
  // placed automatically, on a thread of its own beside the skin stage. Every picture starts
  // from the same OpenGL state, whichever thread draws it: the same bytes on any thread.
  std::string merged_picture;
  std::future<std::string> merged_png;
  {
    auto draw = [m = merged, markers = clouds ? std::vector<Eigen::Vector3d>{} : R.registration.markers_palm] {
      return merged_preview_png(m, markers);
    };
    if (si.rig && !in.auto_rig)
      si.beside_build = [&merged_picture, draw = std::move(draw)] { merged_picture = draw(); };
    else
      merged_png = std::async(side_launch(), std::move(draw));
  }

  // --- skin: strips from the merged cloud, closed into one mesh (docs/skin.md) ---
  si.points = std::move(merged.points);
  si.normals = std::move(merged.normals);
  si.sides = std::move(merged.sides);
  si.auto_rig = in.auto_rig;
  si.baseline = in.baseline || in.options.skin.baseline;
  si.slices = in.options.skin.slices_json;
  si.truth = truth;
  R.skin = run_skin_stage(si, in.options, staged(progress, "skin"));

  // --- patches: bicubic Bézier patches over the whole skin (docs/patches.md) ---
  if (in.options.patches.enabled) {
    progress("patches: fitting and correcting the parameters");
    try {
      R.patches = run_patch_stage(R.skin.skin, R.skin.rig, si.points, si.sides, patch_options(in.options),
                                  truth ? &*truth : nullptr, static_cast<int>(in.options.patches.error_grid),
                                  /*pictures=*/false);
    } catch (const InputError& e) {
      // The skin before it stands; say how to have it without the patches.
      throw InputError(e.where(), e.detail() + " (the skin itself was built: set patches.enabled to false in a "
                                                "--pipeline file to run without the patches)");
    }
    if (const auto note = layout_note(R.patches->patches)) progress("patches: " + *note);
    if (const auto note = separation_note(R.patches->patches)) progress("patches: " + *note);
    if (const auto note = fairness_note(R.patches->patches)) progress("patches: " + *note);
  }
  // patches.step (Open CASCADE: sewing, writing, reading back, ~0.2 s of CPU) beside the rigging,
  // the texture and the pictures; from a copy of the patches (the rigging adds their weights).
  std::future<StepFile> patches_step;
  if (R.patches)
    patches_step = std::async(side_launch(), [patches = R.patches->patches.patches, &seconds = R.step_seconds] {
      const StageTimer t;
      StepFile f = patches_step_file(patches);
      seconds = t.seconds();
      return f;
    });

  // --- rigging: the skin bound to the skeleton, with the posture model (docs/rigging.md) ---
  progress(std::string("rigging: ") + (in.options.rigging.smooth ? "bone-heat weights" : "rigid binding"));
  const StageTimer t_rig;
  const Mesh& mesh = R.skin.skin.mesh;
  R.rigged.mesh = mesh;
  R.rigged.rig = R.skin.rig;
  R.rigged.binding = bind_skin(mesh, bones_from_rig(R.skin.rig), binding_options(in.options));
  // The patches' control points take the skin's weights (a posture moves them as it moves the skin).
  if (R.patches) bind_patch_controls(&R.patches->patches, mesh, R.rigged.binding);
  R.rigged.model = posture_model;
  R.rigging_seconds = t_rig.seconds();

  // --- texture: the skin's colour from the two photos (docs/rigging.md "Texture") ---
  if (back_photo && palm_photo) {
    progress("texture: projecting the back and palm photos onto the skin");
    TextureOptions to;
    to.size = static_cast<int>(in.options.texture.size);
    to.blend_deg = in.options.texture.blend_deg;
    R.texture = bake_skin_texture(R.rigged.mesh.vertices, R.rigged.mesh.faces, *back_photo, *palm_photo, R.registration.back_to_palm,
                                  R.registration.markers_palm, R.registration.marker_radius_mm, to);
    R.rigged.texture = std::move(R.texture->map);
    // Encoded once: texture.png and the glb's image are the same bytes.
    R.rigged.texture_png = encode_rgb8_png(R.rigged.texture.size, R.rigged.texture.size, R.rigged.texture.rgb);
  } else {
    progress(R.texture_note);
  }
  // --- the pictures and the glb: everything the writer only puts into files ---
  progress("pictures: the skin, its postures and the patches; skin.glb");
  const StageTimer t_pictures;
  // The patches' pictures on a thread of their own beside the skin's, the posed ones and the glb.
  std::future<PatchReportPictures> patch_pictures;
  if (R.patches)
    patch_pictures = std::async(side_launch(), [&patches = R.patches->patches, &rig = R.skin.rig] {
      return patch_report_pictures(patches, rig);
    });
  const float texture_weight = static_cast<float>(in.options.texture.weight);
  // skin.png and, for report.html (which the patch stage writes), the posed skins: the postures
  // first, then the seven pictures at once, each drawn into its own slot (skin.png, the
  // largest, first): the same bytes with any number of threads.
  PosedShots posed;
  if (R.patches) posed = posed_shots(R.rigged, texture_weight);
  std::vector<std::string> pictures(1 + posed.meshes.size());
  parallel_jobs(static_cast<long>(pictures.size()), [&](long k) {
    pictures[static_cast<size_t>(k)] = k == 0 ? skin_preview_png(R.skin, R.texture ? &R.rigged.texture : nullptr, texture_weight)
                                              : render_mesh_png({&posed.meshes[static_cast<size_t>(k) - 1]}, posed.view);
  });
  R.skin_png = std::move(pictures[0]);
  for (size_t k = 0; k < posed.meshes.size(); ++k) R.posed.push_back({posed.captions[k], std::move(pictures[k + 1])});
  const std::vector<unsigned char> glb = skin_glb(R.rigged);
  R.glb.assign(glb.begin(), glb.end());
  if (R.patches) R.patches->pictures = patch_pictures.get(), R.patches->step = patches_step.get();
  R.merged_png = merged_png.valid() ? merged_png.get() : std::move(merged_picture);
  R.pictures_seconds = t_pictures.seconds();
  R.seconds = total.seconds();
  return R;
}

std::optional<std::pair<std::string, std::string>> run_photo_paths(const RunInputs& in, std::string* note) {
  if (!in.clouds.empty()) {
    if (note) *note = "no texture: a cloud has no photos";
    return std::nullopt;
  }
  if (!in.options.texture.enabled) {
    if (note) *note = "no texture: texture.enabled is false";
    return std::nullopt;
  }
  const auto exists = [](const std::string& f) { return std::filesystem::exists(f); };
  const std::string bp = in.back_photo.empty() ? in.back_stem + ".photo.png" : in.back_photo;
  const std::string pp = in.palm_photo.empty() ? in.palm_stem + ".photo.png" : in.palm_photo;
  const bool given = !in.back_photo.empty() || !in.palm_photo.empty();
  if (given || (exists(bp) && exists(pp))) return std::pair{bp, pp};
  if (note) *note = "no texture: " + (exists(bp) ? pp : bp) + " not found";
  return std::nullopt;
}

std::vector<std::string> run_output_plan(const RunInputs& in) {
  if (!in.clouds.empty()) {
    std::vector<std::string> n = {"report.json", "skin.glb", "merged.ply", "merged.png"};
    if (in.clouds.size() == 2) n.push_back("registration.json");
    const auto skin = skin_output_plan(in.auto_rig || in.rig_path.empty(), in.options.skin.slices_json,
                                       in.baseline || in.options.skin.baseline);
    n.insert(n.end(), skin.begin(), skin.end());
    if (in.options.patches.enabled) n.insert(n.end(), patch_output_names().begin(), patch_output_names().end());
    return n;
  }
  std::vector<std::string> n = {"report.json", "skin.glb"};
  if (in.scan_clouds) n.insert(n.end(), {"back.ply", "palm.ply"});
  if (run_photo_paths(in)) n.insert(n.end(), {"texture.png", "skin.mtl"});
  n.insert(n.end(), registration_output_names().begin(), registration_output_names().end());
  const auto skin = skin_output_plan(in.auto_rig || in.rig_path.empty(), in.options.skin.slices_json,
                                     in.baseline || in.options.skin.baseline);
  n.insert(n.end(), skin.begin(), skin.end());
  if (in.options.patches.enabled) n.insert(n.end(), patch_output_names().begin(), patch_output_names().end());
  return n;
}

std::vector<std::string> run_output_names() {
  std::vector<std::string> n = {"back.ply", "palm.ply", "report.json", "skin.glb", "texture.png"};
  n.insert(n.end(), registration_output_names().begin(), registration_output_names().end());
  n.insert(n.end(), skin_output_names().begin(), skin_output_names().end());
  n.insert(n.end(), patch_output_names().begin(), patch_output_names().end());
  return n;
}

RunWritten write_run_outputs(OutputSet& out, const RunResult& r) {
  const StageTimer t_write;
  const RunInputs& in = r.inputs;
  Json outputs;
  if (r.cloud) {
    if (r.cloud->halves) {
      Json reg = halves_registration_json(*r.cloud);
      if (r.registration_truth) reg["against_truth"] = *r.registration_truth;
      save_json(out.stage("registration.json"), reg);
      outputs["registration"] = out.final_path("registration.json");
    }
    save_merged(out.stage("merged.ply"), *merged_cloud(r.cloud->merged()));
    outputs["merged_cloud"] = out.final_path("merged.ply");
    write_file_atomic(out.stage("merged.png"), r.merged_png);
    outputs["merged_preview"] = out.final_path("merged.png");
  } else {
    if (r.back_cloud && r.palm_cloud) {  // --scan-clouds
      save_cloud(out.stage("back.ply"), *r.back_cloud);
      outputs["back_cloud"] = out.final_path("back.ply");
      save_cloud(out.stage("palm.ply"), *r.palm_cloud);
      outputs["palm_cloud"] = out.final_path("palm.ply");
    }
    Json reg_report = registration_to_json(r.registration);
    if (r.registration_truth) reg_report["against_truth"] = *r.registration_truth;
    outputs.update(write_registration_outputs(out, r.registration, reg_report, r.merged_png));
  }
  // The quality gates, on the skin as written (skin.ply read back) and the other outputs: on a
  // thread of their own from skin.ply's staging on (reading it back, its crossings and the
  // cloud's distance to it, ~25 ms on the fixture), beside the writing of the other files but
  // report.html, which shows them. The thread reads only what is set here before it starts.
  const MergedArrays merged = r.cloud ? MergedArrays{} : merged_arrays(*r.registration.merged);
  GateInputs gi;
  gi.cloud = r.cloud ? &r.cloud->prepared.points : &merged.points;
  if (r.cloud) gi.cloud_noise_mm = r.cloud->prepared.noise_mm;
  gi.registration = r.cloud ? nullptr : &r.registration;
  gi.patches = r.patches ? &*r.patches : nullptr;
  std::future<QualityGates> gates;
  outputs.update(write_skin_outputs(out, r.skin, r.skin_png, r.rigged.texture.empty() ? nullptr : &r.rigged.texture, [&] {
    gi.skin_file = out.staged_path("skin.ply");
    gi.skin_name = out.final_path("skin.ply");
    gates = std::async(side_launch(), [&gi, &o = in.options] { return check_gates(gi, o); });
  }));
  if (r.texture) {
    write_file_atomic(out.stage("texture.png"), r.rigged.texture_png);
    outputs["texture_png"] = out.final_path("texture.png");
  }
  write_file_atomic(out.stage("skin.glb"), r.glb);
  outputs["skin_glb"] = out.final_path("skin.glb");
  Json step;
  if (r.patches) outputs.update(write_patch_files(out, *r.patches, &step));
  RunWritten W;
  HS_CHECK(gates.valid(), "the gates start once skin.ply is staged");
  W.gates = gates.get();

  Json report;
  report["format"] = "handskin-report/1";
  if (r.cloud) {
    report["inputs"] = {{"clouds", in.clouds}, {"units", length_unit_name(in.units)}};
    if (in.hand) report["inputs"]["hand"] = hand_side_name(*in.hand);
  } else {
    report["inputs"] = {{"back", in.back_stem}, {"palm", in.palm_stem}};
  }
  report["inputs"]["rig"] = in.rig_path.empty() ? "(placed automatically)" : in.rig_path;
  report["inputs"]["pipeline"] = in.pipeline_path.empty() ? "(built-in defaults)" : in.pipeline_path;
  if (!in.markers_path.empty()) report["inputs"]["markers"] = in.markers_path;
  report["pipeline"] = pipeline_to_json(in.options);
  if (in.baseline) report["pipeline"]["skin"]["baseline"] = true;
  Json stages = Json::array();
  if (r.cloud) {
    stages.push_back(to_json(*r.cloud));
    if (r.registration_truth) stages.back()["registration"]["against_truth"] = *r.registration_truth;
  } else {
    stages.push_back({{"name", "ingest"}, {"seconds", r.ingest_seconds}, {"back", to_json(r.back)},
                      {"palm", to_json(r.palm)}});
    Json reg_stage = {{"name", "registration"}, {"seconds", r.registration_seconds}};
    reg_stage.update(registration_summary_json(r.registration));
    if (r.registration_truth) reg_stage["against_truth"] = *r.registration_truth;
    stages.push_back(reg_stage);
  }
  stages.push_back(to_json(r.skin));
  describe_written_skin(W.gates, &stages.back());
  if (r.patches) stages.push_back(to_json(*r.patches));
  {
    size_t influences = 0;
    for (const auto& w : r.rigged.binding.vertices)
      for (int k = 0; k < kMaxInfluences; ++k) influences += w.link[k] >= 0;
    stages.push_back({{"name", "rigging"},
                      {"seconds", r.rigging_seconds},
                      {"binding", r.rigged.binding.mode},
                      {"vertices", r.rigged.mesh.vertices.size()},
                      {"mean_influences", r.rigged.mesh.vertices.empty() ? 0.0 : static_cast<double>(influences) / r.rigged.mesh.vertices.size()},
                      {"posture_model", in.posture_model}});
  }
  if (r.texture) {
    const SkinTexture& t = *r.texture;
    stages.push_back({{"name", "texture"},
                      {"seconds", t.seconds},
                      {"size", r.rigged.texture.size},
                      {"texels_per_mm", t.texels_per_mm},
                      {"area_palm_photo_only", t.palm_only},
                      {"area_back_photo_only", t.back_only},
                      {"area_blended", t.blended},
                      {"area_unseen", t.unseen},
                      {"faces", {{"palm_chart", t.palm_chart_faces}, {"back_chart", t.back_chart_faces}, {"unseen", t.unseen_faces}}}});
  } else {
    stages.push_back({{"name", "texture"}, {"seconds", 0.0}, {"skipped", r.texture_note}});
  }
  {
    // What the writer only puts into files, made after the texture (the STEP file from the
    // patch stage's end on a thread of its own: its seconds overlap the rigging, the texture
    // and these).
    Json pictures = {{"name", "pictures"}, {"seconds", r.pictures_seconds}};
    if (r.patches) pictures["patches_step_seconds"] = r.step_seconds;
    stages.push_back(std::move(pictures));
  }
  report["inputs"]["posture_model"] = in.posture_model;
  // Paths relative to the report (the folder travels with its inputs), and absolute.
  relativise_input_paths(&report["inputs"], out.out_dir(), &report["inputs_absolute"]);
  report["stages"] = stages;  // the computing stages, for the patch report's page
  put_gates(W.gates, &report);
  if (r.patches) {
    outputs.update(write_patch_report(out, *r.patches, report, r.posed));
    report["patches_step"] = step;
  }
  stages.push_back({{"name", "write"}, {"seconds", t_write.seconds()}});
  report["stages"] = stages;
  outputs["report"] = out.final_path("report.json");
  relativise_output_paths(&outputs, out.out_dir());
  report["outputs"] = outputs;
  report["total_seconds"] = r.seconds + t_write.seconds();
  save_json(out.stage("report.json"), report);
  W.report = std::move(report);
  return W;
}

RunWritten run_into_folder(const RunInputs& in, const std::string& out_dir, const OutputSetOptions& out_options,
                           const ProgressFn& progress, const std::function<void(const QualityGates&)>& settle) {
  OutputSet out(out_dir, out_options);  // an output path that cannot be a folder fails before any work
  out.claim(run_output_plan(in), run_output_names());  // the folder writable, locked, its names ours
  const RunResult r = run_pipeline(in, progress);
  if (progress) progress("writing the outputs");
  RunWritten w = write_run_outputs(out, r);
  if (settle) settle(w.gates);
  out.commit();
  return w;
}

}  // namespace handskin
