#include "exporters/qgis/qgis_project.hpp"

#include "core/text.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "crs/crs.hpp"
#include "exporters/zip/zip_writer.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <limits>

namespace fs = std::filesystem;

namespace strata {
namespace {

// A data source path relative to the project file (QGIS "relative paths" mode).
std::string relative_source(const fs::path& target, const fs::path& qgs_dir) {
  fs::path rel = fs::absolute(target).lexically_normal().lexically_relative(fs::absolute(qgs_dir).lexically_normal());
  if (rel.empty()) rel = fs::absolute(target);
  std::string s = rel.generic_string();
  if (!rel.is_absolute() && s.rfind("..", 0) != 0) s = "./" + s;
  return s;
}

// QGIS keeps a layer id from the file only when it is longer than 10 characters
// (QgsMapLayer::readLayerXml) and makes up a new one otherwise, which orphans the
// layer-tree entry: every id gets the "strata_" prefix.
std::string site_layer_id(const std::string& kind) { return "strata_" + kind; }

std::string layer_id(const std::string& kind, const std::string& layer) {
  std::string id = "strata_" + kind + "_";
  for (char c : layer) id += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return id;
}

// QGIS <blendMode> values are QgsPainting::BlendMode numbers (not QPainter's).
constexpr int kBlendMultiply = 6;  // QgsPainting::BlendMultiply

struct MapLayer {
  std::string id, name, xml;  // xml = the <maplayer> element
  bool visible = true;
};

class QgsWriter {
 public:
  QgsWriter(const QgisProjectInput& in, const fs::path& dir) : in_(in), dir_(dir) {}

  std::string srs() const {
    return fmt::format("<spatialrefsys><wkt>{}</wkt><authid>{}</authid></spatialrefsys>", xml_escape(in_.crs_wkt),
                       xml_escape(in_.crs_authid));
  }

  MapLayer raster(const std::string& id, const std::string& name, const fs::path& file, const std::string& pipe,
                  int blend_mode = 0) const {
    MapLayer m{id, name, "", true};
    m.xml = fmt::format(
        "    <maplayer type=\"raster\" hasScaleBasedVisibilityFlag=\"0\" minScale=\"1e+08\" maxScale=\"0\" "
        "styleCategories=\"AllStyleCategories\">\n"
        "      <extent><xmin>{:.3f}</xmin><ymin>{:.3f}</ymin><xmax>{:.3f}</xmax><ymax>{:.3f}</ymax></extent>\n"
        "      <id>{}</id>\n      <datasource>{}</datasource>\n      <layername>{}</layername>\n"
        "      <srs>{}</srs>\n      <provider>gdal</provider>\n"
        "      <pipe>\n{}\n        <brightnesscontrast brightness=\"0\" contrast=\"0\" gamma=\"1\"/>\n"
        "        <huesaturation colorizeOn=\"0\" grayscaleMode=\"0\" saturation=\"0\" colorizeRed=\"255\" "
        "colorizeGreen=\"128\" colorizeBlue=\"128\" colorizeStrength=\"100\"/>\n"
        "        <rasterresampler maxOversampling=\"2\"/>\n      </pipe>\n"
        "      <blendMode>{}</blendMode>\n    </maplayer>\n",
        in_.min.x(), in_.min.y(), in_.max.x(), in_.max.y(), id, xml_escape(relative_source(file, dir_)),
        xml_escape(name), srs(), pipe, blend_mode);
    return m;
  }

  // A GeoPackage feature table, optionally restricted to one layer's rows.
  MapLayer vector(const std::string& id, const std::string& name, const std::string& table,
                  const std::string& geometry, const std::string& subset, const std::string& renderer,
                  const std::string& labeling) const {
    std::string source = relative_source(in_.gpkg, dir_) + "|layername=" + table;
    if (!subset.empty()) source += "|subset=" + subset;
    MapLayer m{id, name, "", true};
    m.xml = fmt::format(
        "    <maplayer type=\"vector\" geometry=\"{}\" hasScaleBasedVisibilityFlag=\"0\" minScale=\"1e+08\" "
        "maxScale=\"0\" labelsEnabled=\"{}\" styleCategories=\"AllStyleCategories\">\n"
        "      <extent><xmin>{:.3f}</xmin><ymin>{:.3f}</ymin><xmax>{:.3f}</xmax><ymax>{:.3f}</ymax></extent>\n"
        "      <id>{}</id>\n      <datasource>{}</datasource>\n      <layername>{}</layername>\n"
        "      <srs>{}</srs>\n      <provider encoding=\"UTF-8\">ogr</provider>\n{}{}"
        "      <blendMode>0</blendMode>\n    </maplayer>\n",
        geometry, labeling.empty() ? 0 : 1, in_.min.x(), in_.min.y(), in_.max.x(), in_.max.y(), id,
        xml_escape(source), xml_escape(name), srs(), renderer, labeling);
    return m;
  }

  static std::string props(const std::vector<std::pair<std::string, std::string>>& kv) {
    std::string s;
    for (const auto& [k, v] : kv) s += fmt::format("<prop k=\"{}\" v=\"{}\"/>", k, xml_escape(v));
    return s;
  }
  static std::string symbol(const std::string& type, const std::string& name, const std::string& cls,
                            const std::vector<std::pair<std::string, std::string>>& kv) {
    return fmt::format(
        "<symbol type=\"{}\" name=\"{}\" alpha=\"1\" clip_to_extent=\"1\" force_rhr=\"0\">"
        "<layer class=\"{}\" enabled=\"1\" pass=\"0\" locked=\"0\">{}</layer></symbol>",
        type, name, cls, props(kv));
  }
  static std::string single_symbol(const std::string& type, const std::string& cls,
                                   const std::vector<std::pair<std::string, std::string>>& kv) {
    return fmt::format(
        "      <renderer-v2 type=\"singleSymbol\" symbollevels=\"0\" enableorderby=\"0\" forceraster=\"0\">\n"
        "        <symbols>{}</symbols>\n"
        "      </renderer-v2>\n",
        symbol(type, "0", cls, kv));
  }
  // A rule-based renderer (QgsRuleBasedRenderer): one rule per filter expression,
  // in order, each with its legend label and simple marker; the filter "ELSE" takes
  // the features no other rule took.
  struct MarkerRule {
    std::string filter, label;
    std::vector<std::pair<std::string, std::string>> marker;  // SimpleMarker properties
  };
  static std::string marker_rules(const std::vector<MarkerRule>& rules) {
    std::string rule_xml, symbols;
    for (std::size_t k = 0; k < rules.size(); ++k) {
      rule_xml += fmt::format("<rule key=\"{{strata-rule-{0}}}\" filter=\"{1}\" label=\"{2}\" symbol=\"{0}\"/>", k,
                              xml_escape(rules[k].filter), xml_escape(rules[k].label));
      symbols += symbol("marker", std::to_string(k), "SimpleMarker", rules[k].marker);
    }
    return fmt::format(
        "      <renderer-v2 type=\"RuleRenderer\" symbollevels=\"0\" enableorderby=\"0\" forceraster=\"0\">\n"
        "        <rules key=\"{{strata-rules}}\">{}</rules>\n"
        "        <symbols>{}</symbols>\n"
        "      </renderer-v2>\n",
        rule_xml, symbols);
  }
  static std::string labels(const std::string& field, bool expression, int placement, const std::string& colour) {
    return fmt::format(
        "      <labeling type=\"simple\"><settings calloutType=\"simple\">"
        "<text-style fieldName=\"{}\" isExpression=\"{}\" fontFamily=\"Sans Serif\" fontSize=\"8\" "
        "fontSizeUnit=\"Point\" textColor=\"{}\" textOpacity=\"1\" namedStyle=\"Regular\"/>"
        "<text-buffer bufferDraw=\"1\" bufferSize=\"0.8\" bufferSizeUnits=\"MM\" bufferColor=\"255,255,255,255\" "
        "bufferOpacity=\"0.8\"/>"
        "<placement placement=\"{}\" dist=\"1.5\" distUnits=\"MM\" repeatDistance=\"40\" repeatDistanceUnits=\"MM\"/>"
        "<rendering obstacle=\"1\" scaleVisibility=\"0\" drawLabels=\"1\"/>"
        "</settings></labeling>\n",
        xml_escape(field), expression ? 1 : 0, colour, placement);
  }

  std::string hillshade_pipe() const {
    return "        <rasterrenderer type=\"hillshade\" band=\"1\" opacity=\"0.6\" alphaBand=\"-1\" azimuth=\"315\" "
           "angle=\"45\" zfactor=\"1\" multidirection=\"1\"><rasterTransparency/></rasterrenderer>";
  }
  std::string ortho_pipe() const {
    return "        <rasterrenderer type=\"multibandcolor\" redBand=\"1\" greenBand=\"2\" blueBand=\"3\" "
           "alphaBand=\"4\" opacity=\"1\"><rasterTransparency/></rasterrenderer>";
  }

 private:
  const QgisProjectInput& in_;
  fs::path dir_;
};

struct Group {
  std::string name;
  bool visible = true;
  std::vector<MapLayer> layers;
};

// A QGIS expression string literal.
std::string quoted(const std::string& text) {
  std::string q = "'";
  for (char c : text) q += c == '\'' ? std::string("''") : std::string(1, c);
  return q + "'";
}

// Finds: diamonds labelled by number, as the finds register names them. With the
// voxel model's verdicts: a rule-based renderer, finds in conflict with the unit
// solids as larger red diamonds first (legend "conflict with the unit solids (N)"),
// labelled "ID: recorded U, lies in G"; the rest as usual (ELSE).
MapLayer finds_layer(const QgsWriter& w, const QgisProjectInput& in) {
  const std::vector<std::pair<std::string, std::string>> usual = {
      {"name", "diamond"}, {"color", "0,110,160,255"}, {"outline_color", "255,255,255,255"},
      {"outline_width", "0.2"}, {"size", "2.6"}};
  const std::string id_label_colour = "0,70,110,255";
  if (!in.find_conflicts) {
    return w.vector(site_layer_id("finds"), "finds", "finds", "Point", "",
                    QgsWriter::single_symbol("marker", "SimpleMarker", usual),
                    QgsWriter::labels("find_id", false, 0, id_label_colour));
  }
  const auto& conflicts = *in.find_conflicts;
  std::vector<QgsWriter::MarkerRule> rules;
  std::string label = "find_id";  // the field itself; an expression only with conflicts to name
  if (!conflicts.empty()) {
    std::string ids, cases;
    for (const QgisFindConflict& c : conflicts) {
      ids += (ids.empty() ? "" : ", ") + quoted(c.id);
      cases += fmt::format(" WHEN \"find_id\" = {} THEN \"find_id\" || ': recorded ' || \"unit\" || {}", quoted(c.id),
                           quoted(c.geometric_unit.empty() ? ", in no unit's solid" : ", lies in " + c.geometric_unit));
    }
    rules.push_back({fmt::format("\"find_id\" IN ({})", ids),
                     fmt::format("conflict with the unit solids ({})", conflicts.size()),
                     {{"name", "diamond"}, {"color", "225,20,20,255"}, {"outline_color", "60,0,0,255"},
                      {"outline_width", "0.4"}, {"size", "3.6"}}});
    label = "CASE" + cases + " ELSE \"find_id\" END";
  }
  rules.push_back({"ELSE", "agree with the unit solids", usual});
  return w.vector(site_layer_id("finds"), "finds", "finds", "Point", "", QgsWriter::marker_rules(rules),
                  QgsWriter::labels(label, !conflicts.empty(), 0, id_label_colour));
}

}  // namespace

QgisProjectInput collect_qgis_input(Project& project) {
  auto& db = project.db();
  const SiteInfo site = project.site();
  QgisProjectInput in;
  in.title = site.name;
  in.gpkg = fs::absolute(project.database_path());
  in.crs_authid = site.crs;
  in.crs_wkt = describe_crs(site.crs).wkt;
  std::vector<LayerRecord> layers = list_layers(db);
  // Capture order: by capture time where both have one, else by creation (id).
  std::stable_sort(layers.begin(), layers.end(), [](const LayerRecord& a, const LayerRecord& b) {
    if (a.captured_at && b.captured_at && *a.captured_at != *b.captured_at) return *a.captured_at < *b.captured_at;
    return a.id < b.id;
  });
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  auto grow = [&](std::optional<double> x0, std::optional<double> y0, std::optional<double> x1,
                  std::optional<double> y1) {
    if (!x0 || !y0 || !x1 || !y1) return;
    lo = lo.cwiseMin(Eigen::Vector2d(*x0, *y0));
    hi = hi.cwiseMax(Eigen::Vector2d(*x1, *y1));
  };
  for (const LayerRecord& l : layers) {
    QgisLayerGroup g;
    g.layer = l.name;
    g.unit = l.unit;
    if (auto p = find_product(db, l.id, "dtm")) g.dtm = project.dir() / p->path;
    if (auto p = find_product(db, l.id, "ortho")) g.ortho = project.dir() / p->path;
    auto count = [&](const char* table) {
      auto st = db.prepare(fmt::format("SELECT count(*) FROM {} WHERE layer = ?", table));
      st.bind(1, l.name);
      return st.step() ? st.get_int(0) : 0;
    };
    g.contours = count("contours") > 0;
    g.footprint = count("footprints") > 0;
    in.layers.push_back(g);
  }
  {
    auto ex = db.prepare("SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'unit_extents'");
    if (ex.step() && ex.get_int(0) > 0) {
      auto n = db.prepare("SELECT count(*) FROM unit_extents");
      in.unit_extents = n.step() && n.get_int(0) > 0;
    }
  }
  {
    auto n = db.prepare("SELECT count(*) FROM finds");
    in.finds = n.step() && n.get_int(0) > 0;
  }
  auto st = db.prepare(
      "SELECT min(min_x), min(min_y), max(max_x), max(max_y) FROM gpkg_contents WHERE data_type IN "
      "('features', 'tiles', '2d-gridded-coverage') AND srs_id = ?");
  st.bind(1, site.srs_id);
  if (st.step()) grow(st.get_optional_double(0), st.get_optional_double(1), st.get_optional_double(2),
                      st.get_optional_double(3));
  if (!(hi.x() >= lo.x())) {
    lo = site.origin.head<2>();
    hi = lo + Eigen::Vector2d(10, 10);
  }
  in.min = lo;
  in.max = hi;
  return in;
}

std::string qgis_project_xml(const QgisProjectInput& in, const fs::path& qgs_dir) {
  QgsWriter w(in, qgs_dir);
  std::vector<Group> groups;

  Group site{"Site", true, {}};
  if (in.finds) site.layers.push_back(finds_layer(w, in));
  if (in.markers) {
    MapLayer m = w.vector(site_layer_id("markers"), "markers", "markers", "Point", "",
                          QgsWriter::single_symbol("marker", "SimpleMarker",
                                                   {{"name", "cross_fill"}, {"color", "230,30,30,255"},
                                                    {"outline_color", "0,0,0,255"}, {"size", "3"}}),
                          QgsWriter::labels("name", false, 0, "200,0,0,255"));
    site.layers.push_back(m);
  }
  if (in.marker_residuals) {
    MapLayer m = w.vector(site_layer_id("marker_residuals"), "marker residuals", "marker_residuals_view", "Point", "",
                          QgsWriter::single_symbol("marker", "SimpleMarker",
                                                   {{"name", "circle"}, {"color", "255,200,0,255"}, {"size", "2"}}),
                          QgsWriter::labels("\"name\" || ' ' || \"layer\" || ': dz ' || "
                                            "format_number(1000 * \"dz_m\", 1) || ' mm'",
                                            true, 0, "120,60,0,255"));
    m.visible = false;
    site.layers.push_back(m);
  }
  if (in.camera_positions) {
    MapLayer m = w.vector(site_layer_id("camera_positions"), "camera positions", "camera_positions", "Point", "",
                          QgsWriter::single_symbol("marker", "SimpleMarker",
                                                   {{"name", "triangle"}, {"color", "60,60,200,255"}, {"size", "1.6"}}),
                          "");
    m.visible = false;
    site.layers.push_back(m);
  }
  if (in.unit_extents) {
    // The excavated extent of every unit, labelled with its volume and interval.
    site.layers.push_back(w.vector(site_layer_id("unit_extents"), "unit extents", "unit_extents", "Polygon", "",
                                   QgsWriter::single_symbol("fill", "SimpleFill",
                                                            {{"style", "no"}, {"color", "0,0,0,0"},
                                                             {"outline_color", "150,90,30,255"},
                                                             {"outline_width", "0.5"}}),
                                   QgsWriter::labels("\"unit\" || ': ' || format_number(\"volume_m3\", 3) || ' m3 (' "
                                                     "|| format_number(\"volume_low_m3\", 3) || '-' || "
                                                     "format_number(\"volume_high_m3\", 3) || ')'",
                                                     true, 0, "150,90,30,255")));
  }
  groups.push_back(site);

  // Latest capture on top; only the latest layer is switched on, so the map shows
  // the current state of the excavation and earlier states are one click away.
  for (std::size_t k = in.layers.size(); k-- > 0;) {
    const QgisLayerGroup& l = in.layers[k];
    Group g{fmt::format("{} (unit {})", l.layer, l.unit), k + 1 == in.layers.size(), {}};
    const std::string subset = fmt::format("\"layer\" = '{}'", l.layer);
    if (l.contours) {
      g.layers.push_back(w.vector(layer_id("contours", l.layer), l.layer + " contours", "contours", "Line", subset,
                                  QgsWriter::single_symbol("line", "SimpleLine",
                                                           {{"line_color", "120,70,20,255"}, {"line_width", "0.2"},
                                                            {"line_width_unit", "MM"}}),
                                  QgsWriter::labels("format_number(\"elevation\", 2)", true, 2, "120,70,20,255")));
    }
    if (l.footprint) {
      g.layers.push_back(w.vector(layer_id("footprint", l.layer), l.layer + " footprint", "footprints", "Polygon",
                                  subset,
                                  QgsWriter::single_symbol("fill", "SimpleFill",
                                                           {{"style", "no"}, {"color", "0,0,0,0"},
                                                            {"outline_color", "220,0,120,255"},
                                                            {"outline_style", "dash"}, {"outline_width", "0.4"}}),
                                  ""));
    }
    if (!l.dtm.empty()) {
      // Over the orthophoto, multiplied: the relief shades the photo (the orthophoto
      // covers the whole DTM, so a hillshade under it would never show), and where
      // the photos did not reach or the orthophoto is switched off it is the plain
      // hillshade on the white canvas.
      g.layers.push_back(w.raster(layer_id("hillshade", l.layer), l.layer + " hillshade", l.dtm, w.hillshade_pipe(),
                                  kBlendMultiply));
    }
    if (!l.ortho.empty()) {
      g.layers.push_back(w.raster(layer_id("ortho", l.layer), l.layer + " orthophoto", l.ortho, w.ortho_pipe()));
    }
    groups.push_back(g);
  }

  std::string tree, maplayers;
  for (const Group& g : groups) {
    tree += fmt::format("    <layer-tree-group name=\"{}\" checked=\"Qt::{}\" expanded=\"1\">\n      <customproperties/>\n",
                        xml_escape(g.name), g.visible ? "Checked" : "Unchecked");
    for (const MapLayer& m : g.layers) {
      tree += fmt::format(
          "      <layer-tree-layer id=\"{}\" name=\"{}\" checked=\"Qt::{}\" expanded=\"0\" providerKey=\"\" "
          "source=\"\"><customproperties/></layer-tree-layer>\n",
          m.id, xml_escape(m.name), m.visible ? "Checked" : "Unchecked");
      maplayers += m.xml;
    }
    tree += "    </layer-tree-group>\n";
  }
  const std::string srs = w.srs();
  return fmt::format(
      "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n"
      "<qgis projectname=\"{0}\" version=\"3.22.0-Białowieża\">\n"
      "  <homePath path=\"\"/>\n  <title>{0}</title>\n"
      "  <projectCrs>{1}</projectCrs>\n"
      "  <layer-tree-group>\n    <customproperties/>\n{2}  </layer-tree-group>\n"
      "  <mapcanvas name=\"theMapCanvas\" annotationsVisible=\"1\">\n    <units>meters</units>\n"
      "    <extent><xmin>{3:.3f}</xmin><ymin>{4:.3f}</ymin><xmax>{5:.3f}</xmax><ymax>{6:.3f}</ymax></extent>\n"
      "    <rotation>0</rotation>\n    <destinationsrs>{1}</destinationsrs>\n  </mapcanvas>\n"
      "  <projectlayers>\n{7}  </projectlayers>\n"
      "  <properties>\n    <Paths><Absolute type=\"bool\">false</Absolute></Paths>\n"
      // Without ProjectionsEnabled QGIS 3.22 ignores <projectCrs> and leaves the project without a CRS.
      "    <SpatialRefSys><ProjectionsEnabled type=\"int\">1</ProjectionsEnabled></SpatialRefSys>\n"
      "    <Measurement><DistanceUnits type=\"QString\">meters</DistanceUnits>"
      "<AreaUnits type=\"QString\">m2</AreaUnits></Measurement>\n  </properties>\n"
      "</qgis>\n",
      xml_escape(in.title), srs, tree, in.min.x(), in.min.y(), in.max.x(), in.max.y(), maplayers);
}

void write_qgis_project(const QgisProjectInput& in, const fs::path& out) {
  const std::string ext = out.extension().string();
  if (ext != ".qgs" && ext != ".qgz") {
    throw InputError(fmt::format("exporter.qgis: {}: the file name must end in .qgs or .qgz", out.string()));
  }
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  fs::create_directories(dir);
  const std::string xml = qgis_project_xml(in, dir);
  if (ext == ".qgz") {
    write_zip(out, {{out.stem().string() + ".qgs", xml}}, "export.qgz.temp_written");
    return;
  }
  write_bytes_atomically(out, "exporter.qgis", xml, "export.qgis.temp_written");
}

}  // namespace strata
