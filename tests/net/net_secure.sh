#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# DDS Security (docs/deploy.md, "Securing a session"), on loopback. The
# certificates are made here, in the test's directory, by deploy/ftm-security.
#   script:  the script's argument errors, refusals to overwrite, key file
#            modes, the room's two CAs (the identity CA signs certificates
#            only, the permissions CA documents only), subjects and
#            permissions without the participants' names, what each role's
#            permissions grant, and `upgrade` of a room of one CA (names,
#            roles, ids and validity kept; the old room unchanged).
#   refused: a program started with an identity its role may not use (a
#            trainee's as server or instructor, an observer's as trainee), an
#            expired certificate, one of another CA, permissions not signed by
#            the permissions CA or changed, a key others may read, a missing
#            bundle: each exits 3 at once, naming the file and the cause
#            (ftm-server, ftm-bot, and ftm-client under Xvfb). Issue 26's
#            attack: a trainee's own signature on a server's or an
#            instructor's permissions (CVE-2023-24011), and the forger's next
#            tries (the identity CA or its own certificate as permissions
#            CA, a permissions CA of the identity CA's key); governance
#            signed by the identity CA; permissions of another room's
#            permissions CA; a certificate signed by the permissions CA; a
#            bundle of a room of one CA, then the room `upgrade` made of it.
#   session: a secured session (server, trainee, instructor, observer) while
#            intruders run: ftm-rogue --forge without security and with a
#            certificate of another CA hear nothing and forge nothing, a rogue
#            trainee's writers are never matched by the server, an unsecured
#            observer receives no frame, and a certified trainee's statuses
#            claiming role server or another's id and its probe input under
#            another's id are rejected; a trainee that signed itself an
#            instructor's and a server's permissions and hands them to Cyclone
#            past the check (ftm-rogue --elevated) is refused by the server's
#            Cyclone (its DDS log) and applies no command nor displaces the
#            server; the bots end on the server's hash, the instructor counts
#            the server's replies only, and the server's recording replays
#            bit-identically.
#   capture: (root and tcpdump, else skipped: 77) what a passive listener on
#            lo records of a secured session: no payload (no session name,
#            no display name), no participant's bundle name; but the roles
#            and ids (subjects, permissions) and the host and program names,
#            as docs/deploy.md lists; an unsecured session, captured alike,
#            shows the names (the search finds what is there).
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

# expect STATUS WANT CMD...: CMD exits with STATUS and says WANT (a shell
# pattern: * stands for anything)
expect() {
    _st=$1 _want=$2
    shift 2
    _out=$(timeout 20 "$@" 2>&1)
    _rc=$?
    [ $_rc -eq "$_st" ] || fail "$*: exit status $_rc, want $_st: $_out"
    # shellcheck disable=SC2254
    case $_out in *$_want*) ;; *) fail "$*: no '$_want' in: $_out" ;; esac
}

# expired CA_PEM CA_KEY CSR OUT: a certificate valid 2020-01-01..02 only
# (openssl ca can backdate; ftm-security cannot)
expired() {
    printf '[ca]\ndefault_ca=c\n[c]\ndatabase=%s/index\nnew_certs_dir=%s\nserial=%s/serial\npolicy=p\ndefault_md=sha256\n[p]\ncommonName=supplied\n' \
        "$dir" "$dir" "$dir" >"$dir/ca.cnf"
    : >"$dir/index"
    echo 01 >"$dir/serial"
    openssl ca -batch -config "$dir/ca.cnf" -cert "$1" -keyfile "$2" -in "$3" -out "$4" \
        -startdate 20200101000000Z -enddate 20200102000000Z -notext -preserveDN >/dev/null 2>&1 ||
        fail "openssl ca could not make an expired certificate"
}

# old_room DIR NAME:ROLE:ID:DAYS...: a room as ftm-security made it before
# it made two CAs: one CA (ca.key, ca.pem) signed the certificates (subject
# CN=NAME,OU=ROLE,O=FTM), the governance and the permissions. ID - for none;
# DAYS 0: expired. Uses the governance of the room $r.
old_room() {
    _o=$1
    shift
    mkdir -p "$_o"
    { openssl ecparam -name prime256v1 -genkey -noout -out "$_o/ca.key" &&
        openssl req -x509 -new -key "$_o/ca.key" -sha256 -days 100 \
            -subj "/O=FTM/CN=FTM training room CA" -out "$_o/ca.pem" &&
        openssl smime -sign -text -in "$r/governance.xml" -out "$_o/governance.p7s" \
            -signer "$_o/ca.pem" -inkey "$_o/ca.key"; } >/dev/null 2>&1 || fail "openssl: a room of one CA"
    for _p; do
        IFS=: read -r _n _role _id _days <<EOF
$_p
EOF
        _b=$_o/$_n
        mkdir "$_b"
        { openssl ecparam -name prime256v1 -genkey -noout -out "$_b/key.pem" &&
            openssl req -new -key "$_b/key.pem" -subj "/O=FTM/OU=$_role/CN=$_n" -out "$dir/old.csr"; } \
            >/dev/null 2>&1 || fail "openssl: a participant of the room of one CA"
        if [ "$_days" = 0 ]; then
            expired "$_o/ca.pem" "$_o/ca.key" "$dir/old.csr" "$_b/cert.pem"
        else
            openssl x509 -req -in "$dir/old.csr" -CA "$_o/ca.pem" -CAkey "$_o/ca.key" -CAcreateserial \
                -CAserial "$_o/ca.srl" -days "$_days" -out "$_b/cert.pem" >/dev/null 2>&1 || fail "openssl x509"
        fi
        printf '<dds><permissions><grant name="%s"><subject_name>CN=%s,OU=%s,O=FTM</subject_name></grant></permissions></dds>\n' \
            "$_n" "$_n" "$_role" >"$_b/permissions.xml"
        openssl smime -sign -text -in "$_b/permissions.xml" -out "$_b/permissions.p7s" -signer "$_o/ca.pem" \
            -inkey "$_o/ca.key" >/dev/null 2>&1 || fail "openssl smime"
        cp "$_o/ca.pem" "$_o/governance.p7s" "$_b/"
        echo "$_role" >"$_b/role"
        [ "$_id" = - ] || echo "$_id" >"$_b/id"
        chmod 600 "$_b/key.pem"
    done
}

# forge T ROLE OUT: issue 26's attack. Trainee T of room $r writes itself
# ROLE's permissions (the grants of ROLE's bundle, its own subject, the
# partition ftm.*) and signs them with its own key and certificate, as
# ftm-security signs with the CA's (CVE-2023-24011: Cyclone 0.10 takes any
# signer that chains to the permissions CA). OUT: T's bundle with those
# permissions and role ROLE, as a stock program would be given it.
forge() {
    _src=$r/server
    [ "$2" = instructor ] && _src=$r/i15
    _subj=$(openssl x509 -in "$r/$1/cert.pem" -noout -subject -nameopt RFC2253)
    _subj=${_subj#subject=}
    _subj=${_subj# }
    cp -r "$r/$1" "$3"
    sed -e "s|<subject_name>.*</subject_name>|<subject_name>$_subj</subject_name>|" \
        -e "s|<partition>ftm\.$2\.[0-9]*</partition>|<partition>ftm.*</partition>|" \
        "$_src/permissions.xml" >"$3/permissions.xml"
    grep -q "<partition>ftm\\.\\*</partition></partitions></publish>" "$3/permissions.xml" || fail "forge: no grant to widen"
    openssl smime -sign -text -in "$3/permissions.xml" -out "$3/permissions.p7s" -signer "$3/cert.pem" \
        -inkey "$3/key.pem" >/dev/null 2>&1 || fail "openssl could not sign the forged permissions"
    echo "$2" >"$3/role"
}

if [ "$mode" = script ]; then
    r=$dir/room
    expect 2 "usage: ftm-security init DIR" "$FTM_SECURITY"
    expect 2 "unknown command 'make'" "$FTM_SECURITY" make "$r"
    expect 2 "init: which directory?" "$FTM_SECURITY" init
    expect 2 "--days wants a number of days, got 'x'" "$FTM_SECURITY" init "$r" --days x
    expect 2 "--days 0: out of range 1..36500" "$FTM_SECURITY" init "$r" --days 0
    expect 2 "init: unknown argument '--force'" "$FTM_SECURITY" init "$r" --force
    expect 1 "$r has no readable identity_ca.key (a room holds identity_ca.key identity_ca.pem permissions_ca.key permissions_ca.pem governance.p7s): run 'ftm-security init $r' first" "$FTM_SECURITY" issue "$r" t --role trainee
    [ ! -e "$r" ] || fail "a refused command left $r behind"
    sec init "$r" --days 100
    for k in identity_ca permissions_ca; do
        [ "$(mode_of "$r/$k.key")" = 600 ] || fail "$k.key has mode $(mode_of "$r/$k.key")"
    done
    room_sum() { cat "$r"/identity_ca.* "$r"/permissions_ca.* "$r/governance.p7s" | cksum; }
    sum=$(room_sum)
    expect 1 "already has a CA" "$FTM_SECURITY" init "$r"
    [ "$(room_sum)" = "$sum" ] || fail "init overwrote the CAs"
    # two CAs, two keys: the identity CA signs certificates only (and what it
    # signs signs nothing), the permissions CA documents only (no CA to X.509)
    ! cmp -s "$r/identity_ca.pem" "$r/permissions_ca.pem" || fail "one certificate for both CAs"
    [ "$(openssl pkey -in "$r/identity_ca.key" -pubout)" != "$(openssl pkey -in "$r/permissions_ca.key" -pubout)" ] ||
        fail "one key for both CAs"
    ext() { openssl x509 -in "$1" -noout -ext basicConstraints,keyUsage 2>/dev/null | tr -d '\n' | tr -s ' '; }
    [ "$(ext "$r/identity_ca.pem")" = "X509v3 Basic Constraints: critical CA:TRUE, pathlen:0X509v3 Key Usage: critical Certificate Sign, CRL Sign" ] ||
        fail "identity CA extensions: $(ext "$r/identity_ca.pem")"
    [ "$(ext "$r/permissions_ca.pem")" = "X509v3 Basic Constraints: critical CA:FALSEX509v3 Key Usage: critical Digital Signature, Non Repudiation" ] ||
        fail "permissions CA extensions: $(ext "$r/permissions_ca.pem")"
    openssl smime -verify -in "$r/governance.p7s" -CAfile "$r/permissions_ca.pem" -out /dev/null 2>/dev/null ||
        fail "governance not signed by the permissions CA"
    expect 2 "--role server|trainee|instructor|observer is required" "$FTM_SECURITY" issue "$r" t
    expect 2 "--role boss: not one of" "$FTM_SECURITY" issue "$r" t --role boss
    expect 2 "participant name '../t'" "$FTM_SECURITY" issue "$r" ../t --role trainee
    expect 2 "participant name '-t'" "$FTM_SECURITY" issue "$r" -t --role trainee
    expect 2 "--id 0: a participant id" "$FTM_SECURITY" issue "$r" t --role trainee --id 0
    expect 2 "--id 4294967296: out of range" "$FTM_SECURITY" issue "$r" t --role trainee --id 4294967296
    expect 2 "--id needs a value" "$FTM_SECURITY" issue "$r" t --role trainee --id
    expect 1 "expires within 101 days" "$FTM_SECURITY" issue "$r" t --role trainee --days 101
    for f in "$r"/*; do
        case ${f##*/} in identity_ca.* | permissions_ca.* | governance.*) ;; *) fail "a refused issue left $f behind" ;; esac
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
    # the certificate of the identity CA, an end entity; the permissions of
    # the permissions CA, for the certificate's subject; valid 3 days
    openssl verify -CAfile "$r/identity_ca.pem" "$b/cert.pem" >/dev/null 2>&1 || fail "certificate not of the identity CA"
    ! openssl verify -CAfile "$r/permissions_ca.pem" "$b/cert.pem" >/dev/null 2>&1 || fail "certificate of the permissions CA"
    [ "$(ext "$b/cert.pem")" = "X509v3 Basic Constraints: critical CA:FALSEX509v3 Key Usage: critical Digital Signature" ] ||
        fail "certificate extensions: $(ext "$b/cert.pem")"
    openssl smime -verify -in "$b/permissions.p7s" -CAfile "$r/permissions_ca.pem" -out "$dir/p.xml" 2>/dev/null ||
        fail "permissions not verifiable with the permissions CA"
    grep -q "<subject_name>CN=ftm.trainee.7,OU=trainee,O=FTM</subject_name>" "$dir/p.xml" || fail "subject"
    cmp -s "$b/identity_ca.pem" "$r/identity_ca.pem" && cmp -s "$b/permissions_ca.pem" "$r/permissions_ca.pem" ||
        fail "the bundle's CAs are not the room's"
    grep -q "<IdentityCA>file:.*/trainee-1/identity_ca.pem</IdentityCA>" "$b/cyclonedds-security.xml" &&
        grep -q "<PermissionsCA>file:.*/trainee-1/permissions_ca.pem</PermissionsCA>" "$b/cyclonedds-security.xml" ||
        fail "cyclonedds-security.xml: each CA in its own role"
    # the participant's name is in neither of what travels in clear in the
    # authentication handshake, the certificate and the permissions
    for role in server trainee instructor observer; do
        ! openssl x509 -in "$r/$role-1/cert.pem" -noout -text | grep -q "$role-1" &&
            ! grep -q "$role-1" "$r/$role-1/permissions.p7s" || fail "the name $role-1 travels in clear"
    done
    openssl x509 -in "$b/cert.pem" -noout -checkend $((2 * 86400)) >/dev/null || fail "certificate < 2 days"
    ! openssl x509 -in "$b/cert.pem" -noout -checkend $((4 * 86400)) >/dev/null || fail "certificate > 4 days"
    # each role: exactly the topics it writes and reads
    grants() { # bundle -> "publish: ... subscribe: ..."
        openssl smime -verify -in "$r/$1/permissions.p7s" -CAfile "$r/permissions_ca.pem" 2>/dev/null |
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
    openssl x509 -in "$r/anyid/cert.pem" -noout -subject -nameopt RFC2253 | grep -q "=CN=ftm.trainee.any,OU=trainee,O=FTM$" ||
        fail "no --id: subject $(openssl x509 -in "$r/anyid/cert.pem" -noout -subject -nameopt RFC2253)"

    # upgrade: a room of one CA (an earlier ftm-security's) made into one of
    # two, each participant reissued under its name, role and id, valid as
    # long as before; the expired one named and left out
    o=$dir/old
    n=$dir/new
    # wall: as long-lived as the old CA
    old_room "$o" station1:trainee:11:10 dr-jansen:instructor:15:20 wall:observer:-:100 gone:trainee:12:0
    old_sum() { find "$o" -type f | sort | xargs cat | cksum; }
    osum=$(old_sum)
    expect 1 "$o is a room of one CA (ca.key, ca.pem), which FTM's programs refuse: any of its participants can sign its own permissions (CVE-2023-24011); make a room of two CAs from it with 'ftm-security upgrade $o NEW_DIR'" \
        "$FTM_SECURITY" issue "$o" x --role trainee
    expect 1 "$o is a room of one CA (ca.key, ca.pem): not overwriting it; make a room of two CAs from it with 'ftm-security upgrade $o NEW_DIR'" \
        "$FTM_SECURITY" init "$o"
    expect 2 "upgrade: which old and new directories?" "$FTM_SECURITY" upgrade "$o"
    expect 2 "upgrade: unknown argument '--force'" "$FTM_SECURITY" upgrade "$o" "$n" --force
    expect 1 "$r has no ca.pem: not a room of one CA" "$FTM_SECURITY" upgrade "$r" "$n"
    expect 1 "$r exists and is not empty" "$FTM_SECURITY" upgrade "$o" "$r"
    [ ! -e "$n" ] || fail "a refused upgrade made $n"
    "$FTM_SECURITY" upgrade "$o" "$n" >"$dir/up.out" 2>&1 || fail "upgrade: $(cat "$dir/up.out")"
    grep -q "not reissued, their certificates have expired (issue them anew in $n): gone$" "$dir/up.out" ||
        fail "upgrade did not name the expired participant: $(cat "$dir/up.out")"
    grep -q "give each participant its new directory in place of the old one" "$dir/up.out" || fail "upgrade: $(cat "$dir/up.out")"
    [ ! -e "$n/gone" ] || fail "upgrade reissued an expired participant"
    ! cmp -s "$n/identity_ca.pem" "$n/permissions_ca.pem" || fail "upgrade made one CA"
    end_of() { date -u -d "$(openssl x509 -in "$1" -noout -enddate | sed 's/^notAfter=//')" +%s; }
    for p in station1:trainee:11 dr-jansen:instructor:15 wall:observer:-; do
        IFS=: read -r nm role id <<EOF
$p
EOF
        [ "$(cat "$n/$nm/role")" = "$role" ] || fail "upgrade: $nm's role"
        if [ "$id" = - ]; then
            [ ! -e "$n/$nm/id" ] || fail "upgrade: $nm got an id"
            cn=ftm.$role.any
        else
            [ "$(cat "$n/$nm/id")" = "$id" ] || fail "upgrade: $nm's id"
            cn=ftm.$role.$id
        fi
        openssl x509 -in "$n/$nm/cert.pem" -noout -subject -nameopt RFC2253 | grep -q "=CN=$cn,OU=$role,O=FTM$" ||
            fail "upgrade: $nm's subject"
        openssl verify -CAfile "$n/identity_ca.pem" "$n/$nm/cert.pem" >/dev/null 2>&1 || fail "upgrade: $nm's certificate"
        # its old end, rounded up to the day
        e_old=$(end_of "$o/$nm/cert.pem")
        e_new=$(end_of "$n/$nm/cert.pem")
        [ "$e_new" -ge "$e_old" ] && [ "$e_new" -le $((e_old + 86400 + 60)) ] ||
            fail "upgrade: $nm valid until $e_new, was $e_old"
    done
    [ "$(end_of "$n/identity_ca.pem")" -ge "$(end_of "$o/ca.pem")" ] || fail "upgrade: the new CA ends before the old"
    [ "$(old_sum)" = "$osum" ] || fail "upgrade changed the old room"
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

if [ "$mode" = capture ]; then
    # What a passive listener on the network records of a secured session
    # (docs/deploy.md, "What a listener learns"): tcpdump on lo, this
    # test's DDS domain only. Needs root (raw capture) and tcpdump.
    skip() { echo "SKIP: $*"; exit 77; }
    [ "$(id -u)" = 0 ] || skip "not root: capturing on lo needs root (CAP_NET_RAW)"
    command -v tcpdump >/dev/null 2>&1 || skip "no tcpdump (Debian package tcpdump, deploy/install-deps.sh)"
    # bundles named and participants shown as people are: neither may travel
    sec issue "$r" station-alice --role trainee --id 21
    sec issue "$r" dr-jansen --role instructor --id 25
    lo=$((7400 + 250 * domain))
    # capture NAME [SECURED]: a session of a server, a trainee and an
    # instructor, every UDP datagram of its domain on lo in $dir/NAME.pcap
    capture() {
        timeout 40 tcpdump -i lo -n -U -Z root -w "$dir/$1.pcap" "udp portrange $lo-$((lo + 249))" \
            2>"$dir/$1-tcpdump.err" &
        _tcpdump=$!
        _i=0
        until grep -q "listening on" "$dir/$1-tcpdump.err"; do
            kill -0 $_tcpdump 2>/dev/null || skip "tcpdump cannot capture on lo: $(cat "$dir/$1-tcpdump.err")"
            _i=$((_i + 1))
            [ $_i -le 200 ] || fail "tcpdump did not start"
            sleep 0.05
        done
        timeout 30 "$FTM_SERVER" --scene default $common --id 1 ${2:+--security "$r/server"} --rate $rate \
            --duration 3 --log "$dir/$1-server.log" >"$dir/$1-server.out" 2>&1 &
        _s=$!
        wait_for "$dir/$1-server.log" "session '$session'" "server did not start" 100
        timeout 30 "$FTM_BOT" --role trainee --name "Alice Zebrafish" --script "$FTM_SCRIPTS/trainee1.bot" \
            $common --id 21 ${2:+--security "$r/station-alice"} --duration 10 >"$dir/$1-bot21.out" 2>&1 &
        _t=$!
        timeout 30 "$FTM_BOT" --role instructor --name "Dr Quixote Jansen" \
            --script "$here/../server/control-instructor.bot" $common --id 25 \
            ${2:+--security "$r/dr-jansen"} --duration 10 >"$dir/$1-bot25.out" 2>&1 &
        _ins=$!
        wait $_s || fail "$1: the server exited with $?"
        wait $_t
        wait $_ins
        grep -q "synced" "$dir/$1-bot21.out" || fail "$1: the trainee never synced"
        kill -INT $_tcpdump
        wait $_tcpdump
        [ "$(tcpdump -r "$dir/$1.pcap" 2>/dev/null | wc -l)" -ge 500 ] ||
            fail "$1: fewer than 500 datagrams captured: $(cat "$dir/$1-tcpdump.err")"
    }
    seen() { grep -a -q -F -- "$2" "$dir/$1.pcap"; }
    capture plain
    capture secured 1
    # an unsecured session shows the names, in its statuses and envelopes
    for w in "Alice Zebrafish" "Dr Quixote Jansen" "$session"; do
        seen plain "$w" || fail "the unsecured capture does not show '$w': the search is broken"
    done
    # secured: no payload (the session name is in every envelope, the
    # display names in the statuses), no bundle name (not in the subjects)
    for w in "Alice Zebrafish" "Quixote" "$session" station-alice dr-jansen; do
        ! seen secured "$w" || fail "a passive listener reads '$w' in the secured session"
    done
    # but in clear, as docs/deploy.md says: in the authentication handshake
    # the permissions (each one's subject, role, id and topic grants; the
    # certificates too, in base64), in discovery the host and program names
    for w in "<subject_name>CN=ftm.trainee.21,OU=trainee,O=FTM</subject_name>" \
        "<subject_name>CN=ftm.instructor.25,OU=instructor,O=FTM</subject_name>" \
        "<partition>ftm.trainee.21</partition>" "<topic>ftm_v1_session_control</topic>" \
        "-----BEGIN CERTIFICATE-----" __Hostname "$(uname -n)" __ProcessName ftm-server ftm-bot __Pid; do
        seen secured "$w" || fail "the secured capture does not show '$w' (docs/deploy.md says it does)"
    done
    echo "PASS secure capture: $(tcpdump -r "$dir/secured.pcap" 2>/dev/null | wc -l) datagrams secured," \
        "$(tcpdump -r "$dir/plain.pcap" 2>/dev/null | wc -l) unsecured"
    exit 0
fi

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
    # an expired certificate
    cp -r "$r/t11" "$dir/expired"
    openssl req -new -key "$dir/expired/key.pem" -subj "/O=FTM/OU=trainee/CN=ftm.trainee.11" -out "$dir/t.csr" 2>/dev/null
    expired "$r/identity_ca.pem" "$r/identity_ca.key" "$dir/t.csr" "$dir/expired/cert.pem"
    expect 3 "the certificate $dir/expired/cert.pem expired on Jan  2 00:00:00 2020 GMT" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/expired" --duration 2
    # a certificate of another room's identity CA in this room's bundle
    sec init "$dir/other"
    sec issue "$dir/other" t11 --role trainee --id 11
    cp -r "$r/t11" "$dir/foreign"
    cp "$dir/other/t11/cert.pem" "$dir/other/t11/key.pem" "$dir/foreign/"
    expect 3 "the certificate $dir/foreign/cert.pem is not signed by the identity CA in $dir/foreign/identity_ca.pem (a certificate of another room?)" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/foreign" --duration 2
    # a certificate signed by the permissions CA (ftm-security never makes
    # one: that CA signs documents only)
    cp -r "$r/t11" "$dir/bypca"
    openssl x509 -req -in "$dir/t.csr" -CA "$r/permissions_ca.pem" -CAkey "$r/permissions_ca.key" -CAcreateserial \
        -CAserial "$dir/pca.srl" -days 5 -out "$dir/bypca/cert.pem" >/dev/null 2>&1 || fail "openssl x509"
    expect 3 "the certificate $dir/bypca/cert.pem is signed by the permissions CA $dir/bypca/permissions_ca.pem, which signs documents only" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/bypca" --duration 2
    # permissions signed by another room's permissions CA; changed after signing
    cp -r "$r/t11" "$dir/perm"
    cp "$dir/other/t11/permissions.p7s" "$dir/perm/"
    expect 3 "$dir/perm/permissions.p7s is signed by 'CN=FTM permissions CA *,O=FTM', not by the permissions CA in $dir/perm/permissions_ca.pem (a document of another room?)" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/perm" --duration 2
    cp "$r/t11/permissions.p7s" "$dir/perm/"
    sed -i 's/<topic>ftm_v1_probe_input</<topic>ftm_v1_session_control</' "$dir/perm/permissions.p7s"
    expect 3 "$dir/perm/permissions.p7s does not verify with the permissions CA in $dir/perm/permissions_ca.pem: it was changed after signing" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/perm" --duration 2
    # governance signed by the identity CA
    cp -r "$r/t11" "$dir/gov"
    openssl smime -sign -text -in "$r/governance.xml" -out "$dir/gov/governance.p7s" -signer "$r/identity_ca.pem" \
        -inkey "$r/identity_ca.key" >/dev/null 2>&1 || fail "openssl smime"
    expect 3 "$dir/gov/governance.p7s is signed by the identity CA $dir/gov/identity_ca.pem, which signs certificates only" \
        "$FTM_BOT" --role observer $common --id 11 --security "$dir/gov" --duration 2
    # issue 26: a trainee signs itself an instructor's and a server's
    # permissions with its own key and certificate; then tries the identity
    # CA, its own certificate and a CA of the identity CA's key as the
    # permissions CA
    forge t12 instructor "$dir/forged-i"
    expect 3 "$dir/forged-i/permissions.p7s is signed by a participant's certificate ('CN=ftm.trainee.12,OU=trainee,O=FTM'), not by the permissions CA in $dir/forged-i/permissions_ca.pem: forged (a participant signing its own permissions, CVE-2023-24011)" \
        "$FTM_BOT" --role instructor --script "$here/../server/control-instructor.bot" $common \
        --id 12 --security "$dir/forged-i" --duration 2
    forge t12 server "$dir/forged-s"
    expect 3 "$dir/forged-s/permissions.p7s is signed by a participant's certificate ('CN=ftm.trainee.12,OU=trainee,O=FTM')" \
        "$FTM_SERVER" --check --scene default $common --id 12 --security "$dir/forged-s"
    cp "$dir/forged-s/identity_ca.pem" "$dir/forged-s/permissions_ca.pem"
    expect 3 "the identity CA $dir/forged-s/identity_ca.pem and the permissions CA $dir/forged-s/permissions_ca.pem are the same certificate: any participant could sign itself any permissions (CVE-2023-24011); use a bundle of a room made by 'ftm-security init' (two CAs); for a room of one CA, make a room of two CAs from it*'ftm-security upgrade ROOM NEW_ROOM'" \
        "$FTM_SERVER" --check --scene default $common --id 12 --security "$dir/forged-s"
    cp "$dir/forged-s/cert.pem" "$dir/forged-s/permissions_ca.pem"
    expect 3 "the CA $dir/forged-s/permissions_ca.pem is not self-signed" \
        "$FTM_SERVER" --check --scene default $common --id 12 --security "$dir/forged-s"
    openssl req -x509 -new -key "$r/identity_ca.key" -sha256 -days 5 -subj "/O=FTM/CN=FTM permissions CA" \
        -out "$dir/forged-s/permissions_ca.pem" >/dev/null 2>&1 || fail "openssl req"
    expect 3 "the identity CA $dir/forged-s/identity_ca.pem and the permissions CA $dir/forged-s/permissions_ca.pem are of the same key" \
        "$FTM_SERVER" --check --scene default $common --id 12 --security "$dir/forged-s"
    # another participant's permissions; a key others may read; wrong id; no bundle
    cp "$r/o13/permissions.p7s" "$dir/perm/"
    expect 3 "the permissions $dir/perm/permissions.p7s have no grant for 'CN=ftm.trainee.11,OU=trainee,O=FTM'" \
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
    # a room of one CA (an earlier ftm-security's): refused by every
    # program, saying why and how to make a room of two from it; the room
    # `upgrade` makes passes
    old_room "$dir/old" server:server:1:10 t11:trainee:11:10
    one_ca="is a bundle of a room with one CA (ca.pem) for identities and permissions, made by an earlier ftm-security: any participant of such a room can sign itself a server's or an instructor's permissions (CVE-2023-24011), so it is refused; make a room of two CAs from it, keeping each participant's name, role and id: 'ftm-security upgrade ROOM NEW_ROOM' (ROOM: the directory with ca.key), then use NEW_ROOM/NAME"
    expect 3 "$dir/old/server $one_ca" \
        "$FTM_SERVER" --scene default $common --id 1 --security "$dir/old/server" --duration 2
    expect 3 "$dir/old/t11 $one_ca" \
        "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
        --security "$dir/old/t11" --duration 2
    sec upgrade "$dir/old" "$dir/up"
    expect 0 "ftm-server --check: ok" \
        "$FTM_SERVER" --check --scene default $common --id 1 --security "$dir/up/server"
    # ftm-client takes it too (where it can open a window: under Xvfb)
    if [ -n "${FTM_CLIENT:-}" ] && command -v xvfb-run >/dev/null 2>&1 && command -v Xvfb >/dev/null 2>&1; then
        : >"$dir/x.xauth"
        ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0 expect 3 \
            "permissions in $r/o13/permissions.p7s to write topic ftm_v1_probe_input (probe input) in partition ftm.observer.13" \
            xvfb-run -a -f "$dir/x.xauth" -s "-screen 0 640x480x24" "$FTM_CLIENT" --role trainee \
            $common --id 13 --security "$r/o13" --size 320x200
        ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0 expect 3 "$dir/old/t11 $one_ca" \
            xvfb-run -a -f "$dir/x.xauth" -s "-screen 0 640x480x24" "$FTM_CLIENT" --role trainee \
            $common --id 11 --security "$dir/old/t11" --size 320x200
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
# issue 26's attack past the check: trainee 16's forged permissions of an
# instructor and of a server, its governance signed by itself too and the
# identity CA as its permissions CA (so that its own Cyclone takes them), in
# a Cyclone configuration of its making (ftm-rogue --cyclone); and, for
# ftm_wire's check, its genuine bundle with the role file changed
sec issue "$r" t16 --role trainee --id 16
t16=$(cd "$r/t16" && pwd)
for role in instructor server; do
    f=$dir/elevated-$role
    forge t16 $role "$f"
    openssl smime -sign -text -in "$r/governance.xml" -out "$f/governance.p7s" -signer "$f/cert.pem" \
        -inkey "$f/key.pem" >/dev/null 2>&1 || fail "openssl smime"
    f=$(cd "$f" && pwd)
    sed -e "s|$t16/permissions_ca.pem|$f/identity_ca.pem|" -e "s|$t16/|$f/|g" "$t16/cyclonedds-security.xml" >"$f.xml"
    grep -q "<PermissionsCA>file:$f/identity_ca.pem</PermissionsCA>" "$f.xml" &&
        grep -q "<Permissions>file:$f/permissions.p7s</Permissions>" "$f.xml" || fail "the forger's Cyclone configuration"
    cp -r "$r/t16" "$f.check"
    echo $role >"$f.check/role"
done
# the server's Cyclone says whom it refuses (warnings, to a file). It runs
# 9 s: in an ASan build the impersonator's writers reached it only 2.8 s
# after they started (the secured matches of each topic, one by one)
sed "s|<Verbosity>none</Verbosity>|<Verbosity>warning</Verbosity><OutputFile>$dir/server-dds.log</OutputFile>|" \
    "$FTM_CONFIG" >"$dir/server.xml"
grep -q "server-dds.log" "$dir/server.xml" || fail "$FTM_CONFIG has no <Verbosity>none</Verbosity> to replace"
timeout 40 "$FTM_SERVER" --scene default --session $session --domain $domain --config "$dir/server.xml" \
    --id 1 --security "$r/server" --rate $rate \
    --duration 9 --record "$dir/session.rec" --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
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
timeout 30 "$FTM_BOT" --role trainee --script "$here/secure-trainee.bot" $common --id 11 \
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
timeout 30 "$FTM_ROGUE" $common --id 12 --impersonate 11 --for 3 --security "$r/t12" \
    >"$dir/imp.out" 2>"$dir/imp.err" &
imp=$!
for role in instructor server; do
    timeout 30 "$FTM_ROGUE" $common --id 16 --elevated $role --for 3 --cyclone "$dir/elevated-$role.xml" \
        --security "$dir/elevated-$role.check" >"$dir/elevated-$role.out" 2>"$dir/elevated-$role.err" &
    eval "e_$role=\$!"
done

wait $server || fail "server exited with $? (displaced by a status claiming role server?)"
wait $imp || fail "the impersonating trainee exited with $?"
# shellcheck disable=SC2154
wait "$e_instructor" || fail "the trainee elevated to instructor exited with $?"
# shellcheck disable=SC2154
wait "$e_server" || fail "the trainee elevated to server exited with $?"
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
# the forged permissions: the server's Cyclone refused both forgers, their
# signer not chaining to the permissions CA (with one CA for both it would);
# no command of theirs applied, the server not displaced (above: the
# trainee's expectations, the server's exit status and final hash)
grep -q "rogue: elevated instructor 16: its session control matched by 0 readers at most; [1-9][0-9]* commands sent, 0 answered, 0 applied" \
    "$dir/elevated-instructor.out" || fail "the elevated instructor: $(cat "$dir/elevated-instructor.out")"
grep -q "rogue: elevated server 16: its status matched by 0 readers at most; [1-9][0-9]* statuses sent" \
    "$dir/elevated-server.out" || fail "the elevated server: $(cat "$dir/elevated-server.out")"
refused=$(sed -n 's/.*Could not get remote participant \([0-9a-f:]*\) permissions from plugin: .*PKCS7_verify:certificate verify error.*unable to get local issuer certificate.*/\1/p' \
    "$dir/server-dds.log" | sort -u | wc -l)
[ "$refused" -eq 2 ] || fail "the server's Cyclone refused $refused forged permissions, want 2: $(cat "$dir/server-dds.log")"
! grep -q "participant 16\|instructor 16\|already served" "$dir/server.log" || fail "the server heard a forger"
! grep -q "no longer confirms\|is taken" "$dir/bot11.err" || fail "trainee 11 lost its id"
# the session replays bit-identically from its recording
timeout 30 "$FTM_SERVER" --replay "$dir/session.rec" >"$dir/replay.out" 2>&1 ||
    fail "the recording does not replay: $(tail -n 3 "$dir/replay.out")"
echo "PASS secure session: $want; $(grep -o 'synced at tick [0-9]*' "$dir/bot11.err"); $(grep -o 'latency mean .* max [0-9]* us' "$dir/bot11.err")"
