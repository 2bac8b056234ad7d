#pragma once
// Internal to src/volume: connected components of a mask on a grid (stack flood
// fill), shared by the gap filling (fill components, enclosed holes), the dug mask
// (noise specks) and the Harris-matrix check (conflict regions).
#include <cstddef>
#include <cstdint>
#include <vector>

namespace strata::volume_detail {

// 4: cells sharing an edge; 8: also cells sharing a corner.
enum class Connectivity { four = 4, eight = 8 };

// The components of the set cells of a mask, cells numbered c = row * nx + col
// (a north-up RasterGrid's index).
struct Components {
  std::vector<std::int32_t> label;  // per cell: its component, -1 where the mask is unset
  // Cells grouped by component: component k holds cells[first[k] .. first[k + 1]),
  // components in the order of their lowest cell, each in flood-fill order
  // (4-connectivity visits neighbours west, east, north, south).
  std::vector<std::size_t> cells;
  std::vector<std::size_t> first;   // count() + 1 offsets into `cells`

  std::size_t count() const { return first.empty() ? 0 : first.size() - 1; }
  std::size_t size(std::size_t k) const { return first[k + 1] - first[k]; }
  const std::size_t* begin(std::size_t k) const { return cells.data() + first[k]; }
  const std::size_t* end(std::size_t k) const { return cells.data() + first[k + 1]; }
};

// Connected components of the cells where `mask` is set on an nx x ny grid.
Components connected_components(const std::vector<std::uint8_t>& mask, int nx, int ny, Connectivity connectivity);

}  // namespace strata::volume_detail
