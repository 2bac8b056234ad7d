#include "cli/commands.hpp"

namespace strata::cli {

void register_synth_command(CLI::App& app) { (void)app; }

}  // namespace strata::cli
