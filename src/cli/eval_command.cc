// placeholder
#include "cli/commands.h"
namespace zipfusion::cli {
void add_eval_command(CLI::App&) {}
}
