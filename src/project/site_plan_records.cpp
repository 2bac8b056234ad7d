#include "project/site_plan_records.hpp"

#include "project/gpkg.hpp"

namespace strata {

std::vector<ContourRecord> list_contours(Database& db, const std::string& layer) {
  auto st = db.prepare("SELECT layer, elevation, geom FROM contours WHERE layer = ? ORDER BY elevation, fid");
  st.bind_all(layer);
  std::vector<ContourRecord> out;
  while (st.step()) {
    ContourRecord c;
    c.layer = st.get_text(0);
    c.elevation = st.get_double(1);
    for (auto& part : read_gpkg_geometry_xy(st.get_blob(2))) {
      for (auto& line : part) c.points.insert(c.points.end(), line.begin(), line.end());
    }
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<FootprintRecord> list_footprints(Database& db, const std::string& layer) {
  auto st = db.prepare("SELECT layer, area_m2, geom FROM footprints WHERE layer = ? ORDER BY fid");
  st.bind_all(layer);
  std::vector<FootprintRecord> out;
  while (st.step()) {
    FootprintRecord f;
    f.layer = st.get_text(0);
    f.area_m2 = st.get_double(1);
    f.polygons = read_gpkg_geometry_xy(st.get_blob(2));
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace strata
