// handskin: range scans of a hand -> rigged skin. The command-line front end: it parses
// options, calls the stages (one file per command group, cli/*_commands.cpp), prints progress
// to stderr and turns errors into one line: exit 1 for bad data, 2 for bad usage, 3 for a
// quality gate failed under --strict (nothing written), 4 for a bug.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "cli/huge_pages.hpp"
#include "core/errors.hpp"
#include "core/output_set.hpp"
#include "core/threads.hpp"
#include "scan/cloud.hpp"

using namespace handskin;

namespace {
// Edit distance (insertions, deletions, substitutions), for "did you mean".
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// The first word that is not a global option (nor --threads's value); null when there is none.
const char* first_word(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string w = argv[i];
    if (w == "--threads") {
      ++i;
      continue;
    }
    if (!w.empty() && w[0] == '-') continue;
    return argv[i];
  }
  return nullptr;
}
// The command the user typed, when it is none of the app's. Empty when the words name a
// command or there is none.
std::string unknown_command(const CLI::App& app, int argc, char** argv) {
  const char* w = first_word(argc, argv);
  if (!w) return "";
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    if (sub->get_name() == w) return "";
  return w;
}
// The command word (first_word); null also when help is asked for (no work to make faster).
const char* command_word(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string w = argv[i];
    if (w == "-h" || w == "--help") return nullptr;
  }
  return first_word(argc, argv);
}
/// The one line an error gets ("error: …", or its JSON line with --log-json); returns `code`.
int fail(const std::string& command, const std::string& message, int code) {
  if (cli::log_options().json)
    cli::log_line("error", command, message, code);
  else
    std::fprintf(stderr, "error: %s\n", message.c_str());
  return code;
}
}  // namespace

int main(int argc, char** argv) {
  cli::rerun_with_huge_pages(command_word(argc, argv), argv);
  cli::reuse_freed_memory(command_word(argc, argv));
  silence_pcl_console();  // our errors name the file; PCL's own lines would only repeat them
  CLI::App app{"handskin: range scans of a hand -> a rigged, animatable skin (after Yasumuro 2000).\n"
               "Millimetres and degrees everywhere; see docs/ for frames and formats."};
  app.require_subcommand(1);
  app.fallthrough();  // -q is accepted after the subcommand too (subcommands inherit this)
  app.set_version_flag("--version", "handskin 0.1.0");
  cli::Progress progress;
  cli::LogOptions& log = cli::log_options();
  app.add_flag("-q,--quiet", log.quiet, "No progress lines on stderr (warnings and errors still)");
  app.add_flag("-v,--verbose", log.verbose,
               "Progress lines with the process's peak memory, and a last line with the command's time and memory");
  app.add_flag("--log-json", log.json,
               "Every stderr line as one JSON object (JSON lines: t, level, stage, message, peak_mb; exit on an error), "
               "for scripts and GUIs");
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
    if (const std::string typed = unknown_command(app, argc, argv); !typed.empty()) {
      std::string names, nearest;
      size_t best = 3;  // suggest only a near miss
      for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        names += (names.empty() ? "" : ", ") + sub->get_name();
        if (const size_t d = edit_distance(typed, sub->get_name()); d < best) best = d, nearest = sub->get_name();
      }
      return fail("", "unknown command '" + typed + "'" + (nearest.empty() ? "" : " (did you mean " + nearest + "?)") +
                          " (commands: " + names + "; see --help)",
                  2);
    }
    // Usage errors: one line, exit 2 (CLI11's own codes are 100+ and its text two lines).
    std::string what = e.what();
    for (char& c : what)
      if (c == '\n') c = ' ';
    while (!what.empty() && what.back() == ' ') what.pop_back();
    return fail("", what + " (see --help)", 2);
  }

  if (threads > 0) set_thread_count(threads);
  std::string command;
  for (const auto& c : commands)
    if (c.app->parsed()) command = c.app->get_name();
  try {
    for (const auto& c : commands)
      if (c.app->parsed()) c.run();
  } catch (const UsageError& e) {
    return fail(command, std::string(e.what()) + " (see --help)", 2);
  } catch (const InputError& e) {
    // A failed write names the output the user asked for, not the staging folder it went to.
    return fail(command, InputError(as_output_path(e.where()), e.detail()).what(), 1);
  } catch (const GateFailure& e) {
    return fail(command, e.what(), 3);
  } catch (const std::exception& e) {
    return fail(command, std::string("internal: ") + e.what(), 4);
  }
  if (log.verbose && !log.json)
    cli::log_line("info", command, "done in " + std::to_string(std::chrono::duration<double>(
                                                      std::chrono::steady_clock::now() - log.t0).count()).substr(0, 5) +
                                       " s, peak memory " + std::to_string(static_cast<int>(cli::peak_memory_mb())) + " MB" +
                                       cli::pages_note());
  return 0;
}
