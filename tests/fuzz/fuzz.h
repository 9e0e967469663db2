/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz targets: each file defines LLVMFuzzerTestOneInput for one parser of
 * untrusted input. Built two ways (tests/fuzz/CMakeLists.txt): with clang's
 * libFuzzer for campaigns (tests/fuzz/run.sh), and with fuzz_replay.c as a
 * plain program that CTest runs over the committed corpus in every build,
 * ASan+UBSan included. A target aborts (fuzz_check) when a property fails,
 * so a finding is a crash, a sanitizer report or a failed property. */
#ifndef FTM_FUZZ_H
#define FTM_FUZZ_H

#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Writes data to a file named `name` in this process's scratch directory
 * (made on first use under $TMPDIR or /tmp, removed at exit) and returns
 * its path (static storage, overwritten by the next call with that name). */
const char *fuzz_write_file(const char *name, const void *data, size_t size);

/* Aborts with a message naming the target and the failed property. */
#define fuzz_check(cond)                                                                  \
    do {                                                                                  \
        if (!(cond))                                                                      \
            fuzz_fail(__FILE__, __LINE__, #cond);                                         \
    } while (0)
_Noreturn void fuzz_fail(const char *file, int line, const char *what);

#endif
