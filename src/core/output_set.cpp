#include "core/output_set.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <mutex>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"

namespace fs = std::filesystem;

namespace handskin {

namespace {

// --- what a signal handler may clean up: fixed storage, async-signal-safe calls only ---
// One slot per set that holds the signal cleanup (a command writing into several folders,
// OutputFiles, has one set per folder, each cleaned up by a signal).
constexpr int kMaxPaths = 256;
constexpr int kMaxCreated = 32;
constexpr int kPathLen = 4096;
constexpr int kMaxSlots = 8;
struct SignalSlot {
  char paths[kMaxPaths][kPathLen];
  char staging[kPathLen];
  char lock[kPathLen];
  char created[kMaxCreated][kPathLen];
  volatile std::sig_atomic_t path_count;
  volatile std::sig_atomic_t created_count;
  volatile std::sig_atomic_t active;  // the set has claimed its folder and not committed
};
SignalSlot g_slots[kMaxSlots];
int g_slots_in_use = 0;                       // (the main thread's count: handlers installed while > 0)
volatile std::sig_atomic_t g_committing = 0;  // files are being moved (a depth): hold signals
volatile std::sig_atomic_t g_pending = 0;     // a signal that arrived during the moves
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};
struct sigaction g_previous[3];

extern "C" void on_signal(int sig) {
  if (g_committing) {  // the moves are short: finish them, then die (see commit())
    g_pending = sig;
    return;
  }
  for (SignalSlot& s : g_slots) {
    if (!s.active) continue;
    for (int i = 0; i < s.path_count; ++i) ::unlink(s.paths[i]);
    if (s.staging[0]) ::rmdir(s.staging);
    if (s.lock[0]) ::unlink(s.lock);
    for (int i = 0; i < s.created_count; ++i) ::rmdir(s.created[i]);  // deepest first; only if empty
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

// Signals held while files are moved into place (nested: OutputFiles holds them across its
// sets' commits); the one that came meanwhile is delivered when the outermost hold ends.
void hold_signals() { g_committing = g_committing + 1; }
void release_signals() {
  g_committing = g_committing - 1;
  if (g_committing == 0 && g_pending) std::raise(g_pending);
}

// Every staging folder made in this process and the output folder it stands for (never
// forgotten: an error is printed after its set is gone), for as_output_path.
std::mutex g_staging_mutex;
std::vector<std::pair<std::string, std::string>>& staging_folders() {
  static std::vector<std::pair<std::string, std::string>> v;
  return v;
}

// HANDSKIN_FAULT=<kind>:<n> (tests only; see the header).
int fault_value(const char* kind) {
  const char* f = std::getenv("HANDSKIN_FAULT");
  if (!f) return -1;
  const std::string s(f);
  const size_t colon = s.find(':');
  if (colon == std::string::npos || s.substr(0, colon) != kind) return -1;
  return std::atoi(s.c_str() + colon + 1);
}
bool fault(const char* kind, int n) { return fault_value(kind) == n; }

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

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

std::string utc_stamp() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", &tm);
  return buf;
}

std::string refuse_hint() {
  return std::string("; handskin replaces only the files it wrote there (listed in ") + kManifestName +
         ", unchanged since): move it away, choose another --out, or give --force to have it moved aside into a "
         "dated backup folder";
}

}  // namespace

OwnedFile describe_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, "cannot read: " + std::string(std::strerror(errno)));
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  HS_CHECK(ctx && EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr) == 1, "SHA-256 unavailable");
  OwnedFile d;
  std::vector<char> buf(1 << 16);
  while (f) {
    f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const std::streamsize n = f.gcount();
    if (n > 0) {
      EVP_DigestUpdate(ctx, buf.data(), static_cast<size_t>(n));
      d.size += static_cast<std::uintmax_t>(n);
    }
  }
  const bool bad = f.bad();
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(ctx, md, &len);
  EVP_MD_CTX_free(ctx);
  if (bad) throw InputError(path, "cannot read");
  static const char* hex = "0123456789abcdef";
  for (unsigned i = 0; i < len; ++i) d.sha256 += {hex[md[i] >> 4], hex[md[i] & 15]};
  return d;
}

std::map<std::string, OwnedFile> read_manifest(const std::string& dir) {
  std::map<std::string, OwnedFile> m;
  const std::string path = (fs::path(dir) / kManifestName).string();
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(path, ec))) return m;
  if (!fs::is_regular_file(fs::symlink_status(path, ec)))
    throw InputError(path, "is not a handskin manifest (not a plain file)");
  Json j;
  try {
    j = Json::parse(read_file(path));
  } catch (const Json::exception&) {
    throw InputError(path, "is not a handskin manifest (not JSON)");
  }
  if (!j.is_object() || j.value("format", std::string()) != "handskin-manifest/1" || !j.contains("files") ||
      !j["files"].is_object())
    throw InputError(path, "is not a handskin manifest (format handskin-manifest/1)");
  for (const auto& [name, f] : j["files"].items()) {
    if (!f.is_object() || !f.contains("size") || !f["size"].is_number_unsigned() || !f.contains("sha256") ||
        !f["sha256"].is_string())
      throw InputError(path, "key 'files." + name + "': needs 'size' and 'sha256'");
    m[name] = {f["size"].get<std::uintmax_t>(), f["sha256"].get<std::string>()};
  }
  return m;
}

OutputSet::OutputSet(std::string out_dir, OutputSetOptions options)
    : out_dir_(std::move(out_dir)), options_(std::move(options)), signals_(options_.signal_cleanup) {
  std::error_code ec;
  if (out_dir_.empty()) throw UsageError("--out", "no output folder given");
  if (fs::exists(out_dir_, ec) && !fs::is_directory(out_dir_, ec))
    throw InputError(out_dir_, "exists and is not a folder");
}

OutputSet::~OutputSet() {
  if (!committed_) discard();
}

void OutputSet::claim(const std::vector<std::string>& writes, const std::vector<std::string>& others) {
  HS_CHECK(!claimed_done_, "an output set is claimed once");
  HS_CHECK(!signals_ || g_slots_in_use < kMaxSlots, "too many output sets with signal cleanup at once");
  for (const auto& n : writes)
    HS_CHECK(n.find('/') == std::string::npos && !n.empty() && n != "." && n != ".." && n.rfind(".handskin", 0) != 0,
             "output names are plain file names, none of handskin's own");
  writes_ = writes;
  others_ = others;
  std::error_code ec;
  // --- the folder: every missing level creatable, the first existing one a folder ---
  const fs::path out = fs::absolute(out_dir_).lexically_normal();
  // Not the system's own folders (a run as root would fill / or /etc with its files): the root
  // and /usr themselves, and the trees of programs, libraries, configuration, devices and the
  // kernel's views, through any link (/lib is usr/lib). /usr/local and /usr/src are left to
  // their owners.
  {
    const fs::path real = fs::weakly_canonical(out, ec).lexically_normal();
    const fs::path seen = ec ? out : real;
    std::string folder = seen.string();
    while (folder.size() > 1 && folder.back() == '/') folder.pop_back();
    if (folder == "/") throw InputError(out_dir_, "is the file system's root: handskin writes into a folder of yours; choose another --out");
    if (folder == "/usr") throw InputError(out_dir_, "is /usr, a system folder: handskin writes into a folder of yours; choose another --out");
    for (const char* sys : {"/bin", "/boot", "/dev", "/etc", "/lib", "/lib32", "/lib64", "/libx32", "/proc", "/sbin", "/sys",
                            "/usr/bin", "/usr/include", "/usr/lib", "/usr/lib32", "/usr/lib64", "/usr/libexec", "/usr/libx32",
                            "/usr/sbin", "/usr/share"})
      if (folder == sys || folder.rfind(std::string(sys) + "/", 0) == 0)
        throw InputError(out_dir_, std::string("is in ") + sys +
                                       ", a system folder: handskin writes into a folder of yours; choose another --out");
  }
  std::vector<fs::path> missing;
  fs::path p = out;
  if (!p.has_filename()) p = p.parent_path();
  while (!p.empty() && !fs::exists(fs::symlink_status(p, ec))) {
    missing.push_back(p);
    if (p == p.root_path()) break;
    p = p.parent_path();
  }
  if (!p.empty() && fs::exists(p, ec) && !fs::is_directory(p, ec))
    throw InputError(out_dir_, "cannot be created: '" + p.string() + "' is a file, not a folder");
  if (!missing.empty() && ::access(p.c_str(), W_OK | X_OK) != 0)
    throw InputError(out_dir_, "cannot be created: '" + p.string() + "' is not writable");
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!fs::create_directory(*it, ec) && !fs::is_directory(*it)) {
      discard();
      throw InputError(out_dir_, "cannot be created: " + (ec ? ec.message() : it->string()));
    }
    created_.insert(created_.begin(), it->string());
  }
  // The folder as the user wrote it must be the one made or found: "a/x/../b" with no a/x
  // names a/b to the eye (and to the creation above) but nothing to the system, and every
  // later step would fail on it, the commit last, after all the work.
  if (!fs::is_directory(out_dir_, ec)) {
    const bool dangling = fs::is_symlink(fs::symlink_status(out_dir_, ec));
    discard();
    throw InputError(out_dir_, dangling ? "is a symbolic link to a folder that does not exist"
                                        : "cannot be reached as written: a '..' follows a folder that does not exist "
                                          "(give it as " + out.string() + ")");
  }
  if (::access(out.c_str(), W_OK | X_OK) != 0) {
    discard();
    throw InputError(out_dir_, "is not writable");
  }
  fs::path beside = options_.stage_inside ? out : staging_parent(out);
  if (!options_.stage_inside && ::access(beside.c_str(), W_OK | X_OK) != 0) {
    // The folder beside it is not the user's to write (`--out ~`: /home is root's): the outputs
    // are staged inside the output folder instead, which the check above found writable.
    options_.stage_inside = true;
    beside = out;
  }
  if (::access(beside.c_str(), W_OK | X_OK) != 0) {
    discard();
    throw InputError(out_dir_, "cannot write beside it: '" + beside.string() +
                                   "' is not writable (the outputs are staged there and moved in together)");
  }
  // --- the signal handlers clean up what the claim made from now on ---
  const std::string lock = (out / kLockName).string();
  if (signals_) {
    slot_ = 0;
    while (g_slots[slot_].active) ++slot_;  // a free one: fewer than kMaxSlots are in use
    SignalSlot& g = g_slots[slot_];
    g.path_count = 0;
    g.staging[0] = 0;
    g.created_count = 0;
    for (const auto& c : created_)
      if (g.created_count < kMaxCreated) copy_path(g.created[g.created_count], c), g.created_count = g.created_count + 1;
    copy_path(g.lock, lock);
    g.active = 1;
    if (g_slots_in_use++ == 0) install_handlers();
  }
  // --- the lock: one command writes a folder at a time ---
  for (int attempt = 0; attempt < 8 && lock_fd_ < 0; ++attempt) {
    const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
      const std::string why = std::strerror(errno);
      if (slot_ >= 0) g_slots[slot_].lock[0] = 0;
      discard();
      throw InputError(out_dir_, "cannot lock: " + why);
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      char pid[32] = {0};
      const ssize_t n = ::pread(fd, pid, sizeof pid - 1, 0);
      ::close(fd);
      if (slot_ >= 0) g_slots[slot_].lock[0] = 0;  // not ours to remove
      discard();
      throw InputError(out_dir_, std::string("another handskin command") +
                                     (n > 0 ? " (pid " + std::string(pid, static_cast<size_t>(n)) + ")" : "") +
                                     " is writing into this folder; try again when it has finished");
    }
    // The holder before us may have removed the file after we opened it: lock the file
    // that is there now.
    struct stat a {}, b {};
    if (::fstat(fd, &a) == 0 && ::stat(lock.c_str(), &b) == 0 && a.st_ino == b.st_ino && a.st_dev == b.st_dev) {
      lock_fd_ = fd;
      const std::string pid = std::to_string(::getpid());
      // The holder's pid, for the message a second command gives (best effort: a lock
      // without it still locks).
      if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, pid.data(), pid.size(), 0);
    } else {
      ::close(fd);
    }
  }
  if (lock_fd_ < 0) {
    if (slot_ >= 0) g_slots[slot_].lock[0] = 0;
    discard();
    throw InputError(out_dir_, "cannot lock: the lock file keeps changing");
  }
  if (const int hold = fault_value("hold"); hold > 0) std::this_thread::sleep_for(std::chrono::seconds(hold));
  // --- ownership: each name in the way must be ours (or, with --force, is moved aside) ---
  try {
    manifest_ = read_manifest(out_dir_);
  } catch (const InputError&) {
    if (!options_.force) {
      discard();
      throw;
    }
    in_the_way_.push_back(kManifestName);  // not ours: aside with the rest
  }
  auto check = [&](const std::string& name, bool writing) {
    const fs::path f = out / name;
    const auto st = fs::symlink_status(f, ec);
    if (!fs::exists(st)) return;
    std::string why;
    if (fs::is_directory(st)) why = "is a folder";
    else if (fs::is_symlink(st)) why = "is a symbolic link";
    else if (!fs::is_regular_file(st)) why = "is not a plain file";
    else if (!manifest_.count(name)) why = "was not written by handskin";
    else {
      OwnedFile d;
      try {
        d = describe_file(f.string());
      } catch (const InputError&) {
        why = "cannot be read";
      }
      if (why.empty() && d == manifest_.at(name)) {
        ours_[name] = d;
        return;
      }
      if (why.empty()) why = "was changed since handskin wrote it";
    }
    if (!writing) return;  // not ours and not in the way: left alone
    if (options_.force) {
      in_the_way_.push_back(name);
      return;
    }
    discard();
    throw InputError((fs::path(out_dir_) / name).string(), "is in the way: it " + why + refuse_hint());
  };
  for (const auto& n : writes) check(n, true);
  for (const auto& n : others)
    if (!contains(writes, n)) check(n, false);
  claimed_done_ = true;
}

std::string OutputSet::stage(const std::string& name) {
  HS_CHECK(claimed_done_, "an output set is claimed before it stages");
  HS_CHECK(contains(writes_, name), "output '" + name + "' was not claimed");
  ensure_staging();
  for (const auto& n : names_) HS_CHECK(n != name, "output '" + name + "' staged twice");
  names_.push_back(name);
  const int n = static_cast<int>(names_.size());
  if (fault("stall", n)) std::this_thread::sleep_for(std::chrono::seconds(30));
  if (fault("stage", n)) throw InputError(final_path(name), "cannot write: injected fault (HANDSKIN_FAULT)");
  const std::string path = (fs::path(staging_) / name).string();
  for (const std::string& q : {path, temp_name_for(path)}) {
    if (slot_ < 0) break;
    SignalSlot& g = g_slots[slot_];
    HS_CHECK(g.path_count < kMaxPaths, "too many outputs in one set");
    copy_path(g.paths[g.path_count], q);
    g.path_count = g.path_count + 1;
  }
  return path;
}

void OutputSet::ensure_staging() {
  if (!staging_.empty()) return;
  const fs::path parent = options_.stage_inside ? fs::path(out_dir_) : staging_parent(out_dir_);
  const std::string leaf = fs::absolute(out_dir_).lexically_normal().filename().string();
  staging_ = (parent / (".handskin-staging-" +
                        (options_.stage_inside ? std::string() : (leaf.empty() ? std::string("out") : leaf) + "-") +
                        std::to_string(::getpid())))
                 .string();
  std::error_code ec;
  fs::remove_all(staging_, ec);
  if (!fs::create_directory(staging_, ec) || ec) {
    staging_.clear();
    throw InputError(out_dir_, "cannot write: cannot create a staging folder in '" + parent.string() + "'" +
                                   (ec ? ": " + ec.message() : std::string()));
  }
  if (slot_ >= 0) copy_path(g_slots[slot_].staging, staging_);
  const std::lock_guard<std::mutex> lock(g_staging_mutex);
  auto& known = staging_folders();  // (a host process writing one folder again and again: once)
  if (std::find(known.begin(), known.end(), std::pair{staging_, out_dir_}) == known.end()) known.emplace_back(staging_, out_dir_);
}

std::string as_output_path(const std::string& path) {
  const std::lock_guard<std::mutex> lock(g_staging_mutex);
  for (const auto& [staging, out] : staging_folders()) {
    if (path.size() <= staging.size() + 1 || path.compare(0, staging.size(), staging) != 0 || path[staging.size()] != '/')
      continue;
    const std::string name = name_of_temp(path.substr(staging.size() + 1));  // an output, or its writer's temporary
    if (name.find('/') != std::string::npos) continue;  // not one of its outputs
    return out == "." ? name : (fs::path(out) / name).string();  // a file of the working folder as given
  }
  return path;
}

std::string OutputSet::staged_path(const std::string& name) const {
  HS_CHECK(contains(names_, name) && !staging_.empty(), "output '" + name + "' was not staged");
  return (fs::path(staging_) / name).string();
}

std::string OutputSet::final_path(const std::string& name) const { return (fs::path(out_dir_) / name).string(); }

void OutputSet::release() noexcept {
  if (lock_fd_ >= 0) {
    std::error_code ec;
    fs::remove(fs::path(out_dir_) / kLockName, ec);  // while still held: see claim()
    ::close(lock_fd_);
    lock_fd_ = -1;
  }
  if (slot_ >= 0) {  // the set holds a slot of the handlers' storage (and none other's)
    SignalSlot& g = g_slots[slot_];
    slot_ = -1;
    g.active = 0;
    g.lock[0] = 0;
    g.staging[0] = 0;
    g.path_count = 0;
    g.created_count = 0;
    if (--g_slots_in_use == 0) restore_handlers();
  }
}

void OutputSet::discard() noexcept {
  std::error_code ec;
  if (!staging_.empty()) fs::remove_all(staging_, ec);
  staging_.clear();
  release();
  for (const auto& d : created_) fs::remove(d, ec);  // deepest first; only if empty
  created_.clear();
}

InputError OutputSet::refusal(const std::string& name, const std::string& why) const {
  return InputError(final_path(name), "cannot move into place: " + why + "; " + out_dir_ + " is as it was");
}

std::string OutputSet::why_not_ours(const std::string& name) const {
  return ours_.count(name) ? "it was changed during the run" : "it appeared during the run and is not handskin's";
}

bool OutputSet::ours_unchanged(const std::string& name) const {
  std::error_code ec;
  const fs::path dst = fs::path(out_dir_) / name;
  const auto it = ours_.find(name);
  if (it == ours_.end() || !fs::is_regular_file(fs::symlink_status(dst, ec))) return false;
  try {
    return describe_file(dst.string()) == it->second;
  } catch (const InputError&) {
    return false;
  }
}

void OutputSet::check_commit() const {
  HS_CHECK(claimed_done_ && !committed_, "an output set is checked between its claim and its commit");
  std::error_code ec;
  const fs::path out(out_dir_);
  if (!fs::is_directory(out, ec)) throw refusal(".", "the output folder is gone");
  for (const auto& name : names_) {
    if (!fs::exists(fs::symlink_status(out / name, ec)) || contains(in_the_way_, name)) continue;
    if (!ours_unchanged(name)) throw refusal(name, why_not_ours(name));
  }
}

void OutputSet::commit() {
  HS_CHECK(!committed_, "an output set is committed once");
  HS_CHECK(claimed_done_, "an output set is claimed before it commits");
  if (signals_) hold_signals();
  std::error_code ec;
  const fs::path out(out_dir_);
  // The new manifest: the old one's entries, the files staged now, less what goes.
  std::map<std::string, OwnedFile> manifest = manifest_;
  ensure_staging();
  for (const auto& n : names_) manifest[n] = describe_file((fs::path(staging_) / n).string());
  struct Move {
    std::string name;
    fs::path kept;  // where the file that was there went (aside or backup); empty: none
    bool placed = false;
  };
  std::vector<Move> done;
  const fs::path aside = fs::path(staging_) / ".replaced";
  fs::path backup;
  bool backup_made = false;
  auto undo = [&] {
    std::error_code ignored;
    for (auto it = done.rbegin(); it != done.rend(); ++it) {
      if (it->placed) fs::remove(out / it->name, ignored);
      if (!it->kept.empty()) fs::rename(it->kept, out / it->name, ignored);
    }
    if (backup_made) fs::remove(backup, ignored);
  };
  auto fail = [&](const std::string& name, const std::string& why) {
    undo();
    moved_aside_.clear();
    discard();
    if (signals_) release_signals();
    throw refusal(name, why);
  };
  if (!fs::is_directory(out, ec)) fail(".", "the output folder is gone");
  fs::create_directory(aside, ec);
  if (ec) fail(".", "cannot create " + aside.string() + ": " + ec.message());
  // What is there under a name we touch: ours (unchanged since the claim) goes aside and is
  // dropped after the commit; with --force, anything else goes into the backup; a thing that
  // appeared or changed during the run stops the commit.
  auto take_away = [&](const std::string& name, bool writing, Move* m) {
    const fs::path dst = out / name;
    if (!fs::exists(fs::symlink_status(dst, ec))) return;
    const bool forced = contains(in_the_way_, name);
    if (name == kManifestName && !forced) {  // read and found ours at the claim
      fs::rename(dst, aside / name, ec);
      if (ec) fail(name, ec.message());
      m->kept = aside / name;
      return;
    }
    if (!forced) {
      if (!ours_unchanged(name)) {
        if (!writing) return;  // not ours (or no longer): left alone (the caller drops it from the manifest)
        fail(name, why_not_ours(name));
      }
      fs::rename(dst, aside / name, ec);
      if (ec) fail(name, ec.message());
      m->kept = aside / name;
      return;
    }
    if (!backup_made) {
      const std::string stamp = "handskin-backup-" + utc_stamp();
      backup = out / stamp;
      for (int k = 2; fs::exists(fs::symlink_status(backup, ec)); ++k) backup = out / (stamp + "-" + std::to_string(k));
      fs::create_directory(backup, ec);
      if (ec) fail(name, "cannot create the backup folder " + backup.string() + ": " + ec.message());
      backup_made = true;
    }
    fs::rename(dst, backup / name, ec);
    if (ec) fail(name, ec.message());
    m->kept = backup / name;
    moved_aside_.push_back((backup / name).string());
  };
  // Names of ours that this run does not write: removed when still ours (left alone, and
  // out of the manifest, when not).
  std::vector<std::string> gone;
  for (const auto* list : {&writes_, &others_})
    for (const auto& name : *list) {
      if (contains(names_, name) || contains(gone, name)) continue;
      gone.push_back(name);
      done.push_back(Move{name, {}, false});
      take_away(name, false, &done.back());
      manifest.erase(name);
    }
  {
    Json files = Json::object();
    for (const auto& [n, f] : manifest) files[n] = {{"size", f.size}, {"sha256", f.sha256}};
    try {
      write_file_atomic((fs::path(staging_) / kManifestName).string(),
                        Json{{"format", "handskin-manifest/1"}, {"files", files}}.dump(1) + "\n");
    } catch (const InputError& e) {
      fail(kManifestName, e.detail());
    }
  }
  int count = 0;
  std::vector<std::string> moves = names_;
  moves.push_back(kManifestName);  // last: it describes the others
  for (const auto& name : moves) {
    done.push_back(Move{name, {}, false});
    take_away(name, true, &done.back());
    ++count;
    if (fault("commit", count)) fail(name, "injected fault (HANDSKIN_FAULT)");
    fs::rename(fs::path(staging_) / name, out / name, ec);
    if (ec) fail(name, ec.message());
    done.back().placed = true;
  }
  committed_ = true;
  fs::remove_all(staging_, ec);
  staging_.clear();
  created_.clear();
  release();
  if (options_.say)
    for (const auto& m : moved_aside_) options_.say("moved aside (not handskin's): " + m);
  if (signals_) release_signals();  // the files are in place: now die as asked
}

// --- OutputFiles ---

namespace {
// A single output's folder as given ("." for a bare name), and its path made absolute and
// normal: the key two spellings of one file share.
std::string folder_of(const std::string& path) {
  const fs::path p(path);
  return p.has_parent_path() ? p.parent_path().string() : std::string(".");
}
std::string whole_path(const std::string& path) {
  return (fs::absolute(folder_of(path)).lexically_normal() / fs::path(path).filename()).string();
}
}  // namespace

OutputFiles::OutputFiles(const std::vector<std::string>& paths, OutputSetOptions options)
    : signal_cleanup_(options.signal_cleanup) {
  std::map<std::string, size_t> folder_set;
  std::vector<std::vector<std::string>> names;
  std::vector<std::string> folders;
  for (const std::string& path : paths) {
    const fs::path p(path);
    const std::string name = p.filename().string();
    if (path.empty() || name.empty() || name == "." || name == "..")
      throw UsageError(path.empty() ? "--out" : path, "names no file (a file's path is wanted)");
    if (name.rfind(".handskin", 0) == 0) throw InputError(path, "is a name handskin keeps for its own bookkeeping");
    const std::string folder = folder_of(path);
    // The folder must be there (a file's folder is not made for it, as write_file_atomic says).
    std::error_code ec;
    const fs::file_status st = fs::status(folder, ec);
    if (!fs::exists(st))
      throw InputError(path, "cannot write: folder '" + folder + "' " +
                                 (ec && ec != std::errc::no_such_file_or_directory ? "cannot be reached: " + ec.message()
                                                                                    : std::string("does not exist")));
    if (!fs::is_directory(st)) throw InputError(path, "cannot write: '" + folder + "' is not a folder");
    const std::string key = fs::absolute(folder).lexically_normal().string();
    const std::string whole = whole_path(path);
    if (where_.count(whole))
      throw UsageError(path, "is given for two outputs");
    auto [it, fresh] = folder_set.emplace(key, folders.size());
    if (fresh) folders.push_back(folder), names.emplace_back();
    names[it->second].push_back(name);
    where_[whole] = {it->second, name};
    given_.push_back(path);
  }
  for (size_t k = 0; k < folders.size(); ++k) {
    OutputSetOptions o = options;
    o.stage_inside = true;
    sets_.push_back(std::make_unique<OutputSet>(folders[k], o));
    try {
      sets_.back()->claim(names[k]);
    } catch (const InputError& e) {
      rethrow_as_given(k, e);
    }
  }
}

void OutputFiles::rethrow_as_given(size_t set, const InputError& e) const {
  // A file named as the user gave it ("picture.png", not "./picture.png").
  for (const std::string& path : given_)
    if (const auto& [s, name] = where_.at(whole_path(path)); s == set && e.where() == sets_[set]->final_path(name))
      throw InputError(path, e.detail());
  throw e;
}

OutputFiles::~OutputFiles() = default;

std::string OutputFiles::stage(const std::string& path) {
  const auto it = where_.find(whole_path(path));
  HS_CHECK(it != where_.end(), "output file '" + path + "' was not claimed");
  return sets_[it->second.first]->stage(it->second.second);
}

void OutputFiles::commit() {
  // A signal during the commits is held until every folder's files are in place.
  struct Hold {
    bool on;
    explicit Hold(bool signals) : on(signals) {
      if (on) hold_signals();
    }
    ~Hold() {
      if (on) release_signals();
    }
  } hold(signal_cleanup_);
  // Every folder checked first (a file changed or put there during the run, a folder gone):
  // a refusal then leaves every folder as it was, not the first ones committed.
  for (size_t k = 0; k < sets_.size(); ++k) try {
      sets_[k]->check_commit();
    } catch (const InputError& e) {
      rethrow_as_given(k, e);
    }
  for (size_t k = 0; k < sets_.size(); ++k) try {
      sets_[k]->commit();
    } catch (const InputError& e) {
      rethrow_as_given(k, e);
    }
}

}  // namespace handskin
