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
for s in "abc:xyz" "127.0.0.1:99999" "224.0.0.1:11811" "bad host:11811" "999.999.999.999" "300.1.1.1:11811" ";;"; do
  one_line_error "ROS_DISCOVERY_SERVER='$s'" "ROS_DISCOVERY_SERVER=" env ROS_DISCOVERY_SERVER="$s" \
    timeout 30 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1
done
echo "hardening: no shell from a scenario; unicast peers, domain ids and discovery servers checked"

# issue 40, item 11: cell_client names the domains there are
out=$(ROS_DOMAIN_ID=232 "$bin/cell_client" 2>&1) && fail "cell_client took domain 232"
grep -q "0 to 231" <<<"$out" || fail "cell_client's domain range: $out"
# an enclave override with a control byte is refused, and printed escaped
err=$(ROS_SECURITY_ENABLE=true ROS_SECURITY_STRATEGY=Enforce ROS_SECURITY_KEYSTORE="$tmp/ks" \
      ROS_SECURITY_ENCLAVE_OVERRIDE=$'/cell\x01\x1b[31m' timeout 30 "$bin/servo" run --pattern "$pattern" 2>&1) &&
  fail "an enclave with control bytes was taken"
grep -q $'\x01' <<<"$err" && fail "the enclave was printed raw: $err"
grep -q 'not an enclave name' <<<"$err" || fail "the enclave's refusal does not say why: $err"
# seeds and numbers are written in decimal: not -1 (2^64 - 1 once), not 0x10 (16 once)
one_line_error "fig5-search --seed -1" "--seed" "$bin/cellsim" fig5-search "$src/sim/scenarios/fig5.yaml" --seed -1 --tries 1
one_line_error "decode-sweep --seed 0x10" "--seed" "$bin/cellsim" decode-sweep "$src/sim/scenarios/plane.yaml" --seed 0x10 --poses 1
one_line_error "pattern generate --seed 1e3" "--seed" "$bin/pattern" generate --rows 4 --cols 4 --seed 1e3 -o "$tmp/p.txt"
one_line_error "experiment --gain 0x10" "--gain" "$bin/cellsim" experiment "$src/sim/scenarios/plane.yaml" --gain 0x10
one_line_error "study axis gain=0x10" "0x10' is not a number" \
  "$bin/cellsim" study "$src/sim/scenarios/plane.yaml" --axis gain=0x10 --runs 1
# the live view listens on an address in digits: a name is never looked up
one_line_error "bridge --address localhost" "names are not looked up" "$bin/cellsim" bridge --address localhost --seconds 1
one_line_error "serve --foxglove-address alone" "needs --foxglove" \
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --foxglove-address 127.0.0.2
echo "hardening: domain range, enclave names, decimal seeds and numbers, the live view's address"
# the project's scripts read their command line before the set-up (minutes of apt and build):
# a typo is named in one line, --help says the usage and runs nothing
one_line_error "bin/experiments --hlep" "unknown argument '--hlep'" "$src/bin/experiments" --hlep
one_line_error "bin/experiments campaign studies" "one argument at most" "$src/bin/experiments" campaign studies
one_line_error "bin/fuzz nope" "unknown target 'nope'" "$src/bin/fuzz" decoder nope
one_line_error "FUZZ_SECONDS=1e3 bin/fuzz" "FUZZ_SECONDS" env FUZZ_SECONDS=1e3 "$src/bin/fuzz"
one_line_error "bin/keystore -x" "unknown option '-x'" "$src/bin/keystore" -x "$tmp/ks"
[ ! -e "$tmp/ks" ] || fail "bin/keystore -x made its DIR"
for s in experiments fuzz keystore; do
  out=$("$src/bin/$s" --help 2>&1) || fail "bin/$s --help: exit $?"
  grep -q "^usage: bin/$s" <<<"$out" || fail "bin/$s --help: no usage line: $out"
done
echo "hardening: the scripts' command lines refused before their set-up"
