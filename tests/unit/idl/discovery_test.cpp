// Discovery as ROS 2 configures it: the variables and their errors (issue 11, item 1).
#include <gtest/gtest.h>

#include "dds/participant.hpp"

namespace cell_dds {
namespace {

TEST(Discovery, LocalhostUnlessTold) {
  const Discovery d = parse_discovery(nullptr, nullptr, nullptr);
  EXPECT_EQ(d.range, DiscoveryRange::kLocalhost);
  EXPECT_TRUE(d.static_peers.empty());
  EXPECT_EQ(parse_discovery("SUBNET", nullptr, nullptr).range, DiscoveryRange::kSubnet);
  EXPECT_EQ(parse_discovery("SYSTEM_DEFAULT", nullptr, nullptr).range, DiscoveryRange::kSubnet);
  EXPECT_EQ(parse_discovery("OFF", nullptr, nullptr).range, DiscoveryRange::kOff);
  EXPECT_EQ(parse_discovery("", nullptr, nullptr).range, DiscoveryRange::kLocalhost);
}

TEST(Discovery, LegacyLocalhostOnlyWinsAsInJazzy) {
  EXPECT_EQ(parse_discovery("SUBNET", nullptr, "1").range, DiscoveryRange::kLocalhost);
  EXPECT_EQ(parse_discovery("SUBNET", nullptr, "0").range, DiscoveryRange::kSubnet);
}

TEST(Discovery, StaticPeersAreIpv4AddressesSeparatedBySemicolons) {
  const Discovery d = parse_discovery("OFF", " 10.0.0.2 ;192.168.1.7;;", nullptr);
  ASSERT_EQ(d.static_peers.size(), 2u);
  EXPECT_EQ(d.static_peers[0], "10.0.0.2");
  EXPECT_EQ(d.static_peers[1], "192.168.1.7");
}

TEST(Discovery, BadValuesNameTheVariable) {
  const auto what = [](const char* r, const char* p, const char* l) {
    try {
      parse_discovery(r, p, l);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(what("EVERYWHERE", nullptr, nullptr).find("ROS_AUTOMATIC_DISCOVERY_RANGE='EVERYWHERE'"), std::string::npos);
  EXPECT_NE(what(nullptr, "10.0.0.300", nullptr).find("ROS_STATIC_PEERS: '10.0.0.300' is not an IPv4 address"),
            std::string::npos);
  EXPECT_NE(what(nullptr, "robot.local", nullptr).find("not an IPv4 address"), std::string::npos);
  EXPECT_NE(what(nullptr, nullptr, "yes").find("ROS_LOCALHOST_ONLY='yes'"), std::string::npos);
  std::string many;
  for (int i = 0; i < 65; ++i) many += "10.0.0.1;";
  EXPECT_NE(what(nullptr, many.c_str(), nullptr).find("more than 64"), std::string::npos);
}

TEST(Discovery, FlagsOverTheEnvironmentAndNameTheFlag) {
  setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF", 1);
  setenv("ROS_STATIC_PEERS", "10.1.1.1", 1);
  Discovery d = discovery_from("", "");
  EXPECT_EQ(d.range, DiscoveryRange::kOff);
  EXPECT_EQ(d.static_peers, std::vector<std::string>{"10.1.1.1"});
  d = discovery_from("SUBNET", "10.2.2.2;10.3.3.3");
  EXPECT_EQ(d.range, DiscoveryRange::kSubnet);
  EXPECT_EQ(d.static_peers.size(), 2u);
  try {
    discovery_from("nowhere", "");
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--discovery-range='nowhere'"), std::string::npos) << e.what();
  }
  unsetenv("ROS_AUTOMATIC_DISCOVERY_RANGE");
  unsetenv("ROS_STATIC_PEERS");
}

}  // namespace
}  // namespace cell_dds

#include "dds/topics.hpp"

namespace cell_dds {
namespace {

TEST(Namespace, TopicsGoUnderTheCellsNamespaceAsInRos2) {
  EXPECT_EQ(namespaced("", kImageTopic), "rt/camera/image_raw");
  EXPECT_EQ(namespaced("cell2", kImageTopic), "rt/cell2/camera/image_raw");
  EXPECT_EQ(namespaced("line_a/cell2", kTwistTopic), "rt/line_a/cell2/servo/cmd_twist");
  EXPECT_EQ(checked_namespace("/cell2"), "cell2");
  EXPECT_EQ(checked_namespace(""), "");
  for (const char* bad : {"2cell", "cell 2", "cell//2", "cell/", "cell-2", "cell\n"}) {
    try {
      checked_namespace(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--namespace '", 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
  EXPECT_THROW(checked_namespace(std::string(65, 'a')), std::invalid_argument);
}

}  // namespace
}  // namespace cell_dds
