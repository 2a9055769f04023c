#!/usr/bin/env bash
# cell_client as a new user meets it (issue 18, item 5): --help says what it does, bad
# arguments are one line, and with no cell on the domain it says so within seconds instead
# of waiting its whole timeout in silence.
set -u
client="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
source "$src/tests/closed_loop/services.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
out=$("$client" --help) || fail "--help: exit $?"
grep -q "usage: cell_client" <<<"$out" || fail "--help prints no usage: $out"
grep -q "TEACH, RESET initial and START" <<<"$out" || fail "--help does not say what it does: $out"
one_line_error "unknown argument" "unknown argument '--bogus'" "$client" --bogus
one_line_error "domain -1" "is not a domain id" "$client" --domain -1
one_line_error "timeout nan" "--timeout 'nan'" "$client" --timeout nan
claim_domain
out=$(timeout 60 "$client" --domain "$cell_domain" --timeout 8 2>&1); rc=$?
[ $rc -eq 1 ] || fail "with no cell: exit $rc ($out)"
grep -q "waiting for cellsim (rt/sim/control) and a servo (rt/servo/status) on domain $cell_domain" <<<"$out" || fail "it does not say what it waits for: $out"
grep -q "after 5 s, no reader on rt/sim/control, no servo on rt/servo/status" <<<"$out" || fail "no early word that nobody is there: $out"
echo "cell_client: --help, one-line errors, an early word when no cell is there"
