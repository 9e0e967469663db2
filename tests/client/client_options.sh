#!/bin/sh
# ftm-client refuses out-of-range options with a message naming them, and
# exits 2 before it opens a window or joins anything (no display needed:
# every run also names a Cyclone configuration that does not exist).
set -u
fail() { echo "FAIL: $*"; exit 1; }
nodds=/nonexistent/ftm-test-cyclonedds.xml
. "$(cd "$(dirname "$0")" && pwd)/../refused.sh"
refused() { # expected-text options...
    want=$1
    shift
    refused_by "$want" "$FTM_CLIENT" --config $nodds "$@"
}
# integers: range-checked, never cast to 32 bits nor read unsigned from a sign
refused "--domain must be an integer in 0..4294967294 (got '-1')" --domain -1
refused "--domain must be an integer in 0..4294967294 (got '4294967295')" --domain 4294967295
refused "--id must be an integer in 0..4294967295 (got '-1')" --id -1
refused "--id must be an integer in 0..4294967295 (got '4294967297')" --id 4294967297
refused "--msaa must be an integer in 0..16 (got '17')" --msaa 17
refused "--msaa must be an integer in 0..16 (got '4x')" --msaa 4x
refused "--swap-interval must be an integer in -1..8 (got '4294967297')" --swap-interval 4294967297
refused "--screenshot-contact must be an integer in 0..9223372036854775807 (got '-5')" \
    --screenshot-contact -5
refused "--screenshot-tick must be an integer in 0..9223372036854775807 (got ' 7')" \
    --screenshot-tick " 7"
# times that would wrap when cast to nanoseconds
for v in 1e300 1e10 inf nan -1; do
    refused "--duration, --bench, --screenshot-after in [0, 1e+09] s" --duration "$v"
done
for v in 0 1e10 inf; do
    refused "--server-timeout, --screenshot-timeout must be in (0, 1e+09] s" --server-timeout "$v"
done
exit 0
