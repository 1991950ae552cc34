# Sourced by the cooker's CLI test scripts. expect_exit BEFORE RC REGEX command... runs the command
# (60 s at most) and checks its exit code, that its standard error matches REGEX, that `snapshot`
# (each script defines what it covers) still prints BEFORE, and that no staged temp file is left.
expect_exit() {
  local before=$1 rc=$2 re=$3; shift 3
  local err; err=$(timeout 60 "$@" 2>&1 >/dev/null); local got=$?
  [ "$got" = "$rc" ] || { echo "FAIL: exit $got, expected $rc: $*: $err"; exit 1; }
  [[ "$err" =~ $re ]] || { echo "FAIL: message '$err' does not match '$re'"; exit 1; }
  [ "$(snapshot)" = "$before" ] || { echo "FAIL: files changed by $*"; exit 1; }
  ls | grep -q 'tmp-' && { echo "FAIL: temp file left"; exit 1; }
  echo "ok: $* -> $got: $err"
}
