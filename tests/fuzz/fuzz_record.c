/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recordings (ftm-server --replay FILE): a file that may be
 * truncated, corrupted or not a recording at all. Properties: open and each
 * entry either fail with a message or give entries in file order, each
 * within the file and the entry size limit; the reader ends (at most one
 * entry per byte of the file). */
#include "fuzz.h"

#include "record.h"

#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write_file("f.rec", data, size);
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_record_open(path, &h, &r, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && r == NULL && err.message[0] != '\0');
        return 0;
    }
    fuzz_check(h.digest_len >= 0 && h.digest_len <= (int32_t)sizeof h.digest);
    fuzz_check(memchr(h.scene_id, 0, sizeof h.scene_id) != NULL);
    uint64_t last_offset = 0, last_index = 0;
    for (size_t i = 0;; i++) {
        fuzz_check(i <= size);
        ftm_record_entry e;
        rc = ftm_record_next(r, &e, &err);
        if (rc <= 0) {
            fuzz_check(rc == 0 || err.message[0] != '\0');
            break;
        }
        fuzz_check(e.offset > last_offset && e.offset < size);
        fuzz_check(e.index == last_index + 1);
        fuzz_check(e.size <= FTM_RECORD_ENTRY_MAX && e.offset + e.size <= size);
        fuzz_check(e.size == 0 || e.payload != NULL);
        last_offset = e.offset;
        last_index = e.index;
    }
    ftm_record_close_reader(r);
    return 0;
}
