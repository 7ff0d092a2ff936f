#pragma once
/// The command-line front end's pieces: one file per command group registers its
/// subcommands (options → a plain args struct) and what to run for them. Commands parse,
/// call the stages, write through an OutputSet and print; no computing here.
#include <CLI/CLI.hpp>

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
