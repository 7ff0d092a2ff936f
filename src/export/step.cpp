#include "export/step.hpp"

#include <unistd.h>

#include <filesystem>
#include <future>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/module.hpp"
#include "export/step_module.h"

namespace handskin {

namespace {

struct StepModule {
  decltype(&handskin_step_write) write = nullptr;
  decltype(&handskin_step_read) read = nullptr;
  std::string failure;
};

// The module, loaded once (core/module.hpp).
const StepModule& step_module() {
  static const StepModule m = [] {
    StepModule m;
    LoadedModule lib = open_module(HANDSKIN_STEP_MODULE, "libhandskin_step.so");
    lib.entry(m.write, "handskin_step_write");
    lib.entry(m.read, "handskin_step_read");
    m.failure = lib.failure;
    return m;
  }();
  return m;
}

const StepModule& loaded(const std::string& path) {
  const StepModule& m = step_module();
  if (!m.failure.empty())
    throw InputError(path, "STEP needs handskin's Open CASCADE module (libhandskin_step.so, Debian's libocct-* "
                           "packages), which could not be loaded: " + m.failure);
  return m;
}

StepSummary summary_of(const HsStepSummary& s) {
  StepSummary r;
  r.faces = s.faces, r.shells = s.shells, r.closed_shells = s.closed_shells, r.solids = s.solids;
  r.free_edges = s.free_edges, r.valid = s.valid != 0;
  r.box = Eigen::AlignedBox3d(Eigen::Vector3d(s.box[0], s.box[1], s.box[2]), Eigen::Vector3d(s.box[3], s.box[4], s.box[5]));
  return r;
}

}  // namespace

void preload_step() {
  static std::future<void> loading = std::async(std::launch::async, [] { step_module(); });
}

void write_patches_step(const std::vector<BezierPatch>& patches, const std::string& path, double sew_tolerance_mm) {
  if (patches.empty()) throw InputError(path, "no patches to write");
  HS_CHECK(sew_tolerance_mm > 0, "the sewing tolerance must be positive");
  std::vector<double> poles;
  poles.reserve(patches.size() * 48);
  std::vector<const char*> names;
  for (const BezierPatch& p : patches) {
    for (const Eigen::Vector3d& c : p.P) {
      if (!c.allFinite()) throw InputError(path, "patch " + p.name + " has a control point that is not finite");
      poles.insert(poles.end(), {c.x(), c.y(), c.z()});
    }
    names.push_back(p.name.c_str());
  }
  const StepModule& m = loaded(path);
  HsStepSummary s{};
  if (m.write(static_cast<int>(patches.size()), poles.data(), names.data(), path.c_str(), sew_tolerance_mm, &s) != 0)
    throw InputError(path, s.error);
}

StepFile patches_step_file(const std::vector<BezierPatch>& patches, double sew_tolerance_mm) {
  // A private file in the temporary folder (OCCT writes and reads files, not memory), removed
  // whatever happens.
  std::string path = (std::filesystem::temp_directory_path() / "handskin-step-XXXXXX").string();
  const int fd = mkstemp(path.data());
  if (fd < 0) throw InputError("patches.step", "cannot make a temporary file in " + std::filesystem::temp_directory_path().string());
  close(fd);
  struct Remove {
    std::string p;
    ~Remove() {
      std::error_code ec;
      std::filesystem::remove(p, ec);
    }
  } remove{path};
  try {
    write_patches_step(patches, path, sew_tolerance_mm);
    StepFile f;
    f.shape = read_step(path);
    f.bytes = read_file(path);
    return f;
  } catch (const InputError& e) {
    throw InputError("patches.step", e.detail());
  }
}

StepSummary read_step(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(path, "no such file");
  const StepModule& m = loaded(path);
  HsStepSummary s{};
  std::vector<char> names(1 << 20);
  if (m.read(path.c_str(), &s, names.data(), static_cast<int>(names.size())) != 0) throw InputError(path, s.error);
  StepSummary r = summary_of(s);
  std::istringstream lines(names.data());
  for (std::string line; std::getline(lines, line);)
    if (!line.empty()) r.names.push_back(line);
  return r;
}

}  // namespace handskin
