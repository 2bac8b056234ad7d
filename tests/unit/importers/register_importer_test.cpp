// importer.units.csv and importer.relations.csv: spreadsheet registers with quoted
// fields, any delimiter, line-numbered errors, nothing imported on failure.
#include "importers/stratigraphy/register_importer.hpp"

#include "importer_fixture.hpp"

namespace strata::test {
namespace {

class RegisterImporterTest : public ImporterTest {
 protected:
  UnitImportSummary units(const std::string& text, bool update = false) {
    return import_units(project(), {update}, write("units.csv", text));
  }
  RelationImportSummary relations(const std::string& text) {
    return import_relations(project(), write("relations.csv", text));
  }
  void expect_units_refused(const std::string& text, const std::string& expected) {
    expect_import_refused(text, expected, [&](const auto& path) { import_units(project(), {}, path); });
  }
  void expect_relations_refused(const std::string& text, const std::string& expected) {
    expect_import_refused(text, expected, [&](const auto& path) { import_relations(project(), path); });
  }
  std::string description(const std::string& code) { return require_unit(db(), code).description; }
};

TEST_F(RegisterImporterTest, QuotedDescriptionKeepsDelimiterAndDoubledQuotes) {
  const auto s = units("code,type,description\n"
                       "104,deposit,\"pale yellowish sandy gravel (sand, gravel)\"\n"
                       "105,Cut,\"pit with \"\"burnt\"\" edge\"\n");
  EXPECT_EQ(s.units_new, 2);
  EXPECT_EQ(description("104"), "pale yellowish sandy gravel (sand, gravel)");
  EXPECT_EQ(description("105"), "pit with \"burnt\" edge");
  EXPECT_EQ(require_unit(db(), "105").type, "cut");  // type in any case, stored lower
}

TEST_F(RegisterImporterTest, SemicolonTabBomAndHeaderInAnyCaseAndOrder) {
  units("\xEF\xBB\xBF" "Description;CODE;Type\n\"ash; charcoal\";201;deposit\n");
  EXPECT_EQ(description("201"), "ash; charcoal");
  units("code\ttype\tdescription\n202\tstructure\twall, north face\n");
  EXPECT_EQ(description("202"), "wall, north face");
  EXPECT_EQ(require_unit(db(), "202").type, "structure");
}

TEST_F(RegisterImporterTest, DescriptionIsOptionalAndExtraColumnsAreNamed) {
  const auto s = units("code,type,excavator\n301,deposit,AB\n");
  EXPECT_EQ(s.units_new, 1);
  EXPECT_EQ(description("301"), "");
  EXPECT_EQ(s.ignored_columns, std::vector<std::string>{"excavator"});
}

TEST_F(RegisterImporterTest, BadLinesNameFileLineAndValueAndImportNothing) {
  expect_units_refused("code,description\n401,x\n", "bad.csv:1: the header has no type column");
  expect_units_refused("code,type\n401,deposit\n,deposit\n", "bad.csv:3: the unit code is empty");
  expect_units_refused("code,type\n401,deposit\n402,layer\n", "bad.csv:3: unit '402': type 'layer' is not one of");
  expect_units_refused("code,type,description\n401,deposit,sand, gravel\n",
                       "bad.csv:2: 4 fields but the header names 3 columns");
  expect_units_refused("code,type\n401,deposit\n401,cut\n", "bad.csv:3: unit '401' appears again, unlike on");
  expect_units_refused("code,type\n", "no rows after the header");
  // Blank and comment lines keep the line numbers of the file.
  expect_units_refused("code,type\n\n# note\n401,deposit\n402,\n", "bad.csv:5: unit '402': type ''");
}

TEST_F(RegisterImporterTest, UnitAlreadyInProjectIsRefusedUnlessUpdateAndSameIsUnchanged) {
  // The fixture's unit 101 is a deposit without description.
  EXPECT_EQ(units("code,type\n101,deposit\n").units_unchanged, 1);
  expect_units_refused("code,type,description\n102,deposit,\n101,cut,pit\n",
                       "bad.csv:3: unit '101' is already in the project (deposit, ''), this gives cut, 'pit'; use "
                       "--update");
  EXPECT_FALSE(find_unit(db(), "102"));
  const auto s = units("code,type,description\n101,cut,pit\n", true);
  EXPECT_EQ(s.units_updated, 1);
  EXPECT_EQ(require_unit(db(), "101").type, "cut");
  EXPECT_EQ(description("101"), "pit");
}

TEST_F(RegisterImporterTest, RelationsInCanonicalFormAndAgainUnchanged) {
  units("code,type\n102,deposit\n103,cut\n");
  const std::string text = "A;Relation;B\n102;below;101\n103;cut_by;102\n";
  EXPECT_EQ(relations(text).relations_new, 2);
  const auto rows = list_relations(db());
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].unit_a, "101");
  EXPECT_EQ(rows[0].kind, "above");
  EXPECT_EQ(rows[0].unit_b, "102");
  EXPECT_EQ(rows[1].unit_a, "102");
  EXPECT_EQ(rows[1].kind, "cuts");
  EXPECT_EQ(rows[1].unit_b, "103");
  const auto again = relations(text);
  EXPECT_EQ(again.relations_new, 0);
  EXPECT_EQ(again.relations_unchanged, 2);
}

TEST_F(RegisterImporterTest, BadRelationsNameTheLineAndTheCycleAndImportNothing) {
  units("code,type\n102,deposit\n103,deposit\n");
  relations("a,relation,b\n101,above,102\n");
  expect_relations_refused("a,relation\n101,above\n", "bad.csv:1: the header has no b column");
  expect_relations_refused("a,relation,b\n102,above,103\n102,overlies,103\n",
                           "bad.csv:3: unknown relation 'overlies'; use one of");
  expect_relations_refused("a,relation,b\n102,above,103\n103,above,999\n",
                           "bad.csv:3: unit '999' is not in the project");
  expect_relations_refused("a,relation,b\n102,above,\n", "bad.csv:2: the unit code in column b is empty");
  // Line 3 closes a cycle through line 2 and the relation already in the project.
  expect_relations_refused("a,relation,b\n102,above,103\n103,above,101\n",
                           "bad.csv:3: relation '103 above 101' refused: it would make the Harris matrix "
                           "contradictory: cycle 103 -> 101 -> 102 -> 103");
  EXPECT_EQ(list_relations(db()).size(), 1u);
}

}  // namespace
}  // namespace strata::test
