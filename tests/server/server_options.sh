#!/bin/sh
# ftm-server refuses out-of-range options with a message naming them, and
# accepts the limits themselves (--offline: no DDS involved).
set -u
fail() { echo "FAIL: $*"; exit 1; }
refused() { # expected-text options...
    want=$1
    shift
    if out=$(timeout 20 "$FTM_SERVER" "$@" 2>&1); then fail "accepted: $*"; fi
    case $out in *"$want"*) ;; *) fail "$*: no '$want' in: $out" ;; esac
}
refused "--heartbeat in (0, 10] seconds" --heartbeat 10.5 --offline 1
refused "--heartbeat in (0, 10] seconds" --heartbeat 0 --offline 1
refused "--rate must be in (0, 100000]" --rate 100001 --offline 1
timeout 20 "$FTM_SERVER" --heartbeat 10 --rate 100000 --offline 5 >/dev/null 2>&1 ||
    fail "--heartbeat 10 --rate 100000 refused"
echo "PASS server options"
