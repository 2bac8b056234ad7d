#pragma once
// Graphviz's layout of a graph: the Harris matrix in the site report and in
// `strata matrix --format svg`.
#include <optional>
#include <string>

namespace strata {

// The SVG that Graphviz's `dot` draws of `dot_text`; nullopt when `dot` is not
// installed or refuses the graph.
std::optional<std::string> graphviz_svg(const std::string& dot_text);

}  // namespace strata
