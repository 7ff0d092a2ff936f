#include "core/output_set.hpp"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>
#include <unistd.h>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"

namespace fs = std::filesystem;

namespace handskin {

namespace {

// --- what a signal handler may clean up: fixed storage, async-signal-safe calls only ---
constexpr int kMaxPaths = 256;
constexpr int kPathLen = 4096;
char g_paths[kMaxPaths][kPathLen];
char g_staging[kPathLen];
volatile std::sig_atomic_t g_path_count = 0;
volatile std::sig_atomic_t g_active = 0;      // a set is staging
volatile std::sig_atomic_t g_committing = 0;  // its files are being moved: hold signals
volatile std::sig_atomic_t g_pending = 0;     // a signal that arrived during the moves
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};
struct sigaction g_previous[3];

extern "C" void on_signal(int sig) {
  if (g_committing) {  // the moves are short: finish them, then die (see commit())
    g_pending = sig;
    return;
  }
  if (g_active) {
    for (int i = 0; i < g_path_count; ++i) ::unlink(g_paths[i]);
    ::rmdir(g_staging);
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void copy_path(char* dst, const std::string& src) {
  std::strncpy(dst, src.c_str(), kPathLen - 1);
  dst[kPathLen - 1] = 0;
}

void install_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  for (int k = 0; k < 3; ++k) sigaction(kSignals[k], &sa, &g_previous[k]);
}

void restore_handlers() {
  for (int k = 0; k < 3; ++k) sigaction(kSignals[k], &g_previous[k], nullptr);
}

// HANDSKIN_FAULT=<kind>:<n> (tests only; see the header).
bool fault(const char* kind, int n) {
  const char* f = std::getenv("HANDSKIN_FAULT");
  if (!f) return false;
  const std::string s(f);
  const size_t colon = s.find(':');
  return colon != std::string::npos && s.substr(0, colon) == kind && std::atoi(s.c_str() + colon + 1) == n;
}

// The folder the staging folder goes in: beside the output folder, in its nearest existing
// ancestor (so that the moves are renames on one file system).
fs::path staging_parent(const fs::path& out) {
  fs::path p = fs::absolute(out).lexically_normal();
  if (p.has_filename()) p = p.parent_path();
  else p = p.parent_path().parent_path();  // "a/b/" -> parent of b
  std::error_code ec;
  while (!p.empty() && !fs::is_directory(p, ec) && p != p.root_path()) p = p.parent_path();
  return p;
}

}  // namespace

OutputSet::OutputSet(std::string out_dir) : out_dir_(std::move(out_dir)) {
  std::error_code ec;
  if (out_dir_.empty()) throw InputError("--out", "no output folder given");
  if (fs::exists(out_dir_, ec) && !fs::is_directory(out_dir_, ec))
    throw InputError(out_dir_, "exists and is not a folder");
}

OutputSet::~OutputSet() {
  if (!committed_) discard();
}

std::string OutputSet::stage(const std::string& name) {
  HS_CHECK(name.find('/') == std::string::npos && !name.empty() && name[0] != '.', "output names are plain file names");
  HS_CHECK(!g_active || staging_ == g_staging, "one output set stages at a time");
  ensure_staging();
  for (const auto& n : names_) HS_CHECK(n != name, "output '" + name + "' staged twice");
  names_.push_back(name);
  const int n = static_cast<int>(names_.size());
  if (fault("stall", n)) std::this_thread::sleep_for(std::chrono::seconds(30));
  if (fault("stage", n)) throw InputError(final_path(name), "cannot write: injected fault (HANDSKIN_FAULT)");
  const std::string path = (fs::path(staging_) / name).string();
  for (const std::string& p : {path, temp_name_for(path)}) {
    HS_CHECK(g_path_count < kMaxPaths, "too many outputs in one set");
    copy_path(g_paths[g_path_count], p);
    g_path_count = g_path_count + 1;
  }
  return path;
}

void OutputSet::ensure_staging() {
  if (!staging_.empty()) return;
  const fs::path parent = staging_parent(out_dir_);
  const std::string leaf = fs::absolute(out_dir_).lexically_normal().filename().string();
  staging_ = (parent / (".handskin-staging-" + (leaf.empty() ? std::string("out") : leaf) + "-" +
                        std::to_string(::getpid())))
                 .string();
  std::error_code ec;
  fs::remove_all(staging_, ec);
  if (!fs::create_directory(staging_, ec) || ec)
    throw InputError(out_dir_, "cannot write: cannot create a staging folder in '" + parent.string() + "'" +
                                   (ec ? ": " + ec.message() : std::string()));
  copy_path(g_staging, staging_);
  g_path_count = 0;
  g_active = 1;
  install_handlers();
}

std::string OutputSet::final_path(const std::string& name) const { return (fs::path(out_dir_) / name).string(); }

void OutputSet::retire(const std::vector<std::string>& names) {
  retired_.insert(retired_.end(), names.begin(), names.end());
}

void OutputSet::discard() noexcept {
  if (staging_.empty()) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
  if (g_active && staging_ == g_staging) {
    g_active = 0;
    restore_handlers();
  }
  staging_.clear();
}

void OutputSet::commit() {
  HS_CHECK(!committed_, "an output set is committed once");
  if (staging_.empty() && retired_.empty()) {
    committed_ = true;
    return;
  }
  g_committing = 1;
  std::error_code ec;
  // Folders we create for the output are removed again if the commit fails.
  std::vector<fs::path> created;
  for (fs::path p = fs::absolute(out_dir_).lexically_normal(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    created.push_back(p);
    if (p == p.root_path()) break;
  }
  struct Move {
    std::string name;
    bool had_old = false, placed = false;
  };
  std::vector<Move> done;
  ensure_staging();
  const fs::path aside = fs::path(staging_) / ".replaced";
  auto undo = [&] {
    std::error_code ignored;
    for (auto it = done.rbegin(); it != done.rend(); ++it) {
      if (it->placed) fs::remove(fs::path(out_dir_) / it->name, ignored);
      if (it->had_old) fs::rename(aside / it->name, fs::path(out_dir_) / it->name, ignored);
    }
    for (const auto& d : created) fs::remove(d, ignored);  // deepest first; only if empty
  };
  auto fail = [&](const std::string& name, const std::string& why) {
    undo();
    g_committing = 0;
    discard();
    const int pending = g_pending;
    if (pending) std::raise(pending);
    throw InputError(final_path(name), "cannot move into place: " + why + "; " + out_dir_ + " is as it was");
  };
  fs::create_directories(out_dir_, ec);
  if (ec || !fs::is_directory(out_dir_)) fail(".", "cannot create the output folder" + (ec ? ": " + ec.message() : ""));
  fs::create_directory(aside, ec);
  if (ec) fail(".", "cannot create " + aside.string() + ": " + ec.message());
  std::vector<std::pair<std::string, bool>> moves;  // name, has a new file
  for (const auto& n : names_) moves.emplace_back(n, true);
  for (const auto& n : retired_)
    if (std::find(names_.begin(), names_.end(), n) == names_.end()) moves.emplace_back(n, false);
  int count = 0;
  for (const auto& [name, fresh] : moves) {
    const fs::path dst = fs::path(out_dir_) / name;
    Move m{name};
    if (fs::exists(fs::symlink_status(dst, ec))) {
      fs::rename(dst, aside / name, ec);
      if (ec) fail(name, ec.message());
      m.had_old = true;
    }
    done.push_back(m);
    if (!fresh) continue;
    ++count;
    if (fault("commit", count)) fail(name, "injected fault (HANDSKIN_FAULT)");
    fs::rename(fs::path(staging_) / name, dst, ec);
    if (ec) fail(name, ec.message());
    done.back().placed = true;
  }
  committed_ = true;
  fs::remove_all(staging_, ec);
  g_active = 0;
  restore_handlers();
  staging_.clear();
  g_committing = 0;
  const int pending = g_pending;
  if (pending) std::raise(pending);  // the files are in place: now die as asked
}

}  // namespace handskin
