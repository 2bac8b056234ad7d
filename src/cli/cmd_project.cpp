#include "cli/commands.hpp"

namespace strata::cli {

void register_project_commands(CLI::App& app) { (void)app; }

}  // namespace strata::cli
