#include "cli/commands.hpp"

namespace strata::cli {

void register_import_commands(CLI::App& app) { (void)app; }

}  // namespace strata::cli
