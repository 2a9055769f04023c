// ROS 2 type hashes (REP-2011, RIHS01) for the types in idl/, computed from the same IDL text
// fastddsgen compiles, so a hash can never drift from the wire type. An endpoint announces
// its type's hash in USER_DATA as "typehash=RIHS01_<sha256>;", as rmw implementations do
// from ROS 2 Iron on; without it Jazzy's tools warn for every topic.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace cell_dds {

struct FieldDescription {
  std::string name;
  int type_id = 0;  // type_description_interfaces/FieldType
  int capacity = 0;         // fixed array size
  int string_capacity = 0;  // bounded string size
  std::string nested_type_name;  // "pkg/msg/Type" for nested types
};
using TypeDescriptions = std::map<std::string, std::vector<FieldDescription>>;  // by "pkg/msg/Type"

// Parses the structs of IDL text in the ROS 2 DDS naming (pkg::msg::dds_::Type_) into ROS
// type descriptions. Throws std::runtime_error naming the token it does not understand.
void parse_idl_types(const std::string& idl_text, TypeDescriptions& out);

// Parses a ROS 2 .msg file of `package`'s type `type` ("cell_msgs", "SimStatus") into its
// description (constants and comments skipped; nested types as "pkg/msg/Type", a bare name
// meaning this package's). Throws std::runtime_error naming the line it does not understand.
void parse_msg_type(const std::string& package, const std::string& type, const std::string& msg_text,
                    TypeDescriptions& out);

// The descriptions of every type in idl/ (the files are compiled in).
const TypeDescriptions& project_type_descriptions();

// REP-2011 hash of `type_name` ("sensor_msgs/msg/Image") and the types it references.
std::string type_hash(const std::string& type_name, const TypeDescriptions& types);
// The JSON text that is hashed (exactly as rosidl's Python json.dumps writes it).
std::string hashable_json(const std::string& type_name, const TypeDescriptions& types);

// "sensor_msgs::msg::dds_::Image_" -> "sensor_msgs/msg/Image"
std::string ros_type_name(const std::string& dds_type_name);

// The USER_DATA an endpoint of that DDS type announces: "typehash=RIHS01_...;" (empty when
// the type is not one of ours).
std::vector<unsigned char> type_hash_user_data(const std::string& dds_type_name);

std::string sha256_hex(const std::string& bytes);

}  // namespace cell_dds
