// handskin: range scans of a hand -> rigged skin. The command-line front end: it parses
// options, calls the stages, prints progress to stderr and turns errors into one line.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "core/transform.hpp"
#include "mesh/trimesh.hpp"
#include "pipeline/options.hpp"
#include "pipeline/run.hpp"
#include "pipeline/skin_stage.hpp"
#include "register/registration.hpp"
#include "posture/calibrate.hpp"
#include "posture/mocap.hpp"
#include "posture/solver.hpp"
#include "render/preview.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "synth/hand_mesher.hpp"
#include "synth/hand_model.hpp"
#include "synth/replica.hpp"

namespace fs = std::filesystem;
using namespace handskin;

namespace {

struct Progress {
  bool quiet = false;
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  void operator()(const std::string& tag, const std::string& msg) const {
    if (quiet) return;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "[%6.2fs] %s: %s\n", s, tag.c_str(), msg.c_str());
  }
};

void check_options(bool ok, const std::string& where, const std::string& err) {
  if (!ok) throw InputError(where, err);
}

// ---------------- synth hand ----------------
struct SynthHandArgs {
  std::string out = "hand";
  HandShapeOptions shape;
  std::string posture = "relaxed", side = "right";
  std::vector<std::string> sets;
  std::optional<double> thumb_pronation, index_ring_ratio, forearm;
  HandMeshOptions mesh;
  bool render = true;
};

void synth_hand(const SynthHandArgs& args, const Progress& progress) {
  SynthHandArgs a = args;
  if (a.side != "right" && a.side != "left") throw InputError("--side", "'" + a.side + "': must be right or left");
  a.shape.side = a.side == "left" ? HandSide::Left : HandSide::Right;
  a.shape.posture = parse_posture(a.posture, a.sets);
  a.shape.thumb_pronation_deg =
      a.thumb_pronation ? *a.thumb_pronation : (a.posture == "relaxed" ? relaxed_thumb_pronation() : 0.0);
  a.shape.index_ring_ratio = a.index_ring_ratio;
  a.shape.forearm_mm = a.forearm;
  std::string err;
  check_options(a.shape.IsValid(&err), "hand options", err);
  check_options(a.mesh.IsValid(&err), "mesh options", err);
  progress("synth hand", "building the skeleton and implicit surface");
  const HandModel model = build_hand_model(a.shape);
  progress("synth hand", "meshing with CGAL's surface mesher (a few seconds)");
  const HandMeshResult r = mesh_hand(model, a.mesh);
  ensure_directory(a.out);
  const std::string mesh_path = (fs::path(a.out) / "hand.ply").string();
  const std::string rig_path = (fs::path(a.out) / "hand_rig.json").string();
  save_mesh(mesh_path, r.mesh);
  save_rig(rig_path, model.rig);
  if (a.render) {
    RenderOptions ro;
    ro.view = named_view("back");
    write_file_atomic((fs::path(a.out) / "hand_back.png").string(), render_mesh_png({&r.mesh}, ro));
    ro.view = named_view("side");
    write_file_atomic((fs::path(a.out) / "hand_side.png").string(), render_mesh_png({&r.mesh}, ro));
  }
  progress("synth hand", std::to_string(r.health.vertices) + " vertices, " + std::to_string(r.health.faces) +
                             " triangles, closed=" + (r.health.closed() ? "yes" : "no") +
                             ", manifold=" + (r.health.manifold() ? "yes" : "no") +
                             ", self-intersections=" + (r.self_intersects ? "yes" : "no") + ", meshed in " +
                             std::to_string(r.seconds).substr(0, 5) + " s");
  std::printf("%s\n%s\n", mesh_path.c_str(), rig_path.c_str());
}

// ---------------- synth scan ----------------
struct SynthScanArgs {
  std::string mesh, rig, out = "scans";
  std::uint64_t seed = 1;
  ReplicaOptions replica;
  ScannerOptions scanner;
  bool render = true;
};

void synth_scan(const SynthScanArgs& a, const Progress& progress) {
  std::string err;
  check_options(a.replica.IsValid(&err), "replica options", err);
  check_options(a.scanner.IsValid(&err), "scanner options", err);
  const TriMesh hand = load_mesh(a.mesh);
  const Rig rig = load_rig(a.rig);
  progress("synth scan", "placing markers and scanning both sides (seed " + std::to_string(a.seed) + ")");
  const ScanPair pair = synthesize_scan_pair(hand, rig, a.replica, a.scanner, a.seed, !progress.quiet);
  ensure_directory(a.out);
  const fs::path out(a.out);
  save_scan((out / "back").string(), pair.back.scan);
  save_scan((out / "palm").string(), pair.palm.scan);
  save_rig((out / "rig.json").string(), pair.rig_palm);
  save_mesh((out / "truth_skin.ply").string(), pair.skin_palm);
  Json truth;
  truth["format"] = "handskin-truth/1";
  truth["hand"] = hand_side_name(rig_side(rig));
  truth["seed"] = a.seed;
  truth["back_to_palm"] = isometry_to_json(pair.back_to_palm);
  truth["palm_from_hand"] = isometry_to_json(pair.T_palm_hand);
  truth["back_from_hand"] = isometry_to_json(pair.T_back_hand);
  truth["marker_radius_mm"] = a.replica.marker_radius_mm;
  Json mp = Json::array(), mb = Json::array(), returns = Json::array();
  for (size_t k = 0; k < pair.markers_hand.size(); ++k) {
    mp.push_back(to_json(pair.T_palm_hand * pair.markers_hand[k]));
    mb.push_back(to_json(pair.T_back_hand * pair.markers_hand[k]));
    auto count = [&](const ScanSimulation& sim) {
      return k + 1 < sim.returns_per_object.size() ? sim.returns_per_object[k + 1] : size_t{0};
    };
    returns.push_back({{"back", static_cast<int>(k) == a.replica.omit_marker_in_back ? size_t{0} : count(pair.back)},
                       {"palm", count(pair.palm)}});
  }
  truth["markers_palm"] = mp;
  truth["markers_back"] = mb;
  truth["marker_returns"] = returns;
  if (a.replica.omit_marker_in_back >= 0) truth["marker_omitted_in_back"] = a.replica.omit_marker_in_back;
  if (pair.extra_bump_hand) truth["extra_bump_back"] = to_json(pair.T_back_hand * *pair.extra_bump_hand);
  truth["skin"] = "truth_skin.ply";
  truth["scanner"] = {{"laser_tilt_deg", a.scanner.laser_tilt_deg},
                      {"max_incidence_deg", a.scanner.max_incidence_deg},
                      {"noise_sigma_mm", a.scanner.noise_sigma_mm},
                      {"table_height_mm", a.scanner.table_height_mm},
                      {"table_tilt_deg", a.scanner.table_tilt_deg}};
  truth["placement_attempts"] = pair.placement_attempts;
  save_json((out / "truth.json").string(), truth);
  if (a.render) {
    write_file_atomic((out / "back_preview.png").string(), render_scan_png(pair.back.scan));
    write_file_atomic((out / "palm_preview.png").string(), render_scan_png(pair.palm.scan));
  }
  progress("synth scan", "back: " + std::to_string(pair.back.scan.count_valid()) + " returns, palm: " +
                             std::to_string(pair.palm.scan.count_valid()) + " returns; " +
                             std::to_string(pair.markers_hand.size()) + " markers visible in both");
  for (const char* f : {"back.png", "back.json", "palm.png", "palm.json", "rig.json", "truth.json", "truth_skin.ply"})
    std::printf("%s\n", (out / f).string().c_str());
}

// ---------------- render ----------------
struct RenderArgs {
  std::string mesh, scan, rig, out, view = "back";
  int width = 800, height = 600;
};

void render(const RenderArgs& a) {
  if (a.mesh.empty() == a.scan.empty()) throw InputError("render", "give exactly one of --mesh or --scan");
  if (!a.scan.empty()) {
    write_file_atomic(a.out, render_scan_png(load_scan(a.scan)));
  } else {
    const TriMesh mesh = load_mesh(a.mesh);
    RenderOptions ro;
    ro.width = a.width;
    ro.height = a.height;
    ro.view = named_view(a.view);
    if (!a.rig.empty()) {
      const Rig rig = load_rig(a.rig);
      // Views are defined in the hand frame: bring the mesh frame there through the rig.
      const Eigen::Isometry3d T = hand_frame_from_rig(rig);
      ro.view = ro.view * T.linear();
      for (const auto& j : rig.joints) ro.points.push_back(j);
    }
    write_file_atomic(a.out, render_mesh_png({&mesh}, ro));
  }
  std::printf("%s\n", a.out.c_str());
}

// ---------------- convert ----------------
struct ConvertArgs {
  std::string in, out, like, side;
};

bool is_cloud_path(const std::string& p) {
  const std::string e = fs::path(p).extension().string();
  return e == ".ply" || e == ".pcd";
}

void convert(const ConvertArgs& a, const Progress& progress) {
  if (!is_cloud_path(a.in)) {
    if (!is_cloud_path(a.out)) throw InputError("--out", "converting a scan needs a .ply or .pcd output");
    const RangeScan scan = load_scan(a.in);
    save_cloud(a.out, *dense_copy(*scan_to_organized_cloud(scan)));
    progress("convert", std::to_string(scan.count_valid()) + " points written");
  } else {
    if (is_cloud_path(a.out)) {
      save_cloud(a.out, *load_cloud(a.in));
    } else {
      // The grid comes from an existing scan's sidecar (--like) or the CUBIST defaults.
      ScanMeta meta = a.like.empty() ? ScanMeta{} : parse_scan_meta(read_file(a.like + ".json"), a.like + ".json");
      if (a.side == "back") meta.side = ScanSide::Back;
      else if (a.side == "palm") meta.side = ScanSide::Palm;
      else if (a.like.empty()) throw InputError("--side", "give --side back or --side palm (or --like <stem>)");
      meta.device = "converted from " + fs::path(a.in).filename().string();
      size_t dropped = 0;
      const RangeScan scan = cloud_to_scan(*load_cloud(a.in), meta, &dropped);
      if (scan.count_valid() == 0) throw InputError(a.in, "no point falls on the scan grid");
      save_scan(a.out, scan);
      progress("convert", std::to_string(scan.count_valid()) + " samples, " + std::to_string(dropped) +
                              " points off the grid or out of range dropped");
    }
  }
  std::printf("%s\n", a.out.c_str());
}

// ---------------- skin ----------------
struct SkinArgs {
  std::string merged, rig, out = "skin", pipeline, truth;
  bool auto_rig = false;
};

void skin_command(const SkinArgs& a, const Progress& progress) {
  PipelineOptions po;
  if (!a.pipeline.empty()) po = load_pipeline(a.pipeline);
  SkinStageInputs in;
  if (!a.rig.empty()) in.rig = load_palm_rig(a.rig);
  in.auto_rig = a.auto_rig;
  if (!a.truth.empty()) in.truth = load_truth_skin(a.truth);  // before any work, so a bad file fails early
  progress("skin", "reading " + a.merged);
  MergedArrays m = merged_arrays(*load_merged(a.merged));
  in.points = std::move(m.points);
  in.normals = std::move(m.normals);
  in.sides = std::move(m.sides);
  in.out_dir = a.out;
  Json report = run_skin_stage(in, po, [&](const std::string& msg) { progress("skin", msg); });
  report["format"] = "handskin-skin-report/1";
  report["inputs"] = {{"merged", a.merged}, {"rig", a.rig.empty() ? "(placed automatically)" : a.rig}, {"pipeline", a.pipeline.empty() ? "(built-in defaults)" : a.pipeline}};
  const std::string rp = (fs::path(a.out) / "skin_report.json").string();
  save_json(rp, report);
  const Json& mesh = report["mesh"];
  const Json& d = report["cloud_to_skin_mm"];
  std::printf("skin: %d vertices, %d triangles, watertight %s, cloud to skin mean %.3f p95 %.3f max %.2f mm, %.0f ms -> %s\n",
              mesh["vertices"].get<int>(), mesh["triangles"].get<int>(), mesh["watertight"].get<bool>() ? "yes" : "no",
              d["mean"].get<double>(), d["p95"].get<double>(), d["max"].get<double>(),
              1000 * report["seconds"].get<double>(), rp.c_str());
  if (report["skeleton"].contains("automatic") && report["skeleton"]["automatic"].contains("against_given_rig")) {
    const Json& e = report["skeleton"]["automatic"]["against_given_rig"];
    std::printf("automatic skeleton: mean joint error %.2f mm (max %.2f, %s) against %s\n",
                e["mean_joint_error_mm"].get<double>(), e["max_joint_error_mm"].get<double>(),
                e["worst_joint"].get<std::string>().c_str(), a.rig.c_str());
  }
  if (report.contains("truth")) {
    const Json& s = report["truth"]["skin_to_truth_mm"];
    const Json& t = report["truth"]["truth_to_skin_mm"];
    std::printf("against the truth: skin->truth mean %.3f p95 %.3f mm; truth->skin within 1 mm %.2f %%\n",
                s["mean"].get<double>(), s["p95"].get<double>(), 100 * t["within_1mm"].get<double>());
  }
}

// ---------------- register ----------------
struct RegisterArgs {
  std::string back, palm, out = "registration", markers, pipeline, truth;
  bool no_refine = false;
};

void register_command(const RegisterArgs& a, const Progress& progress) {
  PipelineOptions po;
  if (!a.pipeline.empty()) po = load_pipeline(a.pipeline);
  RegistrationOptions ro = registration_options(po);
  if (a.no_refine) ro.refine_enabled = false;
  const RangeScan back = load_scan_side(a.back, ScanSide::Back, "--back");
  const RangeScan palm = load_scan_side(a.palm, ScanSide::Palm, "--palm");
  MarkerHints hints;
  if (!a.markers.empty()) hints = load_marker_hints(a.markers);
  // Truth (synthetic data): read before any work so a bad file fails early.
  Eigen::Isometry3d T_true = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> skin;
  if (!a.truth.empty()) {
    const TruthSkin truth = load_truth_skin(a.truth);
    T_true = isometry_from_json(require(truth.json, "back_to_palm", a.truth), "back_to_palm", a.truth);
    skin = mesh_vertices(truth.skin);
  }
  Registration reg = register_scans(back, palm, a.back + ".png", a.palm + ".png", ro,
                                    a.markers.empty() ? nullptr : &hints,
                                    [&](const std::string& m) { progress("register", m); });
  for (const auto& w : reg.warnings) progress("register", "warning: " + w);
  if (!a.truth.empty()) {
    Json t;
    for (const auto& [name, T] : {std::pair<const char*, Eigen::Isometry3d>{"marker_only", reg.marker_only},
                                  {"chosen", reg.back_to_palm}}) {
      const RegistrationError e = registration_error(T, T_true, skin);
      t[name] = {{"rotation_deg", e.rotation_deg}, {"skin_mean_mm", e.mean_mm}, {"skin_max_mm", e.max_mm}};
    }
    t["file"] = a.truth;
    reg.report["against_truth"] = t;
  }
  ensure_directory(a.out);
  save_json((fs::path(a.out) / "registration.json").string(), reg.report);
  save_merged((fs::path(a.out) / "merged.ply").string(), *reg.merged);
  write_file_atomic((fs::path(a.out) / "merged.png").string(), merged_preview_png(merged_arrays(*reg.merged), reg.markers_palm));
  const Json& r = reg.report;
  std::printf("%s: %s, %zu of %zu/%zu markers matched (radius %.3f mm, %s), marker rms %.4f mm (refined %.4f mm), %zu "
              "merged points\n",
              r["status"].get<std::string>().c_str(), r["method"].get<std::string>().c_str(),
              r["matching"]["pairs_back_palm"].size(), r["scans"]["back"]["markers"].size(),
              r["scans"]["palm"]["markers"].size(), reg.marker_radius_mm,
              r["marker_radius"]["source"].get<std::string>().c_str(), r["marker_only"]["rms_mm"].get<double>(),
              r["refined"]["rms_mm"].get<double>(), reg.merged->size());
  if (r.contains("against_truth"))
    std::printf("against truth: rotation %.5f deg, skin mean %.4f mm, max %.4f mm\n",
                r["against_truth"]["chosen"]["rotation_deg"].get<double>(),
                r["against_truth"]["chosen"]["skin_mean_mm"].get<double>(),
                r["against_truth"]["chosen"]["skin_max_mm"].get<double>());
}

// ---------------- solve ----------------
struct SolveArgs {
  std::string model, rig, inputs, out, picture, view = "side";
  std::vector<std::string> sets, torques, targets;
  bool json = false, linear = false;
};

void solve_command(const SolveArgs& a, const Progress& progress) {
  const PostureModel model = load_model(a.model);
  const PostureSolver solver(model);
  auto run = [&](const PostureInputs& in) { return a.linear ? solver.solve_linear(in) : solver.solve(in); };
  if (!a.inputs.empty() || !a.out.empty()) {
    if (a.inputs.empty() || a.out.empty()) throw InputError("solve", "batch mode needs both --inputs and --out");
    if (!a.sets.empty() || !a.torques.empty() || !a.targets.empty() || !a.rig.empty())
      throw InputError("solve", "--set/--torque/--target/--rig do not combine with --inputs (each row's cells are its inputs)");
    const AngleTable in = read_angle_table(a.inputs);
    AngleTable out;
    for (int d = 0; d < kDofCount; ++d) out.columns.push_back(d);
    long clamped_rows = 0, clamped_cells = 0;
    PostureInputs pi;
    for (size_t r = 0; r < in.rows.size(); ++r) {
      pi.pins.clear();
      for (size_t c = 0; c < in.columns.size(); ++c)
        if (std::isfinite(in.rows[r][c])) pi.pins.emplace_back(in.columns[c], in.rows[r][c]);
      const PostureSolution s = run(pi);
      if (s.clamped_inputs) ++clamped_rows, clamped_cells += s.clamped_inputs;
      out.rows.emplace_back(s.angles.begin(), s.angles.end());
    }
    write_angle_table(a.out, out);
    if (clamped_rows)
      progress("solve", "warning: " + std::to_string(clamped_cells) + " input value(s) in " + std::to_string(clamped_rows) +
                            " row(s) lay outside the model's limits and were clamped onto them");
    std::printf("%zu postures solved -> %s\n", out.rows.size(), a.out.c_str());
    return;
  }
  PostureInputs in;
  for (const auto& t : a.sets) {
    int d;
    double v;
    parse_assignment(t, "--set", &d, &v);
    in.pins.emplace_back(d, v);
  }
  for (const auto& t : a.torques) {
    int d;
    double v;
    parse_assignment(t, "--torque", &d, &v);
    in.torques.emplace_back(d, v);
  }
  for (const auto& t : a.targets) {
    int d;
    double v, w;
    parse_assignment(t, "--target", &d, &v, &w);
    in.targets.push_back({d, v, w});
  }
  // The rig (and the skeleton built from it, once) are checked before any solving.
  if (!a.picture.empty() && a.rig.empty()) throw InputError("--picture", "needs --rig (the skeleton to draw)");
  std::optional<Rig> rig;
  std::optional<Skeleton> skeleton;
  if (!a.rig.empty()) {
    rig = load_rig(a.rig);
    skeleton.emplace(*rig, a.rig);
  }
  const PostureSolution s = run(in);
  if (s.clamped_inputs)
    progress("solve", "warning: " + std::to_string(s.clamped_inputs) + " input(s) outside the limits were clamped onto them");
  std::vector<char> pinned(kDofCount, 0), limited(kDofCount, 0);
  for (const auto& [d, v] : in.pins) pinned[d] = 1;
  for (int d : s.at_limit) limited[d] = 1;
  std::array<Eigen::Vector3d, kJointCount> joint_pos;
  if (skeleton) joint_pos = skeleton->positions(s.angles);
  if (!a.picture.empty()) {
    // The relaxed posture in grey, the solved one in red, seen in the hand frame.
    Angles relaxed;
    for (int d = 0; d < kDofCount; ++d) relaxed[d] = model.dof[d].relaxed;
    const auto rest = skeleton->positions(relaxed);
    std::vector<int> parents;
    for (const auto& jn : joints()) parents.push_back(jn.parent);
    RenderOptions ro;
    ro.width = 900;
    ro.height = 600;
    ro.view = named_view(a.view) * hand_frame_from_rig(*rig).linear();
    write_file_atomic(a.picture,
                      render_skeletons_png({{{rest.begin(), rest.end()}, parents, {0.6f, 0.6f, 0.65f}},
                                            {{joint_pos.begin(), joint_pos.end()}, parents, {0.8f, 0.15f, 0.15f}}},
                                           ro));
  }
  if (a.json) {
    Json j;
    j["format"] = "handskin-posture-solution/1";
    j["model"] = model.name;
    Json angles = Json::object();
    for (int d = 0; d < kDofCount; ++d) angles[dofs()[d].name] = s.angles[d];
    j["angles"] = angles;
    Json p = Json::array(), l = Json::array();
    for (int d = 0; d < kDofCount; ++d) {
      if (pinned[d]) p.push_back(dofs()[d].name);
      if (limited[d]) l.push_back(dofs()[d].name);
    }
    j["pinned"] = p;
    j["at_limit"] = l;
    j["iterations"] = s.iterations;
    j["energy"] = s.energy;
    j["converged"] = s.converged;
    j["clamped_inputs"] = s.clamped_inputs;
    if (rig) {
      Json jp = Json::object();
      for (int k = 0; k < kJointCount; ++k) jp[joints()[k].name] = to_json(joint_pos[k]);
      j["joints"] = jp;
    }
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("model %s: %d %s, energy %.4f%s\n", model.name.c_str(), s.iterations,
              solver.has_grids() && !a.linear ? "Gauss-Newton step(s)" : "active-set round(s)", s.energy,
              s.converged ? "" : " (not converged)");
  std::printf("%-18s %9s %9s  %s\n", "DOF", "angle", "relaxed", "");
  for (int d = 0; d < kDofCount; ++d)
    std::printf("%-18s %9.3f %9.3f  %s\n", dofs()[d].name.c_str(), s.angles[d], model.dof[d].relaxed,
                pinned[d] ? "pinned" : limited[d] ? "at limit" : "");
  if (rig) {
    std::printf("\n%-36s %10s %10s %10s\n", "joint (rig frame, mm)", "x", "y", "z");
    for (int k = 0; k < kJointCount; ++k)
      std::printf("%-36s %10.3f %10.3f %10.3f\n", joints()[k].name, joint_pos[k].x(), joint_pos[k].y(), joint_pos[k].z());
  }
}

// ---------------- calibrate ----------------
struct CalibrateArgs {
  std::string angles, out, report;
  std::vector<std::string> pairs;
  CalibrationOptions options;
};

void calibrate_command(CalibrateArgs a, const Progress& progress) {
  for (const auto& p : a.pairs) {
    const size_t colon = p.find(':');
    if (colon == std::string::npos) throw InputError("--pair", "'" + p + "' is not of the form dofA:dofB");
    a.options.pairs.emplace_back(require_dof(p.substr(0, colon), "--pair"), require_dof(p.substr(colon + 1), "--pair"));
  }
  const AngleTable table = read_angle_table(a.angles);
  progress("calibrate", std::to_string(table.rows.size()) + " rows, " + std::to_string(table.columns.size()) + " DOFs");
  Json rep;
  const PostureModel m = calibrate(table, a.options, a.angles, &rep);
  PostureSolver check(m);  // refuses a model that would not solve
  (void)check;
  save_model(a.out, m);
  if (!a.report.empty()) save_json(a.report, rep);
  for (const auto& n : m.notes) progress("calibrate", "note: " + n);
  std::printf("%zu pair(s)%s -> %s\n", m.pairs.size(), m.grids.empty() ? "" : " with grids", a.out.c_str());
  for (const auto& p : rep["pairs"])
    std::printf("  %-16s ~ %-16s r %+.3f  slope %s  spread %.2f deg  weight %.3f\n", p["a"].get<std::string>().c_str(),
                p["b"].get<std::string>().c_str(), p["r"].get<double>(),
                p["slope"].is_null() ? "vertical" : std::to_string(p["slope"].get<double>()).substr(0, 6).c_str(),
                p["spread_rms_deg"].get<double>(), p["weight"].get<double>());
}

// ---------------- mocap ----------------
struct MocapArgs {
  std::string in, out;
  int every = 1;
};

void mocap_command(const MocapArgs& a, const Progress& progress) {
  if (a.every < 1) throw InputError("--every", "must be >= 1");
  const MarkerTrack track = read_marker_file(a.in);
  progress("mocap", std::to_string(track.frames.size()) + " frames, " + std::to_string(track.names.size()) + " markers");
  MocapAngles ang = angles_from_markers(track, a.in);
  AngleTable out;
  out.columns = ang.table.columns;
  for (size_t r = 0; r < ang.table.rows.size(); r += a.every) out.rows.push_back(ang.table.rows[r]);
  write_angle_table(a.out, out);
  for (const auto& n : ang.notes) progress("mocap", n);
  std::printf("%zu rows of %zu angles -> %s (%zu frames had missing markers)\n", out.rows.size(), out.columns.size(),
              a.out.c_str(), ang.frames_with_gaps);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"handskin: range scans of a hand -> a rigged, animatable skin (after Yasumuro 2000).\n"
               "Millimetres and degrees everywhere; see docs/ for frames and formats."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "handskin 0.1.0");
  Progress progress;
  app.add_flag("-q,--quiet", progress.quiet, "No progress lines on stderr");

  // run
  RunInputs run_in;
  auto* run = app.add_subcommand("run", "Run the pipeline on a back/palm scan pair and a rig");
  run->add_option("--back", run_in.back_stem, "Back scan stem (<stem>.png + <stem>.json)")->required();
  run->add_option("--palm", run_in.palm_stem, "Palm scan stem")->required();
  run->add_option("--rig", run_in.rig_path, "hand-rig/1 file, joints in the palm frame (default: placed automatically)");
  run->add_flag("--auto-rig", run_in.auto_rig, "Place the skeleton automatically even with --rig, and report its joint error");
  run->add_option("--out", run_in.out_dir, "Output folder (created if needed)")->required();
  run->add_option("--pipeline", run_in.pipeline_path, "Pipeline parameters (default: built-in = pipelines/cubist.json)");

  run->add_option("--markers", run_in.markers_path,
                  "Manual marker positions (handskin-markers/1) for scans whose bumps the detector misses");

  // register
  RegisterArgs rg;
  auto* regc = app.add_subcommand("register", "Register the back scan into the palm scan's frame and merge them");
  regc->add_option("--back", rg.back, "Back scan stem (<stem>.png + <stem>.json)")->required();
  regc->add_option("--palm", rg.palm, "Palm scan stem")->required();
  regc->add_option("--out", rg.out, "Output folder: registration.json, merged.ply, merged.png")->capture_default_str();
  regc->add_option("--markers", rg.markers, "Manual marker positions (handskin-markers/1), replacing detection");
  regc->add_option("--pipeline", rg.pipeline, "Pipeline parameters (markers, registration sections)");
  regc->add_option("--truth", rg.truth, "truth.json of a synthetic pair: add the errors against it to the report");
  regc->add_flag("--no-refine", rg.no_refine, "Keep the marker-only fit (no joint sphere/ICP refinement)");

  run->add_option("--truth", run_in.truth_path, "truth.json of a synthetic pair: add the skin's errors to the report");

  // skin
  SkinArgs sk;
  auto* skinc = app.add_subcommand("skin", "Skin mesh from a merged cloud and a rig: strips between planes, closed (thesis §4.1.2-4.1.3)");
  skinc->add_option("--merged", sk.merged, "Merged cloud (merged.ply from handskin register)")->required();
  skinc->add_option("--rig", sk.rig, "hand-rig/1 file, joints in the palm frame (default: placed automatically)");
  skinc->add_flag("--auto-rig", sk.auto_rig, "Place the skeleton automatically even with --rig, and report its joint error");
  skinc->add_option("--out", sk.out, "Output folder: skin.ply, skin.obj, skin.png, slices.json, baseline.ply, skin_report.json")
      ->capture_default_str();
  skinc->add_option("--pipeline", sk.pipeline, "Pipeline parameters (slicing, skin sections)");
  skinc->add_option("--truth", sk.truth, "truth.json of a synthetic pair: add the errors against its true skin");

  // solve
  SolveArgs sv;
  auto* solvec = app.add_subcommand("solve", "Posture from a few inputs: springs + constraint potentials (thesis ch. 3)");
  solvec->add_option("--model", sv.model, "Posture model (hand-posture/1 file, or builtin:anatomical / builtin:thesis)")
      ->required();
  solvec->add_option("--set", sv.sets, "Pin a DOF: name=degrees (repeatable), e.g. index.mcp.flex=40 or L2.flex=60");
  solvec->add_option("--torque", sv.torques, "Instructed input on a DOF: name=value (repeatable)");
  solvec->add_option("--target", sv.targets, "Soft target: name=degrees[@weight] (repeatable)");
  solvec->add_option("--rig", sv.rig, "hand-rig/1: also print joint positions of the posture");
  solvec->add_flag("--json", sv.json, "Print JSON (handskin-posture-solution/1)");
  solvec->add_option("--picture", sv.picture, "With --rig: draw the relaxed (grey) and solved (red) skeleton to a PNG");
  solvec->add_option("--view", sv.view, "Picture view: side, back or palm")->capture_default_str();
  solvec->add_flag("--linear", sv.linear, "Ignore the model's non-linear grids");
  solvec->add_option("--inputs", sv.inputs, "Batch: CSV of partial postures (given cells are pinned)");
  solvec->add_option("--out", sv.out, "Batch: CSV of full postures, rows in input order");

  // calibrate
  CalibrateArgs ca2;
  auto* calc = app.add_subcommand("calibrate", "Posture model from a joint-angle CSV (thesis §3.2.2-3.2.3)");
  calc->add_option("--angles", ca2.angles, "Joint-angle CSV (header: DOF names; empty cell = not measured)")->required();
  calc->add_option("--out", ca2.out, "Model to write (hand-posture/1)")->required();
  calc->add_option("--pair", ca2.pairs, "A pair to fit, dofA:dofB (repeatable; default: chosen by correlation)");
  calc->add_option("--min-correlation", ca2.options.min_correlation, "|r| for automatic pairs")->capture_default_str();
  calc->add_option("--max-pairs", ca2.options.max_pairs, "Most automatic pairs")->capture_default_str();
  calc->add_option("--weights", ca2.options.weights, "thesis (eq. 3.18) or inverse (1/spread)")->capture_default_str();
  calc->add_flag("--grids", ca2.options.grids, "Also build non-linear grid potentials (thesis §3.2.3)");
  calc->add_option("--grid-weight", ca2.options.grid_weight, "Weight of the grid potentials")->capture_default_str();
  calc->add_option("--report", ca2.report, "Write the calibration figures as JSON");

  // model
  std::string model_in, model_out;
  auto* modc = app.add_subcommand("model", "Check a posture model and write it out in full (e.g. a built-in set, to edit)");
  modc->add_option("--model", model_in, "hand-posture/1 file, or builtin:anatomical / builtin:thesis")->required();
  modc->add_option("--out", model_out, "Where to write it (absolute-angle pairs, every DOF listed)")->required();

  // mocap
  MocapArgs mc;
  auto* mocc = app.add_subcommand("mocap", "Joint angles from motion capture (Qualisys .tsv, OpenSim .trc) to CSV");
  mocc->add_option("--in", mc.in, "Marker file (.tsv or .trc)")->required();
  mocc->add_option("--out", mc.out, "Joint-angle CSV to write")->required();
  mocc->add_option("--every", mc.every, "Keep every n-th frame")->capture_default_str();

  // synth
  auto* synth = app.add_subcommand("synth", "Make synthetic data: a default hand, or a scan pair of a hand");
  synth->require_subcommand(1);
  SynthHandArgs sh;
  auto* shc = synth->add_subcommand(
      "hand", "Build a hand of the synthetic family (mesh + rig): right or left, any proportions, posed by the skeleton");
  shc->add_option("--out", sh.out, "Output folder: hand.ply, hand_rig.json, hand_back.png, hand_side.png")
      ->capture_default_str();
  shc->add_option("--hand-length", sh.shape.hand_length_mm, "Wrist joint to middle fingertip, mm [120, 260]")
      ->capture_default_str();
  shc->add_option("--spread", sh.shape.finger_spread_deg, "Extra angle between neighbouring fingers, deg [0, 15]")
      ->capture_default_str();
  shc->add_option("--thickness", sh.shape.thickness_scale, "Palm thickness multiplier [0.7, 1.4]")->capture_default_str();
  shc->add_option("--width", sh.shape.width_scale, "Palm and finger breadth multiplier [0.7, 1.4]")->capture_default_str();
  shc->add_option("--thumb-abduction", sh.shape.thumb_abduction_deg,
                  "Thumb metacarpal angle from the index's in the rest frame, deg [20, 70]")
      ->capture_default_str();
  shc->add_option("--finger-thickness", sh.shape.finger_thickness_scale, "Finger girth multiplier [0.7, 1.4]")
      ->capture_default_str();
  shc->add_option("--finger-length", sh.shape.finger_length_scale, "Phalanx length multiplier against the palm [0.85, 1.15]")
      ->capture_default_str();
  shc->add_option("--index-ring-ratio", sh.index_ring_ratio, "Index : ring finger length [0.85, 1.05] (default 0.929)");
  shc->add_option("--forearm", sh.forearm, "Forearm stub beyond the wrist joint, mm [0, 40] (default 12 x scale)");
  shc->add_option("--side", sh.side, "right or left")->capture_default_str();
  shc->add_option("--posture", sh.posture, "relaxed, flat, or a joint-angle CSV (first row; formats/hand-rig.md)")
      ->capture_default_str();
  shc->add_option("--set", sh.sets, "DOF=deg on top of the posture (repeatable), e.g. --set index.pip.flex=30");
  shc->add_option("--thumb-pronation", sh.thumb_pronation,
                  "Thumb sections turned about its axis, deg [0, 90] (default: 35 relaxed, 0 otherwise)");
  shc->add_option("--facet-size", sh.mesh.facet_size_mm, "Mesher facet size bound, mm (smaller: more triangles)")
      ->capture_default_str();
  shc->add_option("--facet-distance", sh.mesh.facet_distance_mm, "Mesher facet distance bound, mm")->capture_default_str();
  shc->add_option("--seed", sh.mesh.seed, "Mesher seed")->capture_default_str();
  shc->add_flag("!--no-render", sh.render, "Do not write preview pictures");

  SynthScanArgs ss;
  auto* ssc = synth->add_subcommand("scan", "Scan a hand replica (hand + 9 markers) back up and palm up");
  ssc->add_option("--mesh", ss.mesh, "Hand surface mesh (.ply/.obj/.off), same frame as --rig")->required();
  ssc->add_option("--rig", ss.rig, "hand-rig/1 of that mesh")->required();
  ssc->add_option("--out", ss.out, "Output folder")->capture_default_str();
  ssc->add_option("--seed", ss.seed, "Random seed (markers, placements, noise)")->capture_default_str();
  ssc->add_option("--marker-radius", ss.replica.marker_radius_mm, "Marker radius, mm")->capture_default_str();
  ssc->add_option("--markers", ss.replica.marker_count, "Number of markers")->capture_default_str();
  ssc->add_option("--omit-back-marker", ss.replica.omit_marker_in_back,
                  "Hard case: leave this marker (0-based) off the back scan")->capture_default_str();
  ssc->add_flag("--extra-bump", ss.replica.extra_bump, "Hard case: a marker-sized blob on the back of the hand");
  ssc->add_option("--max-yaw", ss.replica.max_yaw_deg, "Random yaw on the table, ± deg")->capture_default_str();
  ssc->add_option("--noise", ss.scanner.noise_sigma_mm, "Depth noise sigma before quantisation, mm")->capture_default_str();
  ssc->add_option("--laser-tilt", ss.scanner.laser_tilt_deg, "Laser sheet tilt from vertical, deg")->capture_default_str();
  ssc->add_option("--max-incidence", ss.scanner.max_incidence_deg, "Steepest surface that returns, deg")
      ->capture_default_str();
  ssc->add_option("--table-height", ss.scanner.table_height_mm, "Table top above the Z origin, mm")->capture_default_str();
  ssc->add_option("--table-tilt", ss.scanner.table_tilt_deg, "Table tilt about Y, deg")->capture_default_str();
  ssc->add_option("--resolution", ss.scanner.scanlines, "Scanlines (and points per line)")->capture_default_str();
  ssc->add_option("--x-extent", ss.scanner.x_extent_mm, "Table length the scanlines cover, mm (a large hand with a long "
                                                        "forearm stub needs more than the default)")
      ->capture_default_str();
  ssc->add_option("--y-extent", ss.scanner.y_extent_mm, "Table width a scanline covers, mm")->capture_default_str();
  ssc->add_flag("!--no-render", ss.render, "Do not write preview pictures");

  // render
  RenderArgs ra;
  auto* rc = app.add_subcommand("render", "Draw a mesh (shaded) or a scan (height colours) to a PNG");
  rc->add_option("--mesh", ra.mesh, "Mesh to draw");
  rc->add_option("--scan", ra.scan, "Scan stem to draw");
  rc->add_option("--rig", ra.rig, "Rig of the mesh: views follow the hand, joints drawn as dots");
  rc->add_option("--view", ra.view, "back, palm or side")->capture_default_str();
  rc->add_option("--size", ra.width, "Picture width in pixels (height = 3/4 of it)")->capture_default_str();
  rc->add_option("--out", ra.out, "PNG to write")->required();

  // convert
  ConvertArgs ca;
  auto* cc = app.add_subcommand("convert", "Convert between scans (<stem>) and point clouds (.ply/.pcd)");
  cc->add_option("--in", ca.in, "Scan stem or .ply/.pcd cloud")->required();
  cc->add_option("--out", ca.out, "Scan stem or .ply/.pcd cloud")->required();
  cc->add_option("--like", ca.like, "Cloud -> scan: take the grid from this scan's sidecar (default: CUBIST 512 x 512)");
  cc->add_option("--side", ca.side, "Cloud -> scan: back or palm");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (run->parsed()) {
      if (!run_in.pipeline_path.empty()) run_in.options = load_pipeline(run_in.pipeline_path);
      const RunResult r = run_pipeline(run_in, [&](const std::string& m) { progress("run", m); });
      progress("run", "done in " + std::to_string(r.report["total_seconds"].get<double>()).substr(0, 5) + " s");
      std::printf("outputs in %s (report: %s)\n", run_in.out_dir.c_str(), r.report_path.c_str());
    } else if (skinc->parsed()) {
      skin_command(sk, progress);
    } else if (solvec->parsed()) {
      solve_command(sv, progress);
    } else if (calc->parsed()) {
      calibrate_command(ca2, progress);
    } else if (modc->parsed()) {
      const PostureModel m = load_model(model_in);
      const PostureSolver check(m);  // refuses a model that cannot solve
      save_model(model_out, m);
      std::printf("%s: %zu pairs, %zu grids -> %s\n", m.name.c_str(), m.pairs.size(), m.grids.size(), model_out.c_str());
    } else if (mocc->parsed()) {
      mocap_command(mc, progress);
    } else if (regc->parsed()) {
      register_command(rg, progress);
    } else if (shc->parsed()) {
      synth_hand(sh, progress);
    } else if (ssc->parsed()) {
      ss.scanner.points = ss.scanner.scanlines;
      synth_scan(ss, progress);
    } else if (cc->parsed()) {
      convert(ca, progress);
    } else if (rc->parsed()) {
      ra.height = ra.width * 3 / 4;
      render(ra);
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const InternalError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  }
  return 0;
}
