// handskin: range scans of a hand -> rigged skin. The command-line front end: it parses
// options, calls the stages (one file per command group, cli/*_commands.cpp), prints progress
// to stderr and turns errors into one line: exit 1 for bad data, 2 for bad usage, 3 for a
// quality gate failed under --strict (nothing written), 4 for a bug.
#include <CLI/CLI.hpp>

#include <cstdio>

#include "cli/commands.hpp"
#include "core/errors.hpp"
#include "core/threads.hpp"
#include "scan/cloud.hpp"

using namespace handskin;

int main(int argc, char** argv) {
  silence_pcl_console();  // our errors name the file; PCL's own lines would only repeat them
  CLI::App app{"handskin: range scans of a hand -> a rigged, animatable skin (after Yasumuro 2000).\n"
               "Millimetres and degrees everywhere; see docs/ for frames and formats."};
  app.require_subcommand(1);
  app.fallthrough();  // -q is accepted after the subcommand too (subcommands inherit this)
  app.set_version_flag("--version", "handskin 0.1.0");
  cli::Progress progress;
  app.add_flag("-q,--quiet", progress.quiet, "No progress lines on stderr");
  int threads = 0;
  app.add_option("--threads", threads,
                 "Threads for the parallel steps (default: every core); the outputs are the same bytes with any number")
      ->check(CLI::Range(1, 1024));
  cli::Commands commands;
  cli::add_pipeline_commands(app, progress, &commands);
  cli::add_posture_commands(app, progress, &commands);
  cli::add_synth_commands(app, progress, &commands);
  cli::add_tool_commands(app, progress, &commands);
  cli::add_rigging_commands(app, progress, &commands);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    // Usage errors: one line, exit 2 (CLI11's own codes are 100+ and its text two lines).
    std::string what = e.what();
    for (char& c : what)
      if (c == '\n') c = ' ';
    while (!what.empty() && what.back() == ' ') what.pop_back();
    std::fprintf(stderr, "error: %s (see --help)\n", what.c_str());
    return 2;
  }

  if (threads > 0) set_thread_count(threads);
  try {
    for (const auto& c : commands)
      if (c.app->parsed()) c.run();
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const GateFailure& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: internal: %s\n", e.what());
    return 4;
  }
  return 0;
}
