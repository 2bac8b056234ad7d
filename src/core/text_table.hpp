#pragma once
// Tables for a terminal (`strata info`, `strata markers`): columns as wide as their
// widest cell, two spaces apart, measured in what a terminal shows (a character, two
// for an East Asian wide one, not bytes), so that a unit described in Greek or with
// accents lines up like one in ASCII. A column that is too wide for the terminal wraps
// its text at spaces (or is cut with an ellipsis when it does not wrap): a column never
// runs into the next.
#include <string>
#include <string_view>
#include <vector>

namespace strata {

// Columns a terminal shows for `utf8` (0 for combining marks, 2 for wide characters).
int display_width(std::string_view utf8);

// `utf8` in lines of at most `width` columns, broken at spaces (a word longer than a
// line is broken inside it, never inside a character). At least one line.
std::vector<std::string> wrap_text(std::string_view utf8, int width);

// The terminal's width: $COLUMNS when set, else the terminal's own when stdout is
// one, else 100 (a log file or a pipe).
int terminal_width();

struct TextTable {
  struct Column {
    std::string title;
    bool right = false;  // numbers align right
    // The one column that gives way when the table is wider than the terminal: its
    // text wraps onto further lines of the row. The others keep their width.
    bool wraps = false;
    int max_width = 0;  // columns; over it a cell is cut with an ellipsis (0: no limit)
  };
  std::vector<Column> columns;
  std::vector<std::vector<std::string>> rows;  // cells beyond `columns` are ignored

  void add(std::vector<std::string> row) { rows.push_back(std::move(row)); }
  // Every line ends in '\n', with no trailing spaces; `indent` spaces before each.
  std::string render(int width, int indent = 0) const;
};

}  // namespace strata
