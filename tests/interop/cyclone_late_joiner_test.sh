#!/usr/bin/env bash
# Issue 21, item 2: a Cyclone DDS client (what rmw_cyclonedds users run) that joins a running
# cell gets cellsim's node name on ros_discovery_info. Each join's delay is printed (not
# asserted: loaded machines); the bound only catches a name that never comes.
set -u
bin="$1"; src="$2"; probe="$3"
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
source "$(dirname "$0")/../closed_loop/services.sh"
start_services "$bin" "$src" ""
# the cell is running once the first client has heard it
timeout 120 "$probe" "$ROS_DOMAIN_ID" 100 || { echo "FAIL: cellsim never named on ros_discovery_info"; tail -5 "$tmp/sim.log"; exit 1; }
for i in 1 2 3 4 5; do
  timeout 120 "$probe" "$ROS_DOMAIN_ID" 100 || { echo "FAIL: late joiner $i got no node name"; exit 1; }
done
