// strata unit, relation, matrix, layer
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "pipeline/record_edits.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "stratigraphy/graphviz.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "stratigraphy/recorded_matrix.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <unistd.h>

namespace strata::cli {

namespace {

void register_unit_commands(CLI::App& app) {
  auto* unit = app.add_subcommand("unit", "stratigraphic units (contexts): add, list");
  unit->require_subcommand(1);
  {
    auto* cmd = unit->add_subcommand("add", "record a stratigraphic unit");
    auto dir = std::make_shared<std::string>();
    auto rec = std::make_shared<UnitRecord>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("CODE", rec->code, "unit code, e.g. 101 or US1024")->required();
    cmd->add_option("--type", rec->type, "deposit (default), cut, structure or interface")
        ->check(CLI::IsMember(unit_types()));
    cmd->add_option("--description", rec->description, "free text, e.g. 'dark brown silty fill'");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      const UnitRecord u = add_unit(p, *rec);
      fmt::print("unit {} added ({})\n", u.code, u.type);
    });
  }
  {
    auto* cmd = unit->add_subcommand("list", "list units with their layers");
    auto dir = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->callback([=] {
      Project p = Project::open(*dir);
      const auto layers = list_layers(p.db());
      for (const auto& u : list_units(p.db())) {
        std::string ls;
        for (const auto& l : layers) {
          if (l.unit == u.code) ls += (ls.empty() ? "" : ", ") + l.name;
        }
        fmt::print("{:<10} {:<10} {:<40} layers: {}\n", u.code, u.type, u.description,
                   ls.empty() ? "-" : ls);
      }
    });
  }
}

void register_relation_commands(CLI::App& app) {
  auto* relation = app.add_subcommand("relation", "stratigraphic relations: add, list");
  relation->require_subcommand(1);
  {
    std::string words;
    for (const auto& w : relation_words()) words += (words.empty() ? "" : ", ") + w;
    auto* cmd = relation->add_subcommand(
        "add",
        "record 'A relation B', e.g. '102 below 101' or '205 fills 204'.\nRelations: " + words +
            ".\nA relation that would make the Harris matrix cyclic is refused and the cycle printed.");
    auto dir = std::make_shared<std::string>();
    auto a = std::make_shared<std::string>();
    auto word = std::make_shared<std::string>();
    auto b = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("CODE_A", *a, "first unit")->required();
    cmd->add_option("RELATION", *word, "relation word")->required();
    cmd->add_option("CODE_B", *b, "second unit")->required();
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      const RelationAdded r = add_relation(p, *a, *word, *b);
      fmt::print("{} {} {} {}\n", r.relation.unit_a, r.relation.kind, r.relation.unit_b,
                 r.added ? "recorded" : "was already recorded");
    });
  }
  {
    auto* cmd = relation->add_subcommand("list", "list relations (canonical direction)");
    auto dir = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->callback([=] {
      Project p = Project::open(*dir);
      for (const auto& r : list_relations(p.db())) fmt::print("{} {} {}\n", r.unit_a, r.kind, r.unit_b);
    });
  }
}

void register_matrix_command(CLI::App& app) {
  {
    auto* cmd = app.add_subcommand(
        "matrix",
        "the Harris matrix after transitive reduction (only direct relations drawn); same_as units "
        "share a box, contemporary units are joined by a dashed line");
    auto dir = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>("dot");
    auto out = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("--format", *format, "dot (Graphviz text, default), json, or svg (needs Graphviz)")
        ->check(CLI::IsMember({"dot", "json", "svg"}));
    cmd->add_option("--out", *out, "write to this file instead of stdout");
    cmd->footer("Example: strata matrix site --format svg --out matrix.svg");
    cmd->callback([=] {
      Project p = Project::open(*dir);
      const HarrisMatrix m = recorded_matrix(p.db());
      std::string text = *format == "json" ? m.to_json() : m.to_dot();
      if (*format == "svg") {
        const auto svg = graphviz_svg(text);
        if (!svg) {
          throw InputError(
              "--format svg needs Graphviz's 'dot' (apt-get install graphviz); --format dot gives the "
              "same matrix as text");
        }
        text = *svg;
      }
      if (out->empty()) {
        fmt::print("{}", text);
      } else {
        write_bytes_atomically(*out, "matrix", text);
        log::info("wrote {}", *out);
      }
    });
  }
}

void register_layer_commands(CLI::App& app) {
  auto* layer = app.add_subcommand("layer", "recorded surfaces (photo sets): add, list");
  layer->require_subcommand(1);
  {
    auto* cmd = layer->add_subcommand(
        "add", "record a layer: the surface photographed when a unit's top is exposed");
    auto dir = std::make_shared<std::string>();
    auto rec = std::make_shared<LayerRecord>();
    auto captured = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("LAYER", rec->name, "layer name, e.g. L101")->required();
    cmd->add_option("--unit", rec->unit, "the unit whose top this surface is")->required();
    cmd->add_option("--captured-at", *captured, "capture time, ISO 8601 (default: from the photos' EXIF)");
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      LayerRecord l = *rec;
      if (!captured->empty()) l.captured_at = *captured;
      l = add_layer(p, l);
      fmt::print("layer {} added (unit {})\n", l.name, l.unit);
    });
  }
  {
    auto* cmd = layer->add_subcommand("list", "list layers");
    auto dir = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->callback([=] {
      Project p = Project::open(*dir);
      for (const auto& l : list_layers(p.db())) {
        const auto n = list_images(p.db(), l.id).size();
        fmt::print("{:<10} unit {:<10} {:>4} photos  {}\n", l.name, l.unit, n, l.captured_at.value_or(""));
      }
    });
  }
}

}  // namespace

void register_stratigraphy_commands(CLI::App& app) {
  register_unit_commands(app);
  register_relation_commands(app);
  register_matrix_command(app);
  register_layer_commands(app);
}

}  // namespace strata::cli
