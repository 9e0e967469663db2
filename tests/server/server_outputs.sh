#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server's output files against what it reads (loopback, a DDS domain
# and session of its own, `timeout` around every process):
#   - a real recording (a 1 s session with --record) survives byte for byte
#     every output option naming it under --inputs or --replay — by its
#     name, another spelling, a symbolic or a hard link: each is refused
#     (status 2) before anything is opened for writing; so do a trainee
#     script and the DDS configuration;
#   - an output that is a directory is refused by --check (status 3, naming
#     it) and at start-up (status 3), not after the session when the report
#     is written.
set -u
: "${FTM_SERVER:?}" "${FTM_CONFIG:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-outputs.XXXXXX")
trap 'rm -rf "$dir"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.out "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
common="--session srv-outputs-$$ --domain $domain --config $FTM_CONFIG"
rate=${FTM_TEST_RATE:-200}

cd "$dir" || fail "no $dir"
timeout 30 "$FTM_SERVER" $common --rate "$rate" --duration 1 --record a.rec >rec.out 2>rec.err ||
    fail "the recording session failed"
timeout 30 "$FTM_SERVER" --replay a.rec >replay.out 2>replay.err || fail "the recording does not replay"
cp a.rec orig.rec
ln -s a.rec sym.rec
ln a.rec hard.rec
mkdir sub
for name in a.rec ./a.rec "$dir/a.rec" sub/../a.rec sym.rec hard.rec; do
    for mode in --inputs --replay; do
        for opt in --record --log --report --control-log; do
            # (--record with --replay is refused anyway: a replay records nothing)
            [ "$mode $opt" = "--replay --record" ] && continue
            timeout 30 "$FTM_SERVER" $mode a.rec $opt "$name" >same.out 2>same.err
            rc=$?
            [ $rc -eq 2 ] || fail "$mode a.rec $opt $name: status $rc, not 2"
            grep -qF -- "$opt $name is the recording $mode a.rec reads" same.err ||
                fail "$mode a.rec $opt $name: no clear error"
            cmp -s a.rec orig.rec || fail "$mode a.rec $opt $name changed the recording"
        done
    done
done
# another file is fine, also one named like it elsewhere
timeout 30 "$FTM_SERVER" --inputs a.rec --record sub/a.rec --report sub/a.json >inputs.out 2>inputs.err ||
    fail "--inputs a.rec --record sub/a.rec refused"
timeout 30 "$FTM_SERVER" --replay sub/a.rec >replay2.out 2>replay2.err || fail "sub/a.rec does not replay"
cmp -s a.rec orig.rec || fail "the recording changed"

# an output that is a directory
timeout 30 "$FTM_SERVER" $common --check --record sub --report sub --control-log sub \
    >check.out 2>check.err
rc=$?
[ $rc -eq 3 ] || fail "--check with directories as outputs: status $rc, not 3"
for what in recording "control log" report; do
    grep -q "^$what *FAILS: sub is a directory" check.out || fail "--check: no '$what' failure"
done
grep -q "the session would NOT start" check.out || fail "--check: no verdict"
for opt in --report --control-log --record --log; do
    timeout 30 "$FTM_SERVER" $common --duration 1 $opt sub >dir.out 2>dir.err
    rc=$?
    [ $rc -eq 3 ] || fail "$opt sub: status $rc, not 3"
    grep -q -- "$opt sub is a directory" dir.err || fail "$opt sub: no clear error"
    ! grep -q "session 'srv-outputs" dir.err || fail "$opt sub: the session started"
done
timeout 30 "$FTM_SERVER" --inputs a.rec --report sub >dir.out 2>dir.err
[ $? -eq 3 ] && grep -q -- "--report sub is a directory" dir.err || fail "--inputs --report sub"
# the other files a run reads: a trainee script, the scene file, the configuration
printf '0 0 0 0.2\n1 0 0 0.2\n' >t.bot
cp t.bot t.orig
timeout 30 "$FTM_SERVER" --offline 10 --trainee 11:0:t.bot --reactions t.bot >same.out 2>same.err
[ $? -eq 2 ] && grep -qF -- "--reactions t.bot is the file --trainee t.bot reads" same.err ||
    fail "--reactions naming the trainee script was not refused"
cmp -s t.bot t.orig || fail "the trainee script changed"
cp "$FTM_CONFIG" c.xml
cp c.xml c.orig
timeout 30 "$FTM_SERVER" --config c.xml --session srv-outputs-$$ --domain $domain --check \
    --log c.xml >same.out 2>same.err
[ $? -eq 2 ] && grep -qF -- "--log c.xml is the file --config c.xml reads" same.err ||
    fail "--log naming the configuration was not refused"
cmp -s c.xml c.orig || fail "the configuration changed"
echo "PASS outputs: $(wc -c <a.rec)-byte recording kept under every output option"
