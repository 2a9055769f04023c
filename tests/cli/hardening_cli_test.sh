#!/usr/bin/env bash
# Issue 18 on the command line: no shell is ever run with text from a scenario (item 19), a
# static peer is one unicast host (item 13), domain ids and discovery servers are checked
# (item 18). Each bad value is refused in one line before anything joins a network.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"

# item 19: a scenario whose name would close a shell quote; the plot script is spawned with
# an argument vector, so the name is a title and nothing else
pwned="$tmp/pwned"
sed "s|\.\./\.\./|$src/|g; s|^name: .*|name: \"x'; touch $pwned; echo '\"|" "$src/sim/scenarios/fig5.yaml" > "$tmp/evil.yaml"
grep -q "touch $pwned" "$tmp/evil.yaml" || fail "the test scenario lacks its name"
"$bin/cellsim" experiment "$tmp/evil.yaml" --features ideal --max-iterations 5 -o "$tmp/run" >/dev/null 2>&1
[ -e "$pwned" ] && fail "a scenario's name: ran a shell command"
[ -s "$tmp/run/trace.csv" ] || fail "the experiment with a quoted name did not run"

# item 13: multicast, broadcast and 0.0.0.0 are not peers
for peer in 224.0.0.1 239.255.0.1 255.255.255.255 0.0.0.0; do
  one_line_error "static peer $peer" "not a unicast address" env ROS_STATIC_PEERS="$peer" \
    timeout 30 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1
  one_line_error "--static-peers $peer" "not a unicast address" \
    timeout 30 "$bin/servo" run --pattern "$pattern" --static-peers "$peer"
done

# item 18: domain ids 0..231, for the flag and the variable alike
for d in -1 232 233 1e3 " 7" 4294967296; do
  one_line_error "--domain '$d'" "is not a domain id" timeout 30 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --domain "$d"
  one_line_error "ROS_DOMAIN_ID='$d'" "is not a domain id" env ROS_DOMAIN_ID="$d" timeout 30 "$bin/servo" run --pattern "$pattern"
done
# malformed discovery servers are named, not ignored
for s in "abc:xyz" "127.0.0.1:99999" "224.0.0.1:11811" "bad host:11811"; do
  one_line_error "ROS_DISCOVERY_SERVER='$s'" "ROS_DISCOVERY_SERVER=" env ROS_DISCOVERY_SERVER="$s" \
    timeout 30 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1
done
echo "hardening: no shell from a scenario; unicast peers, domain ids and discovery servers checked"
