// Connected components of a grid mask: an explicit-stack flood fill (no recursion:
// a component can hold millions of cells).
#include "volume/connected_components.hpp"

#include "core/error.hpp"

namespace strata::volume_detail {

Components connected_components(const std::vector<std::uint8_t>& mask, int nx, int ny, Connectivity connectivity) {
  STRATA_CHECK(nx >= 0 && ny >= 0 && mask.size() == std::size_t(nx) * std::size_t(ny),
               "mask of {} cells for a {} x {} grid", mask.size(), nx, ny);
  Components out;
  out.label.assign(mask.size(), -1);
  out.first.push_back(0);
  std::vector<std::size_t> stack;
  const bool eight = connectivity == Connectivity::eight;
  auto visit = [&](std::size_t q, std::int32_t k) {
    if (mask[q] && out.label[q] < 0) {
      out.label[q] = k;
      stack.push_back(q);
    }
  };
  for (std::size_t c0 = 0; c0 < mask.size(); ++c0) {
    if (!mask[c0] || out.label[c0] >= 0) continue;
    const auto k = std::int32_t(out.count());
    visit(c0, k);
    while (!stack.empty()) {
      const std::size_t c = stack.back();
      stack.pop_back();
      out.cells.push_back(c);
      const int i = int(c % std::size_t(nx)), j = int(c / std::size_t(nx));
      if (i > 0) visit(c - 1, k);
      if (i + 1 < nx) visit(c + 1, k);
      if (j > 0) visit(c - std::size_t(nx), k);
      if (j + 1 < ny) visit(c + std::size_t(nx), k);
      if (eight) {
        if (i > 0 && j > 0) visit(c - std::size_t(nx) - 1, k);
        if (i + 1 < nx && j > 0) visit(c - std::size_t(nx) + 1, k);
        if (i > 0 && j + 1 < ny) visit(c + std::size_t(nx) - 1, k);
        if (i + 1 < nx && j + 1 < ny) visit(c + std::size_t(nx) + 1, k);
      }
    }
    out.first.push_back(out.cells.size());
  }
  return out;
}

}  // namespace strata::volume_detail
