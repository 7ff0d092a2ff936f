// synth hand, synth scan, synth cloud, synth angles: synthetic data.
#include <set>
#include <map>
#include <cstring>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>

#include "cli/commands.hpp"
#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/output_set.hpp"
#include "core/rig.hpp"
#include "render/preview.hpp"
#include "scan/cloud.hpp"
#include "scan/cloud_file.hpp"
#include "scan/cubist_io.hpp"
#include "synth/cloud_sim.hpp"
#include "synth/hand_mesher.hpp"
#include "posture/angle_table.hpp"
#include "synth/angle_recording.hpp"
#include "synth/hand_model.hpp"
#include "synth/replica.hpp"
#include "synth/truth.hpp"

namespace handskin::cli {

namespace {

/// Every flag of the synth commands (filled as they are added), to name the one at fault.
std::set<std::string>& synth_flags() {
  static std::set<std::string> flags;
  return flags;
}

/// The options' messages start with a field's name ("marker_radius_mm must be in …"); the
/// user gave a flag (--marker-radius): name it. Fields are flags with '-' for '_' and their
/// unit dropped, but for a few named otherwise; a field that is no flag keeps `where`.
void check_options(bool ok, const std::string& where, const std::string& err) {
  if (ok) return;
  static const std::map<std::string, std::string> renamed = {
      {"finger_spread_deg", "--spread"}, {"noise_sigma_mm", "--noise"}, {"scanlines", "--resolution"},
      {"outlier_share", "--outliers"},   {"omit_marker_in_back", "--omit-back-marker"}};
  const size_t space = err.find(' ');
  const std::string field = err.substr(0, space);
  std::string flag;
  if (const auto it = renamed.find(field); it != renamed.end()) {
    flag = it->second;
  } else {
    std::string f = field;
    for (const char* unit : {"_mm", "_deg", "_scale", "_share"})
      if (f.size() > std::strlen(unit) && f.compare(f.size() - std::strlen(unit), std::string::npos, unit) == 0)
        f.resize(f.size() - std::strlen(unit));
    std::replace(f.begin(), f.end(), '_', '-');
    flag = "--" + f;
  }
  if (space != std::string::npos && synth_flags().count(flag)) throw UsageError(flag, err.substr(space + 1));
  throw UsageError(where, err);  // the options are the flags' values
}

// ---------------- synth hand ----------------
struct SynthHandArgs {
  std::string out = "hand";
  HandShapeOptions shape;
  std::string posture = "relaxed", side = "right";
  std::vector<std::string> sets;
  std::optional<double> thumb_pronation, index_ring_ratio, forearm;
  HandMeshOptions mesh;
  bool no_render = false;
  bool force = false;
};

void synth_hand(const SynthHandArgs& args, const Progress& progress) {
  SynthHandArgs a = args;
  OutputSet out(a.out, output_options(a.force));
  if (a.side != "right" && a.side != "left") throw UsageError("--side", "'" + a.side + "': must be right or left");
  a.shape.side = a.side == "left" ? HandSide::Left : HandSide::Right;
  a.shape.posture = parse_posture(a.posture, a.sets);
  a.shape.thumb_pronation_deg =
      a.thumb_pronation ? *a.thumb_pronation : (a.posture == "relaxed" ? relaxed_thumb_pronation() : 0.0);
  a.shape.index_ring_ratio = a.index_ring_ratio;
  a.shape.forearm_mm = a.forearm;
  std::string err;
  check_options(a.shape.IsValid(&err), "hand options", err);
  check_options(a.mesh.IsValid(&err), "mesh options", err);
  {
    const std::vector<std::string> all = {"hand.ply", "hand_rig.json", "hand_back.png", "hand_side.png"};
    out.claim(!a.no_render ? all : std::vector<std::string>(all.begin(), all.begin() + 2), all);
  }
  progress("synth hand", "building the skeleton and implicit surface");
  const HandModel model = build_hand_model(a.shape);
  progress("synth hand", "meshing with CGAL's surface mesher (a few seconds)");
  const HandMeshResult r = mesh_hand(model, a.mesh);
  save_mesh(out.stage("hand.ply"), r.mesh);
  save_rig(out.stage("hand_rig.json"), model.rig);
  if (!a.no_render) {
    RenderOptions ro;
    ro.view = named_view("back");
    write_file_atomic(out.stage("hand_back.png"), render_mesh_png({&r.mesh}, ro));
    ro.view = named_view("side");
    write_file_atomic(out.stage("hand_side.png"), render_mesh_png({&r.mesh}, ro));
  }
  out.commit();
  progress("synth hand", std::to_string(r.health.vertices) + " vertices, " + std::to_string(r.health.faces) +
                             " triangles, closed=" + (r.health.closed() ? "yes" : "no") +
                             ", manifold=" + (r.health.manifold() ? "yes" : "no") +
                             ", self-intersections=" + (r.self_intersects ? "yes" : "no") + ", meshed in " +
                             std::to_string(r.seconds).substr(0, 5) + " s");
  std::printf("%s\n%s\n", out.final_path("hand.ply").c_str(), out.final_path("hand_rig.json").c_str());
}

// ---------------- synth scan ----------------
struct SynthScanArgs {
  std::string mesh, rig, out = "scans";
  std::uint64_t seed = 1;
  ReplicaOptions replica;
  ScannerOptions scanner;
  bool no_render = false;
  bool photos = true;
  bool force = false;
};

void synth_scan(const SynthScanArgs& a, const Progress& progress) {
  OutputSet out(a.out, output_options(a.force));
  std::string err;
  check_options(a.replica.IsValid(&err), "replica options", err);
  check_options(a.scanner.IsValid(&err), "scanner options", err);
  {
    const std::vector<std::string> all = {"back.png", "back.json", "palm.png", "palm.json", "rig.json", "truth.json",
                                          "truth_skin.ply", "back_preview.png", "palm_preview.png", "back.photo.png",
                                          "palm.photo.png"};
    std::vector<std::string> plan(all.begin(), all.begin() + 7);
    if (!a.no_render) plan.insert(plan.end(), {"back_preview.png", "palm_preview.png"});
    if (a.photos) plan.insert(plan.end(), {"back.photo.png", "palm.photo.png"});
    out.claim(plan, all);
  }
  const Mesh hand = load_mesh(a.mesh);
  const Rig rig = load_rig(a.rig);
  progress("synth scan", "placing markers and scanning both sides (seed " + std::to_string(a.seed) + ")");
  const ScanPair pair = synthesize_scan_pair(hand, rig, a.replica, a.scanner, a.seed, !progress.quiet());
  for (const auto& [stem, sim] : {std::pair<const char*, const ScanSimulation*>{"back", &pair.back}, {"palm", &pair.palm}}) {
    const std::string png = out.stage(std::string(stem) + ".png");
    out.stage(std::string(stem) + ".json");
    save_scan(png.substr(0, png.size() - 4), sim->scan);
  }
  if (a.photos) {
    write_file_atomic(out.stage("back.photo.png"), encode_rgb8_png(pair.back_photo.width, pair.back_photo.height, pair.back_photo.rgb));
    write_file_atomic(out.stage("palm.photo.png"), encode_rgb8_png(pair.palm_photo.width, pair.palm_photo.height, pair.palm_photo.rgb));
  }
  save_rig(out.stage("rig.json"), pair.rig_palm);
  save_mesh(out.stage("truth_skin.ply"), pair.skin_palm);
  save_json(out.stage("truth.json"), truth_to_json(pair, rig, a.seed, a.replica, a.scanner, "truth_skin.ply"));
  if (!a.no_render) {
    write_file_atomic(out.stage("back_preview.png"), render_scan_png(pair.back.scan));
    write_file_atomic(out.stage("palm_preview.png"), render_scan_png(pair.palm.scan));
  }
  out.commit();
  progress("synth scan", "back: " + std::to_string(pair.back.scan.count_valid()) + " returns, palm: " +
                             std::to_string(pair.palm.scan.count_valid()) + " returns; " +
                             std::to_string(pair.markers_hand.size()) + " markers visible in both");
  for (const char* f : {"back.png", "back.json", "palm.png", "palm.json", "rig.json", "truth.json", "truth_skin.ply"})
    std::printf("%s\n", out.final_path(f).c_str());
  if (a.photos)
    for (const char* f : {"back.photo.png", "palm.photo.png"}) std::printf("%s\n", out.final_path(f).c_str());
}

// ---------------- synth cloud ----------------
struct SynthCloudArgs {
  std::string mesh, rig, out = "cloud";
  std::uint64_t seed = 1;
  CloudSimOptions sim;
  std::string units = "mm";
  bool halves = false, force = false;
};

void synth_cloud(SynthCloudArgs a, const Progress& progress) {
  OutputSet out(a.out, output_options(a.force));
  a.sim.units_per_mm = 1.0 / millimetres_per(*parse_length_unit(a.units));
  std::string err;
  check_options(a.sim.IsValid(&err), "cloud options", err);
  const std::vector<std::string> all = {"cloud.ply", "a.ply", "b.ply", "rig.json", "truth.json", "truth_skin.ply"};
  std::vector<std::string> plan = {"cloud.ply", "rig.json", "truth.json", "truth_skin.ply"};
  if (a.halves) plan.insert(plan.end(), {"a.ply", "b.ply"});
  out.claim(plan, all);
  const Mesh hand = load_mesh(a.mesh);
  const Rig rig = load_rig(a.rig);
  progress("synth cloud", "scanning from " + std::to_string(a.sim.views) + " views (seed " + std::to_string(a.seed) + ")");
  const CloudSim sim = simulate_cloud(hand, rig, a.sim, a.seed);
  save_cloud(out.stage("cloud.ply"), sim.points);
  if (a.halves) {
    save_cloud(out.stage("a.ply"), sim.half_a);
    save_cloud(out.stage("b.ply"), sim.half_b);
  }
  save_rig(out.stage("rig.json"), sim.rig);
  save_mesh(out.stage("truth_skin.ply"), sim.skin);
  save_json(out.stage("truth.json"), cloud_truth_to_json(sim, rig, a.seed, a.sim, "truth_skin.ply"));
  out.commit();
  progress("synth cloud", std::to_string(sim.points.size()) + " points: " + std::to_string(sim.hand_points) + " hand, " +
                              std::to_string(sim.stand_points) + " stand, " + std::to_string(sim.outliers) +
                              " outliers; " + std::to_string(sim.dropped_grazing) + " grazing returns dropped");
  for (const auto& f : plan) std::printf("%s\n", out.final_path(f).c_str());
}

// ---------------- synth angles ----------------
struct SynthAnglesArgs {
  AngleRecordingOptions options;
  std::string out, truth;
  bool force = false;
};

void synth_angles(const SynthAnglesArgs& a, const Progress& progress) {
  std::string err;
  check_options(a.options.IsValid(&err), "synth angles", err);
  std::vector<std::string> written = {a.out};
  if (!a.truth.empty()) written.push_back(a.truth);
  OutputFiles files(written, output_options(a.force));
  const AngleRecording r = synth_angle_recording(a.options);
  progress("synth", std::to_string(r.table.rows.size()) + " frames of " + std::to_string(r.table.columns.size()) + " DOFs (" +
                        a.options.kind + ")");
  if (!a.truth.empty()) save_json(files.stage(a.truth), r.truth);
  write_angle_table(files.stage(a.out), r.table);
  files.commit();
  std::printf("%zu frames -> %s%s\n", r.table.rows.size(), a.out.c_str(), a.truth.empty() ? "" : (", truth -> " + a.truth).c_str());
}

}  // namespace

void add_synth_commands(CLI::App& app, const Progress& progress, Commands* out) {
  auto* synth = app.add_subcommand("synth", "Make synthetic data: a hand of the family, a scan pair or a cloud of a hand, or a joint-angle recording");
  synth->require_subcommand(1);
  auto sh = std::make_shared<SynthHandArgs>();
  auto* shc = synth->add_subcommand(
      "hand", "Build a hand of the synthetic family (mesh + rig): right or left, any proportions, posed by the skeleton");
  shc->add_option("--out", sh->out, "Output folder: hand.ply, hand_rig.json, hand_back.png, hand_side.png")
      ->capture_default_str();
  shc->add_option("--hand-length", sh->shape.hand_length_mm, "Wrist joint to middle fingertip, mm [120, 260]")
      ->capture_default_str();
  shc->add_option("--spread", sh->shape.finger_spread_deg, "Extra angle between neighbouring fingers, deg [0, 15]")
      ->capture_default_str();
  shc->add_option("--thickness", sh->shape.thickness_scale, "Palm thickness multiplier [0.7, 1.4]")->capture_default_str();
  shc->add_option("--width", sh->shape.width_scale, "Palm and finger breadth multiplier [0.7, 1.4]")->capture_default_str();
  shc->add_option("--thumb-abduction", sh->shape.thumb_abduction_deg,
                  "Thumb metacarpal angle from the index's in the rest frame, deg [20, 70]")
      ->capture_default_str();
  shc->add_option("--finger-thickness", sh->shape.finger_thickness_scale, "Finger girth multiplier [0.7, 1.4]")
      ->capture_default_str();
  shc->add_option("--finger-length", sh->shape.finger_length_scale, "Phalanx length multiplier against the palm [0.85, 1.15]")
      ->capture_default_str();
  shc->add_option("--index-ring-ratio", sh->index_ring_ratio, "Index : ring finger length [0.85, 1.05] (default 0.929)");
  shc->add_option("--forearm", sh->forearm, "Forearm stub beyond the wrist joint, mm [0, 40] (default 12 x scale)");
  shc->add_option("--side", sh->side, "right or left")->capture_default_str();
  shc->add_option("--posture", sh->posture, "relaxed, flat, or a joint-angle CSV (its first row; docs/formats.md, \"Joint-angle CSV\")")
      ->capture_default_str();
  shc->add_option("--set", sh->sets, "DOF=deg on top of the posture (repeatable), e.g. --set index.pip.flex=30");
  shc->add_option("--thumb-pronation", sh->thumb_pronation,
                  "Thumb sections turned about its axis, deg [0, 90] (default: 35 relaxed, 0 otherwise)");
  shc->add_option("--facet-size", sh->mesh.facet_size_mm, "Mesher facet size bound, mm (smaller: more triangles)")
      ->capture_default_str();
  shc->add_option("--facet-distance", sh->mesh.facet_distance_mm, "Mesher facet distance bound, mm")->capture_default_str();
  shc->add_option("--seed", sh->mesh.seed, "Mesher seed")->capture_default_str();
  shc->add_flag("--no-render", sh->no_render, "Do not write preview pictures");
  shc->add_flag("--force", sh->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  out->push_back({shc, [sh, &progress] { synth_hand(*sh, progress); }});

  auto ss = std::make_shared<SynthScanArgs>();
  auto* ssc = synth->add_subcommand("scan", "Scan a hand replica (hand + 9 markers) back up and palm up");
  ssc->add_option("--mesh", ss->mesh, "Hand surface mesh (.ply/.obj/.off), same frame as --rig")->required();
  ssc->add_option("--rig", ss->rig, "hand-rig/1 of that mesh")->required();
  ssc->add_option("--out", ss->out, "Output folder: back/palm .png + .json, rig.json, truth.json, truth_skin.ply, "
                                    "back/palm .photo.png, back_preview.png, palm_preview.png")
      ->capture_default_str();
  ssc->add_option("--seed", ss->seed, "Random seed (markers, placements, noise)")->capture_default_str();
  ssc->add_option("--marker-radius", ss->replica.marker_radius_mm, "Marker radius, mm")->capture_default_str();
  ssc->add_option("--marker-count", ss->replica.marker_count, "Number of markers on the replica")->capture_default_str();
  ssc->add_option("--omit-back-marker", ss->replica.omit_marker_in_back,
                  "Hard case: leave this marker (0-based) off the back scan")->capture_default_str();
  ssc->add_flag("--extra-bump", ss->replica.extra_bump, "Hard case: a marker-sized blob on the back of the hand");
  ssc->add_option("--saw", ss->replica.saw_mm,
                  "Saw the replica flat this many mm beyond the wrist joint, square to the hand's axis, as a cast is "
                  "sawn (for a mesh whose forearm ends rounded); the true skin is the sawn one");
  ssc->add_option("--max-yaw", ss->replica.max_yaw_deg, "Random yaw on the table, ± deg")->capture_default_str();
  ssc->add_option("--noise", ss->scanner.noise_sigma_mm, "Depth noise sigma before quantisation, mm")->capture_default_str();
  ssc->add_option("--z-step", ss->scanner.z_step_mm, "Depth quantisation step, mm")->capture_default_str();
  ssc->add_option("--laser-tilt", ss->scanner.laser_tilt_deg, "Laser sheet tilt from vertical, deg")->capture_default_str();
  ssc->add_option("--max-incidence", ss->scanner.max_incidence_deg, "Steepest surface that returns, deg")
      ->capture_default_str();
  ssc->add_option("--table-height", ss->scanner.table_height_mm, "Table top above the Z origin, mm")->capture_default_str();
  ssc->add_option("--table-tilt", ss->scanner.table_tilt_deg, "Table tilt about Y, deg")->capture_default_str();
  ssc->add_option("--resolution", ss->scanner.scanlines, "Scanlines (and points per line)")->capture_default_str();
  ssc->add_option("--x-extent", ss->scanner.x_extent_mm, "Table length the scanlines cover, mm (a large hand with a long "
                                                         "forearm stub needs more than the default)")
      ->capture_default_str();
  ssc->add_option("--y-extent", ss->scanner.y_extent_mm, "Table width a scanline covers, mm")->capture_default_str();
  ssc->add_flag("--no-render", ss->no_render, "Do not write preview pictures");
  ssc->add_flag("--force", ss->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  ssc->add_flag_callback("--no-photos", [ss] { ss->photos = false; },
                "Do not write the scans' photos (back.photo.png, palm.photo.png: the camera's colour image on each "
                "range image's grid, which run projects onto the skin as its texture)");
  auto sc = std::make_shared<SynthCloudArgs>();
  auto* scc = synth->add_subcommand("cloud", "Scan a hand from around as today's scanners do: an unorganized cloud (or two "
                                             "halves) with noise along the rays, grazing dropouts, a stand, outliers, an "
                                             "arbitrary pose, and its truth");
  scc->add_option("--mesh", sc->mesh, "Hand surface mesh (.ply/.obj/.off), same frame as --rig")->required();
  scc->add_option("--rig", sc->rig, "hand-rig/1 of that mesh")->required();
  scc->add_option("--out", sc->out, "Output folder: cloud.ply (a.ply, b.ply with --halves), rig.json, truth.json, "
                                    "truth_skin.ply (the cloud's frame = b's)")
      ->capture_default_str();
  scc->add_option("--seed", sc->seed, "Random seed (noise, dropouts, outliers, pose)")->capture_default_str();
  scc->add_option("--views", sc->sim.views, "Directions around the hand's long axis")->capture_default_str();
  scc->add_option("--tilt", sc->sim.tilt_deg, "Views tilted alternately toward the fingertips and the wrist, deg")->capture_default_str();
  scc->add_option("--spacing", sc->sim.spacing_mm, "Ray spacing in each view, mm")->capture_default_str();
  scc->add_option("--noise", sc->sim.noise_mm, "Noise along the rays (sigma), mm")->capture_default_str();
  scc->add_option("--max-incidence", sc->sim.max_incidence_deg, "Steepest surface that returns, deg")->capture_default_str();
  scc->add_option("--dropout-from", sc->sim.dropout_from_deg, "Returns thin out from this incidence on, deg")->capture_default_str();
  scc->add_flag_callback("--no-stand", [sc] { sc->sim.stand = false; }, "No stand under the wrist end");
  scc->add_option("--outliers", sc->sim.outlier_share, "Stray points, as a share of the points")->capture_default_str();
  scc->add_flag_callback("--hand-frame", [sc] { sc->sim.arbitrary_pose = false; }, "Keep the hand frame (no random pose)");
  scc->add_option("--units", sc->units, "Units of the written coordinates: mm, cm, m or in")
      ->check(CLI::IsMember({"mm", "cm", "m", "in"}))->capture_default_str();
  scc->add_flag("--halves", sc->halves, "Also write the back views and the palm views as two clouds (a.ply, b.ply), each in a pose of its own");
  scc->add_flag("--force", sc->force, "Move things in the way of an output aside into a dated backup folder instead of refusing");
  out->push_back({scc, [sc, &progress] { synth_cloud(*sc, progress); }});

  auto sa = std::make_shared<SynthAnglesArgs>();
  auto* sac = synth->add_subcommand(
      "angles", "A joint-angle recording with known structure (a Gaussian of three synergies, or a curved grasp), to test calibration");
  sac->add_option("--out", sa->out, "Joint-angle CSV to write")->required();
  sac->add_option("--truth", sa->truth, "Also write the truth (mean and covariance, or the formulas) as JSON");
  sac->add_option("--kind", sa->options.kind, "gaussian or curved")->check(CLI::IsMember({"gaussian", "curved"}))->capture_default_str();
  sac->add_option("--rows", sa->options.rows, "Frames, [10, 1e6]")->check(CLI::Range(10L, 1000000L))->capture_default_str();
  sac->add_option("--seed", sa->options.seed, "The hand (means, synergy loadings) and the frames")->capture_default_str();
  sac->add_option("--person", sa->options.person, "0: no offsets; k >= 1: person k's own offsets (another glove calibration)")
      ->capture_default_str();
  sac->add_option("--offset-sd", sa->options.offset_sd, "Sd of a person's offsets, deg")->capture_default_str();
  sac->add_option("--gaps", sa->options.gaps, "Fraction of cells left empty, [0, 0.5]")->check(CLI::Range(0.0, 0.5))->capture_default_str();
  sac->add_option("--noise", sa->options.noise, "curved: noise per joint, deg")->capture_default_str();
  add_force_flag(sac, &sa->force);
  out->push_back({sac, [sa, &progress] { synth_angles(*sa, progress); }});

  out->push_back({ssc, [ss, &progress] {
                    ss->scanner.points = ss->scanner.scanlines;
                    synth_scan(*ss, progress);
                  }});
  for (const CLI::App* sub : synth->get_subcommands([](const CLI::App*) { return true; }))
    for (const CLI::Option* o : sub->get_options())
      for (const std::string& name : o->get_lnames()) synth_flags().insert("--" + name);
}

}  // namespace handskin::cli
