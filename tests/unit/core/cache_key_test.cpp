#include "core/cache_key.hpp"

#include <gtest/gtest.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace strata {
namespace {

struct Inner {
  double a = 1.5;
  int b = 2;
};

enum class Mode { one, two };

struct Options {
  Inner inner;
  std::string name = "x";
  std::optional<double> maybe;
  std::vector<Inner> list;
  std::map<int, std::string> names;
  Mode mode = Mode::one;
  bool flag = true;
  Unkeyed<int> threads = 0;
  void validate() const {}  // member functions do not count as fields
};

std::string key(const Options& o) { return CacheKey("test v1").add(o).hex(); }

TEST(Reflect, CountsTheFieldsOfAggregates) {
  EXPECT_EQ(reflect::field_count<Inner>, 2u);
  EXPECT_EQ(reflect::field_count<Options>, 8u);
}

TEST(Reflect, VisitsFieldsInDeclarationOrder) {
  Inner in{3.0, 7};
  std::vector<double> seen;
  reflect::for_each_field(in, [&](const auto& f) { seen.push_back(static_cast<double>(f)); });
  EXPECT_EQ(seen, (std::vector<double>{3.0, 7.0}));
}

TEST(CacheKey, EveryFieldChangesTheKey) {
  const Options base;
  const std::string k0 = key(base);
  EXPECT_EQ(k0, key(base));
  std::vector<Options> changed(8, base);
  changed[0].inner.a = 1.5000000001;
  changed[1].inner.b = 3;
  changed[2].name = "y";
  changed[3].maybe = 0.0;
  changed[4].list.push_back(Inner{});
  changed[5].names[1] = "GCP1";
  changed[6].mode = Mode::two;
  changed[7].flag = false;
  for (std::size_t i = 0; i < changed.size(); ++i) EXPECT_NE(key(changed[i]), k0) << "change " << i;
}

TEST(CacheKey, UnkeyedFieldsDoNotChangeTheKey) {
  Options o;
  const std::string k0 = key(o);
  o.threads = 8;
  EXPECT_EQ(int(o.threads), 8);
  EXPECT_EQ(key(o), k0);
}

TEST(CacheKey, TheNameAndVersionAreInTheKey) {
  const Options o;
  EXPECT_NE(CacheKey("test v1").add(o).hex(), CacheKey("test v2").add(o).hex());
}

TEST(CacheKey, ValuesAreDelimited) {
  // "ab" + "c" and "a" + "bc" must not collide, nor 1 followed by 2 and 12.
  EXPECT_NE(CacheKey("k").add(std::string("ab")).add(std::string("c")).hex(),
            CacheKey("k").add(std::string("a")).add(std::string("bc")).hex());
  EXPECT_NE(CacheKey("k").add(1).add(2).hex(), CacheKey("k").add(12).hex());
  EXPECT_NE(CacheKey("k").add(1).hex(), CacheKey("k").add(1.0).hex());
  EXPECT_NE(CacheKey("k").add(std::vector<int>{}).add(1).hex(), CacheKey("k").add(std::vector<int>{1}).hex());
}

TEST(CacheKey, U64IsTheDigestsFirstBytes) {
  CacheKey a("k");
  CacheKey b("k");
  const std::string hex = a.add(5).hex();
  EXPECT_EQ(b.add(5).u64(), std::stoull(hex.substr(0, 16), nullptr, 16));
}

}  // namespace
}  // namespace strata
