// Benchmarks: `build/bench/handskin_bench`. Figures, not pass/fail.
#include <benchmark/benchmark.h>

#include "register/registration.hpp"

#include "core/atomic_file.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "synth/hand_mesher.hpp"
#include "synth/hand_model.hpp"
#include "synth/replica.hpp"

using namespace handskin;
static const std::string kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

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
BENCHMARK(BM_MeshDefaultHand)->Unit(benchmark::kSecond)->Iterations(1);

static void BM_SynthScanPair(benchmark::State& st) {
  const HandModel m = build_hand_model(HandShapeOptions{});
  const HandMeshResult mesh = mesh_hand(m, HandMeshOptions{});
  std::uint64_t seed = 1;
  for (auto _ : st)
    benchmark::DoNotOptimize(synthesize_scan_pair(mesh.mesh, m.rig, ReplicaOptions{}, ScannerOptions{}, seed++, false));
}
BENCHMARK(BM_SynthScanPair)->Unit(benchmark::kMillisecond)->Iterations(3);

// Registration of the fixture pair, table removal through merge; the per-step split (from
// the stage's own timings, last iteration) is reported as counters in ms.
static void BM_RegisterFixturePair(benchmark::State& st) {
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const RangeScan back = load_scan(dir + "back"), palm = load_scan(dir + "palm");
  Json timings;
  for (auto _ : st) {
    const Registration reg =
        register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, [](const std::string&) {});
    timings = reg.report["timings_ms"];
    benchmark::DoNotOptimize(reg.back_to_palm);
  }
  for (const auto& [k, v] : timings.items()) st.counters[k] = v.get<double>();
}
BENCHMARK(BM_RegisterFixturePair)->Unit(benchmark::kMillisecond)->Iterations(10);

// The same with the refinement off (marker-only fit), to show what the refinement costs.
static void BM_RegisterFixturePairMarkerOnly(benchmark::State& st) {
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const RangeScan back = load_scan(dir + "back"), palm = load_scan(dir + "palm");
  RegistrationOptions o;
  o.refine_enabled = false;
  for (auto _ : st) {
    const Registration reg = register_scans(back, palm, "back", "palm", o, nullptr, [](const std::string&) {});
    benchmark::DoNotOptimize(reg.back_to_palm);
  }
}
BENCHMARK(BM_RegisterFixturePairMarkerOnly)->Unit(benchmark::kMillisecond)->Iterations(10);

BENCHMARK_MAIN();
