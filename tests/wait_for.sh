# SPDX-License-Identifier: GPL-3.0-or-later
# shellcheck shell=sh
# Sourced by the shell tests. wait_for FILE PATTERN WHAT [TRIES]: polls FILE
# every 0.05 s until grep finds PATTERN (a basic regular expression) in it;
# after TRIES polls (default 200, i.e. 10 s) calls the test's own
# fail "WHAT", which prints its logs and exits.
wait_for() {
    _wait_i=0
    until grep -q -- "$2" "$1" 2>/dev/null; do
        _wait_i=$((_wait_i + 1))
        [ "$_wait_i" -gt "${4:-200}" ] && fail "$3"
        sleep 0.05
    done
}
