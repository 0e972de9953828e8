// zipfusion: one zippered mesh per frame from several RGB-D cameras. See README.md.

#include <unistd.h>

#include <cstdio>
#include <exception>
#include <iostream>
#include <mutex>
#include <string>

#include "cli/commands.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/memory.h"

namespace zipfusion::cli {

namespace {

// Progress and diagnostics share standard error, and the sink thread writes too.
std::mutex stderr_mutex;
std::string open_progress_line;  // what the terminal's last line shows unfinished; "" when none

}  // namespace

void show_progress(const std::string& label, int done, int total) {
  static const bool is_terminal = ::isatty(STDERR_FILENO);
  if (!is_terminal) return;
  const std::lock_guard lock(stderr_mutex);
  open_progress_line = label + ": " + std::to_string(done) + "/" + std::to_string(total);
  std::fprintf(stderr, "\r%s", open_progress_line.c_str());
  if (done >= total) {
    std::fprintf(stderr, "\n");
    open_progress_line.clear();
  }
  std::fflush(stderr);
}

void print_diagnostic(const std::string& line) {
  const std::lock_guard lock(stderr_mutex);
  // "\r" and erase to the end of the line: the line takes the progress line's place, which is
  // drawn again under it.
  if (!open_progress_line.empty()) std::fprintf(stderr, "\r\033[K");
  std::fprintf(stderr, "%s\n", line.c_str());
  if (!open_progress_line.empty()) std::fprintf(stderr, "%s", open_progress_line.c_str());
  std::fflush(stderr);
}

void check_every_option(CLI::App& app) {
  static const CLI::Validator given_number(
      [](std::string& text) -> std::string {
        return text.find_first_not_of(" \t") == std::string::npos ? "must be a number, got nothing" : std::string();
      },
      "");
  static const CLI::Validator given_path(
      [](std::string& text) -> std::string { return text.empty() ? "must not be empty" : std::string(); }, "");
  // kFiniteNumber without its name in the help, which lists it only where an option asked for it.
  static const CLI::Validator finite_number = [] {
    CLI::Validator finite = kFiniteNumber;
    finite.description("");
    return finite;
  }();
  for (CLI::Option* option : app.get_options()) {
    const std::string type = option->get_type_name();
    const bool floating = type.rfind("FLOAT", 0) == 0;
    if (floating || type.rfind("INT", 0) == 0 || type.rfind("UINT", 0) == 0) option->check(given_number);
    if (floating) option->check(finite_number);
    if (option->check_lname("out")) option->check(given_path);
  }
  for (CLI::App* command : app.get_subcommands({})) check_every_option(*command);
}

void print_error(const std::string& line) {
  const std::lock_guard lock(stderr_mutex);
  if (!open_progress_line.empty()) std::fprintf(stderr, "\n");  // the progress stays as far as it got
  open_progress_line.clear();
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

}  // namespace zipfusion::cli

int main(int argc, char** argv) {
  zipfusion::keep_freed_memory();
  CLI::App app{"zipfusion: one clean, coloured, connected triangle mesh per frame from several RGB-D cameras"};
  app.set_version_flag("--version", "zipfusion 0.1.0");
  app.require_subcommand(1);
  zipfusion::cli::add_synth_command(app);
  zipfusion::cli::add_info_command(app);
  zipfusion::cli::add_reconstruct_command(app);
  zipfusion::cli::add_eval_command(app);
  zipfusion::cli::add_bench_command(app);
  zipfusion::cli::add_register_command(app);
  zipfusion::cli::add_calibrate_command(app);
  zipfusion::cli::add_serve_command(app);
  zipfusion::cli::add_record_command(app);
  zipfusion::cli::check_every_option(app);
  // CLI11 reads an unknown command (or `calibrate`'s subcommand) as a stray argument and says only
  // that a subcommand is required.
  const CLI::App* level = &app;
  std::string level_name;  // "" or "calibrate "
  for (int k = 1; k < argc && argv[k][0] != '-' && !level->get_subcommands({}).empty(); ++k) {
    std::string commands;
    const CLI::App* found = nullptr;
    for (const CLI::App* command : level->get_subcommands({})) {
      commands += (commands.empty() ? "" : ", ") + command->get_name();
      if (command->check_name(argv[k])) found = command;
    }
    if (found == nullptr) {
      std::cerr << "zipfusion: error: unknown " << level_name << "command \"" << argv[k] << "\" (commands: " << commands << ")\n";
      return 2;
    }
    level = found;
    level_name += found->get_name() + " ";
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version print and exit 0 as CLI11 does; a usage error is one line like every
    // other error, exit 2 (invalid input).
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::cerr << "zipfusion: error: " << e.what() << " (see --help)\n";
    return 2;
  } catch (const zipfusion::cli::Interrupted& e) {
    zipfusion::cli::print_error(e.what());
    return e.exit_code;
  } catch (const zipfusion::InvalidInput& e) {
    zipfusion::cli::print_error(std::string("zipfusion: error: ") + e.what());
    return 2;
  } catch (const zipfusion::IoError& e) {
    zipfusion::cli::print_error(std::string("zipfusion: error: ") + e.what());
    return 3;
  } catch (const std::exception& e) {
    zipfusion::cli::print_error(std::string("zipfusion: error: ") + e.what());
    return 1;
  }
  return 0;
}
