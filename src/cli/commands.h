#pragma once
// Subcommands of the zipfusion CLI: each adds itself to the app and runs from its callback.

#include <CLI/CLI.hpp>
#include <string>

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

//! Progress on standard error, only when it is a terminal: "label: done/total".
void show_progress(const std::string& label, int done, int total);

}  // namespace zipfusion::cli
