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
for v in 0 -0.01 nan inf 1e999 1e-999; do
    refused "--max-penetration must be a length > 0 in metres (got '$v')" --max-penetration "$v" --offline 1
done
refused "--max-penetration: bad number '5cm'" --max-penetration 5cm --offline 1
refused "--replay, --inputs and --offline exclude each other" --replay a.rec --inputs b.rec
refused "--record goes with a session or --inputs" --offline 5 --record x.rec
refused "--record goes with a session or --inputs" --replay a.rec --record x.rec
refused "ftm-server --inputs: /nonexistent/a.rec" --inputs /nonexistent/a.rec
for v in localhost 127.0.0 300.1.1.1 ::g ''; do
    refused "--metrics-addr needs an IPv4 or IPv6 address (got '$v')" --metrics-addr "$v" --offline 1
done
refused "--record-dir goes with a session, without --record" --record-dir /tmp --record x.rec
refused "--record-dir goes with a session, without --record" --record-dir /tmp --offline 5
refused "--check checks a session's set-up: not with --replay" --check --replay a.rec
refused "--check checks a session's set-up: not with --replay" --offline 5 --check
t="--trainee 1:0:a.bot"
# shellcheck disable=SC2086 # nine options
refused "at most 8 --trainee options" --offline 5 $t $t $t $t $t $t $t $t $t
timeout 20 "$FTM_SERVER" --heartbeat 10 --rate 100000 --offline 5 >/dev/null 2>&1 ||
    fail "--heartbeat 10 --rate 100000 refused"
echo "PASS server options"
