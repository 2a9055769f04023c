// grant_probe --enclave E (--publish | --subscribe) TOPIC [--domain N]: joins the domain as
// enclave E of the keystore named by ROS_SECURITY_KEYSTORE (DDS-Security on, Enforce) and
// tries to create one writer or reader on the DDS topic TOPIC. Exit 0: the permissions
// allow it; 3: refused; 2: anything else. For the enclave x action matrix of the security
// test (issue 18, item 12): what a compromised node could do is tested, not read off XML.
#include <cstdio>
#include <cstring>
#include <string>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/participant.hpp"
#include "dds/topics.hpp"

int main(int argc, char** argv) {
  std::string enclave, topic, domain;
  bool publish = false, subscribe = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--enclave") enclave = v;
    else if (k == "--publish") publish = true, topic = v;
    else if (k == "--subscribe") subscribe = true, topic = v;
    else if (k == "--domain") domain = v;
    else {
      std::fprintf(stderr, "grant_probe: unknown argument %s\n", k.c_str());
      return 2;
    }
  }
  if (enclave.empty() || topic.empty() || publish == subscribe) {
    std::fprintf(stderr, "usage: grant_probe --enclave E (--publish | --subscribe) TOPIC [--domain N]\n");
    return 2;
  }
  cell_dds::ParticipantPtr p;
  try {
    cell_dds::ParticipantOptions o;
    o.domain_id = cell_dds::domain_id_from(domain);
    o.name = "grant_probe";
    o.security = cell_dds::security_from_env();
    o.enclave = enclave;
    p = cell_dds::make_participant(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "grant_probe: %s\n", e.what());
    return 2;
  }
  try {
    using T = cell_msgs::msg::dds_::SimControl_PubSubType;
    if (publish) {
      cell_dds::Writer<T> w(*p, topic, cell_dds::writer_qos(cell_dds::Stream::kCommand));
    } else {
      cell_dds::Reader<T> r(*p, topic, cell_dds::reader_qos(cell_dds::Stream::kCommand), [](cell_msgs::msg::dds_::SimControl_&&) {});
    }
  } catch (const std::exception& e) {
    std::printf("refused: %s %s as %s\n", publish ? "publish" : "subscribe", topic.c_str(), enclave.c_str());
    return 3;
  }
  std::printf("allowed: %s %s as %s\n", publish ? "publish" : "subscribe", topic.c_str(), enclave.c_str());
  return 0;
}
