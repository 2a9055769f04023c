#!/usr/bin/env bash
# Another vendor's client on our topics: Cyclone DDS (idlc types from idl/) commands cellsim
# and receives images and twists from the Fast DDS services.
set -u
bin="$1"; src="$2"; client="$3"
# Cyclone on loopback only, finding the services by unicast (no multicast onto the network)
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
source "$(dirname "$0")/../closed_loop/services.sh"
start_services "$bin" "$src" "--max-frames 3000"
if timeout 200 "$client" "$ROS_DOMAIN_ID" 150; then exit 0; fi
echo "FAIL: the Cyclone DDS client was not served"; tail -5 "$tmp/sim.log" "$tmp/servo.log"
exit 1
