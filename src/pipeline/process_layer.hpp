#pragma once
// The run controller of `strata process` and of the field station's process job: which
// stages a layer goes through, in which order, what each is told by the ones before it,
// and the field report after them. Both front ends call process_layers; neither
// decides the order of stages itself. Orchestration only: each stage is its own
// controller (align_layer, dense_layer, products_layer) and the maths is below them.
#include "pipeline/align_layer.hpp"
#include "pipeline/dense_layer.hpp"
#include "pipeline/products_layer.hpp"
#include "project/project.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// The last stage a run goes to.
enum class ProcessUntil { sparse, dense, products };
ProcessUntil parse_process_until(const std::string& text);  // InputError naming the value
const char* to_string(ProcessUntil until);

// What one run asks of every layer.
struct ProcessRun {
  AlignOptions align;
  DenseOptions dense;
  ProductsOptions products;
  ProcessUntil until = ProcessUntil::products;
  bool cell_given = false;  // products.dtm.cell_m was given; else the DTM cell follows the dense surface
};

// One layer's run: each stage's result when it ran (or was up to date).
struct LayerRun {
  std::string layer;
  bool photos = true;  // false: a layer of range scans or depth sequences alone, fused without alignment
  std::optional<AlignResult> align;
  std::optional<DenseLayerResult> dense;
  std::optional<ProductsLayerResult> products;
  std::optional<std::filesystem::path> report;  // the field report, when it could be written
};

// The figures as `process --json` prints them.
nlohmann::json to_json(const LayerRun& run);

// Told as each stage of each layer ends, so a front end can show it at once (the
// terminal prints its tables, the server its events). Any may be empty.
struct ProcessObserver {
  std::function<void(const LayerRun&)> layer_started;  // .layer and .photos set
  std::function<void(const LayerRun&)> aligned;
  std::function<void(const LayerRun&)> densified;
  std::function<void(const LayerRun&)> products_made;
};

// The layers `names` (each resolved once; InputError naming an unknown one) through the
// stages `run` asks for, in the order given. Before anything is computed, every photo
// the run will read is checked against its SHA-256 (verify_media). The field report of
// each layer is rewritten after its stages; a report that cannot be written is said
// in a warning and does not undo the processing. The caller holds the project lock.
std::vector<LayerRun> process_layers(Project& project, const std::vector<std::string>& names, const ProcessRun& run,
                                     const ProcessObserver& observer = {});

}  // namespace strata
