#pragma once
// The stage results as JSON: what `process --json` prints and what the
// reconstructions table's quality_json column holds, written and read back through
// one description per struct (json_fields.hpp).
#include "pipeline/stage_results.hpp"
#include "project/database.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace strata {

nlohmann::json to_json(const AlignmentQuality& quality);
// Missing keys (a record of an earlier version) keep their defaults.
AlignmentQuality alignment_quality_from_json(const nlohmann::json& j);

nlohmann::json to_json(const DenseQuality& quality);
DenseQuality dense_quality_from_json(const nlohmann::json& j);

nlohmann::json to_json(const ProductsQuality& quality);
ProductsQuality products_quality_from_json(const nlohmann::json& j);

// A stage's row of the reconstructions table ('sparse', 'dense', 'products'): the
// key of the inputs it was computed from and its quality. A quality that does not
// parse reads as an empty object (every figure at its default).
struct StageRecord {
  std::string inputs_key;
  nlohmann::json quality;
};
std::optional<StageRecord> load_stage_record(Database& db, std::int64_t layer_id, const char* stage);
std::optional<DenseQuality> stored_dense_quality(Database& db, std::int64_t layer_id);
std::optional<ProductsQuality> stored_products_quality(Database& db, std::int64_t layer_id);
std::optional<AlignmentQuality> stored_alignment_quality(Database& db, std::int64_t layer_id);

}  // namespace strata
