// strata init, strata info
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/text_table.hpp"
#include "crs/crs.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <map>

namespace strata::cli {
namespace {

nlohmann::json project_summary(Project& p) {
  auto& db = p.db();
  const SiteInfo site = p.site();
  nlohmann::json j;
  j["site"] = {{"name", site.name},
               {"crs", site.crs},
               {"origin", {site.origin.x(), site.origin.y(), site.origin.z()}},
               {"origin_set", site.origin_set},
               {"schema_version", p.schema_version()},
               {"folder", p.dir().string()}};
  std::map<std::string, nlohmann::json> layers_of_unit;
  std::map<std::int64_t, int> photos_per_layer, observations_per_layer;
  {
    auto st = db.prepare("SELECT layer_id, count(*) FROM images GROUP BY layer_id");
    while (st.step()) photos_per_layer[st.get_int(0)] = int(st.get_int(1));
  }
  std::map<std::int64_t, int> markers_per_layer;
  {
    auto st = db.prepare(
        "SELECT i.layer_id, count(*), count(DISTINCT o.marker_id) FROM observations o "
        "JOIN images i ON i.id = o.image_id GROUP BY i.layer_id");
    while (st.step()) {
      observations_per_layer[st.get_int(0)] = int(st.get_int(1));
      markers_per_layer[st.get_int(0)] = int(st.get_int(2));
    }
  }
  j["layers"] = nlohmann::json::array();
  for (const auto& l : list_layers(db)) {
    nlohmann::json lj = {{"name", l.name},
                         {"unit", l.unit},
                         {"photos", photos_per_layer[l.id]},
                         {"markers_observed", markers_per_layer[l.id]},
                         {"observations", observations_per_layer[l.id]}};
    if (l.captured_at) lj["captured_at"] = *l.captured_at;
    j["layers"].push_back(lj);
    layers_of_unit[l.unit].push_back(l.name);
  }
  j["units"] = nlohmann::json::array();
  for (const auto& u : list_units(db)) {
    j["units"].push_back({{"code", u.code},
                          {"type", u.type},
                          {"description", u.description},
                          {"layers", layers_of_unit.count(u.code) ? layers_of_unit[u.code]
                                                                  : nlohmann::json::array()}});
  }
  j["relations"] = int(list_relations(db).size());
  const auto markers = list_markers(db);
  j["markers"] = {{"total", markers.size()},
                  {"control", std::count_if(markers.begin(), markers.end(),
                                            [](const MarkerRecord& m) { return m.kind == "control"; })},
                  {"check", std::count_if(markers.begin(), markers.end(),
                                          [](const MarkerRecord& m) { return m.kind == "check"; })}};
  j["photos"] = db.query_int("SELECT count(*) FROM images").value_or(0);
  j["cameras"] = db.query_int("SELECT count(*) FROM cameras").value_or(0);
  return j;
}

void print_summary(const nlohmann::json& j) {
  const auto& s = j["site"];
  fmt::print("site      {}  ({})\n", s["name"].get<std::string>(), s["folder"].get<std::string>());
  fmt::print("CRS       {}\n", s["crs"].get<std::string>());
  if (s["origin_set"].get<bool>()) {
    fmt::print("origin    E {:.3f}  N {:.3f}  Z {:.3f}  (site frame = CRS minus origin)\n",
               s["origin"][0].get<double>(), s["origin"][1].get<double>(), s["origin"][2].get<double>());
  } else {
    fmt::print("origin    not set yet (fixed from the first markers imported)\n");
  }
  fmt::print("units     {}   relations {}\n", j["units"].size(), j["relations"].get<int>());
  // Descriptions wrap within their column (docs/cli.md): a long one never runs into
  // the layers column.
  const int width = terminal_width();
  if (!j["units"].empty()) {
    TextTable units;
    units.columns = {{"unit"}, {"type"}, {"description", false, true}, {"layers"}};
    for (const auto& u : j["units"]) {
      std::string layers;
      for (const auto& l : u["layers"]) layers += (layers.empty() ? "" : ", ") + l.get<std::string>();
      units.add({u["code"].get<std::string>(), u["type"].get<std::string>(), u["description"].get<std::string>(),
                 layers.empty() ? "-" : layers});
    }
    fmt::print("{}", units.render(width, 2));
  }
  fmt::print("layers    {}\n", j["layers"].size());
  if (!j["layers"].empty()) {
    TextTable layers;
    layers.columns = {{"layer"}, {"unit"}, {"photos", true}, {"markers seen", true}, {"observations", true}};
    for (const auto& l : j["layers"]) {
      layers.add({l["name"].get<std::string>(), l["unit"].get<std::string>(), std::to_string(l["photos"].get<int>()),
                  std::to_string(l["markers_observed"].get<int>()), std::to_string(l["observations"].get<int>())});
    }
    fmt::print("{}", layers.render(width, 2));
  }
  fmt::print("markers   {} ({} control, {} check)\n", j["markers"]["total"].get<int>(),
             j["markers"]["control"].get<int>(), j["markers"]["check"].get<int>());
  fmt::print("photos    {}   cameras {}\n", j["photos"].get<int>(), j["cameras"].get<int>());
}

}  // namespace

void register_project_commands(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand("init", "create a project folder with its database (project.gpkg)");
    auto dir = std::make_shared<std::string>();
    auto crs = std::make_shared<std::string>();
    auto name = std::make_shared<std::string>();
    auto origin = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder to create")->required();
    cmd->add_option("--crs", *crs,
                    "site CRS: projected, in metres, e.g. EPSG:32636 (UTM 36N). Geographic CRSs "
                    "(degrees) are refused")
        ->required();
    cmd->add_option("--name", *name, "site name (default: the folder name)");
    cmd->add_option("--origin", *origin,
                    "site-frame origin E,N,Z in the site CRS (default: rounded from the first "
                    "markers imported)");
    cmd->footer("Example: strata init trench7 --crs EPSG:32636 --name \"Tell X, trench 7\"");
    cmd->callback([=] {
      CreateOptions o;
      o.crs = *crs;
      o.name = *name;
      if (!origin->empty()) o.origin = parse_vector3(*origin, "--origin");
      Project p = Project::create(*dir, o);
      const SiteInfo site = p.site();
      fmt::print("created project {} in {} ({})\n", site.name, p.dir().string(), site.crs);
    });
  }
  {
    auto* cmd = app.add_subcommand("info", "summary of a project: site, CRS, units, layers, counts");
    auto dir = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_flag("--json", *json, "machine-readable output");
    cmd->callback([=] {
      Project p = Project::open(*dir);
      const auto summary = project_summary(p);
      if (*json) {
        fmt::print("{}\n", summary.dump(2));
      } else {
        print_summary(summary);
      }
    });
  }
}

}  // namespace strata::cli
