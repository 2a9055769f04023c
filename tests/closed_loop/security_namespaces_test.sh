#!/usr/bin/env bash
# Per-namespace permissions (issue 18, item 12): under --namespace NAME, where NAME is also
# another node's topic prefix (servo, sim, camera), each enclave may publish and subscribe
# exactly its own topics in its own namespace, and nothing in another: the servo enclave of
# namespace servo may not command rt/servo/sim/control (its RESET once moved the robot 229 mm),
# the cellsim enclave of namespace sim may not write rt/sim/servo/cmd_twist. Each cell of the
# matrix is a real secured participant asking Fast DDS for the endpoint.
set -u
probe="$1"; src="$2"
source "$(dirname "$0")/services.sh"
source "$src/tests/cli/lib.sh"
isolated_cell_domain
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$src/bin/keystore" "$tmp/ks" --namespace servo --namespace sim --namespace camera >/dev/null || fail "bin/keystore --namespace"
grep -rl '<topic>[^<]*\*' "$tmp/ks/enclaves" && fail "a permissions file grants a topic pattern"
export ROS_SECURITY_KEYSTORE="$tmp/ks" ROS_SECURITY_ENABLE=true ROS_SECURITY_STRATEGY=Enforce
cells=0
expect() {  # expect allowed|refused ENCLAVE publish|subscribe TOPIC
  "$probe" --enclave "$2" --"$3" "$4" >/dev/null 2>&1; rc=$?
  case "$1:$rc" in allowed:0|refused:3) ;; *) fail "$2 $3 $4: expected $1, exit $rc" ;; esac
  cells=$((cells + 1))
}
for ns in servo sim camera; do
  p="rt/$ns"
  # each enclave's own topics in its namespace
  expect allowed "$ns/servo" publish "$p/servo/cmd_twist"
  expect allowed "$ns/servo" subscribe "$p/camera/image_raw"
  expect allowed "$ns/cellsim" publish "$p/camera/image_raw"
  expect allowed "$ns/servo" subscribe "$p/camera/white/image_raw"
  expect allowed "$ns/cellsim" publish "$p/camera/white/image_raw"
  expect allowed "$ns/cellsim" subscribe "$p/servo/cmd_twist"
  expect allowed "$ns/operator" publish "$p/sim/control"
  expect allowed "$ns/viewer" subscribe "$p/servo/status"
  # what each may not do there
  expect refused "$ns/servo" publish "$p/sim/control"
  expect refused "$ns/servo" publish "$p/camera/image_raw"
  expect refused "$ns/servo" publish "$p/camera/white/image_raw"
  expect refused "$ns/cellsim" publish "$p/servo/cmd_twist"
  expect refused "$ns/viewer" publish "$p/sim/control"
  expect refused "$ns/operator" publish "$p/servo/cmd_twist"
  # nothing across a namespace: the topic names that a pattern rt/NAME/* would have matched
  for other in servo sim camera; do
    expect refused "$ns/servo" publish "$p/$other/sim/control"
    expect refused "$ns/cellsim" publish "$p/$other/servo/cmd_twist"
    expect refused "$ns/operator" publish "$p/$other/sim/control"
    [ "$other" = "$ns" ] && continue
    expect refused "$ns/servo" publish "rt/$other/servo/cmd_twist"
    expect refused "$ns/operator" publish "rt/$other/sim/control"
    expect refused "$ns/viewer" subscribe "rt/$other/camera/image_raw"
  done
  # nor in the root namespace
  expect refused "$ns/operator" publish "rt/sim/control"
  expect refused "$ns/servo" publish "rt/servo/cmd_twist"
done
# the root enclaves: their own topics, and none of a namespace's
expect allowed servo publish rt/servo/cmd_twist
expect refused servo publish rt/servo/sim/control
expect refused cellsim publish rt/sim/servo/cmd_twist
expect refused operator publish rt/servo/sim/control
echo "security namespaces: $cells enclave x action cells as granted"
