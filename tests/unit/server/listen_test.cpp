#include "core/error.hpp"
#include "server/server.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace {

TEST(ListenAddress, LoopbackAddressesAreToldApart) {
  EXPECT_TRUE(parse_listen_address("127.0.0.1:8720").loopback);
  EXPECT_TRUE(parse_listen_address("localhost:80").loopback);
  EXPECT_TRUE(parse_listen_address("[::1]:8720").loopback);
  EXPECT_EQ(parse_listen_address("[::1]:8720").host, "::1");
  EXPECT_FALSE(parse_listen_address("0.0.0.0:8720").loopback);
  EXPECT_FALSE(parse_listen_address("192.168.1.20:8720").loopback);
  EXPECT_EQ(parse_listen_address("127.0.0.1:0").port, 0);
}

TEST(ListenAddress, MalformedAddressesAreRefusedNamingThem) {
  for (const char* bad : {"8720", "127.0.0.1", "127.0.0.1:99999", "127.0.0.1:-1", ":8720", "a b:1"}) {
    try {
      parse_listen_address(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace strata
