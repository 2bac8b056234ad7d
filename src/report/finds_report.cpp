// The site report's finds: how many were recorded in each unit, and, once the voxel
// model of the units exists, every find against the unit whose solid holds its
// point (volume/finds.hpp, as `strata finds` lists them), conflicts first as
// warnings with what to do.
#include "core/error.hpp"
#include "core/text.hpp"
#include "project/find_records.hpp"
#include "report/report_internal.hpp"
#include "volume/finds.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>

namespace strata::report_detail {
namespace {

std::string missing(const std::string& text) { return "<p class=\"missing\">" + xml_escape(text) + "</p>\n"; }

std::string format_position(const Eigen::Vector3d& p) {
  return fmt::format("E {:.2f}, N {:.2f}, Z {:.2f}", p.x(), p.y(), p.z());
}

// One warning per find in conflict, in the field's words: what is contradicted,
// by how much, and what to re-check.
Finding conflict_finding(const FindPlacement& p, double tolerance_m) {
  const FindRecord& f = p.find;
  Finding w;
  w.severity = Severity::warning;
  w.rule = "find_conflict";
  const std::string where = p.geometric_unit ? "lies in unit " + *p.geometric_unit : "lies in no unit's solid";
  const std::string how_far =
      p.distance_m ? fmt::format("{:.3f} m from the solid of {} (more than the {:.3f} m tolerance)", *p.distance_m,
                                 f.unit, tolerance_m)
                   : fmt::format("and unit {} has no solid in the model", f.unit);
  w.message = fmt::format("find {} was recorded in unit {}, but its point ({}) {}, {}", f.id, f.unit,
                          format_position(f.position), where, how_far);
  const std::string surfaces =
      p.geometric_unit ? fmt::format("the layer surfaces put the boundary between units {} and {} in the wrong place",
                                     f.unit, *p.geometric_unit)
                       : fmt::format("the layer surfaces miss unit {}", f.unit);
  w.advice = fmt::format(
      "re-check the find's record (the unit on its bag and in the finds register) and its survey (the "
      "total-station point, the prism height, the station); if both are right, {} here: look at the layer "
      "photos around the find",
      surfaces);
  return w;
}

// Finds per recorded unit, by verdict.
struct UnitCounts {
  int finds = 0, inside = 0, near = 0, unchecked = 0, conflicts = 0;
};

std::string counts_table(const std::map<std::string, UnitCounts>& units, bool checked) {
  std::string s = checked ? "<table class=\"grid\"><tr><th>recorded unit</th><th>finds</th><th>in its solid</th>"
                            "<th>within the tolerance</th><th>unit without a solid</th><th>conflicts</th></tr>"
                          : "<table class=\"grid\"><tr><th>recorded unit</th><th>finds</th></tr>";
  for (const auto& [unit, c] : units) {
    s += checked ? fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                               xml_escape(unit), c.finds, c.inside, c.near, c.unchecked, c.conflicts ? "bad" : "",
                               c.conflicts)
                 : fmt::format("<tr><td>{}</td><td>{}</td></tr>", xml_escape(unit), c.finds);
  }
  return s + "</table>\n";
}

std::string checked_finds_html(const FindsCheck& check, std::vector<Finding>* warnings) {
  std::vector<const FindPlacement*> order;
  std::map<std::string, UnitCounts> units;
  std::vector<Finding> found;
  for (const auto& p : check.finds) {
    order.push_back(&p);
    UnitCounts& c = units[p.find.unit];
    ++c.finds;
    if (p.conflict) {
      ++c.conflicts;
      found.push_back(conflict_finding(p, check.tolerance_m));
    } else if (p.geometric_unit == p.find.unit) {
      ++c.inside;
    } else if (p.distance_m) {
      ++c.near;
    } else {
      ++c.unchecked;
    }
  }
  // Conflicts first; otherwise as recorded (by find number).
  std::stable_sort(order.begin(), order.end(),
                   [](const FindPlacement* a, const FindPlacement* b) { return a->conflict && !b->conflict; });
  std::string s;
  if (found.empty()) {
    s += fmt::format("<p class=\"ok\">All {} finds lie in the solid of the unit they were recorded in, or within "
                     "{:.3f} m of it.</p>\n",
                     check.finds.size(), check.tolerance_m);
  } else {
    s += fmt::format("<div class=\"verdict warning\">{} of {} finds conflict with the unit solids: re-check their "
                     "record or their survey</div>\n",
                     found.size(), check.finds.size());
    s += findings_html(found);
  }
  s += counts_table(units, true);
  s += "<table class=\"grid\"><tr><th>find</th><th>type</th><th>recorded unit</th><th>geometric unit</th>"
       "<th>distance to the recorded unit's solid (m)</th><th>E</th><th>N</th><th>Z</th><th>verdict</th></tr>";
  for (const FindPlacement* p : order) {
    const FindRecord& f = p->find;
    const std::string verdict = p->conflict                         ? "conflict"
                                : p->geometric_unit == f.unit       ? "in its unit"
                                : p->distance_m                     ? "within the tolerance"
                                                                    : "unit without a solid";
    s += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.3f}</td><td>{:.3f}</td>"
                     "<td>{:.3f}</td><td class=\"{}\">{}</td></tr>",
                     xml_escape(f.id), xml_escape(f.type), xml_escape(f.unit),
                     xml_escape(p->geometric_unit.value_or("none")),
                     p->distance_m ? fmt::format("{:.3f}", *p->distance_m) : "no solid", f.position.x(),
                     f.position.y(), f.position.z(), p->conflict ? "bad" : "", verdict);
  }
  s += "</table>\n";
  s += "<p class=\"caption\">" +
       xml_escape(fmt::format(
           "Geometric unit: the unit whose voxel ({:.3f} m) holds the find's point in the voxel model of strata "
           "volume; distance: from the point to the nearest voxel of the recorded unit, 0 inside it. A find "
           "conflicts when the two units differ and the distance exceeds {:.3f} m (one voxel and {:.2f} m of "
           "survey error), as strata finds DIR lists them.",
           check.voxel_size_m, check.tolerance_m, kFindSurveyError)) +
       "</p>\n";
  if (warnings) *warnings = std::move(found);
  return s;
}

std::string record_only_html(const std::vector<FindRecord>& finds, const std::string& why) {
  std::map<std::string, UnitCounts> units;
  for (const auto& f : finds) ++units[f.unit].finds;
  std::string s = missing(why) + counts_table(units, false);
  s += "<table class=\"grid\"><tr><th>find</th><th>type</th><th>recorded unit</th><th>E</th><th>N</th><th>Z</th>"
       "<th>description</th></tr>";
  for (const auto& f : finds) {
    s += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.3f}</td><td>{:.3f}</td><td>{:.3f}</td><td>{}</td></tr>",
                     xml_escape(f.id), xml_escape(f.type), xml_escape(f.unit), f.position.x(), f.position.y(),
                     f.position.z(), xml_escape(f.description));
  }
  return s + "</table>\n";
}

}  // namespace

std::string finds_section_html(Project& project, std::vector<Finding>* warnings) {
  std::string s = "<section><h2>Finds</h2>\n";
  const std::vector<FindRecord> finds = list_finds(project.db());
  if (finds.empty()) {
    return s + missing("No finds recorded yet; import them with: strata import finds DIR FILE.csv") + "</section>\n";
  }
  if (!project_voxel_model(project)) {
    return s +
           record_only_html(finds, fmt::format("{} finds as recorded; not yet checked against the unit solids: "
                                               "run strata volume DIR, then this report again.",
                                               finds.size())) +
           "</section>\n";
  }
  try {
    s += checked_finds_html(check_project_finds(project, FindCheckOptions{}), warnings);
  } catch (const Error& e) {
    s += record_only_html(finds, fmt::format("The finds could not be checked against the unit solids: {}", e.what()));
  }
  return s + "</section>\n";
}

}  // namespace strata::report_detail
