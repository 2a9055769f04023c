#!/usr/bin/env bash
# Two hosts, modelled as two network namespaces joined by a veth pair (no loopback between
# them): cellsim in one, servo and a default-configured Cyclone DDS client in the other
# (issue 11, item 2). MODE subnet: ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET, multicast discovery
# over the veth; MODE static: ROS_STATIC_PEERS naming the other host, unicast only.
# The Cyclone client commands the run (TEACH, RESET initial, START) and must receive images,
# twists and joint states; cellsim must then converge. Every packet stays inside the
# namespaces this test creates. Exit 77 (skipped) when the machine refuses namespaces.
# usage: two_hosts_test.sh BIN SRC CYCLONE_CLIENT MODE
set -u
bin="$1"; src="$2"; client="$3"; mode="$4"
source "$(dirname "$0")/../closed_loop/services.sh"
skip() { echo "SKIP: $*"; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "network namespaces need root"
command -v ip >/dev/null || skip "no ip command (iproute2)"
tag=$(( $$ % 10000 ))
a="cellsimA$tag"; b="cellsrvB$tag"; va="vcA$tag"; vb="vcB$tag"
net="10.$(( 100 + $$ % 100 )).$(( $$ % 250 ))"
tmp=$(mktemp -d)
cleanup() {
  [ -n "${sim:-}" ] && kill -INT "$sim" 2>/dev/null
  [ -n "${servo:-}" ] && kill -INT "$servo" 2>/dev/null
  sleep 0.5
  [ -n "${sim:-}" ] && kill -KILL "$sim" 2>/dev/null
  [ -n "${servo:-}" ] && kill -KILL "$servo" 2>/dev/null
  ip netns del "$a" 2>/dev/null; ip netns del "$b" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
ip netns add "$a" 2>/dev/null || skip "cannot create a network namespace (ip netns add refused)"
ip netns add "$b" || skip "cannot create a second network namespace"
ip link add "$va" type veth peer name "$vb" || skip "cannot create a veth pair"
ip link set "$va" netns "$a" && ip link set "$vb" netns "$b" || skip "cannot move the veth ends"
for ns in "$a" "$b"; do ip -n "$ns" link set lo up; done
ip -n "$a" addr add "$net.1/24" dev "$va"; ip -n "$a" link set "$va" up
ip -n "$b" addr add "$net.2/24" dev "$vb"; ip -n "$b" link set "$vb" up
# multicast (SPDP, and a default Cyclone client) goes out of the veth
ip -n "$a" route add 224.0.0.0/4 dev "$va"; ip -n "$b" route add 224.0.0.0/4 dev "$vb"

claim_domain
export ROS_DOMAIN_ID="$cell_domain"
unset ROS_LOCALHOST_ONLY ROS_STATIC_PEERS CYCLONEDDS_URI
case "$mode" in
  subnet) env_a=(ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET); env_b=(ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET) ;;
  static) env_a=(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "ROS_STATIC_PEERS=$net.2")
          env_b=(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "ROS_STATIC_PEERS=$net.1") ;;
  *) echo "usage: two_hosts_test.sh BIN SRC CLIENT subnet|static"; exit 2 ;;
esac
ip netns exec "$b" env "${env_b[@]}" "$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" \
  --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
servo=$!
ip netns exec "$a" env "${env_a[@]}" "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --exit-on-converged \
  --max-frames 1500 > "$tmp/sim.log" 2>&1 &
sim=$!
# a client with Cyclone's default configuration, on the servo's host
if ! ip netns exec "$b" timeout 150 "$client" "$ROS_DOMAIN_ID" 120 > "$tmp/client.log" 2>&1; then
  echo "FAIL ($mode): the default-configured Cyclone DDS client in the servo's namespace was not served"
  tail -3 "$tmp/client.log" "$tmp/sim.log" "$tmp/servo.log"; exit 1
fi
for _ in $(seq 1 1200); do kill -0 "$sim" 2>/dev/null || break; sleep 0.1; done
wait "$sim"; rc=$?; sim=""
if ! ended_at_goal "$rc" "$tmp/sim.log"; then
  echo "FAIL ($mode): cellsim did not converge across the two namespaces (exit $rc, $final)"
  tail -n 8 "$tmp/sim.log" "$tmp/servo.log"; exit 1
fi
echo "two hosts ($mode): $(tail -1 "$tmp/client.log"); converged across the veth: $final"
