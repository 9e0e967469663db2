/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Wire decoder (ftm_wire_decode): what a peer sends. Input: byte 0 picks
 * the kind (mod 8: 0 is an unknown kind, 7 the control reply), byte 1 the
 * mesh size the indices are checked against (0: unknown), the rest is the
 * payload.
 * Properties: a rejected payload gets a negative code and a message; an
 * accepted one encodes, and the encoding decodes and encodes to the same
 * bytes (what the server relays is what it understood). */
#include "fuzz.h"

#include "ftm/wire.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    int kind = data[0] % 8;
    ftm_wire_limits limits;
    memset(&limits, 0, sizeof limits);
    limits.node_count = data[1] ? (int32_t)data[1] * 16 : 0;
    const uint8_t *payload = data + 2;
    size_t n = size - 2;

    ftm_wire_msg msg;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_wire_decode(kind, payload, n, &limits, &msg, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && err.message[0] != '\0');
        fuzz_check(strcmp(ftm_err_name(rc), "unknown") != 0); /* a code of the one list */
        fuzz_check(msg.storage == NULL);
        return 0;
    }
    fuzz_check(kind >= FTM_WIRE_KIND_MIN && kind <= FTM_WIRE_KIND_MAX);
    fuzz_check((int)msg.kind == kind);

    uint8_t *once = NULL, *twice = NULL;
    size_t once_size = 0, twice_size = 0;
    rc = ftm_wire_encode(&msg, &once, &once_size, &err);
    fuzz_check(rc == FTM_OK);
    ftm_wire_msg back;
    rc = ftm_wire_decode(kind, once, once_size, &limits, &back, &err);
    fuzz_check(rc == FTM_OK);
    rc = ftm_wire_encode(&back, &twice, &twice_size, &err);
    fuzz_check(rc == FTM_OK);
    fuzz_check(once_size == twice_size && memcmp(once, twice, once_size) == 0);
    free(once);
    free(twice);
    ftm_wire_msg_free(&back);
    ftm_wire_msg_free(&msg);
    return 0;
}
