// Benchmarks: `build/bench/handskin_bench`. Figures, not pass/fail.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <chrono>
#include <fcntl.h>
#include <filesystem>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "posture/calibrate.hpp"
#include "synth/angle_recording.hpp"
#include "rigging/deform.hpp"
#include "render/preview.hpp"
#include "rigging/crease.hpp"
#include "texture/texture.hpp"
#include "rigging/gltf.hpp"
#include "studio/api.hpp"
#include "studio/server.hpp"
#include "posture/solver.hpp"
#include "register/registration.hpp"
#include "skin/auto_rig.hpp"
#include "patches/layout.hpp"
#include "patches/patches.hpp"
#include "pipeline/patch_report.hpp"
#include "export/step.hpp"
#include "pipeline/patch_stage.hpp"
#include "skin/baseline.hpp"
#include "skin/skin_mesh.hpp"

#include "core/atomic_file.hpp"
#include "core/random.hpp"
#include "scan/cloud.hpp"
#include "scan/cloud_file.hpp"
#include "scan/cubist_io.hpp"
#include "synth/hand_mesher.hpp"
#include "synth/hand_model.hpp"
#include "synth/replica.hpp"
#include "synth/cloud_sim.hpp"
#include "register/cloud_prep.hpp"

#include <httplib.h>  // after Eigen's headers (see studio/server.cpp)

#include <atomic>
#include <thread>

using namespace handskin;
static const std::string kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

// HANDSKIN_BENCH_SMOKE set: every benchmark once (the test bench_smoke, with
// --benchmark_min_time=0.001 for the ones that pick their own count): a benchmark that throws,
// crashes or whose command fails is found by the test suite, not by the next person timing.
static int its(int n) {
  static const bool smoke = std::getenv("HANDSKIN_BENCH_SMOKE") != nullptr;
  return smoke ? 1 : n;
}

static void BM_DecodeScan512(benchmark::State& st) {
  const std::string png = read_file(kFix + "back.png"), json = read_file(kFix + "back.json");
  for (auto _ : st) benchmark::DoNotOptimize(decode_scan(png, "back.png", json, "back.json"));
}
BENCHMARK(BM_DecodeScan512)->Unit(benchmark::kMillisecond);

static void BM_ScanToCloud512(benchmark::State& st) {
  const RangeScan s = load_scan(kFix + "back");
  for (auto _ : st) benchmark::DoNotOptimize(dense_copy(*scan_to_organized_cloud(s)));
}
BENCHMARK(BM_ScanToCloud512)->Unit(benchmark::kMillisecond);

static void BM_MeshDefaultHand(benchmark::State& st) {
  const HandModel m = build_hand_model(HandShapeOptions{});
  for (auto _ : st) benchmark::DoNotOptimize(mesh_hand(m, HandMeshOptions{}));
}
BENCHMARK(BM_MeshDefaultHand)->Unit(benchmark::kSecond)->Iterations(its(1));

static void BM_SynthScanPair(benchmark::State& st) {
  const HandModel m = build_hand_model(HandShapeOptions{});
  const HandMeshResult mesh = mesh_hand(m, HandMeshOptions{});
  std::uint64_t seed = 1;
  for (auto _ : st)
    benchmark::DoNotOptimize(synthesize_scan_pair(mesh.mesh, m.rig, ReplicaOptions{}, ScannerOptions{}, seed++, false));
}
BENCHMARK(BM_SynthScanPair)->Unit(benchmark::kMillisecond)->Iterations(its(3));

// Registration of the fixture pair with `o`, table removal through merge; the per-step split
// (from the stage's own timings, last iteration) and the marker radius used are counters.
static void time_fixture_registration(benchmark::State& st, const RegistrationOptions& o) {
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const RangeScan back = load_scan(dir + "back"), palm = load_scan(dir + "palm");
  std::vector<std::pair<std::string, double>> timings;
  double radius = 0;
  for (auto _ : st) {
    const Registration reg = register_scans(back, palm, "back", "palm", o, nullptr, [](const std::string&) {});
    timings = reg.figures.timings_ms;
    radius = reg.marker_radius_mm;
    benchmark::DoNotOptimize(reg.back_to_palm);
  }
  for (const auto& [k, v] : timings) st.counters[k] = v;
  st.counters["radius_mm"] = radius;
}

// The radius given (4 mm).
static void BM_RegisterFixturePair(benchmark::State& st) { time_fixture_registration(st, RegistrationOptions{}); }
BENCHMARK(BM_RegisterFixturePair)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// The same with the refinement off (marker-only fit), to show what the refinement costs.
static void BM_RegisterFixturePairMarkerOnly(benchmark::State& st) {
  RegistrationOptions o;
  o.refine_enabled = false;
  time_fixture_registration(st, o);
}
BENCHMARK(BM_RegisterFixturePairMarkerOnly)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// The default pipeline's registration: the marker radius estimated from the scans first
// (every candidate radius detected in both scans and matched), then the registration.
static void BM_RegisterFixturePairRadiusEstimated(benchmark::State& st) {
  RegistrationOptions o;
  o.estimate_radius = true;
  time_fixture_registration(st, o);
}
BENCHMARK(BM_RegisterFixturePairRadiusEstimated)->Unit(benchmark::kMillisecond)->Iterations(its(5));

// ---- posture solver ----
namespace {
int dof(const char* n) { return dof_index(n).value(); }

// A calibrated model with grids: the ring/little MCP pair along a measured curve.
PostureModel curved_model() {
  AngleTable t;
  t.columns = {dof("ring.mcp.flex"), dof("little.mcp.flex"), dof("middle.mcp.flex")};
  Rng rng(9);
  for (int r = 0; r < 600; ++r) {
    const double u = rng.uniform(0, M_PI / 2);
    const double ring = 60 - 60 * std::cos(u) + rng.normal() * 0.5;
    t.rows.push_back({ring, 60 * std::sin(u) + rng.normal() * 0.5, 0.8 * ring + rng.normal()});
    t.lines.push_back(r);
  }
  CalibrationOptions o;
  o.method = "thesis-pairs";
  o.grids = true;
  return calibrate(t, o, "bench", nullptr);
}

// Calibrated from a synthetic recording (19 DOFs): the Gaussian (dense synergy rows) or a
// mixture of 8 Gaussians.
PostureModel synthetic_model(const std::string& kind, const std::string& method) {
  AngleRecordingOptions r;
  r.kind = kind;
  r.rows = 4000;
  CalibrationOptions o;
  o.method = method;
  o.evaluate = false;
  if (method == "mixture") o.components = 8;
  o.shrinkage = 0.01;
  return calibrate(synth_angle_recording(r).table, o, "bench", nullptr);
}

// Rows pinning the standard tasks' joint sets (one MCP; the MCPs; the PIPs), values varying.
std::vector<PostureInputs> task_rows() {
  const std::vector<std::vector<int>> sets = {
      {dof("middle.mcp.flex")},
      {dof("thumb.mcp.flex"), dof("index.mcp.flex"), dof("middle.mcp.flex"), dof("ring.mcp.flex"), dof("little.mcp.flex")},
      {dof("index.pip.flex"), dof("middle.pip.flex"), dof("ring.pip.flex"), dof("little.pip.flex")}};
  Rng rng(4);
  std::vector<PostureInputs> rows(4096);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int d : sets[i % 3]) rows[i].pins.emplace_back(d, rng.uniform(10, 70));
  return rows;
}
}  // namespace

// The default (Gaussian) calibration's model in batch: postures per second on one core.
static void BM_PostureGaussianBatch(benchmark::State& st) {
  const PostureSolver s(synthetic_model("gaussian", "gaussian"));
  const std::vector<PostureInputs> rows = task_rows();
  size_t i = 0;
  for (auto _ : st) benchmark::DoNotOptimize(s.solve(rows[i++ % rows.size()]).angles[0]);
  st.SetItemsProcessed(static_cast<int64_t>(st.iterations()));
}
BENCHMARK(BM_PostureGaussianBatch)->Unit(benchmark::kMicrosecond);

// The mixture mode (8 components): one posture (issue 14's bound: 50 µs).
static void BM_PostureMixtureSolve(benchmark::State& st) {
  const PostureSolver s(synthetic_model("curved", "mixture"));
  const std::vector<PostureInputs> rows = task_rows();
  size_t i = 0;
  for (auto _ : st) benchmark::DoNotOptimize(s.solve(rows[i++ % rows.size()]).angles[0]);
  st.SetItemsProcessed(static_cast<int64_t>(st.iterations()));
  st.counters["components"] = static_cast<double>(s.model().mixture.components.size());
}
BENCHMARK(BM_PostureMixtureSolve)->Unit(benchmark::kMicrosecond);

// One posture from one pinned input, linear model, the factorisation cached (same pin set).
static void BM_PostureLinearSolve(benchmark::State& st) {
  const PostureSolver s(builtin_model("anatomical"));
  PostureInputs in;
  in.pins = {{dof("little.mcp.flex"), 40.0}};
  double v = 0;
  for (auto _ : st) {
    in.pins[0].second = 20.0 + std::fmod(v += 0.37, 50.0);
    benchmark::DoNotOptimize(s.solve_linear(in).angles[dof("ring.mcp.flex")]);
  }
}
BENCHMARK(BM_PostureLinearSolve)->Unit(benchmark::kMicrosecond);

// One posture with non-linear grid potentials (Gauss–Newton to convergence).
static void BM_PostureNonlinearSolve(benchmark::State& st) {
  const PostureSolver s(curved_model());
  PostureInputs in;
  in.pins = {{dof("ring.mcp.flex"), 30.0}};
  double v = 0, iters = 0;
  for (auto _ : st) {
    in.pins[0].second = 5.0 + std::fmod(v += 0.37, 50.0);
    const PostureSolution sol = s.solve_nonlinear(in);
    iters += sol.iterations;
    benchmark::DoNotOptimize(sol.angles[dof("little.mcp.flex")]);
  }
  st.counters["gn_steps"] = iters / static_cast<double>(st.iterations());
}
BENCHMARK(BM_PostureNonlinearSolve)->Unit(benchmark::kMicrosecond);

// Batch: rows pinning one to three of six DOFs (the sets a glove or slider rig gives),
// values varying every row; postures per second on one core.
static void BM_PostureBatch(benchmark::State& st) {
  const PostureSolver s(builtin_model("anatomical"));
  const int pool[] = {dof("index.mcp.flex"), dof("middle.mcp.flex"), dof("ring.mcp.flex"),
                      dof("little.mcp.flex"), dof("thumb.mcp.flex"), dof("index.pip.flex")};
  Rng rng(4);
  std::vector<PostureInputs> rows(4096);
  for (auto& r : rows) {
    const int n = 1 + static_cast<int>(rng.uniform(0, 3));
    for (int k = 0; k < n; ++k) r.pins.emplace_back(pool[(static_cast<int>(rng.uniform(0, 6)) + k) % 6], rng.uniform(0, 80));
  }
  size_t i = 0;
  for (auto _ : st) benchmark::DoNotOptimize(s.solve_linear(rows[i++ % rows.size()]).angles[0]);
  st.SetItemsProcessed(static_cast<int64_t>(st.iterations()));
}
BENCHMARK(BM_PostureBatch)->Unit(benchmark::kMicrosecond);

// The fixture pair registered and merged (once).
static const MergedArrays& fixture_merged() {
  static const MergedArrays m = [] {
    const RangeScan back = load_scan(kFix + "back"), palm = load_scan(kFix + "palm");
    const Registration reg =
        register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, [](const std::string&) {});
    return merged_arrays(*reg.merged);
  }();
  return m;
}

// The skin stage (issue 5's goal: ≤ 200 ms): rings, stitching, decimation, checks.
static void skin_build(benchmark::State& st, const MergedArrays& m, const Rig& rig) {
  SkinResult s;
  for (auto _ : st) s = build_skin(m.points, rig, SkinOptions{});
  st.counters["points"] = static_cast<double>(m.points.size());
  st.counters["triangles"] = static_cast<double>(s.health.faces);
  st.counters["rings_ms"] = 1000 * s.seconds_rings;
  st.counters["stitch_ms"] = 1000 * s.seconds_union;
  st.counters["decimate_ms"] = 1000 * s.seconds_decimation;
  st.counters["fit_ms"] = 1000 * s.seconds_fit;
  st.counters["checks_ms"] = 1000 * s.seconds_checks;
}
static void BM_SkinBuild(benchmark::State& st) { skin_build(st, fixture_merged(), load_rig(kFix + "rig.json")); }
BENCHMARK(BM_SkinBuild)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// Automatic skeleton placement in the fixture's merged cloud.
static void BM_SkinAutoRig(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  for (auto _ : st) benchmark::DoNotOptimize(place_skeleton(m.points, m.sides));
}
BENCHMARK(BM_SkinAutoRig)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// The skin stage's baseline: Poisson (PCL, one thread) on the fixture's merged cloud (≤ 40 000 points).
static void BM_SkinPoissonBaseline(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  size_t faces = 0;
  for (auto _ : st) faces = poisson_baseline(m.points, m.normals).mesh.n_faces();
  st.counters["triangles"] = static_cast<double>(faces);
}
BENCHMARK(BM_SkinPoissonBaseline)->Unit(benchmark::kSecond)->Iterations(its(1));

// Bézier patches (issue 13): layout + fit + parameter correction of the 98 patches on the
// fixture's merged cloud and skin (the skin built outside the timing); bar 300 ms.
static void BM_PatchesFixture(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  static const Rig rig = load_rig(kFix + "rig.json");
  static const SkinResult skin = build_skin(m.points, rig, SkinOptions{});
  PatchSkin p;
  for (auto _ : st) p = fit_patch_skin(skin, rig, m.points, m.sides, PatchOptions{});
  st.counters["patches"] = static_cast<double>(p.patches.size());
  st.counters["rounds"] = static_cast<double>(p.max_update_per_round.size());
  st.counters["palm_mean_mm"] = p.side[0].mean;
  st.counters["back_mean_mm"] = p.side[1].mean;
}
BENCHMARK(BM_PatchesFixture)->Unit(benchmark::kMillisecond)->Iterations(its(5));

// The hand's patch layout alone on the fixture's skin: what the skin stage's check of each
// placed skeleton costs (docs/skin.md, "What refuses takes in").
static void BM_PatchLayout(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  static const Rig rig = load_rig(kFix + "rig.json");
  static const SkinResult skin = build_skin(m.points, rig, SkinOptions{});
  PatchLayout l;
  for (auto _ : st) l = hand_patch_layout(skin, rig, m.points, m.sides);
  st.counters["faces"] = static_cast<double>(l.faces.size());
}
BENCHMARK(BM_PatchLayout)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// The same refined to 0.5 mm (issue 38: --patch-tolerance 0.5; bar: at most 2 x BM_PatchesFixture).
static void BM_PatchesFixtureTolerance(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  static const Rig rig = load_rig(kFix + "rig.json");
  static const SkinResult skin = build_skin(m.points, rig, SkinOptions{});
  PatchOptions o;
  o.tolerance_mm = 0.5;
  PatchSkin p;
  for (auto _ : st) p = fit_patch_skin(skin, rig, m.points, m.sides, o);
  st.counters["patches"] = static_cast<double>(p.patches.size());
  st.counters["fits"] = p.refinement ? static_cast<double>(p.refinement->patches.size()) : 0.0;
  st.counters["held"] = p.refinement && p.refinement->held ? 1.0 : 0.0;
  st.counters["worst_mm"] = p.refinement ? p.refinement->worst_mm.back() : 0.0;
}
BENCHMARK(BM_PatchesFixtureTolerance)->Unit(benchmark::kMillisecond)->Iterations(its(2));

// patches.step of the fixture's 98 patches (the fit outside the timing): made (faces, sewing,
// the STEP model, the file) and read back as written, as every run does on a thread of its own
// (export/step.cpp; the run's report gives it as patches_step_seconds).
static void BM_PatchesStep(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  static const Rig rig = load_rig(kFix + "rig.json");
  static const SkinResult skin = build_skin(m.points, rig, SkinOptions{});
  static const PatchSkin p = fit_patch_skin(skin, rig, m.points, m.sides, PatchOptions{});
  StepFile f;
  for (auto _ : st) f = patches_step_file(p.patches);
  st.counters["bytes"] = static_cast<double>(f.bytes.size());
  st.counters["closed_solid"] = f.shape.solids == 1 && f.shape.closed_shells == 1 && f.shape.valid ? 1.0 : 0.0;
}
BENCHMARK(BM_PatchesStep)->Unit(benchmark::kMillisecond)->Iterations(its(10));

// The fitting-error report of the 98 patches on the fixture (issue 13's bar: ≤ 1 s): Table
// 4.1's cell-grid error and the noise floor, then report.html with its four pictures (the fit
// outside the timing).
static void BM_PatchReport(benchmark::State& st) {
  const MergedArrays& m = fixture_merged();
  static const Rig rig = load_rig(kFix + "rig.json");
  static const SkinResult skin = build_skin(m.points, rig, SkinOptions{});
  static const PatchStageResult r = run_patch_stage(skin, rig, m.points, m.sides, PatchOptions{}, nullptr);
  size_t bytes = 0;
  PatchStageResult page = r;
  for (auto _ : st) {
    page.figures = patch_report_figures(r.patches, 100);
    page.pictures = patch_report_pictures(r.patches, rig);
    bytes = patch_report_html(page).size();
  }
  st.counters["html_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_PatchReport)->Unit(benchmark::kMillisecond)->Iterations(its(3));

// The rigged skin (issue 15): the fixture's skin bound by bone heat (outside the timing), then
// per posture: one solve of the anatomical model from a pinned input, the link motions, and
// the ~4000-vertex skin deformed (LBS, and DQS). Postures per second on one core.
namespace {
struct RiggedFixture {
  Rig rig;
  SkinResult skin;
  std::vector<Eigen::Vector3d> rest;
  SkinBinding binding;
};
const RiggedFixture& rigged_fixture() {
  static const RiggedFixture f = [] {
    RiggedFixture r;
    r.rig = load_rig(kFix + "rig.json");
    r.skin = build_skin(fixture_merged().points, r.rig, SkinOptions{});
    r.rest = r.skin.mesh.vertices;
    r.binding = bind_skin(r.skin.mesh, bones_from_rig(r.rig), BindingOptions{});
    return r;
  }();
  return f;
}
void pose_skin(benchmark::State& st, Blend blend, bool guarded = false) {
  const RiggedFixture& f = rigged_fixture();
  const CreaseGuard guard = crease_guard(f.rest, f.binding, f.rig);
  const Skeleton skel(f.rig);
  const PostureSolver solver(builtin_model("anatomical"));
  PostureInputs in;
  in.pins = {{dof_index("index.pip.flex").value(), 0.0}};
  std::vector<Eigen::Vector3d> out;
  double v = 0;
  for (auto _ : st) {
    in.pins[0].second = std::fmod(v += 0.37, 100.0);
    const auto motions = link_motions(skel, solver.solve(in).angles);
    deform_into(f.rest, f.binding, motions, blend, &out);
    if (guarded) guard_creases(guard, motions, &out);
    benchmark::DoNotOptimize(out[0]);
  }
  st.SetItemsProcessed(static_cast<int64_t>(st.iterations()));
  st.counters["vertices"] = static_cast<double>(f.rest.size());
  st.counters["triangles"] = static_cast<double>(f.skin.mesh.n_faces());
}
}  // namespace
static void BM_PoseSkinLBS(benchmark::State& st) { pose_skin(st, Blend::Linear); }
BENCHMARK(BM_PoseSkinLBS)->Unit(benchmark::kMicrosecond);
static void BM_PoseSkinDQS(benchmark::State& st) { pose_skin(st, Blend::DualQuaternion); }
BENCHMARK(BM_PoseSkinDQS)->Unit(benchmark::kMicrosecond);
// The same with the crease guard after the blend (pose's default).
static void BM_PoseSkinLBSGuarded(benchmark::State& st) { pose_skin(st, Blend::Linear, true); }
BENCHMARK(BM_PoseSkinLBSGuarded)->Unit(benchmark::kMicrosecond);
static void BM_PoseSkinDQSGuarded(benchmark::State& st) { pose_skin(st, Blend::DualQuaternion, true); }
BENCHMARK(BM_PoseSkinDQSGuarded)->Unit(benchmark::kMicrosecond);

// The crease guard's second half on the fixture's fist (DQS, the planes applied outside the
// timing): the self-intersection tests and the smoothing of the 21 folding pairs, per call.
static void BM_UntangleFist(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  const Skeleton skel(f.rig);
  const auto motions = link_motions(skel, PostureSolver(builtin_model("anatomical")).solve(fist_inputs()).angles);
  const std::vector<std::array<int, 3>> faces = f.skin.mesh.faces;
  const std::vector<int> dominant = dominant_links(faces, f.binding);
  auto guarded = deform(f.rest, f.binding, motions, Blend::DualQuaternion);
  guard_creases(crease_guard(f.rest, f.binding, f.rig), motions, &guarded);
  Untangled u;
  for (auto _ : st) {
    auto v = guarded;
    u = untangle_folds(faces, dominant, &v);
    benchmark::DoNotOptimize(v[0]);
  }
  st.counters["folding_before"] = static_cast<double>(u.folding_before);
  st.counters["folding_after"] = static_cast<double>(u.folding_after);
  st.counters["rounds"] = u.rounds;
}
BENCHMARK(BM_UntangleFist)->Unit(benchmark::kMillisecond);

// The Bézier patches posed (rigid binding of the control points) and tessellated at 16 × 16
// per patch (the vertices; the topology is the rest posture's). Postures per second.
static void BM_PosePatches(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  static const PatchSkin p = fit_patch_skin(f.skin, f.rig, fixture_merged().points, fixture_merged().sides, PatchOptions{});
  const Skeleton skel(f.rig);
  Angles a{};
  double v = 0;
  std::vector<Eigen::Vector3d> verts;
  for (auto _ : st) {
    a[dof_index("index.pip.flex").value()] = std::fmod(v += 0.37, 100.0);
    tessellation_vertices(pose_patch_skin(p, skel, a), 16, &verts);
    benchmark::DoNotOptimize(verts.data());
  }
  st.counters["vertices"] = static_cast<double>(verts.size());
  st.SetItemsProcessed(static_cast<int64_t>(st.iterations()));
  st.counters["patches"] = static_cast<double>(p.patches.size());
}
BENCHMARK(BM_PosePatches)->Unit(benchmark::kMillisecond);

// A 1024 × 1024 PNG of the fixture's skin by Mesa's off-screen OpenGL (context, 2x
// supersampled draw, downsampling, PNG encoding), after start-up.
static void BM_RenderSkin1024(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  RenderOptions ro;
  ro.width = ro.height = 1024;
  ro.view = named_view("back") * hand_frame_from_rig(f.rig).linear();
  size_t bytes = 0;
  for (auto _ : st) bytes = render_mesh_png({&f.skin.mesh}, ro).size();
  st.counters["png_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_RenderSkin1024)->Unit(benchmark::kMillisecond);

// The skin's texture baked from the fixture's two photos (visibility rays, two charts, the
// bake, the fill and padding of a 1024^2 atlas), and the skin's picture with it.
namespace {
const SkinTexture& fixture_texture() {
  static const SkinTexture t = [] {
    const RiggedFixture& f = rigged_fixture();
    const RangeScan back = load_scan(kFix + "back"), palm = load_scan(kFix + "palm");
    const Registration reg = register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, [](const std::string&) {});
    return bake_skin_texture(f.rest, f.skin.mesh.faces, load_scan_photo(kFix + "back.photo.png", back),
                             load_scan_photo(kFix + "palm.photo.png", palm), reg.back_to_palm, reg.markers_palm,
                             reg.marker_radius_mm, TextureOptions{});
  }();
  return t;
}
}  // namespace
static void BM_TextureBake(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  const SkinTexture& t0 = fixture_texture();
  const RangeScan back = load_scan(kFix + "back"), palm = load_scan(kFix + "palm");
  const ScanPhoto bp = load_scan_photo(kFix + "back.photo.png", back), pp = load_scan_photo(kFix + "palm.photo.png", palm);
  const Registration reg = register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, [](const std::string&) {});
  const auto faces = f.skin.mesh.faces;
  for (auto _ : st)
    benchmark::DoNotOptimize(bake_skin_texture(f.rest, faces, bp, pp, reg.back_to_palm, reg.markers_palm, reg.marker_radius_mm,
                                               TextureOptions{}).map.rgb.data());
  st.counters["texels_per_mm"] = t0.texels_per_mm;
  st.counters["blended_area"] = t0.blended;
}
BENCHMARK(BM_TextureBake)->Unit(benchmark::kMillisecond)->Iterations(its(5));
static void BM_RenderSkinTextured1024(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  RenderOptions ro;
  ro.width = ro.height = 1024;
  ro.view = named_view("back") * hand_frame_from_rig(f.rig).linear();
  ro.texture = &fixture_texture().map;
  size_t bytes = 0;
  for (auto _ : st) bytes = render_mesh_png({&f.skin.mesh}, ro).size();
  st.counters["png_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_RenderSkinTextured1024)->Unit(benchmark::kMillisecond);

// The studio (issue 16): a solve through the API in process (JSON in, angles and joint
// transforms out), and 10 000 solve requests over loopback HTTP from one client (keep-alive),
// with their latency percentiles and errors.
namespace {
const std::string& studio_glb() {
  static const std::string path = [] {
    const RiggedFixture& f = rigged_fixture();
    RiggedSkin s;
    s.mesh = {f.rest, f.skin.mesh.faces};
    s.rig = f.rig;
    s.binding = f.binding;
    s.model = builtin_model("anatomical");
    const auto bytes = skin_glb(s);
    const std::string p = (std::filesystem::temp_directory_path() / "handskin-bench-studio.glb").string();
    write_file_atomic(p, std::string(bytes.begin(), bytes.end()));
    return p;
  }();
  return path;
}
}  // namespace
static void BM_StudioApiSolve(benchmark::State& st) {
  const StudioModel m(read_skin_glb(studio_glb()));
  double v = 0;
  for (auto _ : st) {
    v = std::fmod(v + 0.37, 90.0);
    benchmark::DoNotOptimize(m.solve("{\"inputs\": {\"L2.flex\": " + std::to_string(v) + "}}").body.size());
  }
}
BENCHMARK(BM_StudioApiSolve)->Unit(benchmark::kMicrosecond);
static void BM_StudioLoadTest10k(benchmark::State& st) {
  const std::string web = (std::filesystem::temp_directory_path() / "handskin-bench-studio-web").string();
  std::filesystem::create_directories(web);
  write_file_atomic(web + "/index.html", "<!doctype html><title>bench</title>");
  StudioOptions o;
  o.model = studio_glb();
  o.port = 0;
  o.web_dir = web;
  StudioServer server(o);
  std::atomic<int> port{-1};
  std::thread t([&] { server.run([&](int p) { port = p; }); });
  while (port < 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::vector<double> ms;
  int errors = 0;
  for (auto _ : st) {
    httplib::Client c("127.0.0.1", port);
    c.set_keep_alive(true);
    c.set_tcp_nodelay(true);  // as browsers do; without it Nagle and delayed ACKs add ~40 ms a request
    ms.clear();
    errors = 0;
    for (int k = 0; k < 10000; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      const auto r = c.Post("/api/solve", "{\"inputs\": {\"L2.flex\": " + std::to_string(k % 90) + "}}", "application/json");
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      errors += !r || r->status != 200;
    }
  }
  server.stop();
  t.join();
  std::sort(ms.begin(), ms.end());
  st.counters["p50_ms"] = ms[ms.size() / 2];
  st.counters["p99_ms"] = ms[ms.size() * 99 / 100];
  st.counters["max_ms"] = ms.back();
  st.counters["errors"] = errors;
  st.counters["requests"] = static_cast<double>(ms.size());
}
BENCHMARK(BM_StudioLoadTest10k)->Unit(benchmark::kSecond)->Iterations(its(1));

// Binding the fixture's skin by bone heat (24 sparse solves with one factorisation).
static void BM_BindSkin(benchmark::State& st) {
  const RiggedFixture& f = rigged_fixture();
  for (auto _ : st) benchmark::DoNotOptimize(bind_skin(f.skin.mesh, bones_from_rig(f.rig), BindingOptions{}).vertices.size());
}
BENCHMARK(BM_BindSkin)->Unit(benchmark::kMillisecond);

// ------------------------------------------------------------------ the whole command
// `handskin run` as a user runs it, in a child process: wall time, and the child's peak
// resident memory (wait4's ru_maxrss). Goals (issue 12): the fixture ≤ 1.5 s median, and
// ≤ 1.5 GB for the fixture and for the largest scan the format allows.
struct ChildRun {
  double seconds = 0, peak_mb = 0;
  int exit_code = -1;
};

// Fork, exec, wait: the child's wall time, peak memory and exit code.
static ChildRun fork_exec(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    const int devnull = open("/dev/null", O_WRONLY);
    dup2(devnull, 1);
    dup2(devnull, 2);
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  ChildRun r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.peak_mb = ru.ru_maxrss / 1024.0;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

// The commands are started by a small process forked at the bench's start, before any
// benchmark loaded its data: a child's ru_maxrss counts the pages of the process it was forked
// from, until its exec, and by BM_RunFixtureNoPatches the bench holds ~130 MB (the fixture's
// clouds, skins and patches), which it reported as that run's peak (its own: ~115 MB). The
// spawner's own pages at the fork (~5 MB) stay below any command's.
struct Spawner {
  int to = -1, from = -1;
  pid_t pid = -1;
};
static Spawner g_spawner;

static bool read_all(int fd, void* p, size_t n) {
  for (char* c = static_cast<char*>(p); n > 0;) {
    const ssize_t k = read(fd, c, n);
    if (k <= 0) return false;
    c += k, n -= static_cast<size_t>(k);
  }
  return true;
}
static bool write_all(int fd, const void* p, size_t n) {
  for (const char* c = static_cast<const char*>(p); n > 0;) {
    const ssize_t k = write(fd, c, n);
    if (k <= 0) return false;
    c += k, n -= static_cast<size_t>(k);
  }
  return true;
}

static void start_spawner() {
  int req[2], res[2];
  if (pipe(req) != 0) return;
  if (pipe(res) != 0) {
    close(req[0]), close(req[1]);
    return;
  }
  const pid_t pid = fork();
  if (pid < 0) {
    for (int fd : {req[0], req[1], res[0], res[1]}) close(fd);
    return;
  }
  if (pid == 0) {  // the spawner: a request is its arguments' bytes, each ended by '\0'
    close(req[1]), close(res[0]);
    for (;;) {
      std::uint32_t n = 0;
      if (!read_all(req[0], &n, sizeof n)) _exit(0);
      std::string bytes(n, '\0');
      if (!read_all(req[0], bytes.data(), n)) _exit(0);
      std::vector<std::string> args;
      for (size_t a = 0; a < bytes.size();) {
        const size_t e = bytes.find('\0', a);
        args.push_back(bytes.substr(a, e - a));
        a = e + 1;
      }
      const ChildRun r = fork_exec(args);
      if (!write_all(res[1], &r, sizeof r)) _exit(0);
    }
  }
  close(req[0]), close(res[1]);
  g_spawner = {req[1], res[0], pid};
}

static void stop_spawner() {
  if (g_spawner.pid < 0) return;
  close(g_spawner.to), close(g_spawner.from);
  waitpid(g_spawner.pid, nullptr, 0);
  g_spawner = {};
}

static ChildRun run_child(const std::vector<std::string>& args) {
  if (g_spawner.pid >= 0) {
    std::string bytes;
    for (const auto& a : args) bytes += a, bytes += '\0';
    const auto n = static_cast<std::uint32_t>(bytes.size());
    ChildRun r;
    if (write_all(g_spawner.to, &n, sizeof n) && write_all(g_spawner.to, bytes.data(), n) &&
        read_all(g_spawner.from, &r, sizeof r))
      return r;
  }
  return fork_exec(args);
}

// A command that did not exit as it should has no meaningful time: the benchmark says so.
static void report_child(benchmark::State& st, const std::vector<std::string>& args, int expect_exit = 0) {
  ChildRun r;
  for (auto _ : st) {
    r = run_child(args);
    st.SetIterationTime(r.seconds);
  }
  st.counters["peak_rss_MB"] = r.peak_mb;
  st.counters["exit_code"] = r.exit_code;
  if (r.exit_code != expect_exit)
    st.SkipWithError(("exit code " + std::to_string(r.exit_code) + ", expected " + std::to_string(expect_exit)).c_str());
}

// A command's start and end with no work (`handskin --version`): the dynamic loader's share of
// every command (the libraries linked, their symbols relocated). PCL's io, surface and filters
// libraries are a module loaded at first use (scan/pcl_module.hpp) for this.
static void BM_ProcessStart(benchmark::State& st) { report_child(st, {HANDSKIN_BINARY, "--version"}); }
BENCHMARK(BM_ProcessStart)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(5))->Repetitions(its(5))
    ->ReportAggregatesOnly(true);

static void BM_RunFixture(benchmark::State& st) {
  const std::string out = "/tmp/handskin-bench-run";
  report_child(st, {HANDSKIN_BINARY, "-q", "run", "--back", kFix + "back", "--palm", kFix + "palm", "--rig",
                    kFix + "rig.json", "--out", out});
}
BENCHMARK(BM_RunFixture)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(1))->Repetitions(its(5))
    ->ReportAggregatesOnly(true);

// The same without the patch stage (patches.enabled false): the run as issue 12 measured it.
static void BM_RunFixtureNoPatches(benchmark::State& st) {
  const std::string dir = "/tmp/handskin-bench-run-nopatches";
  std::filesystem::create_directories(dir);
  write_file_atomic(dir + "/pipeline.json", R"({"format": "handskin-pipeline/1", "patches": {"enabled": false}})");
  report_child(st, {HANDSKIN_BINARY, "-q", "run", "--back", kFix + "back", "--palm", kFix + "palm", "--rig",
                    kFix + "rig.json", "--pipeline", dir + "/pipeline.json", "--out", dir + "/out"});
}
BENCHMARK(BM_RunFixtureNoPatches)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(1))->Repetitions(its(5))
    ->ReportAggregatesOnly(true);

// A cloud from any scanner (issue 37): the fixture's true skin scanned from 8 views at 0.4 mm
// ray spacing with 0.2 mm noise, a stand and outliers — about 500 000 points, made once
// (binary PLY). BM_RunCloud500k times `run --cloud` on it with the fixture's rig (the hand's
// fingers are straight, so its palm side needs the rig or --hand); BM_CloudPrep500k the
// cloud stage's cleaning alone, in process.
static const std::string& cloud_500k() {
  static const std::string path = [] {
    const std::string dir = "/tmp/handskin-bench-cloud";
    std::filesystem::create_directories(dir);
    CloudSimOptions o;
    o.spacing_mm = 0.4;
    o.noise_mm = 0.2;
    const CloudSim sim = simulate_cloud(load_mesh(kFix + "truth_skin.ply"), load_rig(kFix + "rig.json"), o, 5);
    save_cloud(dir + "/cloud.ply", sim.points);
    save_rig(dir + "/rig.json", sim.rig);
    return dir + "/cloud.ply";
  }();
  return path;
}
static void BM_RunCloud500k(benchmark::State& st) {
  const std::string& cloud = cloud_500k();
  const std::string dir = std::filesystem::path(cloud).parent_path().string();
  report_child(st, {HANDSKIN_BINARY, "-q", "run", "--cloud", cloud, "--rig", dir + "/rig.json", "--out", dir + "/out"});
  st.counters["points"] = static_cast<double>(read_point_cloud(cloud).points.size());
}
BENCHMARK(BM_RunCloud500k)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(1))->Repetitions(its(3))
    ->ReportAggregatesOnly(true);
static void BM_CloudPrep500k(benchmark::State& st) {
  const PointCloudFile f = read_point_cloud(cloud_500k());
  for (auto _ : st) benchmark::DoNotOptimize(prepare_cloud(f.points, {}, "cloud", "mm", CloudPrepOptions{}));
  st.counters["points"] = static_cast<double>(f.points.size());
}
BENCHMARK(BM_CloudPrep500k)->Unit(benchmark::kMillisecond)->Iterations(its(3));

// The largest scans the format allows (2048 × 2048 samples; 4096 × 1024), every pixel a
// return (a table with nothing on it): the worst a small file can ask of `run`. They are
// refused (no markers on an empty table) — the figure is what refusing them costs.
static void largest_scan_run(benchmark::State& st, int scanlines, int points) {
  const std::string dir = "/tmp/handskin-bench-largest-" + std::to_string(scanlines);
  std::filesystem::create_directories(dir);
  for (const char* side : {"back", "palm"}) {
    RangeScan s;
    s.meta.scanlines = scanlines;
    s.meta.points = points;
    s.meta.x_step_mm = 250.0 / scanlines;
    s.meta.y_step_mm = 200.0 / points;
    s.meta.side = std::string(side) == "back" ? ScanSide::Back : ScanSide::Palm;
    s.values.assign(static_cast<size_t>(scanlines) * points, 0);
    Rng rng(3);
    for (auto& v : s.values) v = static_cast<std::uint16_t>(100 + rng.next() % 3);
    save_scan(dir + "/" + side, s);
  }
  report_child(st, {HANDSKIN_BINARY, "-q", "run", "--back", dir + "/back", "--palm", dir + "/palm", "--out", dir + "/out"},
               1);
}
static void BM_RunLargestScan2048x2048(benchmark::State& st) { largest_scan_run(st, 2048, 2048); }
BENCHMARK(BM_RunLargestScan2048x2048)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(1));
static void BM_RunLargestScan4096x1024(benchmark::State& st) { largest_scan_run(st, 4096, 1024); }
BENCHMARK(BM_RunLargestScan4096x1024)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(its(1));

// With HANDSKIN_BENCH_MERGED (a merged.ply) and HANDSKIN_BENCH_RIG (its rig) set, the skin
// stage is also timed on that cloud, as BM_SkinBuild/file: e.g. a larger synthetic hand from
// scripts/skin_study.py.
int main(int argc, char** argv) {
  const char* merged = std::getenv("HANDSKIN_BENCH_MERGED");
  const char* rig = std::getenv("HANDSKIN_BENCH_RIG");
  if (merged && rig) {
    benchmark::RegisterBenchmark("BM_SkinBuild/file", [merged, rig](benchmark::State& st) {
      static const MergedArrays m = read_merged(merged);
      static const Rig r = load_rig(rig);
      skin_build(st, m, r);
    })->Unit(benchmark::kMillisecond)->Iterations(its(10));
  }
  start_spawner();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  stop_spawner();
  return 0;
}
