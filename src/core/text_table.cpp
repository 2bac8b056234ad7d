#include "core/text_table.hpp"

#include <sys/ioctl.h>
#include <unicode/uchar.h>
#include <unicode/utf8.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <string>

namespace strata {
namespace {

int code_point_width(UChar32 c) {
  if (c < 0) return 1;  // a byte that is not UTF-8 shows as one replacement character
  const int8_t type = u_charType(c);
  if (type == U_NON_SPACING_MARK || type == U_ENCLOSING_MARK || type == U_FORMAT_CHAR || type == U_CONTROL_CHAR)
    return 0;
  const int ea = u_getIntPropertyValue(c, UCHAR_EAST_ASIAN_WIDTH);
  return ea == U_EA_WIDE || ea == U_EA_FULLWIDTH ? 2 : 1;
}

// Calls f(begin, end, width) for each code point of `s` (byte offsets).
template <typename F>
void each_code_point(std::string_view s, F&& f) {
  int32_t i = 0;
  const auto n = int32_t(s.size());
  while (i < n) {
    const int32_t begin = i;
    UChar32 c = 0;
    U8_NEXT(s.data(), i, n, c);
    f(std::size_t(begin), std::size_t(i), code_point_width(c));
  }
}

// The longest prefix of `s` at most `width` columns wide (whole code points).
std::size_t prefix_within(std::string_view s, int width) {
  std::size_t end = 0;
  int used = 0;
  bool full = false;
  each_code_point(s, [&](std::size_t, std::size_t e, int w) {
    if (full || used + w > width) {
      full = true;
      return;
    }
    used += w;
    end = e;
  });
  return end;
}

std::string cut(std::string_view s, int width) {
  if (display_width(s) <= width) return std::string(s);
  if (width <= 1) return width == 1 ? "…" : "";
  return std::string(s.substr(0, prefix_within(s, width - 1))) + "…";
}

std::string padded(const std::string& s, int width, bool right) {
  const std::string pad(std::size_t(std::max(0, width - display_width(s))), ' ');
  return right ? pad + s : s + pad;
}

}  // namespace

int display_width(std::string_view utf8) {
  int w = 0;
  each_code_point(utf8, [&](std::size_t, std::size_t, int cw) { w += cw; });
  return w;
}

std::vector<std::string> wrap_text(std::string_view text, int width) {
  width = std::max(width, 1);
  std::vector<std::string> lines;
  std::string line;
  int line_width = 0;
  auto flush = [&] {
    lines.push_back(line);
    line.clear();
    line_width = 0;
  };
  std::size_t i = 0;
  while (i < text.size()) {
    if (text[i] == ' ' || text[i] == '\t' || text[i] == '\n' || text[i] == '\r') {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < text.size() && text[j] != ' ' && text[j] != '\t' && text[j] != '\n' && text[j] != '\r') ++j;
    std::string_view word = text.substr(i, j - i);
    i = j;
    int w = display_width(word);
    if (line_width > 0 && line_width + 1 + w > width) flush();
    // A word longer than a whole line is broken inside it.
    while (w > width) {
      if (line_width > 0) flush();
      const std::size_t take = std::max<std::size_t>(1, prefix_within(word, width));
      line = std::string(word.substr(0, take));
      flush();
      word = word.substr(take);
      w = display_width(word);
    }
    if (word.empty()) continue;
    if (line_width > 0) {
      line += ' ';
      ++line_width;
    }
    line += word;
    line_width += w;
  }
  if (!line.empty() || lines.empty()) flush();
  return lines;
}

int terminal_width() {
  if (const char* c = std::getenv("COLUMNS")) {
    char* end = nullptr;
    const long v = std::strtol(c, &end, 10);
    if (end != c && *end == '\0' && v >= 20 && v <= 1000) return int(v);
  }
  winsize ws{};
  if (isatty(STDOUT_FILENO) && ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20) return ws.ws_col;
  return 100;
}

std::string TextTable::render(int width, int indent) const {
  constexpr int kGap = 2;         // spaces between columns
  constexpr int kMinWrapped = 16;  // a wrapped column narrower than this reads as a list of fragments
  const std::size_t n = columns.size();
  std::vector<int> widths(n, 0);
  for (std::size_t c = 0; c < n; ++c) {
    widths[c] = display_width(columns[c].title);
    for (const auto& row : rows) {
      if (c < row.size()) widths[c] = std::max(widths[c], display_width(row[c]));
    }
    if (columns[c].max_width > 0) widths[c] = std::min(widths[c], std::max(columns[c].max_width, 1));
  }
  int total = indent + kGap * int(n > 0 ? n - 1 : 0);
  for (int w : widths) total += w;
  for (std::size_t c = 0; c < n && total > width; ++c) {
    if (!columns[c].wraps) continue;
    const int narrower = std::max(kMinWrapped, widths[c] - (total - width));
    if (narrower < widths[c]) {
      total -= widths[c] - narrower;
      widths[c] = narrower;
    }
  }

  std::string out;
  auto emit = [&](const std::vector<std::vector<std::string>>& cells) {
    std::size_t height = 1;
    for (const auto& lines : cells) height = std::max(height, lines.size());
    for (std::size_t l = 0; l < height; ++l) {
      std::string line(std::size_t(indent), ' ');
      for (std::size_t c = 0; c < n; ++c) {
        const std::string text = l < cells[c].size() ? cells[c][l] : "";
        if (c > 0) line += std::string(kGap, ' ');
        line += padded(text, widths[c], columns[c].right);
      }
      while (!line.empty() && line.back() == ' ') line.pop_back();
      out += line + '\n';
    }
  };
  auto cells_of = [&](auto cell) {
    std::vector<std::vector<std::string>> cells(n);
    for (std::size_t c = 0; c < n; ++c) {
      const std::string text = cell(c);
      cells[c] = columns[c].wraps ? wrap_text(text, widths[c]) : std::vector<std::string>{cut(text, widths[c])};
    }
    return cells;
  };
  emit(cells_of([&](std::size_t c) { return columns[c].title; }));
  for (const auto& row : rows) emit(cells_of([&](std::size_t c) { return c < row.size() ? row[c] : std::string(); }));
  return out;
}

}  // namespace strata
