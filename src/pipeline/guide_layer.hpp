#pragma once
// 'strata markers guide': the controller that loads a layer's alignment and clicks,
// runs the guide (georef/guide.hpp) and stores its observations (source 'guided').
#include "georef/guide.hpp"
#include "project/project.hpp"

#include <string>
#include <vector>

namespace strata {

struct GuideLayerResult {
  std::string layer;
  MarkerGuideSummary summary;
  std::vector<std::string> photo_names;  // index of GuidePhoto -> photo name
  int replaced = 0;                      // guided rows of the layer before this run
  std::vector<std::string> unregistered_clicks;  // "GCP3 in L1_0004.jpg": photos the alignment left out
};

// Refuses (ProcessingError) a layer without a stored alignment or one that is not
// georeferenced, and (InputError) a marker clicked in only one registered photo or a
// layer with no marker clicked in two; nothing is written then. Otherwise replaces
// the layer's guided observations in one transaction.
GuideLayerResult guide_layer(Project& project, const std::string& layer_name, const MarkerGuideOptions& options);

}  // namespace strata
