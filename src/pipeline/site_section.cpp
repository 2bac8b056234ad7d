#include "pipeline/site_section.hpp"

#include "core/door.hpp"
#include "project/find_records.hpp"
#include "project/site_bounds.hpp"

namespace strata {

SiteSection cut_site_section(Project& project, const SiteVolumeOptions& model, const SiteSectionRequest& request) {
  request.finds.validate();
  const SiteInfo site = project.site();
  check_site_position(site, request.a, "section: the line's first end");
  check_site_position(site, request.b, "section: the line's second end");
  door::number_in(request.scale, 1, 100'000, "section: the scale 1:N, N", "");
  const SiteModel m = load_site_model(project, model);
  const Eigen::Vector2d origin = m.site.origin.head<2>();
  SiteSection s;
  s.site = m.site;
  s.profile = cut_section(request.a - origin, request.b - origin, m.layers, m.solids, request.step_m);
  const std::vector<FindRecord> recorded = list_finds(project.db());
  s.finds_recorded = recorded.size();
  s.finds_projected = add_section_finds(s.profile, recorded, m.site.origin, request.finds);
  s.drawing.scale = request.scale;
  s.drawing.title = door::text("section: --title", request.title, 200);
  s.drawing.crs = m.site.crs;
  for (const auto& u : m.units) s.drawing.unit_types[u.code] = u.type;
  return s;
}

}  // namespace strata
