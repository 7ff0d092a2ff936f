// How registration accuracy depends on the scanner and the markers: the fixture's hand
// scanned at several noise levels, depth steps and marker sizes, 10 seeded pairs each, registered, compared with the truth.
// Prints a table (docs/registration.md). Usage: handskin_registration_study [pairs]
#include <cstdio>
#include <cstdlib>

#include "register/registration.hpp"
#include "synth/replica.hpp"

using namespace handskin;

int main(int argc, char** argv) {
  const int pairs = argc > 1 ? std::atoi(argv[1]) : 10;
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const Mesh mesh = load_mesh(dir + "truth_skin.ply");
  const Rig rig = load_rig(dir + "rig.json");
  struct Condition {
    const char* name;
    double noise, z_step, marker_radius;
  };
  const Condition conditions[] = {{"CUBIST (sigma 0.05, step 0.2)", 0.05, 0.2, 4.0},
                                  {"no noise, step 0.2", 0.0, 0.2, 4.0},
                                  {"sigma 0.05, step 0.02", 0.05, 0.02, 4.0},
                                  {"no noise, step 0.02", 0.0, 0.02, 4.0},
                                  {"sigma 0.1, step 0.2", 0.1, 0.2, 4.0},
                                  {"CUBIST (sigma 0.05, step 0.2)", 0.05, 0.2, 3.0},
                                  {"CUBIST (sigma 0.05, step 0.2)", 0.05, 0.2, 3.5}};
  std::printf("| scanner, markers | rotation mean / worst (deg) | marker-only mean (deg) | skin mean / worst max (mm) |\n");
  std::printf("|---|---|---|---|\n");
  for (const auto& c : conditions) {
    ScannerOptions so;
    so.noise_sigma_mm = c.noise;
    so.z_step_mm = c.z_step;
    ReplicaOptions ro;
    ro.marker_radius_mm = c.marker_radius;
    RegistrationOptions rgo;
    rgo.spheres.radius_mm = c.marker_radius;
    double rot = 0, rot_worst = 0, rot_m = 0, mean = 0, max_worst = 0;
    for (int seed = 101; seed < 101 + pairs; ++seed) {
      const ScanPair pair = synthesize_scan_pair(mesh, rig, ro, so, seed, false);
      const std::vector<Eigen::Vector3d> skin = pair.skin_palm.vertices;
      const Registration reg = register_scans(pair.back.scan, pair.palm.scan, "back", "palm", rgo,
                                              nullptr, [](const std::string&) {});
      const RegistrationError e = registration_error(reg.back_to_palm, pair.back_to_palm, skin);
      const RegistrationError m = registration_error(reg.marker_only, pair.back_to_palm, skin);
      rot += e.rotation_deg;
      rot_worst = std::max(rot_worst, e.rotation_deg);
      rot_m += m.rotation_deg;
      mean += e.mean_mm;
      max_worst = std::max(max_worst, e.max_mm);
    }
    std::printf("| %s, %.1f mm | %.4f / %.4f | %.4f | %.4f / %.4f |\n", c.name, c.marker_radius, rot / pairs, rot_worst, rot_m / pairs,
                mean / pairs, max_worst);
    std::fflush(stdout);
  }
  return 0;
}
