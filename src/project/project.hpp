#pragma once
// A strata project: a folder with project.gpkg (the database), media/ (original
// photos, content-addressed, never modified), cache/ and products/.
#include "project/database.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace strata {

struct SiteInfo {
  std::string name;
  std::string crs;         // e.g. "EPSG:32636"
  int srs_id = 0;          // gpkg_spatial_ref_sys id of the site CRS
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // metres, site CRS
  bool origin_set = false; // false until given or fixed from the first markers
};

struct CreateOptions {
  std::string crs;                          // required; projected, metres
  std::string name;                         // default: folder name
  std::optional<Eigen::Vector3d> origin;    // default: from the first markers imported
};

class Project {
 public:
  static constexpr const char* kDatabaseName = "project.gpkg";

  // Creates a new project folder (which must not hold a project yet).
  static Project create(const std::filesystem::path& dir, const CreateOptions& options);
  // Opens an existing project, applying pending schema migrations.
  static Project open(const std::filesystem::path& dir);

  Database& db() { return *db_; }
  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path database_path() const { return dir_ / kDatabaseName; }
  std::filesystem::path media_dir() const { return dir_ / "media"; }
  std::filesystem::path cache_dir() const { return dir_ / "cache"; }
  std::filesystem::path products_dir() const { return dir_ / "products"; }

  SiteInfo site();
  // Fixes the site origin (metres, site CRS) unless already set. The origin is
  // rounded (100 m horizontally, 1 m vertically) so that site-frame coordinates
  // are short and the origin is easy to quote.
  void set_origin_if_unset(const Eigen::Vector3d& near);

  int schema_version();

 private:
  Project(std::filesystem::path dir, std::unique_ptr<Database> db);
  std::filesystem::path dir_;
  std::unique_ptr<Database> db_;
};

// Latest schema version this build knows (number of the last migration).
int latest_schema_version();
// Applies migrations above the database's current level, each in a transaction.
// Returns the number applied.
int apply_migrations(Database& db);

}  // namespace strata
