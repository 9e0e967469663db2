/* SPDX-License-Identifier: GPL-3.0-or-later */
/* client-badframe: publishes malformed tick frames into a session, for the
 * client's bad-input test (tests/client_gl/client_gl.sh, mode badinput).
 * Waits until a tick frame reader (the client) has matched, then sends
 * three payloads that cannot decode: random bytes, a truncated varint and
 * a length running past the end. Exit 0 when sent, 1 when nobody matched. */
#include "ftm/wire.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int main(int argc, char **argv)
{
    const char *config = NULL, *session = "ftm";
    uint32_t domain = 0, id = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        const char *a = argv[i], *v = argv[i + 1];
        char *end = NULL;
        errno = 0;
        if (strcmp(a, "--config") == 0)
            config = v;
        else if (strcmp(a, "--session") == 0)
            session = v;
        else if (strcmp(a, "--domain") == 0)
            domain = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--id") == 0)
            id = (uint32_t)strtoul(v, &end, 10);
        else {
            fprintf(stderr, "client-badframe: unknown option %s\n", a);
            return 2;
        }
        if (end && (*end || errno)) {
            fprintf(stderr, "client-badframe: %s: bad number '%s'\n", a, v);
            return 2;
        }
    }
    if (argc % 2 != 1 || id == 0) {
        fprintf(stderr, "usage: client-badframe --id N [--config F] [--domain D] [--session S]\n");
        return 2;
    }
    ftm_wire_transport_def wd;
    memset(&wd, 0, sizeof wd);
    wd.config = config;
    wd.domain_id = domain;
    wd.session = session;
    wd.participant_id = id;
    wd.publish = FTM_WIRE_KIND_BIT(FTM_WIRE_TICK);
    ftm_error err = {0, ""};
    ftm_wire_transport *t;
    if (ftm_wire_transport_create(&wd, &t, &err)) {
        fprintf(stderr, "client-badframe: %s\n", err.message);
        return 1;
    }
    /* the server's other participants (bots, the client) read tick frames */
    if (ftm_wire_wait_matched(t, FTM_WIRE_TICK, 1, 10LL * 1000000000LL, &err)) {
        fprintf(stderr, "client-badframe: %s\n", err.message);
        ftm_wire_transport_destroy(t);
        return 1;
    }
    uint8_t junk[61];
    uint32_t lcg = 777u;
    for (size_t i = 0; i < sizeof junk; i++) {
        lcg = lcg * 1103515245u + 12345u;
        junk[i] = (uint8_t)(lcg >> 23);
    }
    const uint8_t truncated[] = {0x08, 0x01, 0x10, 0xff, 0xff};     /* varint without its end */
    const uint8_t overrun[] = {0x08, 0x01, 0x2a, 0x7f, 0x01, 0x02}; /* length 127, 2 bytes */
    const struct {
        const void *p;
        size_t n;
        const char *what;
    } bad[3] = {{junk, sizeof junk, "random bytes"},
                {truncated, sizeof truncated, "truncated varint"},
                {overrun, sizeof overrun, "length past the end"}};
    for (int i = 0; i < 3; i++) {
        if (ftm_wire_publish_raw(t, FTM_WIRE_TICK, bad[i].p, bad[i].n, &err))
            fprintf(stderr, "client-badframe: %s\n", err.message);
        else
            printf("client-badframe: sent %s\n", bad[i].what);
        struct timespec ts = {0, 100000000};
        nanosleep(&ts, NULL);
    }
    fflush(stdout);
    ftm_wire_flush(t, 1000000000LL, NULL);
    ftm_wire_transport_destroy(t);
    return 0;
}
