#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The tree's license (docs/licenses.md): LICENSE holds the GPL version 3,
# and every source file of the project (C, headers, the protocol and IDL,
# CMake, shell and Python scripts) names GPL-3.0-or-later in an SPDX line
# among its first three. Prints each file that does not.
#   sh test_license.sh SOURCE_DIR
set -u
src=${1:?source directory}
cd "$src" || exit 2
grep -q "GNU GENERAL PUBLIC LICENSE" LICENSE 2>/dev/null && grep -q "Version 3, 29 June 2007" LICENSE ||
    { echo "FAIL: LICENSE is not the GNU GPL version 3"; exit 1; }
missing=$(find common server client bot session tools tests proto deploy .ci CMakeLists.txt \
        -path tests/fuzz/corpus -prune -o -path '*/build' -prune -o -type f \
        \( -name '*.c' -o -name '*.h' -o -name '*.cpp' -o -name '*.inc' -o -name '*.proto' \
           -o -name '*.idl' -o -name '*.sh' -o -name '*.py' -o -name '*.cmake' \
           -o -name CMakeLists.txt -o -name 'ftm-*' -o -name run \) -print 2>/dev/null |
    grep -v '\.service\.in$\|\.conf\.example$' |
    while read -r f; do
        head -n 3 "$f" | grep -q "SPDX-License-Identifier: GPL-3.0-or-later" || echo "$f"
    done)
if [ -n "$missing" ]; then
    echo "FAIL: no 'SPDX-License-Identifier: GPL-3.0-or-later' in the first three lines of:"
    echo "$missing"
    exit 1
fi
echo "ok: LICENSE is the GPL v3; every source file names GPL-3.0-or-later"
