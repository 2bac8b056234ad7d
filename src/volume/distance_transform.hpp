#pragma once
// Internal to src/volume: exact Euclidean distance transform on a grid
// (Felzenszwalb and Huttenlocher 2012), used by the gap filling and the dug mask.
#include <cstdint>
#include <vector>

namespace strata::volume_detail {

// For every cell of an nx x ny grid: distance (in cells) to the nearest cell where
// `feature` is set, and that cell's index; inf and -1 when there is none.
void distance_transform(const std::vector<std::uint8_t>& feature, int nx, int ny, std::vector<double>& dist,
                        std::vector<std::int64_t>* nearest);

}  // namespace strata::volume_detail
