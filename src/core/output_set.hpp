#pragma once
/// A command's output files, written as one set: every file is first written into a staging
/// folder beside the output folder; `commit()` moves them all into place, or none of them.
///
///  - Until `commit()`, the output folder is not touched (not even created).
///  - `commit()` moves each file over its destination; a file it replaces is kept aside and
///    put back if a later move fails, so a failed commit leaves the folder as it was.
///    SIGINT, SIGTERM and SIGHUP are held during the moves (a few renames) and delivered after.
///  - A set destroyed without a commit (an exception, a failed stage) removes its staging
///    folder. A SIGINT/SIGTERM/SIGHUP while files are being staged removes them too, then
///    ends the process as the signal would have.
///  - Files in the output folder that the set does not write are never touched, except the
///    names given to `retire()` (outputs of an earlier run that this one does not make: left
///    beside the new report they would look like part of it).
///
/// Fault injection for tests (docs/architecture.md): HANDSKIN_FAULT=stage:N makes the N-th
/// staged file fail, commit:N the N-th move of the commit, stall:N waits 30 s before staging
/// the N-th file (so a test can send a signal mid-write).
#include <string>
#include <vector>

namespace handskin {

class OutputSet {
 public:
  /// `out_dir` is where the files go; it may not exist yet. Nothing is created here.
  explicit OutputSet(std::string out_dir);
  ~OutputSet();
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  /// The path to write output `name` (a plain file name) to now; its final path is
  /// `final_path(name)`. Creates the staging folder on first use. Throws InputError when the
  /// staging folder cannot be made (the output folder's parent is not writable).
  std::string stage(const std::string& name);
  /// Where `name` will be once committed (for reports and messages).
  std::string final_path(const std::string& name) const;
  /// Names of ours to remove from the output folder at commit if this set does not write them.
  void retire(const std::vector<std::string>& names);
  /// Move every staged file into the output folder (created if needed). Throws InputError
  /// naming the file when a move fails, after putting everything back.
  void commit();

  const std::string& out_dir() const { return out_dir_; }
  const std::vector<std::string>& names() const { return names_; }

 private:
  void ensure_staging();
  void discard() noexcept;
  std::string out_dir_, staging_;
  std::vector<std::string> names_, retired_;
  bool committed_ = false;
};

}  // namespace handskin
