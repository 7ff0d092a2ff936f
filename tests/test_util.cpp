#include "test_util.hpp"
#include "core/atomic_file.hpp"

#include <gtest/gtest.h>

#include "synth/replica.hpp"

#include <zlib.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>
#include <unistd.h>
#include <sys/wait.h>

namespace handskin::test {

const Json* report_stage(const Json& report, const std::string& name) {
  for (const auto& s : report["stages"])
    if (s["name"] == name) return &s;
  return nullptr;
}

namespace {
// The folders temp_dir made in this process, removed once every test has run when all passed
// (a suite run had left ~3 000 of them, 13 GB, in /tmp); kept, and named, when one failed or
// HANDSKIN_KEEP_TEST_DIRS is set, for looking into.
std::vector<std::filesystem::path>& made_dirs() {
  static std::vector<std::filesystem::path> dirs;
  return dirs;
}

class TempDirCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    namespace fs = std::filesystem;
    auto& dirs = made_dirs();
    if (dirs.empty()) return;
    const bool keep = std::getenv("HANDSKIN_KEEP_TEST_DIRS") != nullptr;
    if (keep || !::testing::UnitTest::GetInstance()->Passed()) {
      std::fprintf(stderr, "test folders kept:");
      for (const auto& d : dirs) std::fprintf(stderr, " %s", d.c_str());
      std::fprintf(stderr, "\n");
      return;
    }
    for (const auto& d : dirs) {
      std::error_code ec;
      // A test's read-only folder (test_trust) is made writable again first; links are removed,
      // never followed (std::filesystem::remove_all).
      for (auto it = fs::recursive_directory_iterator(d, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
        if (it->is_directory(ec) && !it->is_symlink(ec)) fs::permissions(it->path(), fs::perms::owner_all, fs::perm_options::add, ec);
      fs::remove_all(d, ec);
    }
    dirs.clear();
  }
};
[[maybe_unused]] ::testing::Environment* const temp_dir_cleanup = ::testing::AddGlobalTestEnvironment(new TempDirCleanup);
}  // namespace

std::string temp_dir(const std::string& tag) {
  namespace fs = std::filesystem;
  static int counter = 0;
  const fs::path p = fs::temp_directory_path() / ("handskin-test-" + std::to_string(::getpid()) + "-" + tag + "-" +
                                                  std::to_string(counter++));
  fs::remove_all(p);
  fs::create_directories(p);
  made_dirs().push_back(p);
  return p.string();
}

std::string make_png(int w, int h, int depth, int colour_type, const std::vector<std::uint8_t>& raw) {
  auto be32 = [](std::uint32_t v) {
    return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                       static_cast<char>(v)};
  };
  auto chunk = [&](const std::string& type, const std::string& data) {
    const std::string td = type + data;
    const auto crc = static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(td.data()), td.size()));
    return be32(static_cast<std::uint32_t>(data.size())) + td + be32(crc);
  };
  const int channels = colour_type == 2 ? 3 : colour_type == 4 ? 2 : colour_type == 6 ? 4 : 1;
  const size_t row_bytes = static_cast<size_t>(w) * channels * depth / 8;
  std::string filtered;
  for (int r = 0; r < h; ++r) {
    filtered.push_back('\0');
    filtered.append(reinterpret_cast<const char*>(raw.data()) + r * row_bytes, row_bytes);
  }
  uLongf n = compressBound(filtered.size());
  std::string z(n, '\0');
  compress(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(filtered.data()), filtered.size());
  z.resize(n);
  std::string ihdr = be32(w) + be32(h);
  ihdr += static_cast<char>(depth);
  ihdr += static_cast<char>(colour_type);
  ihdr += std::string(3, '\0');
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + chunk("IDAT", z) + chunk("IEND", "");
}

int run(const std::string& cmd, std::string* output) {
  FILE* pipe = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf{};
  output->clear();
  while (size_t n = std::fread(buf.data(), 1, buf.size(), pipe)) output->append(buf.data(), n);
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

double winding_number(const Mesh& mesh, const Eigen::Vector3d& p) {
  // Van Oosterom–Strackee solid angle per triangle.
  double total = 0;
  for (const auto& f : mesh.faces) {
    Eigen::Vector3d v[3];
    for (int k = 0; k < 3; ++k) v[k] = mesh.vertices[f[k]] - p;
    const double a = v[0].norm(), b = v[1].norm(), c = v[2].norm();
    const double num = v[0].dot(v[1].cross(v[2]));
    const double den = a * b * c + v[0].dot(v[1]) * c + v[1].dot(v[2]) * a + v[2].dot(v[0]) * b;
    total += 2.0 * std::atan2(num, den);
  }
  return total / (4.0 * M_PI);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

void add_box(Scene* s, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int object) {
  std::vector<Eigen::Vector3d> v;
  for (int k = 0; k < 8; ++k) v.emplace_back(k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z());
  const std::vector<std::array<int, 3>> f = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                             {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  s->add(v, f, object);
}

void add_sphere(Scene* s, const Eigen::Vector3d& centre, double radius, int object) {
  std::vector<Eigen::Vector3d> v;
  std::vector<std::array<int, 3>> f;
  icosphere(centre, radius, 5, &v, &f);
  s->add(v, f, object);
}

std::map<std::string, std::string> snapshot(const std::string& dir) {
  namespace fs = std::filesystem;
  std::map<std::string, std::string> s;
  if (!fs::exists(dir)) return {{"(absent)", ""}};
  for (const auto& e : fs::recursive_directory_iterator(dir))
    s[fs::relative(e.path(), dir).string()] = e.is_regular_file() ? read_file(e.path().string()) : "(folder)";
  return s;
}

const std::string& default_fixture_run() {
  static const std::string dir = [] {
    const std::string fix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
    const std::string d = temp_dir("fixture-run") + "/run";
    std::string out;
    const int rc = run(std::string(HANDSKIN_BINARY) + " -q run --back " + fix + "back --palm " + fix + "palm --rig " + fix +
                           "rig.json --out " + d,
                       &out);
    if (rc != 0) ADD_FAILURE() << out;
    return d;
  }();
  return dir;
}

}  // namespace handskin::test
