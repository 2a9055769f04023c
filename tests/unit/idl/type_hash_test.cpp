// REP-2011 type hashes from our IDL against the hashes ROS 2 Jazzy's rosidl generates
// (shared/ros2_type_hashes.md): if one differs, Jazzy tools show "Topic type hash: INVALID".
#include "dds/type_hash.hpp"

#include <gtest/gtest.h>

namespace cell_dds {
namespace {

TEST(TypeHash, Sha256KnownAnswers) {
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(std::string(1000, 'a')).size(), 64u);
}

TEST(TypeHash, StandardTypesMatchRos2Jazzy) {
  const TypeDescriptions& t = project_type_descriptions();
  const std::pair<const char*, const char*> known[] = {
      {"sensor_msgs/msg/Image", "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"},
      {"sensor_msgs/msg/CameraInfo", "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275"},
      {"geometry_msgs/msg/TwistStamped", "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64"},
      {"geometry_msgs/msg/PoseStamped", "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"},
      {"rosgraph_msgs/msg/Clock", "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"},
      {"std_msgs/msg/Header", "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"},
      {"builtin_interfaces/msg/Time", "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"},
      {"rmw_dds_common/msg/ParticipantEntitiesInfo",
       "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e"},
  };
  for (const auto& [name, hash] : known) EXPECT_EQ(type_hash(name, t), hash) << name << "\n" << hashable_json(name, t);
}

// The project's own package as ROS 2 Jazzy's rosidl hashes it: `colcon build` of
// idl/ros2/cell_msgs under a Jazzy built from source, read from
// install/cell_msgs/share/cell_msgs/msg/<Type>.json. A bounded sequence keeps its bound in the
// hash (SimStatus's `string[<=8] recent_refusals`).
TEST(TypeHash, TheCellsOwnTypesMatchRosidl) {
  const TypeDescriptions& t = project_type_descriptions();
  const std::pair<const char*, const char*> rosidl[] = {
      {"cell_msgs/msg/DecodedSpots", "RIHS01_af323c34ca12399b3505ea9caa9a3aac9ee44b660c8522cbf943ea026b909f0f"},
      {"cell_msgs/msg/ServoStatus", "RIHS01_51ba623bb501b49cd27a7da68969ddffa29e4ef5898922bac45b43cff19e1a62"},
      {"cell_msgs/msg/SimControl", "RIHS01_a5e44507be1c0d7aaee0cfb8bde948949f7603e99277720b9f036985cf1533fd"},
      {"cell_msgs/msg/SimStatus", "RIHS01_75728caaef8f6c00053aaac5cb590f5bfd8ad501d079d80c2076d4e1addf7386"},
      {"cell_msgs/msg/Spot", "RIHS01_c685c4a864d5b88fd7f46443a4ed711ae0e83c1f7ceabc410e74cdb45904a141"},
      {"cell_msgs/msg/SpotTruth", "RIHS01_994289730dda0f786b037c8918cb7b5a170239e233e0bf8d21c9f99547c1d132"},
      {"cell_msgs/msg/SpotTruthArray", "RIHS01_f2c038187ed2079a7ee5d97914d0aff17ac84ba41101ad5142170210778a1f42"},
  };
  for (const auto& [type, hash] : rosidl) EXPECT_EQ(type_hash(type, t), hash) << type;
}

TEST(TypeHash, TypesAbsentFromOurIdlAgreeToo) {
  // std_msgs/String, JointState and TransformStamped are not on our topics: described here in
  // IDL the way rosidl turns their .msg files into IDL, they must hash as Jazzy says
  TypeDescriptions t = project_type_descriptions();
  parse_idl_types(R"(module std_msgs { module msg { module dds_ { struct String_ { string data; }; }; }; };
module sensor_msgs { module msg { module dds_ { struct JointState_ { std_msgs::msg::dds_::Header_ header;
  sequence<string> name; sequence<double> position; sequence<double> velocity; sequence<double> effort; }; }; }; };
module geometry_msgs { module msg { module dds_ {
  struct Transform_ { geometry_msgs::msg::dds_::Vector3_ translation; geometry_msgs::msg::dds_::Quaternion_ rotation; };
  struct TransformStamped_ { std_msgs::msg::dds_::Header_ header; string child_frame_id;
    geometry_msgs::msg::dds_::Transform_ transform; }; }; }; };)",
                  t);
  EXPECT_EQ(type_hash("std_msgs/msg/String", t), "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18");
  EXPECT_EQ(type_hash("sensor_msgs/msg/JointState", t),
            "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e");
  EXPECT_EQ(type_hash("geometry_msgs/msg/TransformStamped", t),
            "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206");
}

TEST(TypeHash, EveryTopicTypeAnnouncesItsHash) {
  for (const char* dds : {"sensor_msgs::msg::dds_::Image_", "cell_msgs::msg::dds_::ServoStatus_",
                          "cell_msgs::msg::dds_::SimControl_", "cell_msgs::msg::dds_::SimStatus_",
                          "cell_msgs::msg::dds_::DecodedSpots_", "cell_msgs::msg::dds_::SpotTruthArray_"}) {
    const auto ud = type_hash_user_data(dds);
    const std::string s(ud.begin(), ud.end());
    EXPECT_EQ(s.rfind("typehash=RIHS01_", 0), 0u) << dds;
    EXPECT_EQ(s.size(), std::string("typehash=RIHS01_;").size() + 64) << dds;
  }
  EXPECT_TRUE(type_hash_user_data("not::a::Type_").empty());
}

}  // namespace
}  // namespace cell_dds
