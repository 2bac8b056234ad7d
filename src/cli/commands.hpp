#pragma once
// Each command group registers its subcommands on the application. A command's
// callback parses and validates, calls the library, and throws strata::Error
// subclasses for anything the user can fix; main() maps them to one line on
// stderr and a non-zero exit status.
#include <CLI/CLI.hpp>

namespace strata::cli {

void register_project_commands(CLI::App& app);   // init, info
void register_stratigraphy_commands(CLI::App& app);  // unit, relation, matrix, layer
void register_import_commands(CLI::App& app);    // import photos|markers, markers
// camera list|set|clear, import calibration (after register_import_commands)
void register_camera_commands(CLI::App& app);
void register_markers_command(CLI::App& app);  // markers (the list and residuals), markers guide
void register_synth_command(CLI::App& app);      // synth
void register_registration_commands(CLI::App& app);  // register scan
void register_process_commands(CLI::App& app);   // process, (later) volume, check
void register_export_commands(CLI::App& app);    // export ...
void register_viewer_command(CLI::App& exp);     // export viewer (under export)
void register_products_commands(CLI::App& app);  // export dtm|ortho|qgis|grass
void register_volume_commands(CLI::App& app);    // volume, check, export thickness|voxels|section
void register_report_command(CLI::App& app);      // report
void register_finds_command(CLI::App& app);       // finds (with the volume commands)
void register_serve_command(CLI::App& app);       // serve (the field station)

}  // namespace strata::cli
