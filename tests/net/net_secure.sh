#!/bin/sh
# DDS Security (docs/deploy.md, "Securing a session"), on loopback. The
# certificates are made here, in the test's directory, by deploy/ftm-security.
#   script:  the script's argument errors, refusals to overwrite, key file
#            modes, and what each role's permissions grant.
#   refused: a program started with an identity its role may not use (a
#            trainee's as server or instructor, an observer's as trainee), an
#            expired certificate, one of another CA, permissions not signed by
#            the CA or changed, a key others may read, a missing bundle: each
#            exits 3 at once, naming the file and the cause (ftm-server,
#            ftm-bot, and ftm-client under Xvfb).
#   session: a secured session (server, trainee, instructor, observer) while
#            intruders run: ftm-rogue --forge without security and with a
#            certificate of another CA hear nothing and forge nothing, a rogue
#            trainee's writers are never matched by the server, an unsecured
#            observer receives no frame, and a certified trainee's statuses
#            claiming role server or another's id and its probe input under
#            another's id are rejected; the bots end on the server's hash,
#            the instructor counts the server's replies only, and the
#            server's recording replays bit-identically.
# Every process runs under `timeout`; the test itself has a CTest TIMEOUT.
set -u
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
mode=${1:?mode}
: "${FTM_SECURITY:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-net-secure-$mode.XXXXXX")
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err "$dir"/*.log; do [ -f "$f" ] && { echo "== $f"; tail -n 25 "$f"; }; done; exit 1; }
sec() { "$FTM_SECURITY" "$@" >"$dir/sec.out" 2>&1 || fail "ftm-security $*: $(cat "$dir/sec.out")"; }
mode_of() { stat -c %a "$1"; }

# expect STATUS WANT CMD...: CMD exits with STATUS and says WANT
expect() {
    _st=$1 _want=$2
    shift 2
    _out=$(timeout 20 "$@" 2>&1)
    _rc=$?
    [ $_rc -eq "$_st" ] || fail "$*: exit status $_rc, want $_st: $_out"
    case $_out in *"$_want"*) ;; *) fail "$*: no '$_want' in: $_out" ;; esac
}

if [ "$mode" = script ]; then
    r=$dir/room
    expect 2 "usage: ftm-security init DIR" "$FTM_SECURITY"
    expect 2 "unknown command 'make'" "$FTM_SECURITY" make "$r"
    expect 2 "init: which directory?" "$FTM_SECURITY" init
    expect 2 "--days wants a number of days, got 'x'" "$FTM_SECURITY" init "$r" --days x
    expect 2 "--days 0: out of range 1..36500" "$FTM_SECURITY" init "$r" --days 0
    expect 2 "init: unknown argument '--force'" "$FTM_SECURITY" init "$r" --force
    expect 1 "has no readable CA" "$FTM_SECURITY" issue "$r" t --role trainee
    [ ! -e "$r" ] || fail "a refused command left $r behind"
    sec init "$r" --days 100
    [ "$(mode_of "$r/ca.key")" = 600 ] || fail "ca.key has mode $(mode_of "$r/ca.key")"
    sum=$(cat "$r/ca.key" "$r/ca.pem" "$r/governance.p7s" | cksum)
    expect 1 "already has a CA" "$FTM_SECURITY" init "$r"
    [ "$(cat "$r/ca.key" "$r/ca.pem" "$r/governance.p7s" | cksum)" = "$sum" ] || fail "init overwrote the CA"
    expect 2 "--role server|trainee|instructor|observer is required" "$FTM_SECURITY" issue "$r" t
    expect 2 "--role boss: not one of" "$FTM_SECURITY" issue "$r" t --role boss
    expect 2 "participant name '../t'" "$FTM_SECURITY" issue "$r" ../t --role trainee
    expect 2 "participant name '-t'" "$FTM_SECURITY" issue "$r" -t --role trainee
    expect 2 "--id 0: a participant id" "$FTM_SECURITY" issue "$r" t --role trainee --id 0
    expect 2 "--id 4294967296: out of range" "$FTM_SECURITY" issue "$r" t --role trainee --id 4294967296
    expect 2 "--id needs a value" "$FTM_SECURITY" issue "$r" t --role trainee --id
    expect 1 "expires within 101 days" "$FTM_SECURITY" issue "$r" t --role trainee --days 101
    for f in "$r"/*; do
        case ${f##*/} in ca.* | governance.*) ;; *) fail "a refused issue left $f behind" ;; esac
    done
    for role in server trainee instructor observer; do
        sec issue "$r" "$role-1" --role $role --id 7 --days 3
    done
    b=$r/trainee-1
    [ "$(mode_of "$b/key.pem")" = 600 ] || fail "key.pem has mode $(mode_of "$b/key.pem")"
    [ "$(mode_of "$b")" = 700 ] || fail "the bundle has mode $(mode_of "$b")"
    [ "$(cat "$b/id")" = 7 ] && [ "$(cat "$b/role")" = trainee ] || fail "id/role files"
    sum=$(cat "$b"/* | cksum)
    expect 1 "exists: not overwriting it" "$FTM_SECURITY" issue "$r" trainee-1 --role observer
    [ "$(cat "$b"/* | cksum)" = "$sum" ] || fail "issue overwrote a bundle"
    # signed by the CA, for the certificate's subject, valid 3 days
    openssl smime -verify -in "$b/permissions.p7s" -CAfile "$r/ca.pem" -out "$dir/p.xml" 2>/dev/null ||
        fail "permissions not verifiable with the CA"
    grep -q "<subject_name>CN=trainee-1,OU=trainee,O=FTM</subject_name>" "$dir/p.xml" || fail "subject"
    openssl x509 -in "$b/cert.pem" -noout -checkend $((2 * 86400)) >/dev/null || fail "certificate < 2 days"
    ! openssl x509 -in "$b/cert.pem" -noout -checkend $((4 * 86400)) >/dev/null || fail "certificate > 4 days"
    # each role: exactly the topics it writes and reads
    grants() { # bundle -> "publish: ... subscribe: ..."
        openssl smime -verify -in "$r/$1/permissions.p7s" -CAfile "$r/ca.pem" 2>/dev/null |
            sed -n 's/.*<publish>\(.*\)<\/publish>.*/publish:\1/p; s/.*<subscribe>\(.*\)<\/subscribe>.*/subscribe:\1/p' |
            sed 's/<topics>//g; s/<\/topics>//g; s/<topic>ftm_v1_/ /g; s/<\/topic>//g' |
            sed 's/<partitions><partition>/ in /; s/<\/partition><\/partitions>//' | tr '\n' ' '
    }
    # each writes in its own partition only (ftm.ROLE.ID), reads all of FTM's
    want_s="publish: scene_announce tick_frame keyframe participant_status control_reply in ftm.server.7 subscribe: participant_status probe_input session_control in ftm.* "
    want_t="publish: participant_status probe_input in ftm.trainee.7 subscribe: scene_announce tick_frame keyframe participant_status probe_input in ftm.* "
    want_i="publish: participant_status session_control in ftm.instructor.7 subscribe: scene_announce tick_frame keyframe participant_status probe_input control_reply in ftm.* "
    want_o="publish: participant_status in ftm.observer.7 subscribe: scene_announce tick_frame keyframe participant_status probe_input in ftm.* "
    [ "$(grants server-1)" = "$want_s" ] || fail "server grants: $(grants server-1)"
    [ "$(grants trainee-1)" = "$want_t" ] || fail "trainee grants: $(grants trainee-1)"
    [ "$(grants instructor-1)" = "$want_i" ] || fail "instructor grants: $(grants instructor-1)"
    [ "$(grants observer-1)" = "$want_o" ] || fail "observer grants: $(grants observer-1)"
    sec issue "$r" anyid --role trainee
    [ ! -e "$r/anyid/id" ] && grants anyid | grep -q "probe_input in ftm.trainee.\* " || fail "no --id: $(grants anyid)"
    echo "PASS secure script"
    exit 0
fi

: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
domain=$(( 1 + $$ % 97 ))
session="net-secure-$$"
rate=${FTM_TEST_RATE:-200}
common="--session $session --domain $domain --config $FTM_CONFIG"
r=$dir/room
sec init "$r"
sec issue "$r" server --role server --id 1
sec issue "$r" t11 --role trainee --id 11
sec issue "$r" i15 --role instructor --id 15
sec issue "$r" o13 --role observer --id 13
sec issue "$r" t12 --role trainee --id 12

if [ "$mode" = refused ]; then
    # an identity its role may not use: refused by DDS Security's permissions
    expect 3 "not permitted by the DDS Security permissions in $r/t11/permissions.p7s to write topic ftm_v1_scene_announce" \
        "$FTM_SERVER" --scene default $common --id 11 --security "$r/t11" --duration 2
    expect 3 "not permitted by the DDS Security permissions in $r/t11/permissions.p7s to write topic ftm_v1_session_control" \
        "$FTM_BOT" --role instructor --script "$here/../server/control-instructor.bot" $common \
        --id 11 --security "$r/t11" --duration 2
    expect 3 "to write topic ftm_v1_probe_input" \
        "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 13 \
        --security "$r/o13" --duration 2
    # an identity of a wider role than the program's: its grants would do
    expect 3 "the identity in $r/t11 was issued for role trainee, and this program runs as observer" \
        "$FTM_BOT" --role observer $common --id 11 --security "$r/t11" --duration 2
    # an expired certificate (openssl ca can backdate; ftm-security cannot)
    cp -r "$r/t11" "$dir/expired"
    openssl req -new -key "$dir/expired/key.pem" -subj "/O=FTM/OU=trainee/CN=t11" -out "$dir/t.csr" 2>/dev/null
    printf '[ca]\ndefault_ca=c\n[c]\ndatabase=%s/index\nnew_certs_dir=%s\nserial=%s/serial\npolicy=p\ndefault_md=sha256\n[p]\ncommonName=supplied\n' \
        "$dir" "$dir" "$dir" >"$dir/ca.cnf"
    : >"$dir/index"
    echo 01 >"$dir/serial"
    openssl ca -batch -config "$dir/ca.cnf" -cert "$r/ca.pem" -keyfile "$r/ca.key" -in "$dir/t.csr" \
        -out "$dir/expired/cert.pem" -startdate 20200101000000Z -enddate 20200102000000Z -notext \
        -preserveDN >/dev/null 2>&1 || fail "openssl ca could not make an expired certificate"
    expect 3 "the certificate $dir/expired/cert.pem expired on Jan  2 00:00:00 2020 GMT" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/expired" --duration 2
    # a certificate of another CA in this room's bundle
    sec init "$dir/other"
    sec issue "$dir/other" t11 --role trainee --id 11
    cp -r "$r/t11" "$dir/foreign"
    cp "$dir/other/t11/cert.pem" "$dir/other/t11/key.pem" "$dir/foreign/"
    expect 3 "the certificate $dir/foreign/cert.pem is not signed by the CA in $dir/foreign/ca.pem" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/foreign" --duration 2
    # permissions signed by another CA; permissions changed after signing
    cp -r "$r/t11" "$dir/perm"
    cp "$dir/other/t11/permissions.p7s" "$dir/perm/"
    expect 3 "$dir/perm/permissions.p7s is not signed by the CA in $dir/perm/ca.pem" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/perm" --duration 2
    cp "$r/t11/permissions.p7s" "$dir/perm/"
    sed -i 's/<topic>ftm_v1_probe_input</<topic>ftm_v1_session_control</' "$dir/perm/permissions.p7s"
    expect 3 "$dir/perm/permissions.p7s is not signed by the CA in $dir/perm/ca.pem (or was changed after signing)" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/perm" --duration 2
    # another participant's permissions; a key others may read; wrong id; no bundle
    cp "$r/o13/permissions.p7s" "$dir/perm/"
    expect 3 "the permissions $dir/perm/permissions.p7s have no grant for 'CN=t11,OU=trainee,O=FTM'" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/perm" --duration 2
    cp -r "$r/t11" "$dir/open"
    chmod 644 "$dir/open/key.pem"
    expect 3 "the private key $dir/open/key.pem may be read by others (mode 0644)" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/open" --duration 2
    expect 3 "the identity in $r/t11 was issued for participant id 11, not 12" \
        "$FTM_BOT" --role observer $common --id 12 --security "$r/t11" --duration 2
    # the bundle's id file removed: its permissions still bind it to id 11
    cp -r "$r/t11" "$dir/noid"
    rm "$dir/noid/id"
    expect 3 "to write topic ftm_v1_participant_status (participant status) in partition ftm.trainee.12" \
        "$FTM_BOT" --role observer $common --id 12 --security "$dir/noid" --duration 2
    expect 3 "DDS Security: $dir/none: No such file or directory" \
        "$FTM_SERVER" --scene default $common --security "$dir/none" --duration 2
    # ftm-client takes it too (where it can open a window: under Xvfb)
    if [ -n "${FTM_CLIENT:-}" ] && command -v xvfb-run >/dev/null 2>&1 && command -v Xvfb >/dev/null 2>&1; then
        : >"$dir/x.xauth"
        ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0 expect 3 \
            "permissions in $r/o13/permissions.p7s to write topic ftm_v1_probe_input (probe input) in partition ftm.observer.13" \
            xvfb-run -a -f "$dir/x.xauth" -s "-screen 0 640x480x24" "$FTM_CLIENT" --role trainee \
            $common --id 13 --security "$r/o13" --size 320x200
    else
        echo "(ftm-client not checked: no FTM_CLIENT or no xvfb-run)"
    fi
    echo "PASS secure refused"
    exit 0
fi

[ "$mode" = session ] || fail "unknown mode $mode"
: "${FTM_ROGUE:?}"
sec init "$dir/other"
sec issue "$dir/other" intruder --role server
timeout 40 "$FTM_SERVER" --scene default $common --id 1 --security "$r/server" --rate $rate \
    --duration 6 --record "$dir/session.rec" --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
server=$!
wait_for "$dir/server.log" "session '$session'" "server did not start" 100
# intruders: forgers of the server without security and with another CA's
# certificate; a rogue trainee without security; an unsecured observer
timeout 30 "$FTM_ROGUE" $common --id 1 --forge 5 --taken 11 --innocent 13 \
    >"$dir/forge0.out" 2>"$dir/forge0.err" &
f0=$!
timeout 30 "$FTM_ROGUE" $common --id 1 --forge 5 --taken 11 --innocent 13 \
    --security "$dir/other/intruder" >"$dir/forge1.out" 2>"$dir/forge1.err" &
f1=$!
timeout 30 "$FTM_ROGUE" $common --id 91 --victim 11 >"$dir/rogue.out" 2>"$dir/rogue.err" &
rogue=$!
timeout 30 "$FTM_BOT" --role observer $common --id 14 --duration 5 \
    >"$dir/bot14.out" 2>"$dir/bot14.err" &
b14=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --security "$r/t11" --duration 15 >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 30 "$FTM_BOT" --role observer $common --id 13 --security "$r/o13" --duration 15 \
    >"$dir/bot13.out" 2>"$dir/bot13.err" &
b13=$!
timeout 30 "$FTM_BOT" --role instructor --script "$here/../server/control-instructor.bot" $common \
    --id 15 --security "$r/i15" --duration 15 >"$dir/bot15.out" 2>"$dir/bot15.err" &
b15=$!
# a certified trainee (12) writing what its certificate does not cover
wait_for "$dir/bot11.err" "participant id 11 is confirmed" "trainee 11 was never confirmed"
timeout 30 "$FTM_ROGUE" $common --id 12 --impersonate 11 --for 2 --security "$r/t12" \
    >"$dir/imp.out" 2>"$dir/imp.err" &
imp=$!

wait $server || fail "server exited with $? (displaced by a status claiming role server?)"
wait $imp || fail "the impersonating trainee exited with $?"
grep -q "rogue: impersonated" "$dir/imp.out" || fail "the impersonating trainee sent nothing"
for b in 11 13; do
    eval "pid=\$b$b"
    wait "$pid" || fail "bot $b exited with $?"
done
wait $b15; rc15=$?
wait $b14; rc14=$?
wait $f0 || fail "the unsecured forger exited with $?"
wait $f1 || fail "the forger with another CA's certificate exited with $?"
wait $rogue; rcr=$?

want=$(sed -n 's/^ftm-server: \(final tick .*\)$/\1/p' "$dir/server.out")
[ -n "$want" ] || fail "no final line from the server"
for b in 11 13; do
    got=$(sed -n "s/^ftm-bot $b: \\(final tick .*\\) synced\$/\\1/p" "$dir/bot$b.out")
    [ "$got" = "$want" ] || fail "bot $b: '$got', server: '$want'"
    grep -q "0 mismatches" "$dir/bot$b.err" || fail "bot $b saw hash mismatches"
done
grep -q "0 of 3 expectations failed" "$dir/bot11.err" || fail "trainee 11's expectations"
grep -q "participant id 11 is confirmed" "$dir/bot11.err" || fail "trainee 11 was never confirmed"
# the instructor's commands reached the server and were answered by it alone
[ $rc15 -eq 4 ] || fail "instructor exited with $rc15, want 4 (a command refused)"
grep -q "commands: 3 sent, 2 applied, 0 changed, 1 refused, 0 unanswered" "$dir/bot15.err" ||
    fail "the instructor's commands were not answered by the server alone"
# the intruders heard none of the session (the unsecured ones hear each
# other: participants 14, 91, 92), so forged nothing
for f in 0 1; do
    ! grep -q "heard participant \(1\|11\|13\|15\)\$" "$dir/forge$f.out" ||
        fail "forger $f heard the session: $(grep 'heard participant' "$dir/forge$f.out" | tr '\n' ' ')"
    grep -q "forge done: 0 statuses, 0 replies; heard [0-9]* statuses, 0 commands" "$dir/forge$f.out" ||
        fail "forger $f: $(grep 'forge done' "$dir/forge$f.out")"
done
[ $rcr -eq 3 ] && grep -q "peers matched" "$dir/rogue.err" ||
    fail "the unsecured rogue trainee was matched by the server (exit $rcr)"
[ $rc14 -ne 0 ] && grep -q "NOT synced, 0 frames received" "$dir/bot14.err" ||
    fail "the unsecured observer received the session (exit $rc14)"
! grep -v "rejected .* from participant 12 seq\|participant 12 gone" "$dir/server.log" |
    grep -q "participant 9[1-2]\|participant 12\|rogue" ||
    fail "the server heard a rogue"
# the certified trainee's claims were set aside: its certificate is trainee 12's
grep -q "rejected participant status from participant 12 seq [0-9]*: its writer is certified as trainee 12, not as role server" \
    "$dir/server.log" || fail "the server did not reject a trainee's status claiming role server"
grep -q "rejected participant status from participant 12 seq [0-9]*: its writer is certified as trainee 12, not participant 11" \
    "$dir/server.log" || fail "the server did not reject a status naming participant 11"
grep -q "rejected probe input from participant 12 seq [0-9]*: its writer is certified as trainee 12, not participant 11" \
    "$dir/server.log" || fail "the server did not reject probe input naming participant 11"
! grep -q "no longer confirms\|is taken" "$dir/bot11.err" || fail "trainee 11 lost its id"
# the session replays bit-identically from its recording
timeout 30 "$FTM_SERVER" --replay "$dir/session.rec" >"$dir/replay.out" 2>&1 ||
    fail "the recording does not replay: $(tail -n 3 "$dir/replay.out")"
echo "PASS secure session: $want; $(grep -o 'synced at tick [0-9]*' "$dir/bot11.err"); $(grep -o 'latency mean .* max [0-9]* us' "$dir/bot11.err")"
