# Sourced by the CLI test scripts.
fail() { echo "FAIL: $*"; exit 1; }
# one_line_error WHAT EXPECTED COMMAND...: the command must fail with exactly one line on
# stderr containing EXPECTED.
one_line_error() {
  local what="$1" expect="$2"; shift 2
  err=$("$@" 2>&1 >/dev/null); rc=$?
  [ $rc -ne 0 ] || fail "$what: exit 0"
  [ "$(printf '%s\n' "$err" | wc -l)" -eq 1 ] || fail "$what: not one line: $err"
  grep -q -- "$expect" <<<"$err" || fail "$what: '$err' lacks '$expect'"
}
