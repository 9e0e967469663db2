# SPDX-License-Identifier: GPL-3.0-or-later
# shellcheck shell=sh
# Sourced by the option tests. refused_by WANT PROGRAM ARGS...: runs PROGRAM
# with ARGS (no display, at most 20 s) and calls the test's own fail unless
# it exits with status 2 (a usage error) and says WANT.
refused_by() {
    _want=$1
    shift
    _out=$(DISPLAY= WAYLAND_DISPLAY= timeout 20 "$@" 2>&1)
    _rc=$?
    [ $_rc -eq 2 ] || fail "$*: exit status $_rc, not 2 (usage): $_out"
    case $_out in *"$_want"*) ;; *) fail "$*: no '$_want' in: $_out" ;; esac
}
