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
  std::vector<std::string> single_clicks;  // "GCP7 in L1_0003.jpg": markers left out, clicked in one photo
};

// Refuses (ProcessingError) a layer without a stored alignment or one that is not
// georeferenced, and (InputError) a marker clicked in only one registered photo (unless
// `leave_out_single_clicks`: the marker workspace, where a person clicks one marker after
// another; such markers are then named in single_clicks) or a layer with no marker
// clicked in two; nothing is written then. Otherwise replaces the layer's guided
// observations in one transaction.
GuideLayerResult guide_layer(Project& project, const std::string& layer_name, const MarkerGuideOptions& options,
                             bool leave_out_single_clicks = false);

}  // namespace strata
