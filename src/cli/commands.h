#pragma once
// Subcommands of the zipfusion CLI: each adds itself to the app and runs from its callback.

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace zipfusion::cli {

void add_synth_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_reconstruct_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_register_command(CLI::App& app);
void add_calibrate_command(CLI::App& app);
void add_serve_command(CLI::App& app);
void add_record_command(CLI::App& app);

//! A whole number, said so before a range is tested ("abc" or "1.5" is not "out of range").
inline const CLI::Validator kWholeNumber(
    [](std::string& text) -> std::string {
      size_t used = 0;
      try {
        std::stoll(text, &used);
      } catch (const std::out_of_range&) {
        return std::string();  // a whole number, too large: the range check says so
      } catch (const std::exception&) {
        used = 0;
      }
      return used > 0 && used == text.size() ? std::string() : "must be a whole number, got " + text;
    },
    "INT");

//! The --threads option every subcommand has: 0 (all cores) to kMostThreads.
inline constexpr int kMostThreads = 1024;
inline CLI::Option* add_threads_option(CLI::App* cmd, int& threads, const std::string& what = "Worker threads (0 = all cores)") {
  return cmd->add_option("--threads", threads, what)->check(kWholeNumber)->check(CLI::Range(0, kMostThreads))->capture_default_str();
}

//! A number that is finite: CLI11's Range lets NaN through (every comparison with it is false).
inline const CLI::Validator kFiniteNumber(
    [](std::string& text) -> std::string {
      double value = 0;
      try {
        value = std::stod(text);
      } catch (const std::exception&) {
        return "must be a number, got " + text;
      }
      return std::isfinite(value) ? std::string() : "must be a finite number, got " + text;
    },
    "FINITE");

//! Checks that every command's options share, added after the commands: every number option
//! refuses an empty value, which CLI11 reads as 0 (`--coarse-levels ""` ran with no coarse levels),
//! and every floating-point one NaN and infinity, which CLI11's Range lets through
//! (`--scale-tolerance nan` turned the calibration's scale check off); numbers are found by the
//! type CLI11 gives them (INT, UINT, FLOAT), and keep their own checks. Every --out refuses an empty
//! path, which some commands found only after all their work, when the result could not be moved
//! into place.
void check_every_option(CLI::App& app);

//! A run stopped by a signal after it kept what it had made: the message says what. The process
//! exits 128 + the signal's number, as a shell reports a process the signal ended (130 for Ctrl-C).
struct Interrupted : std::runtime_error {
  Interrupted(const std::string& what, int signal) : std::runtime_error(what), exit_code(128 + (signal > 0 ? signal : 2)) {}
  int exit_code;
};

//! JSON text for output: a path that is not UTF-8 (Linux allows any bytes in a name) has its
//! stray bytes written as U+FFFD instead of making nlohmann::json throw.
template <typename Json>
std::string json_text(const Json& j, int indent = -1) {
  return j.dump(indent, ' ', false, Json::error_handler_t::replace);
}

//! printf's formatting into a string, of any length. Numbers and C strings only (.c_str()).
std::string format(const char* fmt, auto... values) {
  static_assert(((std::is_arithmetic_v<decltype(values)> || std::is_pointer_v<decltype(values)>) && ...), "printf takes numbers and C strings");
  const int length = std::snprintf(nullptr, 0, fmt, values...);
  if (length <= 0) return {};
  std::string text(static_cast<size_t>(length), '\0');
  std::snprintf(text.data(), text.size() + 1, fmt, values...);
  return text;
}

//! Progress on standard error, only when it is a terminal: "label: done/total", redrawn in place
//! until done reaches total.
void show_progress(const std::string& label, int done, int total);

//! One line (without its newline) on standard error, for a warning while progress may be shown:
//! it takes the unfinished progress line's place, and the progress is drawn again under it.
void print_diagnostic(const std::string& line);

//! The line of an error that ends the run; an unfinished progress line is ended first.
void print_error(const std::string& line);

}  // namespace zipfusion::cli
