#pragma once
/// The command-line front end's pieces: one file per command group registers its
/// subcommands (options → a plain args struct) and what to run for them. Commands parse,
/// call the stages, write through an OutputSet and print; no computing here.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "core/paths.hpp"
#include "pipeline/gates.hpp"
#include "scan/cubist_io.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace handskin::cli {

/// What goes to stderr, and how (global flags, docs/cli.md): progress lines unless `quiet`;
/// warnings and errors always; with `verbose` each line also gives the process's peak memory;
/// with `json` every stderr line is one JSON object (JSON lines, for scripts and GUIs):
/// {"t": seconds since start, "level": "info"|"warning"|"error", "stage": …, "message": …,
/// "peak_mb": …} (and "exit" on an error).
struct LogOptions {
  bool quiet = false, verbose = false, json = false;
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
};
inline LogOptions& log_options() {
  static LogOptions o;
  return o;
}
/// The process's peak resident memory so far, MB.
inline double peak_memory_mb() {
  struct rusage u {};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}
/// One stderr line at `level` ("info": a progress line; "warning"; "error", with its exit code).
inline void log_line(const char* level, const std::string& stage, const std::string& message, int exit_code = 0) {
  const LogOptions& o = log_options();
  const bool info = std::strcmp(level, "info") == 0;
  if (info && o.quiet) return;
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - o.t0).count();
  if (o.json) {
    Json j{{"t", std::round(s * 1000) / 1000}, {"level", level}, {"stage", stage}, {"message", message},
           {"peak_mb", std::round(peak_memory_mb())}};
    if (!info && std::strcmp(level, "warning") != 0) j["exit"] = exit_code;
    std::fprintf(stderr, "%s\n", j.dump().c_str());
  } else if (info) {
    if (o.verbose)
      std::fprintf(stderr, "[%6.2fs %5.0f MB] %s: %s\n", s, peak_memory_mb(), stage.c_str(), message.c_str());
    else
      std::fprintf(stderr, "[%6.2fs] %s: %s\n", s, stage.c_str(), message.c_str());
  } else {
    std::fprintf(stderr, "%s: %s\n", level, message.c_str());
  }
  std::fflush(stderr);
}

/// Progress lines on stderr ("[  1.23s] stage: message"; log_line's forms). A message that
/// starts with "warning: " is a warning: shown with -q too.
struct Progress {
  void operator()(const std::string& tag, const std::string& msg) const {
    if (msg.rfind("warning: ", 0) == 0)
      log_line("warning", tag, msg.substr(9));
    else
      log_line("info", tag, msg);
  }
  bool quiet() const { return log_options().quiet; }
};

/// How a command's OutputSet treats things in the way (--force) and says what it moved aside
/// (always, on stderr: a user's file moved is never silent).
inline OutputSetOptions output_options(bool force) {
  OutputSetOptions o;
  o.force = force;
  o.say = [](const std::string& m) { log_line("warning", "output", m); };
  return o;
}

/// `--force` for a command that writes files the user names (OutputFiles).
inline void add_force_flag(CLI::App* command, bool* force) {
  command->add_flag("--force", *force,
                    "Move a file in the way of an output (same name, not written by handskin, or changed since) aside "
                    "into a dated backup folder beside it instead of refusing");
}

/// Each failed gate as one warning line on stderr (always, -q or not); with `strict` and a
/// failed gate, a GateFailure naming them (the caller has not committed: nothing is written).
inline void settle_gates(const QualityGates& g, bool strict, const std::string& out_dir) {
  for (const auto& q : g.gates)
    if (!q.pass) log_line("warning", "gates", gate_warning(q));
  if (strict && !g.all_pass())
    throw GateFailure(out_dir + ": " + std::to_string(g.failed().size()) + " quality gate(s) failed (" +
                      g.failed_list() + "); --strict: nothing was written");
}

/// One stdout line: how many gates passed, and which failed.
inline void print_gates(const QualityGates& g) {
  const size_t failed = g.failed().size();
  std::printf("quality gates: %zu of %zu passed%s\n", g.gates.size() - failed, g.gates.size(),
              failed == 0 ? "" : (" (failed: " + g.failed_list() + ")").c_str());
}

/// A picture is written as PNG: a path that does not end in .png is refused (UsageError
/// naming `flag`) rather than given PNG bytes under another name.
inline void require_png(const std::string& path, const std::string& flag) {
  if (lower_extension(path) != ".png") throw UsageError(flag, "'" + path + "': pictures are written as PNG (.png)");
}

/// An option that names a scan takes its stem or either of its files ("back", "back.json",
/// "back.png": scan_stem) and holds the stem.
inline CLI::Validator scan_stem_option() {
  return CLI::Validator([](std::string& s) { s = scan_stem(s); return std::string(); }, "STEM");
}

/// A subcommand and what to do when it was given.
struct Command {
  CLI::App* app = nullptr;
  std::function<void()> run;
};
using Commands = std::vector<Command>;

void add_pipeline_commands(CLI::App& app, const Progress& progress, Commands* out);  ///< run, register, skin
void add_posture_commands(CLI::App& app, const Progress& progress, Commands* out);   ///< solve, calibrate, model, mocap
void add_synth_commands(CLI::App& app, const Progress& progress, Commands* out);     ///< synth hand, synth scan
void add_tool_commands(CLI::App& app, const Progress& progress, Commands* out);      ///< render, convert
void add_rigging_commands(CLI::App& app, const Progress& progress, Commands* out);   ///< pose

}  // namespace handskin::cli
