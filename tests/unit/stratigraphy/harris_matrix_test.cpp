#include "core/error.hpp"
#include "stratigraphy/harris_matrix.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace strata {
namespace {

CanonicalRelation rel(const std::string& a, const std::string& w, const std::string& b) {
  return canonical_relation(a, w, b);
}

std::vector<std::pair<std::string, std::string>> named(const HarrisMatrix& m,
                                                       const std::vector<std::pair<int, int>>& e) {
  std::vector<std::pair<std::string, std::string>> out;
  for (auto [a, b] : e) out.emplace_back(m.nodes()[a].label(), m.nodes()[b].label());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(Relations, InversesAreTurnedAround) {
  auto r = rel("102", "below", "101");
  EXPECT_EQ(r.unit_a, "101");
  EXPECT_EQ(r.kind, RelationKind::above);
  EXPECT_EQ(r.unit_b, "102");
  r = rel("204", "filled_by", "205");
  EXPECT_EQ(r.unit_a, "205");
  EXPECT_EQ(r.kind, RelationKind::fills);
  r = rel("110", "cut_by", "111");
  EXPECT_EQ(r.unit_a, "111");
  EXPECT_EQ(r.kind, RelationKind::cuts);
  EXPECT_THROW(rel("1", "beside", "2"), InputError);
  EXPECT_THROW(rel("1", "above", "1"), InputError);
}

TEST(HarrisMatrix, CycleIsRefusedAndPrinted) {
  HarrisMatrix m({"101", "102", "103"}, {rel("101", "above", "102"), rel("102", "above", "103")});
  try {
    m.add(rel("103", "above", "101"));
    FAIL() << "cycle accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("103 -> 101 -> 102 -> 103"), std::string::npos) << msg;
  }
  // The matrix is unchanged by the refused relation.
  EXPECT_EQ(m.edges().size(), 2u);
}

TEST(HarrisMatrix, SameAsGroupsCountInCycles) {
  // 101 above 102, 103 above 104; 102 same_as 103 is fine; then 104 above 101 closes
  // 101 -> {102=103} -> 104 -> 101.
  HarrisMatrix m({"101", "102", "103", "104"},
                 {rel("101", "above", "102"), rel("103", "above", "104"), rel("102", "same_as", "103")});
  EXPECT_TRUE(m.later_than("101", "104"));
  EXPECT_THROW(m.add(rel("104", "above", "101")), InputError);
  // A same_as between units already ordered is a contradiction too.
  EXPECT_THROW(m.add(rel("101", "same_as", "104")), InputError);
  EXPECT_THROW(m.add(rel("101", "contemporary_with", "102")), InputError);
}

TEST(HarrisMatrix, TransitiveReductionKeepsOnlyDirectRelations) {
  HarrisMatrix m({"1", "2", "3", "4"}, {rel("1", "above", "2"), rel("2", "above", "3"),
                                        rel("1", "above", "3"), rel("1", "cuts", "4"),
                                        rel("3", "above", "4")});
  EXPECT_EQ(m.edges().size(), 5u);
  const auto reduced = named(m, m.reduced_edges());
  const std::vector<std::pair<std::string, std::string>> expected = {{"1", "2"}, {"2", "3"}, {"3", "4"}};
  EXPECT_EQ(reduced, expected);
  const auto order = m.topological_order();
  ASSERT_EQ(order.size(), 4u);
  EXPECT_EQ(m.nodes()[order.front()].label(), "1");
  EXPECT_EQ(m.nodes()[order.back()].label(), "4");
}

TEST(HarrisMatrix, DotAndJsonNameTheNodes) {
  HarrisMatrix m({"10", "11", "12"}, {rel("10", "above", "11"), rel("11", "same_as", "12")});
  const std::string dot = m.to_dot();
  EXPECT_NE(dot.find("label=\"11 = 12\""), std::string::npos) << dot;
  const std::string json = m.to_json();
  EXPECT_NE(json.find("\"later\": \"10\""), std::string::npos) << json;
}

}  // namespace
}  // namespace strata
