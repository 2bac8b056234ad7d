// Terminal tables: widths in what a terminal shows, wrapping and cutting that keep the
// columns apart (the `strata info` unit list ran a description into the next column).
#include "core/text_table.hpp"

#include <gtest/gtest.h>

#include <sstream>

namespace strata {
namespace {

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

TEST(TextTable, DisplayWidthCountsCharactersNotBytes) {
  EXPECT_EQ(display_width("topsoil"), 7);
  EXPECT_EQ(display_width("ε\u0301πίχωση"), 7) << "a combining accent takes no column";
  EXPECT_EQ(display_width("café"), 4);
  EXPECT_EQ(display_width("土層"), 4) << "East Asian wide characters take two";
  EXPECT_EQ(display_width(std::string("a\xff" "b")), 3) << "a stray byte shows as one character";
}

TEST(TextTable, WrapBreaksAtSpacesAndInsideOverlongWords) {
  EXPECT_EQ(wrap_text("dark greyish-brown loam with charcoal", 14),
            (std::vector<std::string>{"dark", "greyish-brown", "loam with", "charcoal"}));
  EXPECT_EQ(wrap_text("abcdefghij", 4), (std::vector<std::string>{"abcd", "efgh", "ij"}));
  EXPECT_EQ(wrap_text("", 10), std::vector<std::string>{""});
  EXPECT_EQ(wrap_text("ένα δύο τρία", 7), (std::vector<std::string>{"ένα δύο", "τρία"}));
}

TEST(TextTable, ColumnsNeverRunIntoEachOther) {
  TextTable t;
  t.columns = {{"unit"}, {"type"}, {"description", false, true}, {"layers"}};
  t.add({"101", "deposit", "topsoil: dark greyish-brown loose loam with modern debris and roots", "L1"});
  t.add({"102", "cut", "pit cut", "L2, L3"});
  const auto lines = lines_of(t.render(50));
  for (const auto& l : lines) EXPECT_LE(display_width(l), 50) << l;
  // The layers column starts at the same column on every row that has it, after a gap.
  const auto at = lines[0].find("layers");
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(lines[1].substr(at), "L1");
  EXPECT_EQ(lines[1].substr(at - 2, 2), "  ");
  bool all_words = true;
  std::string joined;
  for (std::size_t i = 1; i < lines.size() && lines[i].rfind("102", 0) != 0; ++i) joined += lines[i] + "\n";
  for (const char* w : {"topsoil:", "greyish-brown", "modern", "roots"}) all_words &= joined.find(w) != std::string::npos;
  EXPECT_TRUE(all_words) << "the wrapped description keeps every word:\n" << joined;
  EXPECT_EQ(lines.back().substr(0, 3), "102");
  EXPECT_EQ(lines.back().substr(at), "L2, L3");
}

TEST(TextTable, CutColumnsEndInAnEllipsisAndNumbersAlignRight) {
  TextTable t;
  t.columns = {{"name", false, false, 6}, {"photos", true}};
  t.add({"a very long layer name", "7"});
  t.add({"L2", "120"});
  const auto lines = lines_of(t.render(80));
  EXPECT_EQ(lines[0], "name    photos");
  EXPECT_EQ(lines[1], "a ver…       7");
  EXPECT_EQ(lines[2], "L2         120");
}

}  // namespace
}  // namespace strata
