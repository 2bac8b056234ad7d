#pragma once
// Finds recorded in place (schema 9, GeoPackage feature table `finds`): one total
// station point per object, with the unit the excavator recorded it in. Callers
// own the transaction.
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct FindRecord {
  std::int64_t fid = 0;
  std::string id;                                      // the find's number, unique
  std::string unit;                                    // recorded unit code
  std::string type;                                    // pottery, bone, ... (may be empty)
  std::string description;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // metres, site CRS (E, N, Z)
  std::string source;                                  // file name, or "find add"
  std::string imported_at;                             // ISO 8601 UTC; set by upsert_find
};

std::optional<FindRecord> find_find(Database& db, const std::string& id);
// Inserts or replaces (by id) a find with its GeoPackage point; stamps imported_at.
std::int64_t upsert_find(Database& db, const FindRecord& f, int srs_id);
std::vector<FindRecord> list_finds(Database& db);  // ordered by id

}  // namespace strata
