#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "mesh/mesh.hpp"
#include "synth/scanner.hpp"

namespace handskin::test {

/// A fresh empty folder under the system temp dir, removed after the last test when every test
/// of the process passed (kept, and named on stderr, when one failed or HANDSKIN_KEEP_TEST_DIRS is set).
std::string temp_dir(const std::string& tag);
/// PNG of any depth/colour type built by hand (zlib), for inputs libpng's writer won't make.
std::string make_png(int w, int h, int depth, int colour_type, const std::vector<std::uint8_t>& raw_rows_no_filter);
/// Run a shell command; returns exit code, stdout+stderr in *output.
int run(const std::string& cmd, std::string* output);
/// `handskin run` on the default fixture (scans, photos, rig), once per test process: its
/// output folder. A failed run is reported as a test failure.
const std::string& default_fixture_run();
/// Generalised winding number of point p w.r.t. a closed triangle mesh (≈1 inside, ≈0 outside).
double winding_number(const Mesh& mesh, const Eigen::Vector3d& p);
void write_text(const std::string& path, const std::string& text);
/// Every file under `dir`: relative name -> bytes ("(folder)" for a folder); a missing folder
/// is {"(absent)": ""}. For comparing an output folder before and after a command.
std::map<std::string, std::string> snapshot(const std::string& dir);
/// The stage named `name` in a report.json's "stages" (run's report), or nullptr.
const Json* report_stage(const Json& report, const std::string& name);
/// Scene objects with exact geometry for the scanner and registration tests.
/// The message of the InputError `f` throws, or "(no error)".
template <class F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

void add_box(Scene* s, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int object);
void add_sphere(Scene* s, const Eigen::Vector3d& centre, double radius, int object);

}  // namespace handskin::test
