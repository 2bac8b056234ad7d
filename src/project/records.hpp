#pragma once
// Row structs of the project database and the queries that read and write them.
// Callers own the transaction; these functions only run statements.
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct UnitRecord {
  std::int64_t id = 0;
  std::string code;
  std::string type = "deposit";  // deposit|cut|structure|interface
  std::string description;
};

struct RelationRecord {
  std::int64_t id = 0;
  std::string unit_a;  // unit code
  std::string kind;    // canonical: above|cuts|fills|abuts|same_as|contemporary_with
  std::string unit_b;
};

struct LayerRecord {
  std::int64_t id = 0;
  std::string name;
  std::string unit;  // unit code
  std::optional<std::string> captured_at;
};

struct CameraRecord {
  std::int64_t id = 0;
  std::string make, model;
  int width = 0, height = 0;              // pixels
  std::optional<double> focal_mm;         // EXIF FocalLength
  std::optional<double> focal_35mm;       // EXIF FocalLengthIn35mmFilm
  std::optional<double> sensor_width_mm;
  std::optional<double> focal_px;         // prior, pixels
  std::string focal_source = "unknown";
};

struct ImageRecord {
  std::int64_t id = 0;
  std::int64_t layer_id = 0;
  std::string name;        // original file name
  std::string sha256;
  std::string media_path;  // relative to the project folder
  std::int64_t bytes = 0;
  int width = 0, height = 0;
  std::optional<std::int64_t> camera_id;
  std::optional<std::string> captured_at;
  bool exif_ok = false;
};

struct MarkerRecord {
  std::int64_t id = 0;
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // metres, site CRS (E, N, Z)
  Eigen::Vector3d sigma = Eigen::Vector3d::Constant(0.01);  // metres
  // The survey stated `sigma` (a file's sigma column, or --sigma), rather than strata
  // weighing the marker with its default: only a stated sigma moves the verdict.
  bool sigma_stated = false;
  std::string kind = "control";                        // control|check
  std::string source;
};

struct ObservationRecord {
  std::int64_t id = 0;
  std::int64_t marker_id = 0;
  std::int64_t image_id = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  // detected (coded target) | clicked (placed by a person) | guided (markers guide);
  // schema 7 renamed the 'manual' rows of earlier projects to clicked.
  std::string source = "clicked";
};

// A marker as the last alignment of a layer saw it (table marker_residuals).
struct MarkerResidualRecord {
  std::string layer, marker;
  std::string role;  // control|check|rejected
  bool triangulated = false;
  Eigen::Vector3d residual_m = Eigen::Vector3d::Zero();  // photogrammetric minus surveyed (E, N, Z)
  double reprojection_px = 0;
  int images = 0;
};

// ---- units and relations
// The unit types the schema accepts (the units table's CHECK constraint).
const std::vector<std::string>& unit_types();
std::int64_t insert_unit(Database& db, const UnitRecord& u);
// Replaces the type and description of the unit with u's code.
void update_unit(Database& db, const UnitRecord& u);
std::optional<UnitRecord> find_unit(Database& db, const std::string& code);
UnitRecord require_unit(Database& db, const std::string& code);  // InputError when missing
std::vector<UnitRecord> list_units(Database& db);
std::int64_t insert_relation(Database& db, const RelationRecord& r);  // 0 when it existed
std::vector<RelationRecord> list_relations(Database& db);

// ---- layers
std::int64_t insert_layer(Database& db, const LayerRecord& l);
std::optional<LayerRecord> find_layer(Database& db, const std::string& name);
LayerRecord require_layer(Database& db, const std::string& name);  // InputError when missing
std::vector<LayerRecord> list_layers(Database& db);
// The marker residuals of every layer's current alignment (or of `layer` only), in
// layer order (list_layers) then marker name.
std::vector<MarkerResidualRecord> list_marker_residuals(Database& db, const std::string& layer = "");

// ---- cameras and images
std::int64_t find_or_insert_camera(Database& db, const CameraRecord& c);
std::optional<CameraRecord> find_camera(Database& db, std::int64_t id);
std::int64_t insert_image(Database& db, const ImageRecord& im);
std::optional<ImageRecord> find_image_by_sha(Database& db, const std::string& sha256);
std::vector<ImageRecord> find_images_by_name(Database& db, const std::string& name);
std::vector<ImageRecord> list_images(Database& db, std::optional<std::int64_t> layer_id = {});

// ---- markers and observations
std::optional<MarkerRecord> find_marker(Database& db, const std::string& name);
// Inserts or updates by name; writes the GeoPackage point geometry too.
std::int64_t upsert_marker(Database& db, const MarkerRecord& m, int srs_id);
std::vector<MarkerRecord> list_markers(Database& db);
// Returns false when the same (marker, image, source) existed (then updated).
bool upsert_observation(Database& db, const ObservationRecord& o);
std::vector<ObservationRecord> list_observations(Database& db,
                                                 std::optional<std::int64_t> layer_id = {});

}  // namespace strata

namespace strata {

// ---- products: files under the project folder, recorded with their checksum
struct ProductRecord {
  std::int64_t id = 0;
  std::optional<std::int64_t> layer_id;
  std::optional<std::int64_t> unit_id;
  std::string kind;
  std::string path;  // relative to the project folder
  std::string sha256;
  std::int64_t bytes = 0;
  std::string params_json = "{}";
};
// Records (or replaces, by path) a product; computes size and checksum from the file.
std::int64_t record_product(Database& db, const std::filesystem::path& project_dir, ProductRecord p);
std::vector<ProductRecord> list_products(Database& db, std::optional<std::int64_t> layer_id = {},
                                         const std::string& kind = "");
std::optional<ProductRecord> find_product(Database& db, std::int64_t layer_id, const std::string& kind);

}  // namespace strata
