#!/usr/bin/env bash
# DDS-Security (issue 11, item 3), on loopback: a keystore from bin/keystore; with security
# enforced the closed loop converges; an unauthenticated client cannot command the cell (the
# robot does not move); the viewer's enclave may not publish; a servo whose certificate comes
# from another CA is never admitted.
set -u
bin="$1"; src="$2"; client="$3"; cyclone="${4:-}"
source "$(dirname "$0")/services.sh"
source "$src/tests/cli/lib.sh"
isolated_cell_domain
tmp=$(mktemp -d)
pids=()
trap 'kill -INT "${pids[@]}" 2>/dev/null; sleep 1; kill -KILL "${pids[@]}" 2>/dev/null; rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
"$src/bin/keystore" "$tmp/ks" >/dev/null || fail "bin/keystore"
"$src/bin/keystore" "$tmp/other" >/dev/null || fail "bin/keystore (another CA)"
secure=(env ROS_SECURITY_KEYSTORE="$tmp/ks" ROS_SECURITY_ENABLE=true ROS_SECURITY_STRATEGY=Enforce)
stop() { kill -INT "${pids[@]}" 2>/dev/null; wait "${pids[@]}" 2>/dev/null; pids=(); }

# 1. secured, the loop converges; an unauthenticated Cyclone DDS reader (loopback only) on
#    the same domain meanwhile receives nothing
"${secure[@]}" "$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo1.log" 2>&1 &
pids+=($!)
if [ -n "$cyclone" ]; then
  CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>' \
    timeout 30 "$cyclone" "$ROS_DOMAIN_ID" 12 > "$tmp/cyclone.log" 2>&1 &
  eavesdropper=$!
fi
"${secure[@]}" timeout 120 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged \
  --max-frames 800 --record "$tmp/secured.mcap" > "$tmp/sim1.log" 2>&1 ||
  fail "secured run: cellsim exit $? ($(tail -1 "$tmp/sim1.log"))"
converged_at_goal "$tmp/sim1.log" || fail "secured run did not converge: $final"
# issue 40, item 2: the secured run was recorded (the cellsim enclave may read what it records),
# the servo's spots included, and replays bit for bit
grep -q "^cellsim: recorded messages: .*/servo/spots [1-9]" "$tmp/sim1.log" ||
  fail "the secured recording lacks the servo's spots: $(grep recorded "$tmp/sim1.log")"
out=$("$bin/servo" replay "$tmp/secured.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical 2>&1) ||
  fail "the secured recording does not replay bit for bit: $out"
echo "security: recorded and replayed: $out"
grep -o "loop rate [0-9]* iterations/s" "$tmp/sim1.log"
# issue 18, item 6: a secured run says so
grep -q "cellsim: DDS-Security on: enclave /cellsim, Enforce" "$tmp/sim1.log" || fail "the secured cellsim never said security is on"
grep -q "servo: DDS-Security on: enclave /servo" "$tmp/servo1.log" || fail "the secured servo never said security is on"
if [ -n "$cyclone" ]; then
  wait "$eavesdropper" && fail "an unauthenticated Cyclone DDS client was served by the secured cell"
  grep -q "no simulator on rt/sim/control, no servo\|: 0 images" "$tmp/cyclone.log" || fail "the unauthenticated client saw the cell: $(tail -1 "$tmp/cyclone.log")"
fi
stop

# 2. an unauthenticated client's commands never reach the secured cell
"${secure[@]}" "$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo2.log" 2>&1 &
pids+=($!)
"${secure[@]}" "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" > "$tmp/sim2.log" 2>&1 &
sim=$!
pids+=($sim)
sleep 1
if timeout 30 "$client" --domain "$ROS_DOMAIN_ID" --timeout 6 > "$tmp/client.log" 2>&1; then
  fail "an unauthenticated client commanded the secured cell"
fi
kill -INT "$sim"; wait "$sim" 2>/dev/null
grep -q "cellsim: 0 frames, 0 twists applied" "$tmp/sim2.log" && grep -q "; 0 commands" "$tmp/sim2.log" ||
  fail "the secured cell heard the unauthenticated client: $(grep 'twists applied' "$tmp/sim2.log")"
stop

# 3. the viewer's enclave may read, not publish: a servo run under it is refused its twist writer
one_line_error "viewer publishing" "cannot create a DDS writer for rt/servo/cmd_twist" \
  sh -c "ROS_SECURITY_ENCLAVE_OVERRIDE=viewer ROS_SECURITY_KEYSTORE='$tmp/ks' ROS_SECURITY_ENABLE=true \
         '$bin/servo' run --pattern '$pattern' 2>&1 >/dev/null | grep -v '^fastdds: ' >&2; exit 1"

# 4. a servo certified by another CA is not admitted: the cell never starts teaching
env ROS_SECURITY_KEYSTORE="$tmp/other" ROS_SECURITY_ENABLE=true "$bin/servo" run --pattern "$pattern" \
  > "$tmp/servo4.log" 2>&1 &
pids+=($!)
"${secure[@]}" timeout 8 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged \
  > "$tmp/sim4.log" 2>&1
grep -q "cellsim: 0 frames" "$tmp/sim4.log" || fail "a servo from another CA was admitted: $(grep 'twists applied' "$tmp/sim4.log")"
stop

# 5. missing enclave files: one line naming the file (Enforce)
one_line_error "missing enclave" "enclaves/nobody/identity_ca.cert.pem: missing" \
  env ROS_SECURITY_ENCLAVE_OVERRIDE=nobody ROS_SECURITY_KEYSTORE="$tmp/ks" ROS_SECURITY_ENABLE=true \
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml"
# 6. a certificate the CA did not sign: one line
cp -r "$tmp/ks" "$tmp/forged"
cp "$tmp/other/enclaves/cellsim/cert.pem" "$tmp/forged/enclaves/cellsim/cert.pem"
one_line_error "foreign certificate" "cannot create a DDS participant 'cellsim'" \
  env ROS_SECURITY_KEYSTORE="$tmp/forged" ROS_SECURITY_ENABLE=true "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml"
echo "security: secured loop converged; unauthenticated client, viewer writer and foreign CA refused"
