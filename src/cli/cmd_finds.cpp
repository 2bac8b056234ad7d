// strata finds: every find with its recorded unit and the unit whose solid holds it.
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "volume/finds.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <memory>

namespace strata::cli {
namespace {

nlohmann::ordered_json to_json(const FindPlacement& p) {
  const auto& f = p.find;
  return {{"id", f.id},
          {"recorded_unit", f.unit},
          {"geometric_unit", p.geometric_unit ? nlohmann::ordered_json(*p.geometric_unit) : nullptr},
          {"distance_m", p.distance_m ? nlohmann::ordered_json(*p.distance_m) : nullptr},
          {"conflict", p.conflict},
          {"type", f.type},
          {"E", f.position.x()},
          {"N", f.position.y()},
          {"Z", f.position.z()}};
}

void print_table(const FindsCheck& check) {
  fmt::print("{:<12} {:>9} {:>10} {:>11} {:>9}  {}\n", "find", "recorded", "geometric", "distance m", "conflict",
             "type");
  int inside = 0;
  for (const auto& p : check.finds) {
    inside += p.geometric_unit == p.find.unit ? 1 : 0;
    fmt::print("{:<12} {:>9} {:>10} {:>11} {:>9}  {}\n", p.find.id, p.find.unit, p.geometric_unit.value_or("-"),
               p.distance_m ? fmt::format("{:.3f}", *p.distance_m) : "no solid", p.conflict ? "CONFLICT" : "",
               p.find.type);
  }
  fmt::print("{} finds: {} inside their recorded unit's solid, {} within {:.3f} m of it or not checkable, {} "
             "conflict(s) (voxels of {} m)\n",
             check.finds.size(), inside, int(check.finds.size()) - inside - check.conflicts(), check.tolerance_m,
             check.conflicts(), check.voxel_size_m);
}

}  // namespace

void register_finds_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "finds",
      "finds recorded in place against the voxel model of the units ('strata volume' writes it): for each\n"
      "find its recorded unit, the unit whose solid holds its point, and the distance from the point to\n"
      "the recorded unit's solid. A find conflicts when the two units differ and that distance exceeds\n"
      "--tolerance. Exit status 1 when any find conflicts.");
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto options = std::make_shared<FindCheckOptions>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_flag("--json", *json,
                "print a JSON list of {id, recorded_unit, geometric_unit (null: none), distance_m (null: the "
                "recorded unit has no solid), conflict, type, E, N, Z}");
  cmd->add_option("--tolerance", options->tolerance_m,
                  fmt::format("distance to the recorded unit's solid that is still no conflict, metres (default: "
                              "one voxel edge + {} m of survey error, 0.02 m with 1 cm voxels)",
                              kFindSurveyError));
  cmd->callback([=] {
    Project p = Project::open(*dir);
    const FindsCheck check = check_project_finds(p, *options);
    if (*json) {
      nlohmann::ordered_json list = nlohmann::ordered_json::array();
      for (const auto& f : check.finds) list.push_back(to_json(f));
      fmt::print("{}\n", list.dump(2));
    } else {
      print_table(check);
    }
    if (check.conflicts() > 0)
      throw ProcessingError(fmt::format("finds: {} of {} finds conflict with their recorded unit (they lie in "
                                        "another unit's solid or none, more than {:.3f} m from the recorded one's)",
                                        check.conflicts(), check.finds.size(), check.tolerance_m));
  });
}

}  // namespace strata::cli
