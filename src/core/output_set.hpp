#pragma once
/// A command's output files, written as one set into a folder that handskin owns only in part.
///
/// Ownership (docs/formats.md "Files handskin writes"): the folder holds a manifest,
/// `.handskin-manifest.json` (format handskin-manifest/1), listing every file handskin put
/// there with its size and SHA-256. A file is *ours* when the manifest lists it and it is
/// unchanged since (same size, same hash). Only our files are ever replaced or removed.
///
///  - `claim(names)` comes first, before any work: every name the command may write or
///    retire is checked. One that is in the way and not ours (a user's file, a folder, a file
///    changed since we wrote it) is refused with an InputError naming it — or, with `force`,
///    marked to be moved aside at commit into a dated backup folder
///    (`handskin-backup-YYYYMMDD-HHMMSS/`), never deleted. The output folder is created here
///    if needed (so "cannot be created / is not writable" is known before any work) and
///    locked: a second command claiming the same folder is refused at once while the first
///    holds it (flock on `.handskin-lock`). A set destroyed without a commit removes the lock
///    and the folders it created.
///  - Every file is then written into a staging folder beside the output folder (inside it
///    when the folder beside is not writable, or with `stage_inside`); `commit()`
///    moves them all into place, or none of them. A file it replaces is kept aside and put back
///    if a later move fails, so a failed commit leaves the folder as it was. The manifest is
///    written last. SIGINT, SIGTERM and SIGHUP are held during the moves (a few renames) and
///    delivered after.
///  - A set destroyed without a commit (an exception, a failed stage) removes its staging
///    folder. A SIGINT/SIGTERM/SIGHUP before the commit removes it too (and the lock, and the
///    folders the set created), then ends the process as the signal would have.
///  - The `others` given to `claim()` (outputs of an earlier run that this one does not make:
///    left beside the new report they would look like part of it) are removed when ours, left
///    alone otherwise.
///
/// Fault injection for tests (docs/architecture.md): HANDSKIN_FAULT=stage:N makes the N-th
/// staged file fail, commit:N the N-th move of the commit, stall:N waits 30 s before staging
/// the N-th file (so a test can send a signal mid-write), hold:N waits N seconds after the
/// claim (so a test can start a second command on the same folder).
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace handskin {

class InputError;

/// A path inside a staging folder that an OutputSet of this process made, as the output it
/// stands for (`/out/.handskin-staging-12/skin.ply` and its writer's temporary file →
/// `/out/skin.ply`); any other path as it is. For error messages: a failed write names the
/// file the user asked for, not handskin's staging (the CLI's and the Python module's errors).
std::string as_output_path(const std::string& path);

/// The manifest's name in an output folder.
inline constexpr const char* kManifestName = ".handskin-manifest.json";
/// The lock's name in an output folder.
inline constexpr const char* kLockName = ".handskin-lock";

/// A file as the manifest records it.
struct OwnedFile {
  std::uintmax_t size = 0;
  std::string sha256;  ///< lowercase hex
  bool operator==(const OwnedFile& o) const { return size == o.size && sha256 == o.sha256; }
};

/// Size and SHA-256 of a regular file (OpenSSL). Throws InputError when it cannot be read.
OwnedFile describe_file(const std::string& path);

/// The manifest of `dir` (name → file); empty when there is none. A manifest that is not
/// handskin-manifest/1 is an InputError naming it (it is not ours to overwrite).
std::map<std::string, OwnedFile> read_manifest(const std::string& dir);

struct OutputSetOptions {
  bool force = false;  ///< move things in the way aside into a dated backup instead of refusing
  std::function<void(const std::string&)> say;  ///< one progress line (what was moved aside)
  /// The SIGINT/SIGTERM/SIGHUP handlers that clean up a set cut short (the CLI's sets). Off
  /// for a host process that owns its signals (the Python module): a signal then does what the
  /// host says, and any number of sets may be open at once (one per output folder).
  bool signal_cleanup = true;
  /// The staging folder inside the output folder (hidden, `.handskin-staging-<pid>`) instead
  /// of beside it: for OutputFiles, whose folder (the user's, e.g. the working folder) may
  /// sit in one the user cannot write. A set stages inside on its own too when the folder
  /// beside its output folder is not writable (`--out ~`).
  bool stage_inside = false;
};

class OutputSet {
 public:
  /// `out_dir` is where the files go; it may not exist yet. Nothing is created here.
  explicit OutputSet(std::string out_dir, OutputSetOptions options = {});
  ~OutputSet();
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  /// Before any work: lock the folder (creating it if needed) and check every name the
  /// command will write (`writes`: each must be free or ours; see above). `others` are names
  /// of earlier runs' outputs that this one does not write: removed at the commit when ours,
  /// left alone otherwise (a claimed write that is not staged is treated the same). Throws
  /// InputError naming the first name in the way, or the folder when it cannot be created,
  /// written or locked.
  void claim(const std::vector<std::string>& writes, const std::vector<std::string>& others = {});
  /// The path to write output `name` (a claimed plain file name) to now; its final path is
  /// `final_path(name)`. Creates the staging folder on first use. Throws InputError when the
  /// staging folder cannot be made (the output folder's parent is not writable).
  std::string stage(const std::string& name);
  /// Where staged output `name` is now (to read it back before the commit).
  std::string staged_path(const std::string& name) const;
  /// Where `name` will be once committed (for reports and messages).
  std::string final_path(const std::string& name) const;
  /// Move every staged file into the output folder, things in the way that `force` moves
  /// aside into the backup, and write the manifest. Throws InputError naming the file when a
  /// move fails (or a file of ours was changed during the run), after putting everything back.
  void commit();
  /// What commit would refuse before it moves anything: the output folder gone, a file under
  /// a staged name that appeared or was changed during the run (not one --force moves aside).
  /// Throws InputError as commit would; leaves everything as it is. (OutputFiles checks every
  /// folder's set before committing any.)
  void check_commit() const;
  /// What commit moved aside (final paths in the backup folder).
  const std::vector<std::string>& moved_aside() const { return moved_aside_; }

  const std::string& out_dir() const { return out_dir_; }
  const std::vector<std::string>& names() const { return names_; }

 private:
  void ensure_staging();
  bool ours_unchanged(const std::string& name) const;  ///< listed at the claim and the same bytes now
  /// commit's and check_commit's refusal of `name`, and why a file there is not ours to replace.
  InputError refusal(const std::string& name, const std::string& why) const;
  std::string why_not_ours(const std::string& name) const;
  void discard() noexcept;
  void release() noexcept;
  std::string out_dir_, staging_;
  OutputSetOptions options_;
  std::vector<std::string> names_, writes_, others_, moved_aside_;
  std::map<std::string, OwnedFile> manifest_;  ///< as read at the claim
  std::map<std::string, OwnedFile> ours_;      ///< the claimed names that exist and are ours
  std::vector<std::string> in_the_way_;        ///< claimed names that exist and are not ours (force)
  std::vector<std::string> created_;           ///< folders the claim made, deepest first
  int lock_fd_ = -1;
  bool claimed_done_ = false, committed_ = false;
  bool signals_;  ///< options_.signal_cleanup: this set registers with the signal handlers
  int slot_ = -1;  ///< its place in the handlers' fixed storage while it holds one (from the claim to the release)
};

/// Single output files that the user names (`render --out picture.png`, `model --out
/// model.json`, a CSV, a posed mesh): owned as an output folder's files are, each file in the
/// folder it goes to. The constructor claims every path before any work (one OutputSet per
/// folder, staging inside it, so that only that folder need be writable): a file in the way
/// that handskin did not write, or that was changed since it did, is refused with an InputError
/// naming it (with `force`, moved aside into a dated backup folder at the commit). Then each
/// file is written to `stage(path)`, and `commit()` moves them into place and records them in
/// their folder's manifest, so that the next command may replace them. Destroyed without a
/// commit, nothing is written.
class OutputFiles {
 public:
  /// Throws UsageError for a path that names no file (empty, "dir/") or is given twice, and
  /// InputError for one whose folder does not exist, that names handskin's own bookkeeping
  /// (`.handskin-…`), or that is in the way.
  explicit OutputFiles(const std::vector<std::string>& paths, OutputSetOptions options = {});
  ~OutputFiles();
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;
  /// Where to write `path` (one of the constructor's) now.
  std::string stage(const std::string& path);
  /// Every staged file into place, folder by folder.
  void commit();

 private:
  std::vector<std::unique_ptr<OutputSet>> sets_;
  [[noreturn]] void rethrow_as_given(size_t set, const InputError& e) const;
  bool signal_cleanup_ = true;  ///< the sets' (every folder's set is cleaned up by a signal)
  std::vector<std::string> given_;  ///< the paths as given (their set and name: where_)
  std::map<std::string, std::pair<size_t, std::string>> where_;  ///< path → (set, file name)
};

}  // namespace handskin
