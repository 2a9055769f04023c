/* Issue 21, item 2, as a ROS 2 client on Cyclone DDS sees it: it joins a running cell and
 * reads ros_discovery_info (rmw_dds_common/ParticipantEntitiesInfo, reliable, transient
 * local, as rmw_cyclonedds reads it) until cellsim's node is named. rmw_cyclonedds users saw
 * about 3 s before the names came (the endpoints were _CREATED_BY_BARE_DDS_APP_ meanwhile).
 * usage: cyclone_graph_probe DOMAIN TIMEOUT_S   prints the delay; exit 0 once named */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dds/dds.h"
#include "rmw_dds_common.h"

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: cyclone_graph_probe DOMAIN TIMEOUT_S\n");
    return 2;
  }
  const dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  const double timeout = atof(argv[2]);
  const double joined = now_s();
  const dds_entity_t p = dds_create_participant(domain, NULL, NULL);
  if (p < 0) {
    fprintf(stderr, "cyclone_graph_probe: no participant: %s\n", dds_strretcode(-p));
    return 1;
  }
  const dds_entity_t topic =
      dds_create_topic(p, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc, "ros_discovery_info", NULL, NULL);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 16);
  const dds_entity_t r = dds_create_reader(p, topic, q, NULL);
  dds_delete_qos(q);
  int named = 0;
  while (!named && now_s() - joined < timeout) {
    void* samples[4] = {NULL};
    dds_sample_info_t infos[4];
    const int n = dds_take(r, samples, infos, 4, 4);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_* s = samples[i];
      for (uint32_t k = 0; k < s->node_entities_info_seq._length; ++k)
        if (strcmp(s->node_entities_info_seq._buffer[k].node_name, "cellsim") == 0) named = 1;
    }
    if (n > 0) dds_return_loan(r, samples, n);
    if (!named) dds_sleepfor(DDS_MSECS(2));
  }
  if (!named) {
    fprintf(stderr, "cyclone_graph_probe: no node named cellsim on ros_discovery_info within %.0f s\n", timeout);
    dds_delete(p);
    return 1;
  }
  printf("cyclone late joiner: cellsim's node name after %.0f ms\n", 1e3 * (now_s() - joined));
  dds_delete(p);
  return 0;
}
