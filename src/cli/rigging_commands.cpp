// pose, animate, studio: the rigged skin (skin.glb) posed and animated by the solver.
#include <filesystem>
#include <memory>

#include "cli/commands.hpp"
#include "pipeline/mesh_files.hpp"
#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "posture/angle_table.hpp"
#include "posture/solver.hpp"
#include "render/preview.hpp"
#include "rigging/animation.hpp"
#include "rigging/pose.hpp"
#include "studio/server.hpp"
#include "rigging/gltf.hpp"

namespace handskin::cli {

namespace {

struct PoseArgs {
  std::string model, posture, out, png, view = "back", blend = "dqs";
  std::vector<std::string> sets, torques, targets;
  int size = 1024;
  double texture_weight = 0.7;
  bool no_crease_guard = false, force = false;
};

void pose_command(const PoseArgs& a, const Progress& progress) {
  namespace fs = std::filesystem;
  if (a.out.empty() && a.png.empty()) throw UsageError("pose", "nothing to write: give --out and/or --png");
  std::string ext;
  if (!a.out.empty()) {
    ext = fs::path(a.out).extension().string();
    if (ext != ".glb") require_mesh_extension(a.out, "--out");
  }
  if (!a.png.empty()) require_png(a.png, "--png");
  const Blend blend = parse_blend(a.blend, "--blend");
  PostureInputs given;  // the flags' inputs (after the --posture file's pins, below)
  int d;
  double v, w;
  for (const auto& s : a.sets) parse_assignment(s, "--set", &d, &v), given.pins.emplace_back(d, v);
  for (const auto& s : a.torques) parse_assignment(s, "--torque", &d, &v), given.torques.emplace_back(d, v);
  for (const auto& s : a.targets) parse_assignment(s, "--target", &d, &v, &w), given.targets.push_back({d, v, w});
  const Eigen::Matrix3d view = a.png.empty() ? Eigen::Matrix3d::Identity() : named_view(a.view);
  // Every usage error said: the outputs claimed before any work.
  std::vector<std::string> written;
  for (const std::string* f : {&a.out, &a.png})
    if (!f->empty()) written.push_back(*f);
  OutputFiles files(written, output_options(a.force));
  const RiggedSkin skin = read_skin_glb(a.model);
  PostureInputs in;
  if (!a.posture.empty()) {
    const AngleTable t = read_angle_table(a.posture);
    if (t.rows.empty()) throw InputError(a.posture, "no posture row");
    for (size_t c = 0; c < t.columns.size(); ++c)
      if (std::isfinite(t.rows[0][c])) in.pins.emplace_back(t.columns[c], t.rows[0][c]);
  }
  in.pins.insert(in.pins.end(), given.pins.begin(), given.pins.end());
  in.torques = given.torques;
  in.targets = given.targets;
  const PostureSolver solver(skin.model);
  const PostureSolution sol = solver.solve(in);
  if (sol.clamped_inputs)
    progress("pose", "warning: " + std::to_string(sol.clamped_inputs) + " input(s) outside the model's limits were clamped onto them");
  Untangled u;
  const std::vector<Eigen::Vector3d> posed =
      SkinPoser(skin.mesh.vertices, skin.mesh.faces, skin.binding, skin.rig, !a.no_crease_guard).pose(sol.angles, blend, &u);
  if (!a.no_crease_guard) {
    if (u.folding_before)
      progress("pose", "crease guard: " + std::to_string(u.folding_before) + " folding triangle pair(s) smoothed out over " +
                           std::to_string(u.moved) + " vertices in " + std::to_string(u.rounds) + " round(s)" +
                           (u.folding_after ? "; " + std::to_string(u.folding_after) + " remain" : ""));
  }
  // Everything computed; now the files, each atomically.
  if (!a.out.empty()) {
    if (ext == ".glb") {
      const std::vector<unsigned char> glb = skin_glb(skin, &sol.angles);
      write_file_atomic(files.stage(a.out), std::string(glb.begin(), glb.end()));
    } else {
      save_mesh(files.stage(a.out), Mesh{posed, skin.mesh.faces});
    }
  }
  if (!a.png.empty()) {
    const Mesh mesh{posed, skin.mesh.faces};
    RenderOptions ro;
    ro.width = ro.height = a.size;
    ro.view = view * hand_frame_from_rig(skin.rig).linear();
    if (!skin.texture.empty()) ro.texture = &skin.texture, ro.texture_weight = static_cast<float>(a.texture_weight);
    write_file_atomic(files.stage(a.png), render_mesh_png({&mesh}, ro));
  }
  files.commit();
  std::printf("posed %zu vertices (%s, %s binding)%s%s\n", posed.size(), a.blend.c_str(), skin.binding.mode.c_str(),
              a.out.empty() ? "" : (" -> " + a.out).c_str(), a.png.empty() ? "" : (" -> " + a.png).c_str());
}

struct AnimateArgs {
  std::string model, keys, out, csv;
  double fps = 30;
  bool inputs_only = false, force = false;
};

void animate_command(const AnimateArgs& a, const Progress& progress) {
  namespace fs = std::filesystem;
  if (fs::path(a.out).extension() != ".glb") throw UsageError("--out", "'" + a.out + "': the animation is written as a .glb");
  if (!a.csv.empty() && fs::path(a.csv).extension() != ".csv")
    throw UsageError("--csv", "'" + a.csv + "': the frames are written as a .csv");
  std::vector<std::string> written = {a.out};
  if (!a.csv.empty()) written.push_back(a.csv);
  OutputFiles files(written, output_options(a.force));
  const RiggedSkin skin = read_skin_glb(a.model);
  const KeyFrames keys = read_keyframes(a.keys);
  const PostureSolver solver(skin.model);
  progress("animate", std::to_string(keys.times.size()) + " keys over " + number_text(keys.times.back() - keys.times.front()) +
                          " s, " + (a.inputs_only ? "the inputs interpolated and the solver filling in every frame"
                                                  : "every DOF interpolated between the solved keys"));
  const PostureAnimation anim = animate(solver, keys, a.fps, a.inputs_only, a.keys);
  if (anim.clamped)
    progress("animate", "warning: " + std::to_string(anim.clamped) + " value(s) outside the model's limits were moved onto them");
  const std::vector<unsigned char> glb = skin_glb(skin, nullptr, &anim);
  // Everything computed; now the files, each atomically.
  write_file_atomic(files.stage(a.out), std::string(glb.begin(), glb.end()));
  if (!a.csv.empty()) write_file_atomic(files.stage(a.csv), animation_csv(anim));
  files.commit();
  std::printf("animated %zu frames over %s s at %s fps -> %s%s\n", anim.frames.size(), number_text(anim.times.back()).c_str(),
              number_text(a.fps).c_str(), a.out.c_str(), a.csv.empty() ? "" : (", " + a.csv).c_str());
}

void studio_command(const StudioOptions& o, const Progress& progress) {
  StudioServer server(o);  // the model and the page load, or a one-line error, before listening
  server.run([&](int port) {
    progress("studio", "serving " + o.model + " on http://" + o.address + ":" + std::to_string(port) + "/ (Ctrl-C stops)");
    std::printf("http://%s:%d/\n", o.address.c_str(), port);
    std::fflush(stdout);
  });
}

}  // namespace

/// The skin.glb a command poses (`--skin`); `--model` is a posture model in every command,
/// so here it is refused with the name to use (hidden from --help).
static void add_skin_option(CLI::App* c, std::string* skin, const std::string& help) {
  c->add_option("--skin", *skin, help)->required();
  c->add_option_function<std::string>("--model", [](const std::string&) {
     throw CLI::ValidationError("--model", "is a posture model in every command; give the skin.glb as --skin");
   })->group("");
}

void add_rigging_commands(CLI::App& app, const Progress& progress, Commands* out) {
  auto pa = std::make_shared<PoseArgs>();
  auto* pc = app.add_subcommand("pose", "Pose a rigged skin (skin.glb from run): the solver's posture from a few inputs, the skin deformed");
  add_skin_option(pc, &pa->model, "skin.glb (its extras carry the rig and the posture model)");
  pc->add_option("--set", pa->sets, "Pin a DOF: name=degrees (repeatable), e.g. L2.flex=60");
  pc->add_option("--torque", pa->torques, "Instructed input on a DOF: name=value (repeatable)");
  pc->add_option("--target", pa->targets, "Soft target: name=degrees[@weight] (repeatable)");
  pc->add_option("--posture", pa->posture, "Joint-angle CSV: its first row's cells are pinned");
  pc->add_option("--blend", pa->blend, "dqs (dual quaternions: keeps the volume at bent joints) or lbs (linear blend, what glTF viewers do)")
      ->check(CLI::IsMember({"lbs", "dqs"}))
      ->capture_default_str();
  pc->add_option("--out", pa->out, "Posed skin: .ply, .obj, .off or .stl (vertex order kept; .stl for printing), or .glb (the rigged skin with the posture on its joints)");
  pc->add_option("--png", pa->png, "Also a picture of the posed skin (.png)");
  pc->add_option("--view", pa->view, "Picture view: back, palm or side")->check(CLI::IsMember({"back", "palm", "side"}))->capture_default_str();
  pc->add_option("--size", pa->size, "Picture width and height, px")->check(CLI::Range(16, 4096))->capture_default_str();
  pc->add_flag("--no-crease-guard", pa->no_crease_guard,
               "Leave the blend as it is (what glTF viewers show): by default the skin on the inside of a bent joint is "
               "held to its side of the joint's bisecting plane, and what still crumples there is smoothed out, so it does not "
               "fold into itself");
  pc->add_option("--texture-weight", pa->texture_weight,
                 "Picture of a textured skin: colour = (1 - w) shading + w texture (the thesis blended 0.3 : 0.7)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  add_force_flag(pc, &pa->force);
  out->push_back({pc, [pa, &progress] { pose_command(*pa, progress); }});

  auto aa = std::make_shared<AnimateArgs>();
  auto* ac = app.add_subcommand("animate",
                                "Animate a rigged skin (skin.glb from run) from keyframes: a glTF animation that three.js, Blender "
                                "and WebXR play, and the frames as a joint-angle CSV (docs/studio.md)");
  add_skin_option(ac, &aa->model, "skin.glb (its extras carry the rig and the posture model)");
  ac->add_option("--keys", aa->keys,
                 "Keys: a joint-angle CSV, one key a row, with a 'time' column in seconds (without one, keys are 1 s apart); "
                 "empty cells are not given")
      ->required();
  ac->add_flag("--inputs-only", aa->inputs_only,
               "Constrained animation: interpolate only the keys' DOFs (each key must give them all) and let the solver "
               "produce the whole hand at every frame; without it each key is solved into a whole posture and every DOF "
               "is interpolated (cubic Bezier in time)");
  ac->add_option("--fps", aa->fps, "Frames per second, [1, 240]")->check(CLI::Range(1.0, 240.0))->capture_default_str();
  ac->add_option("--out", aa->out, "The animated skin: .glb (the rigged skin with an animation 'handskin')")->required();
  ac->add_option("--csv", aa->csv, "Also the frames: time and every DOF per row (.csv)");
  add_force_flag(ac, &aa->force);
  out->push_back({ac, [aa, &progress] { animate_command(*aa, progress); }});

  auto so = std::make_shared<StudioOptions>();
  so->web_dir = HANDSKIN_STUDIO_WEB;
  auto* sc = app.add_subcommand("studio", "The hand studio: a local web page that poses the skin live with the solver (docs/studio.md)");
  add_skin_option(sc, &so->model, "skin.glb (from run)");
  sc->add_option("--port", so->port, "Port to listen on (0: any free one, printed)")->check(CLI::Range(0, 65535))->capture_default_str();
  sc->add_option("--address", so->address, "Address to listen on (loopback unless given)")->capture_default_str();
  sc->add_option("--web", so->web_dir, "The built page's folder")->capture_default_str();
  out->push_back({sc, [so, &progress] { studio_command(*so, progress); }});
}

}  // namespace handskin::cli
