// strata import photos|scan|depth|markers|finds|units|relations, strata markers, strata find add
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "importers/depth/depth_importer.hpp"
#include "importers/finds/find_importer.hpp"
#include "importers/markers/marker_importer.hpp"
#include "importers/photos/photo_importer.hpp"
#include "importers/scans/scan_importer.hpp"
#include "importers/stratigraphy/register_importer.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "stratigraphy/harris_matrix.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <map>
#include <memory>

namespace strata::cli {

namespace {

void print_find_summary(const std::string& what, const FindImportSummary& s) {
  fmt::print("{} ({}): {} new, {} updated, {} unchanged finds\n", what, s.source_crs, s.finds_new, s.finds_updated,
             s.finds_unchanged);
}

// strata import finds DIR FILE, strata find add DIR --id ... --at E,N,Z --unit CODE
void register_find_imports(CLI::App& app, CLI::App& import) {
  const char* crs_help =
      "CRS of the coordinates (default: the site CRS); e.g. EPSG:4326 for longitude/latitude in degrees";
  const char* update_help =
      "replace finds already in the project whose position, unit, type or description differ (default: refuse "
      "them; the same find again is left as it is)";
  {
    auto* cmd = import.add_subcommand(
        "finds",
        "import finds recorded in place from a total-station CSV (id,E,N,Z,unit[,type][,description];\n"
        "header optional; comma, semicolon, tab or space separated). Every unit must already be in the\n"
        "project. Nothing is imported when any line is bad. 'strata finds DIR' then tells which unit's\n"
        "solid holds each find.");
    auto dir = std::make_shared<std::string>();
    auto file = std::make_shared<std::string>();
    auto options = std::make_shared<FindImportOptions>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("FILE", *file, "finds CSV")->required();
    cmd->add_option("--crs", options->crs, crs_help);
    cmd->add_flag("--update", options->update, update_help);
    cmd->footer("Example: strata import finds site finds.csv");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      print_find_summary(*file, import_finds(p, *options, *file));
    });
  }
  auto* find = app.add_subcommand("find", "finds recorded in place: add one ('strata finds DIR' lists them)");
  find->require_subcommand(1);
  auto* cmd = find->add_subcommand("add", "record one find at a surveyed point, in a unit of the project");
  auto dir = std::make_shared<std::string>();
  auto at = std::make_shared<std::string>();
  auto record = std::make_shared<FindRecord>();
  auto options = std::make_shared<FindImportOptions>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--id", record->id, "the find's number")->required();
  cmd->add_option("--at", *at, "E,N,Z of the find (metres in the site CRS, or in --crs)")->required();
  cmd->add_option("--unit", record->unit, "code of the unit it was recorded in")->required();
  cmd->add_option("--type", record->type, "pottery, bone, lithic, metal, ...");
  cmd->add_option("--description", record->description, "free text");
  cmd->add_option("--crs", options->crs, crs_help);
  cmd->add_flag("--update", options->update, update_help);
  cmd->footer("Example: strata find add site --id F17 --at 734012.402,4174018.311,1450.127 --unit 102 --type pottery");
  cmd->callback([=] {
    FindRecord f = *record;
    f.position = parse_vector3(*at, "--at");
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    print_find_summary("find " + f.id, add_find(p, *options, f));
  });
}

void warn_ignored_columns(const std::string& file, const std::vector<std::string>& columns) {
  if (!columns.empty())
    log::warn("{}: columns not recorded by strata, ignored: {}", file, fmt::join(columns, ", "));
}

// strata import units DIR FILE, strata import relations DIR FILE
void register_stratigraphy_imports(CLI::App& import) {
  {
    auto* cmd = import.add_subcommand(
        "units",
        "import a unit register kept in a spreadsheet: a header row naming the columns code, type\n"
        "and optionally description (any order, any case), then one unit per line. Comma, semicolon\n"
        "or tab separated (detected); a value holding the delimiter or a quote goes in double quotes,\n"
        "a quote inside doubled (\"\"), as spreadsheets export CSV. A value may not span lines. type is\n"
        "deposit, cut, structure or interface. Other columns are ignored and named. A unit already in\n"
        "the project with another type or description is refused (or replaced with --update); the\n"
        "same unit again is left as it is. Nothing is imported when any line is bad.");
    auto dir = std::make_shared<std::string>();
    auto file = std::make_shared<std::string>();
    auto options = std::make_shared<UnitImportOptions>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("FILE", *file, "unit register (CSV)")->required();
    cmd->add_flag("--update", options->update,
                  "replace the type and description of units already in the project (default: refuse them)");
    cmd->footer("Example: strata import units site units.csv\n"
                "  code,type,description\n"
                "  104,deposit,\"pale yellowish sandy gravel (sand, gravel)\"");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      const auto s = import_units(p, *options, *file);
      warn_ignored_columns(*file, s.ignored_columns);
      fmt::print("{}: {} new, {} updated, {} unchanged units\n", *file, s.units_new, s.units_updated,
                 s.units_unchanged);
    });
  }
  auto* cmd = import.add_subcommand(
      "relations",
      "import stratigraphic relations: a header row naming the columns a, relation and b (any order,\n"
      "any case), then one 'A relation B' per line, e.g. 102,below,101. Relations: " +
          fmt::format("{}", fmt::join(relation_words(), ", ")) +
          ".\nDelimiters and quotes as for 'import units'. Every unit must already be in the project. A\n"
          "relation that would make the Harris matrix cyclic is refused with its line and the cycle.\n"
          "Relations already recorded are left as they are. Nothing is imported when any line is bad.");
  auto dir = std::make_shared<std::string>();
  auto file = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("FILE", *file, "relations (CSV)")->required();
  cmd->footer("Example: strata import relations site relations.csv\n"
              "  a,relation,b\n"
              "  101,above,102");
  cmd->callback([=] {
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const auto s = import_relations(p, *file);
    warn_ignored_columns(*file, s.ignored_columns);
    fmt::print("{}: {} new relations, {} already recorded\n", *file, s.relations_new, s.relations_unchanged);
  });
}

std::string scan_summary(const ImportedScan& s) {
  std::vector<std::string> has;
  if (s.info.has_colour) has.push_back("colour");
  if (s.info.has_intensity) has.push_back("intensity");
  if (s.info.has_normals) has.push_back("normals");
  std::string where;
  if (s.bounds) {
    const Eigen::Vector3d size = s.bounds->max - s.bounds->min;
    where = fmt::format(", {:.2f} x {:.2f} x {:.2f} m in the site frame", size.x(), size.y(), size.z());
  }
  return fmt::format("{}: {} points, {}{}, registration {}{}", s.file, s.info.points, s.info.format,
                     has.empty() ? "" : fmt::format(" (with {})", fmt::join(has, ", ")), to_string(s.registration),
                     where);
}

// strata import scan DIR --layer L [--crs EPSG:n | --transform FILE] [--sigma M] FILE...
void register_scan_import(CLI::App& import) {
  auto* cmd = import.add_subcommand(
      "scan",
      "copy range scans (point clouds) of a layer into media/ (named by SHA-256, never modified) and\n"
      "record them. Formats: PLY (ascii or binary; x y z, colour, intensity, normals), PTS (a count, then\n"
      "x y z [intensity [r g b]]), XYZ/TXT (x y z [r g b]), LAS 1.2-1.4 point formats 0-3 and 6-8\n"
      "(uncompressed). E57 and LAZ: convert to LAS or PLY first (CloudCompare, PDAL). Every point is\n"
      "read and checked; a wrong header, a truncated file, a NaN coordinate or an empty cloud imports\n"
      "nothing. Registration states: 'survey' (--crs: the scanner software already registered the\n"
      "scan to the survey), 'transform' (--transform: its pose into the site frame is known),\n"
      "'unregistered' (its own frame; 'strata register scan' places it by ICP). See docs/range.md.");
  auto dir = std::make_shared<std::string>();
  auto options = std::make_shared<ScanImportOptions>();
  auto files = std::make_shared<std::vector<std::string>>();
  auto crs = std::make_shared<std::string>();
  auto transform = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", options->layer, "layer the scans record")->required();
  cmd->add_option("--crs", *crs,
                  "CRS of the scans' coordinates (e.g. EPSG:32636): the scan is registered to the survey and\n"
                  "transformed into the site CRS with PROJ");
  cmd->add_option("--transform", *transform,
                  "text file of a 4x4 row-major matrix (16 numbers) taking the scanner frame into the site\n"
                  "frame (site CRS minus the site origin); rigid or similarity only");
  cmd->add_option("--sigma", options->sigma_m,
                  fmt::format("instrument range noise, metres, one sigma (default {}; phone LiDAR about 0.015)",
                              kDefaultScanSigmaM));
  cmd->add_option("FILE", *files, "point clouds (.ply, .pts, .xyz, .txt, .las)")->required();
  cmd->footer("Example: strata import scan site --layer L101 --crs EPSG:32636 --sigma 0.003 station1.las station2.las");
  cmd->callback([=] {
    if (!crs->empty()) options->crs = *crs;
    if (!transform->empty()) options->transform = *transform;
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const std::vector<std::filesystem::path> paths(files->begin(), files->end());
    const auto s = import_scans(p, *options, paths);
    for (const auto& a : s.already_present) log::info("already imported, skipped: {}", a);
    for (const auto& scan : s.imported) fmt::print("{}\n", scan_summary(scan));
    fmt::print("layer {}: {} scan(s) imported, {} already present\n", options->layer, s.imported.size(),
               s.already_present.size());
  });
}

// strata import depth DIR --layer L --intrinsics FILE [--depth-scale S] [--noise-k K] [--poses FILE]
//                     [--colour DIR] [--sequence NAME] FRAME...
void register_depth_import(CLI::App& import) {
  auto* cmd = import.add_subcommand(
      "depth",
      "copy an RGB-D depth sequence of a layer into media/ (named by SHA-256, never modified) and\n"
      "record it: 16-bit greyscale PNG depth frames (0 = no depth; --depth-scale metres a unit), in\n"
      "the order given, the camera's intrinsics (a text file: width, height, fx, fy, cx, cy), optional\n"
      "colour frames (8-bit PNG, same file names, in --colour) and the poses the device recorded\n"
      "(--poses: 'file tx ty tz qx qy qz qw' a line, camera -> site frame; without them the\n"
      "registration tracks the colour frames and places the sequence on the surveyed markers they\n"
      "see). Every file is read and\n"
      "checked; a wrong header, a truncated or damaged file, a frame of another size or without a\n"
      "pose imports nothing. 'strata register depth' then places the frames. See docs/range.md.");
  auto dir = std::make_shared<std::string>();
  auto options = std::make_shared<DepthImportOptions>();
  auto files = std::make_shared<std::vector<std::string>>();
  auto intrinsics = std::make_shared<std::string>();
  auto poses = std::make_shared<std::string>();
  auto colour = std::make_shared<std::string>();
  auto sequence = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("--layer", options->layer, "layer the sequence records")->required();
  cmd->add_option("--intrinsics", *intrinsics, "the depth camera's intrinsics file")->required();
  cmd->add_option("--depth-scale", options->depth_scale_m, "metres per unit of the PNG (default 0.001: millimetres)");
  cmd->add_option("--noise-k", options->noise_k,
                  fmt::format("depth noise: one sigma = K z^2, K in 1/m (default {}: 1.5 mm at 1 m)",
                              kDefaultDepthNoiseK));
  cmd->add_option("--poses", *poses,
                  "the poses the device recorded, one line a frame (without them 'register depth' needs\n"
                  "--colour and 3 surveyed markers in view)");
  cmd->add_option("--colour", *colour, "folder of the colour frames, named as the depth frames");
  cmd->add_option("--sequence", *sequence, "name of the sequence (default: the folder of the first frame)");
  cmd->add_option("FRAME", *files, "depth frames (.png), in the order they were taken")->required();
  cmd->footer("Example: strata import depth site --layer L4 --intrinsics cam.txt --poses poses.txt --colour rgb/ depth/*.png");
  cmd->callback([=] {
    options->intrinsics = *intrinsics;
    if (!poses->empty()) options->poses = *poses;
    if (!colour->empty()) options->colour_dir = *colour;
    if (!sequence->empty()) options->sequence = *sequence;
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const std::vector<std::filesystem::path> paths(files->begin(), files->end());
    const auto s = import_depth(p, *options, paths);
    fmt::print("layer {}: depth sequence '{}' imported: {} frame(s) of {} x {} px, {} with colour, {} with a "
               "recorded pose, {:.1f} million depths\n",
               options->layer, s.sequence, s.frames, s.intrinsics.width, s.intrinsics.height, s.with_colour,
               s.with_pose, 1e-6 * double(s.valid_pixels));
  });
}

}  // namespace

void register_import_commands(CLI::App& app) {
  auto* import = app.add_subcommand("import", "bring photos, range scans, surveyed markers, finds and the unit register into a project");
  import->require_subcommand(1);
  {
    auto* cmd = import->add_subcommand(
        "photos",
        "copy a layer's photos into media/ (named by SHA-256, never modified) and read their EXIF.\n"
        "Importing the same file again is a no-op. If any file is unreadable, truncated or not an\n"
        "image, nothing is imported (unless --skip-bad).");
    auto dir = std::make_shared<std::string>();
    auto options = std::make_shared<PhotoImportOptions>();
    auto files = std::make_shared<std::vector<std::string>>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("--layer", options->layer, "layer the photos belong to")->required();
    cmd->add_flag("--skip-bad", options->skip_bad, "import the good files and list the bad ones");
    cmd->add_option("FILE", *files, "photos (JPEG, PNG or TIFF)")->required();
    cmd->footer("Example: strata import photos site --layer L101 card/DCIM/100CANON/*.JPG");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      std::vector<std::filesystem::path> paths(files->begin(), files->end());
      const auto s = import_photos(p, *options, paths);
      for (const auto& b : s.bad) log::warn("skipped bad file {}", b);
      for (const auto& a : s.already_present) log::info("already imported, skipped: {}", a);
      if (!s.without_exif.empty()) {
        log::warn("{} photo(s) without usable EXIF focal length (the focal length will be "
                  "estimated during alignment): {}{}",
                  s.without_exif.size(), s.without_exif.front(), s.without_exif.size() > 1 ? ", ..." : "");
      }
      fmt::print("layer {}: {} photo(s) imported, {} already present, {} bad\n", options->layer,
                 s.imported, s.already_present.size(), s.bad.size());
    });
  }
  {
    auto* cmd = import->add_subcommand(
        "markers",
        "import surveyed markers (ground control) from a CSV file (name,E,N,Z[,sigma][,kind];\n"
        "header optional; comma, semicolon, tab or space separated; kind = control|check) or an\n"
        "OpenDroneMap gcp_list.txt (first line a CRS, then geo_x geo_y geo_z im_x im_y image [name];\n"
        "its image observations are stored too, for photos already imported).\n"
        "Coordinates in another CRS (--crs, or the ODM header) are transformed into the site CRS.");
    auto dir = std::make_shared<std::string>();
    auto file = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>("auto");
    auto options = std::make_shared<MarkerImportOptions>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("FILE", *file, "marker file")->required();
    cmd->add_option("--format", *format, "csv, odm, or auto (default: detected)");
    cmd->add_option("--crs", options->crs,
                    "CRS of the file's coordinates (default: the site CRS for CSV, the header for "
                    "ODM); e.g. EPSG:4326 for longitude/latitude in degrees");
    auto* sigma = cmd->add_option("--sigma", options->default_sigma,
                                  "the survey's precision, metres per axis (1 sigma), for markers without a "
                                  "sigma column; the verdict then judges the layer against it (without it: "
                                  "weighed with 0.01 and judged against the report's fixed tolerances)");
    cmd->add_flag("--update", options->update, "replace markers already in the project");
    cmd->add_option("--layer", options->layer, "ODM: observed images are in this layer");
    cmd->add_flag("--skip-missing-images", options->skip_missing_images,
                  "ODM: skip (and list) observations of photos not in the project or layer, e.g. a "
                  "site-wide gcp_list imported layer by layer (default: refuse the file)");
    cmd->footer("Example: strata import markers site survey.csv --crs EPSG:32636");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      options->format = parse_marker_format(*format);
      options->sigma_stated = sigma->count() > 0;
      const auto s = import_markers(p, *options, *file);
      fmt::print("{} ({}, {}): {} new, {} updated, {} unchanged markers; {} new, {} updated observations\n",
                 *file, s.format, s.source_crs, s.markers_new, s.markers_updated, s.markers_unchanged,
                 s.observations_new, s.observations_updated);
      if (!s.skipped.empty()) {
        log::warn("{} observation(s) of photos not in the project skipped:", s.skipped.size());
        for (std::size_t i = 0; i < s.skipped.size() && i < 10; ++i) log::warn("  {}", s.skipped[i]);
        if (s.skipped.size() > 10) log::warn("  ... and {} more", s.skipped.size() - 10);
      }
    });
  }
  register_scan_import(*import);
  register_depth_import(*import);
  register_find_imports(app, *import);
  register_stratigraphy_imports(*import);
  register_markers_command(app);
}

}  // namespace strata::cli
