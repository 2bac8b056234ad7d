// Finds projected onto a section: a diagonal line with finds planted at known
// chainages and offsets either side of it, one too far from the plane and one
// beyond the end; their chainage, height and offset, and how the drawing (SVG) and
// the GeoPackage carry them.
#include "core/error.hpp"
#include "exporters/section/section_writers.hpp"
#include "support/test_support.hpp"
#include "volume/section.hpp"

#include <fmt/format.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <limits>
#include <map>
#include <tuple>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000, 4174000, 1450);  // metres, EPSG:32636
// Coordinates near 10^6 m carry about 1e-9 m of rounding through a subtraction and
// a dot product: a micrometre is far above it and far below the millimetre that
// matters on a drawing.
constexpr double kProjectionTol = 1e-6;  // metres

// A -> B: 3 m at bearing atan2(0.6, 0.8) (direction (0.6, 0.8)); the right-hand
// side of A -> B, in front of the drawing, is (0.8, -0.6).
const Eigen::Vector2d kA(0.5, 0.5), kB(0.5 + 1.8, 0.5 + 2.4);
const Eigen::Vector2d kAlong(0.6, 0.8), kRight(0.8, -0.6);

// Two flat surfaces on a 3 x 3 m grid of 5 cm: L1 (unit 101's top) at z = 0, L2
// (unit 102's top) at z = -0.3; unit 101 is the 0.3 m between them.
std::vector<LayerSurface> flat_layers() {
  const RasterGrid g = RasterGrid::from_south_west_centre(0.025, 0.025, 0.05, 60, 60);
  std::vector<LayerSurface> layers(2);
  layers[0].layer = "L1";
  layers[0].unit = "101";
  layers[1].layer = "L2";
  layers[1].unit = "102";
  for (int k = 0; k < 2; ++k) {
    layers[std::size_t(k)].z = HeightRaster<double>::empty(g);
    std::fill(layers[std::size_t(k)].z.z.begin(), layers[std::size_t(k)].z.z.end(), k == 0 ? 0.0 : -0.3);
  }
  return layers;
}

FindRecord find_at(const std::string& id, const std::string& unit, double chainage, double offset, double z) {
  FindRecord f;
  f.id = id;
  f.unit = unit;
  f.type = "pottery";
  const Eigen::Vector2d xy = kA + chainage * kAlong + offset * kRight;
  f.position = kOrigin + Eigen::Vector3d(xy.x(), xy.y(), z);
  return f;
}

std::vector<FindRecord> planted_finds() {
  return {find_at("F2", "101", 2.0, -0.20, -0.20),    // behind the plane
          find_at("F1", "101", 1.0, 0.10, -0.12),     // in front
          find_at("F3", "101", 1.5, 0.30, -0.10),     // 0.30 m from the plane: beyond 0.25
          find_at("F4", "101", 3.2, 0.00, -0.10)};    // on the line's extension past B
}

SectionProfile section() {
  const auto layers = flat_layers();
  return cut_section(kA, kB, layers, build_unit_solids(layers, VolumeOptions{}));
}

TEST(SectionFinds, ChainageHeightAndOffsetOfTheFindsNearThePlane) {
  SectionProfile p = section();
  ASSERT_NEAR(p.length(), 3.0, 1e-12);
  EXPECT_EQ(add_section_finds(p, planted_finds(), kOrigin, {}), 2u);  // default 0.25 m
  EXPECT_EQ(p.finds_within_m, 0.25);
  ASSERT_EQ(p.finds.size(), 2u);
  // By chainage: F1 first although it was given second.
  EXPECT_EQ(p.finds[0].id, "F1");
  EXPECT_NEAR(p.finds[0].s, 1.0, kProjectionTol);
  EXPECT_NEAR(p.finds[0].offset, 0.10, kProjectionTol);
  EXPECT_NEAR(p.finds[0].z, -0.12, kProjectionTol);
  EXPECT_EQ(p.finds[0].unit, "101");
  EXPECT_EQ(p.finds[0].type, "pottery");
  EXPECT_EQ(p.finds[1].id, "F2");
  EXPECT_NEAR(p.finds[1].s, 2.0, kProjectionTol);
  EXPECT_NEAR(p.finds[1].offset, -0.20, kProjectionTol);
  EXPECT_NEAR(p.finds[1].z, -0.20, kProjectionTol);

  // A wider band takes F3 (0.30 m in front); F4 stays out: its foot is past B.
  SectionFindOptions wide;
  wide.within_m = 0.35;
  EXPECT_EQ(add_section_finds(p, planted_finds(), kOrigin, wide), 3u);
  EXPECT_EQ(p.finds[1].id, "F3");
  EXPECT_NEAR(p.finds[1].offset, 0.30, kProjectionTol);
  // Seen from the other side (B -> A): chainage from B, offsets change sign.
  const auto layers = flat_layers();
  SectionProfile back = cut_section(kB, kA, layers, {});
  add_section_finds(back, planted_finds(), kOrigin, {});
  ASSERT_EQ(back.finds.size(), 2u);
  EXPECT_EQ(back.finds[0].id, "F2");
  EXPECT_NEAR(back.finds[0].s, 1.0, kProjectionTol);
  EXPECT_NEAR(back.finds[0].offset, 0.20, kProjectionTol);

  // 0 switches the finds off; a negative or NaN distance is refused by name.
  SectionFindOptions off;
  off.within_m = 0;
  EXPECT_EQ(add_section_finds(p, planted_finds(), kOrigin, off), 0u);
  EXPECT_TRUE(p.finds.empty());
  EXPECT_EQ(p.finds_within_m, 0.0);
  for (double bad : {-0.1, std::numeric_limits<double>::quiet_NaN()}) {
    SectionFindOptions o;
    o.within_m = bad;
    try {
      add_section_finds(p, planted_finds(), kOrigin, o);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--finds-within " + fmt::format("{}", bad)), std::string::npos) << e.what();
    }
  }
}

TEST(SectionFinds, DrawnAsLabelledMarkersAndWrittenAsPoints) {
  SectionProfile p = section();
  add_section_finds(p, planted_finds(), kOrigin, {});
  test::ScratchDir dir("section_finds");
  SectionDrawingOptions d;
  d.crs = "EPSG:32636";
  write_section_svg(dir / "s.svg", p, kOrigin, d);
  const std::string svg = test::read_text(dir / "s.svg");
  // At 1:20 (50 mm of paper per metre) from the 32 mm left margin; heights from the
  // top of the drawing at 1450.10 m (the tenth above the highest surface + 5 cm),
  // 28 mm below the top of the page. F1: filled (in front), F2: open (behind).
  EXPECT_NE(svg.find(R"(<g class="find" data-find="F1"><circle cx="82.00" cy="39.00" r="0.9" fill="black")"),
            std::string::npos)
      << svg;
  EXPECT_NE(svg.find(R"(<g class="find" data-find="F2"><circle cx="132.00" cy="43.00" r="0.9" fill="white")"),
            std::string::npos);
  EXPECT_NE(svg.find(">F1</text>"), std::string::npos);
  EXPECT_NE(svg.find(">F2</text>"), std::string::npos);
  EXPECT_EQ(svg.find("data-find=\"F3\""), std::string::npos);
  EXPECT_EQ(svg.find("data-find=\"F4\""), std::string::npos);
  EXPECT_NE(svg.find("find, up to 0.25 m in front"), std::string::npos);
  EXPECT_NE(svg.find("find, up to 0.25 m behind"), std::string::npos);

  write_section_gpkg(dir / "s.gpkg", p, kOrigin, "EPSG:32636");
  GDALAllRegister();
  GDALDataset* ds = GDALDataset::Open((dir / "s.gpkg").c_str(), GDAL_OF_VECTOR);
  ASSERT_NE(ds, nullptr);
  OGRLayer* finds = ds->GetLayerByName("section_finds");
  ASSERT_NE(finds, nullptr);
  EXPECT_EQ(finds->GetFeatureCount(), 2);
  std::map<std::string, std::tuple<double, double, double>> want = {{"F1", {1.0, 1450 - 0.12, 0.10}},
                                                                    {"F2", {2.0, 1450 - 0.20, -0.20}}};
  finds->ResetReading();
  while (OGRFeature* f = finds->GetNextFeature()) {
    const std::string id = f->GetFieldAsString("find_id");
    ASSERT_TRUE(want.count(id)) << id;
    const auto [s, h, offset] = want.at(id);
    EXPECT_EQ(std::string(f->GetFieldAsString("unit")), "101");
    EXPECT_NEAR(f->GetFieldAsDouble("chainage_m"), s, kProjectionTol) << id;
    EXPECT_NEAR(f->GetFieldAsDouble("height_m"), h, kProjectionTol) << id;
    EXPECT_NEAR(f->GetFieldAsDouble("offset_m"), offset, kProjectionTol) << id;
    // The point on the plane, in the CRS; the surveyed one in e, n.
    const OGRPoint* q = f->GetGeometryRef()->toPoint();
    const Eigen::Vector2d on_line = kOrigin.head<2>() + kA + s * kAlong;
    EXPECT_NEAR(q->getX(), on_line.x(), kProjectionTol) << id;
    EXPECT_NEAR(q->getY(), on_line.y(), kProjectionTol) << id;
    EXPECT_NEAR(q->getZ(), h, kProjectionTol) << id;
    EXPECT_NEAR(f->GetFieldAsDouble("e"), on_line.x() + offset * kRight.x(), kProjectionTol) << id;
    EXPECT_NEAR(f->GetFieldAsDouble("n"), on_line.y() + offset * kRight.y(), kProjectionTol) << id;
    want.erase(id);
    OGRFeature::DestroyFeature(f);
  }
  EXPECT_TRUE(want.empty());
  GDALClose(ds);

  // Without finds projected, no table.
  SectionFindOptions off;
  off.within_m = 0;
  add_section_finds(p, planted_finds(), kOrigin, off);
  write_section_gpkg(dir / "plain.gpkg", p, kOrigin, "EPSG:32636");
  ds = GDALDataset::Open((dir / "plain.gpkg").c_str(), GDAL_OF_VECTOR);
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetLayerByName("section_finds"), nullptr);
  EXPECT_NE(ds->GetLayerByName("section_units"), nullptr);
  GDALClose(ds);
}

}  // namespace
}  // namespace strata
