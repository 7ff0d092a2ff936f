// solve, calibrate, model, mocap: the posture commands.
#include <cstring>
#include <memory>
#include <optional>

#include "cli/commands.hpp"
#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/rig.hpp"
#include "posture/calibrate.hpp"
#include "posture/mocap.hpp"
#include "posture/solution_io.hpp"
#include "posture/solver.hpp"
#include "render/preview.hpp"

namespace handskin::cli {

namespace {

// ---------------- solve ----------------
struct SolveArgs {
  std::string model, rig, inputs, out, picture, view = "side";
  std::vector<std::string> sets, torques, targets;
  bool json = false, linear = false, force = false;
};

PostureInputs parse_inputs(const SolveArgs& a) {
  PostureInputs in;
  int d;
  double v, w;
  for (const auto& t : a.sets) parse_assignment(t, "--set", &d, &v), in.pins.emplace_back(d, v);
  for (const auto& t : a.torques) parse_assignment(t, "--torque", &d, &v), in.torques.emplace_back(d, v);
  for (const auto& t : a.targets) parse_assignment(t, "--target", &d, &v, &w), in.targets.push_back({d, v, w});
  return in;
}

void solve_command(const SolveArgs& a, const Progress& progress) {
  const PostureModel model = load_model(a.model);
  const PostureSolver solver(model);
  if (!a.inputs.empty() || !a.out.empty()) {
    if (a.inputs.empty() || a.out.empty()) throw UsageError("solve", "batch mode needs both --inputs and --out");
    if (!a.sets.empty() || !a.torques.empty() || !a.targets.empty() || !a.rig.empty())
      throw UsageError("solve", "--set/--torque/--target/--rig do not combine with --inputs (each row's cells are its inputs)");
    OutputFiles files({a.out}, output_options(a.force));
    const BatchSolution b = solve_batch(solver, read_angle_table(a.inputs), a.linear);
    write_angle_table(files.stage(a.out), b.angles);
    files.commit();
    if (b.clamped_rows)
      progress("solve", "warning: " + std::to_string(b.clamped_cells) + " input value(s) in " +
                            std::to_string(b.clamped_rows) + " row(s) lay outside the model's limits and were clamped onto them");
    std::printf("%zu postures solved -> %s\n", b.angles.rows.size(), a.out.c_str());
    return;
  }
  const PostureInputs in = parse_inputs(a);
  // The rig (and the skeleton built from it, once) are checked before any solving.
  if (!a.picture.empty() && a.rig.empty()) throw UsageError("--png", "needs --rig (the skeleton to draw)");
  if (!a.picture.empty()) require_png(a.picture, "--png");
  // The picture's view (a usage error) before its file is claimed.
  const Eigen::Matrix3d view = a.picture.empty() ? Eigen::Matrix3d::Identity() : named_view(a.view);
  std::optional<OutputFiles> files;
  if (!a.picture.empty()) files.emplace(std::vector<std::string>{a.picture}, output_options(a.force));
  std::optional<Rig> rig;
  std::optional<Skeleton> skeleton;
  if (!a.rig.empty()) {
    rig = load_rig(a.rig);
    skeleton.emplace(*rig);
  }
  const PostureSolution s = a.linear ? solver.solve_linear(in) : solver.solve(in);
  if (s.clamped_inputs)
    progress("solve", "warning: " + std::to_string(s.clamped_inputs) + " input(s) outside the limits were clamped onto them");
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
    ro.view = view * hand_frame_from_rig(*rig).linear();
    write_file_atomic(files->stage(a.picture),
                      render_skeletons_png({{{rest.begin(), rest.end()}, parents, {0.6f, 0.6f, 0.65f}},
                                            {{joint_pos.begin(), joint_pos.end()}, parents, {0.8f, 0.15f, 0.15f}}},
                                           ro));
    files->commit();
  }
  if (a.json) {
    std::printf("%s\n", posture_solution_to_json(model, in, s, rig ? &joint_pos : nullptr).dump(2).c_str());
    return;
  }
  std::vector<char> pinned(kDofCount, 0), limited(kDofCount, 0);
  for (const auto& [d, v] : in.pins) pinned[d] = 1;
  for (int d : s.at_limit) limited[d] = 1;
  if (!s.component_weights.empty()) {
    std::printf("model %s: mixture of %zu Gaussians, posterior weights", model.name.c_str(), s.component_weights.size());
    for (double w : s.component_weights) std::printf(" %.3f", w);
    std::printf(", free energy %.4f\n", s.energy);
  } else {
    std::printf("model %s: %d %s, energy %.4f%s\n", model.name.c_str(), s.iterations,
                solver.has_grids() && !a.linear ? "Gauss-Newton step(s)" : "active-set round(s)", s.energy,
                s.converged ? "" : " (not converged)");
  }
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
  std::vector<std::string> angles;
  std::string out, report;
  std::vector<std::string> pairs;
  CalibrationOptions options;
  bool no_evaluate = false, force = false;
};

// The cross-validation as a table: per scheme and task, the model's held-out RMS beside the
// training mean posture's and the linear regression's.
void print_cross_validation(const Json& rep) {
  if (!rep.contains("cross_validation")) return;
  auto num = [](const Json& v) { return v.is_number() ? std::to_string(v.get<double>()).substr(0, 5) : std::string("  -  "); };
  for (const char* scheme : {"blocks", "recordings"}) {
    if (!rep["cross_validation"].contains(scheme)) continue;
    const Json& cv = rep["cross_validation"][scheme];
    std::printf("held-out %s (%d folds), RMS deg over the predicted joints:\n",
                std::string(scheme) == "blocks" ? "blocks of each recording" : "recordings, one left out at a time",
                cv["folds"].get<int>());
    const bool linear = !cv["tasks"].empty() && cv["tasks"][0].contains("linear_model_rms_deg");
    std::printf("  %-34s %7s %s %7s %7s %7s\n", "task", "model", linear ? "linear" : "", "mean", "linreg", "ratio");
    for (const auto& t : cv["tasks"])
      std::printf("  %-34s %7s %s %7s %7s %7s\n", t["task"].get<std::string>().c_str(), num(t["model_rms_deg"]).c_str(),
                  linear ? num(t["linear_model_rms_deg"]).c_str() : "", num(t["mean_posture_rms_deg"]).c_str(),
                  num(t["linear_regression_rms_deg"]).c_str(), num(t["model_over_regression"]).c_str());
  }
  for (const auto& s : rep["tasks_skipped"]) std::printf("  (skipped: %s)\n", s.get<std::string>().c_str());
}

void calibrate_command(CalibrateArgs a, const Progress& progress) {
  for (const auto& p : a.pairs) {
    const size_t colon = p.find(':');
    if (colon == std::string::npos) throw UsageError("--pair", "'" + p + "' is not of the form dofA:dofB");
    const int da = require_dof(p.substr(0, colon), "--pair"), db = require_dof(p.substr(colon + 1), "--pair");
    if (da == db) throw UsageError("--pair", "'" + p + "' names one DOF twice; a pair needs two different DOFs");
    a.options.pairs.emplace_back(da, db);
  }
  a.options.evaluate = !a.no_evaluate;
  std::string err;
  if (!a.options.IsValid(&err)) {
    // The options' messages name their fields; the user gave flags: name the flag.
    for (const auto& [field, flag] : std::initializer_list<std::pair<const char*, const char*>>{
             {"weights", "--weights"}, {"method", "--method"}, {"offsets", "--offsets"}, {"shrinkage", "--shrinkage"},
             {"components", "--components"}, {"folds", "--folds"}, {"pairs", "--pair"}})
      if (err.rfind(std::string(field) + " ", 0) == 0) throw UsageError(flag, err.substr(std::strlen(field) + 1));
    throw UsageError("calibrate", err);
  }
  std::vector<std::string> written = {a.out};
  if (!a.report.empty()) written.push_back(a.report);
  OutputFiles files(written, output_options(a.force));
  std::vector<AngleTable> tables;
  size_t rows = 0;
  for (const auto& f : a.angles) tables.push_back(read_angle_table(f)), rows += tables.back().rows.size();
  progress("calibrate", std::to_string(a.angles.size()) + " recording(s), " + std::to_string(rows) + " rows; method " +
                            a.options.method + (a.options.evaluate ? ", with cross-validation" : ""));
  Json rep;
  const PostureModel m = calibrate(tables, a.angles, a.options, &rep);
  const PostureSolver check(m);  // refuses a model that would not solve
  save_model(files.stage(a.out), m);
  if (!a.report.empty()) save_json(files.stage(a.report), rep);
  files.commit();
  for (const auto& n : m.notes) progress("calibrate", "note: " + n);
  if (a.options.method == "thesis-pairs") {
    std::printf("%zu pair(s)%s -> %s\n", m.pairs.size(), m.grids.empty() ? "" : " with grids", a.out.c_str());
    for (const auto& p : rep["pairs"])
      std::printf("  %-16s ~ %-16s r %+.3f  slope %s  spread %.2f deg  weight %.3f\n", p["a"].get<std::string>().c_str(),
                  p["b"].get<std::string>().c_str(), p["r"].get<double>(),
                  p["slope"].is_null() ? "vertical" : std::to_string(p["slope"].get<double>()).substr(0, 6).c_str(),
                  p["spread_rms_deg"].get<double>(), p["weight"].get<double>());
  } else {
    std::printf("%s: %zu DOFs from %lld frames (%lld complete), shrinkage %g, offsets %s, %zu synergy row(s)%s -> %s\n",
                a.options.method.c_str(), rep["gaussian"]["dofs"].get<size_t>(), rep["frames"].get<long long>(),
                rep["frames_complete"].get<long long>(), rep["shrinkage"].get<double>(), rep["offsets"].get<std::string>().c_str(),
                m.constraints.size(),
                m.mixture.components.empty() ? "" : (", " + std::to_string(m.mixture.components.size()) + " mixture components").c_str(),
                a.out.c_str());
  }
  print_cross_validation(rep);
}

// ---------------- mocap ----------------
struct MocapArgs {
  std::string in, out;
  int every = 1;
  bool force = false;
};

void mocap_command(const MocapArgs& a, const Progress& progress) {
  if (a.every < 1) throw UsageError("--every", "must be >= 1");
  OutputFiles files({a.out}, output_options(a.force));
  const MarkerTrack track = read_marker_file(a.in);
  progress("mocap", std::to_string(track.frames.size()) + " frames, " + std::to_string(track.names.size()) + " markers");
  MocapAngles ang = angles_from_markers(track, a.in);
  AngleTable out;
  out.columns = ang.table.columns;
  for (size_t r = 0; r < ang.table.rows.size(); r += a.every) out.rows.push_back(ang.table.rows[r]);
  write_angle_table(files.stage(a.out), out);
  files.commit();
  for (const auto& n : ang.notes) progress("mocap", n);
  std::printf("%zu rows of %zu angles -> %s (%zu frames had missing markers)\n", out.rows.size(), out.columns.size(),
              a.out.c_str(), ang.frames_with_gaps);
}

struct ModelArgs {
  std::string in, out;
  bool force = false;
};

}  // namespace

void add_posture_commands(CLI::App& app, const Progress& progress, Commands* out) {
  auto sv = std::make_shared<SolveArgs>();
  auto* solvec = app.add_subcommand("solve", "Posture from a few inputs: springs + constraint potentials (thesis ch. 3)");
  solvec->add_option("--model", sv->model, "Posture model (hand-posture/1 file, or builtin:anatomical / builtin:thesis)")
      ->required();
  solvec->add_option("--set", sv->sets, "Pin a DOF: name=degrees (repeatable), e.g. index.mcp.flex=40 or L2.flex=60");
  solvec->add_option("--torque", sv->torques, "Instructed input on a DOF: name=value (repeatable, |value| <= 1e4)");
  solvec->add_option("--target", sv->targets, "Soft target: name=degrees[@weight] (repeatable, weight in (0, 1e6])");
  solvec->add_option("--rig", sv->rig, "hand-rig/1: also print joint positions of the posture");
  solvec->add_flag("--json", sv->json, "Print JSON (handskin-posture-solution/1)");
  solvec->add_option("--png", sv->picture, "With --rig: draw the relaxed (grey) and solved (red) skeleton to a PNG");
  solvec->add_option("--view", sv->view, "Picture view: side, back or palm")->capture_default_str();
  solvec->add_flag("--linear", sv->linear, "Ignore the model's non-linear grids or mixture (the linear model alone)");
  solvec->add_option("--inputs", sv->inputs, "Batch: CSV of partial postures (given cells are pinned)");
  solvec->add_option("--out", sv->out, "Batch: CSV of full postures, rows in input order");
  add_force_flag(solvec, &sv->force);
  out->push_back({solvec, [sv, &progress] { solve_command(*sv, progress); }});

  auto ca = std::make_shared<CalibrateArgs>();
  auto* calc = app.add_subcommand("calibrate", "Posture model from joint-angle recordings, with held-out figures");
  calc->add_option("--angles", ca->angles,
                   "Joint-angle CSV (header: DOF names; empty cell = not measured); repeat for several recordings (one per person or session)")
      ->required();
  calc->add_option("--out", ca->out, "Model to write (hand-posture/1)")->required();
  calc->add_option("--method", ca->options.method,
                   "gaussian (conditional mean of the shrunk joint covariance), mixture (of Gaussians, non-linear), "
                   "or thesis-pairs (thesis §3.2.2-3.2.3)")
      ->check(CLI::IsMember({"gaussian", "mixture", "thesis-pairs"}))
      ->capture_default_str();
  calc->add_option("--offsets", ca->options.offsets,
                   "Per-recording offsets: remove, keep, or auto (chosen by leaving recordings out)")
      ->check(CLI::IsMember({"auto", "remove", "keep"}))
      ->capture_default_str();
  calc->add_option("--shrinkage", ca->options.shrinkage, "Covariance shrinkage toward its diagonal, [0, 1]; default: chosen by cross-validation")
      ->check(CLI::Range(0.0, 1.0));
  calc->add_option("--components", ca->options.components, "Mixture components, 2-16; default: chosen by cross-validation")
      ->check(CLI::Range(2, 16));
  calc->add_option("--folds", ca->options.folds, "Held-out blocks per recording, 2-50")->check(CLI::Range(2, 50))->capture_default_str();
  calc->add_flag("--no-evaluate", ca->no_evaluate, "Skip the cross-validated figures (the fit still validates its choices)");
  calc->add_option("--pair", ca->pairs, "thesis-pairs: a pair to fit, dofA:dofB (repeatable; default: chosen by correlation)");
  calc->add_option("--min-correlation", ca->options.min_correlation, "thesis-pairs: |r| for automatic pairs")->capture_default_str();
  calc->add_option("--max-pairs", ca->options.max_pairs, "thesis-pairs: most automatic pairs")->capture_default_str();
  calc->add_option("--weights", ca->options.weights, "thesis-pairs: thesis (eq. 3.18) or inverse (1/spread)")->capture_default_str();
  calc->add_flag("--grids", ca->options.grids, "thesis-pairs: also build non-linear grid potentials (thesis §3.2.3)");
  calc->add_option("--grid-weight", ca->options.grid_weight, "thesis-pairs: weight of the grid potentials, (0, 1e3]")->capture_default_str();
  calc->add_option("--report", ca->report, "Write the calibration figures and the cross-validation as JSON");
  add_force_flag(calc, &ca->force);
  out->push_back({calc, [ca, &progress] { calibrate_command(*ca, progress); }});

  auto mo = std::make_shared<ModelArgs>();
  auto* modc = app.add_subcommand("model", "Check a posture model and write it out in full (e.g. a built-in set, to edit)");
  modc->add_option("--model", mo->in, "hand-posture/1 file, or builtin:anatomical / builtin:thesis")->required();
  modc->add_option("--out", mo->out, "Where to write it (absolute-angle pairs, every DOF listed)")->required();
  add_force_flag(modc, &mo->force);
  out->push_back({modc, [mo] {
                    OutputFiles files({mo->out}, output_options(mo->force));
                    const PostureModel m = load_model(mo->in);
                    const PostureSolver check(m);  // refuses a model that cannot solve
                    save_model(files.stage(mo->out), m);
                    files.commit();
                    std::printf("%s: %zu pairs, %zu grids -> %s\n", m.name.c_str(), m.pairs.size(), m.grids.size(),
                                mo->out.c_str());
                  }});

  auto mc = std::make_shared<MocapArgs>();
  auto* mocc = app.add_subcommand("mocap", "Joint angles from motion capture (Qualisys .tsv, OpenSim .trc) to CSV");
  mocc->add_option("--in", mc->in, "Marker file (.tsv or .trc)")->required();
  mocc->add_option("--out", mc->out, "Joint-angle CSV to write")->required();
  mocc->add_option("--every", mc->every, "Keep every n-th frame")->capture_default_str();
  add_force_flag(mocc, &mc->force);
  out->push_back({mocc, [mc, &progress] { mocap_command(*mc, progress); }});
}

}  // namespace handskin::cli
