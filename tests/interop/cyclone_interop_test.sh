#!/usr/bin/env bash
# Another vendor's client on our topics: Cyclone DDS (idlc types from idl/) commands cellsim
# and receives images and twists from the Fast DDS services.
set -u
bin="$1"; src="$2"; client="$3"
export ROS_DOMAIN_ID=$(( $$ % 150 + 50 ))
# Cyclone on loopback only, finding the services by unicast (no multicast onto the network)
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
tmp=$(mktemp -d)
cleanup() { kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
"$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
servo=$!
"$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 3000 > "$tmp/sim.log" 2>&1 &
sim=$!
if timeout 200 "$client" "$ROS_DOMAIN_ID" 150; then exit 0; fi
echo "FAIL: the Cyclone DDS client was not served"; tail -5 "$tmp/sim.log" "$tmp/servo.log"
exit 1
