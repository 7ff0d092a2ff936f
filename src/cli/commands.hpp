#pragma once
/// The command-line front end's pieces: one file per command group registers its
/// subcommands (options → a plain args struct) and what to run for them. Commands parse,
/// call the stages, write through an OutputSet and print; no computing here.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output_set.hpp"
#include "pipeline/gates.hpp"

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace handskin::cli {

/// Progress lines on stderr ("[  1.23s] stage: message"), off with -q.
struct Progress {
  bool quiet = false;
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  void operator()(const std::string& tag, const std::string& msg) const {
    if (quiet) return;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "[%6.2fs] %s: %s\n", s, tag.c_str(), msg.c_str());
  }
};

/// How a command's OutputSet treats things in the way (--force) and says what it moved aside
/// (always, on stderr: a user's file moved is never silent).
inline OutputSetOptions output_options(bool force) {
  OutputSetOptions o;
  o.force = force;
  o.say = [](const std::string& m) { std::fprintf(stderr, "warning: %s\n", m.c_str()); };
  return o;
}

/// Each failed gate as one warning line on stderr (always, -q or not); with `strict` and a
/// failed gate, a GateFailure naming them (the caller has not committed: nothing is written).
inline void settle_gates(const QualityGates& g, bool strict, const std::string& out_dir) {
  for (const auto& q : g.gates)
    if (!q.pass) std::fprintf(stderr, "warning: %s\n", gate_warning(q).c_str());
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
