#include "pipeline/process_layer.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "pipeline/stage_json.hpp"
#include "project/depth_records.hpp"
#include "project/media.hpp"
#include "project/records.hpp"
#include "project/scan_records.hpp"
#include "report/report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

void tell(const std::function<void(const LayerRun&)>& f, const LayerRun& run) {
  if (f) f(run);
}

// The DTM cell when none was given: the dense surface's sampling. Cells finer than it
// only interpolate, coarser ones lose detail; rounded to the millimetre so reruns agree.
double dtm_cell_from_dense(const DenseQuality& dense) {
  return std::max(0.005, std::round(dense.figures.gsd_m * 1000.0) / 1000.0);
}

LayerRun process_one(Project& p, const LayerRecord& layer, const ProcessRun& run, const ProcessObserver& observer) {
  LayerRun out;
  out.layer = layer.name;
  // A layer recorded by range scans or depth sequences alone has nothing to align:
  // its registered scans and depth frames are fused directly (docs/range.md).
  const std::size_t scans = list_scans(p.db(), layer.id).size();
  const std::size_t sequences = list_depth_sequences(p.db(), layer.id).size();
  out.photos = !(list_images(p.db(), layer.id).empty() && scans + sequences > 0);
  tell(observer.layer_started, out);
  bool aligned_anew = false;
  if (!out.photos) {
    log::info("== layer {}: no photos, {} range scan(s), {} depth sequence(s): no alignment", layer.name, scans,
              sequences);
  } else {
    log::info("== layer {}: alignment", layer.name);
    out.align = align_layer(p, layer.name, run.align);
    aligned_anew = !out.align->skipped;
    if (out.align->skipped) log::info("layer {}: alignment up to date, not recomputed", layer.name);
    tell(observer.aligned, out);
  }
  if (run.until != ProcessUntil::sparse) {
    log::info("== layer {}: dense surface", layer.name);
    out.dense = dense_layer(p, layer.name, run.dense, run.align.force || aligned_anew);
    if (out.dense->skipped) log::info("layer {}: dense surface up to date, not recomputed", layer.name);
    tell(observer.densified, out);
    if (run.until == ProcessUntil::products) {
      log::info("== layer {}: DTM, orthophoto, site plan", layer.name);
      ProductsOptions po = run.products;
      // Targets in the orthophoto are read as in the photos.
      po.ortho_markers.targets = run.align.targets;
      po.ortho_markers.naming = run.align.naming;
      if (!run.cell_given) po.dtm.cell_m = dtm_cell_from_dense(out.dense->quality);
      out.products = products_layer(p, layer.name, po, run.align.force || !out.dense->skipped);
      tell(observer.products_made, out);
    }
  }
  // The field report is rewritten after every run, so the trench edge always has the
  // current verdict.
  try {
    out.report = write_layer_report_product(p, layer.name);
    log::info("field report: {}", out.report->string());
  } catch (const Error& e) {
    log::warn("layer {}: the field report could not be written: {}", layer.name, e.what());
  }
  return out;
}

}  // namespace

ProcessUntil parse_process_until(const std::string& text) {
  if (text == "sparse") return ProcessUntil::sparse;
  if (text == "dense") return ProcessUntil::dense;
  if (text == "products") return ProcessUntil::products;
  throw InputError(fmt::format("until '{}' is not a stage: sparse, dense or products", text));
}

const char* to_string(ProcessUntil until) {
  switch (until) {
    case ProcessUntil::sparse: return "sparse";
    case ProcessUntil::dense: return "dense";
    case ProcessUntil::products: return "products";
  }
  return "products";
}

nlohmann::json to_json(const LayerRun& run) {
  nlohmann::json q = run.align ? to_json(run.align->quality) : nlohmann::json{{"layer", run.layer}, {"photos", false}};
  if (run.dense) q["dense"] = to_json(run.dense->quality);
  if (run.products) q["products"] = to_json(run.products->quality);
  return q;
}

std::vector<LayerRun> process_layers(Project& project, const std::vector<std::string>& names, const ProcessRun& run,
                                     const ProcessObserver& observer) {
  std::vector<LayerRecord> layers;
  for (const auto& name : names) layers.push_back(require_layer(project.db(), name));
  // Every photo the run will read still holds what was imported, before anything is
  // computed from any layer (project/media.hpp).
  for (const auto& l : layers) {
    const MediaCheckSummary checked = verify_media(project.dir(), list_images(project.db(), l.id));
    log::info("layer {}: {} photos match their SHA-256 ({} read in full)", l.name, checked.photos, checked.hashed);
  }
  std::vector<LayerRun> out;
  for (const auto& l : layers) out.push_back(process_one(project, l, run, observer));
  return out;
}

}  // namespace strata
