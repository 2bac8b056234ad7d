#pragma once
// Feature tracks: the same scene point followed through several images, built from
// pairwise verified matches by union-find (Moulon & Monasse 2012, "Unordered feature
// tracking made fast and easy").
#include "features/types.hpp"
#include "geometry/reconstruction.hpp"

#include <cstddef>
#include <vector>

namespace strata {

struct TrackStatistics {
  std::size_t tracks = 0;               // kept
  std::size_t inconsistent_tracks = 0;  // components with two keypoints of one image
  std::size_t repaired_tracks = 0;      // tracks recovered by splitting those
  std::size_t observations = 0;         // track elements kept
};

// Connected components of the match graph on (image, keypoint) nodes. A component
// holding two keypoints of one image is ambiguous (a repeated texture or a wrong
// match chained through others): it is split once by keeping only the matches that
// close a triangle of the graph (a true match of a track seen n times closes n - 2),
// and whatever still holds two keypoints of one image is dropped whole.
// Elements are sorted by image.
// Matches naming keypoints or images out of range are a bug in the caller (checked).
std::vector<std::vector<TrackElement>> build_tracks(const std::vector<ImageKeypoints>& keypoints,
                                                    const std::vector<PairMatches>& matches,
                                                    TrackStatistics* stats = nullptr);

}  // namespace strata
