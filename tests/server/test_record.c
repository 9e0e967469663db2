/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file (server/record.h): round trip, the reader's
 * clear errors on truncated, oversized and corrupted files and headers, and
 * the writer's 1 MiB buffer. */
#include "depth_ctl.h" /* FTM_DEPTH_CTL_MAX */
#include "record.h"

#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmocka.h>

static char path[256], bad[256];

static void sample_header(ftm_record_header *h)
{
    memset(h, 0, sizeof *h);
    snprintf(h->scene_id, sizeof h->scene_id, "default");
    for (int i = 0; i < 32; i++)
        h->digest[i] = (uint8_t)i;
    h->digest_len = 32;
    h->tick_rate_hz = 1000;
    h->depth_max = 8;
    h->depth_min = 2;
    h->node_count = 1728;
}

static void write_sample(void)
{
    ftm_record_header h;
    sample_header(&h);
    h.max_penetration = 0.0125;
    snprintf(h.session, sizeof h.session, "ward-3");
    ftm_record_writer *w = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_create(path, &h, &w, &err), FTM_OK);
    uint8_t payload[300];
    for (int i = 0; i < 300; i++)
        payload[i] = (uint8_t)(i * 7);
    for (int i = 0; i < 10; i++) {
        ftm_record_entry e = {.tick = (uint64_t)i, .kind = 3, .sender = 1, .incoming = i % 2,
                              .gone = i == 9, .time_ns = (uint64_t)i * 1000, .payload = payload,
                              .size = (size_t)(i == 9 ? 0 : 1 + i * 30)};
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    assert_true(ftm_record_bytes(w) > 8);
    assert_int_equal(ftm_record_close(w, &err), FTM_OK);
}

static long file_size(const char *p)
{
    FILE *f = fopen(p, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fclose(f);
    return n;
}

/* Copies the first n bytes of path to bad, with byte at `at` xor'ed by x. */
static void copy_bad(long n, long at, uint8_t x)
{
    FILE *in = fopen(path, "rb"), *out = fopen(bad, "wb");
    assert_non_null(in);
    assert_non_null(out);
    for (long i = 0; i < n; i++) {
        int c = fgetc(in);
        assert_true(c != EOF);
        fputc(i == at ? (c ^ x) : c, out);
    }
    fclose(in);
    fclose(out);
}

/* Reads a whole file: 0 if clean, the error code otherwise (message in err). */
static int read_all(const char *p, int *entries, ftm_error *err)
{
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    int rc = ftm_record_open(p, &h, &r, err);
    *entries = 0;
    if (rc)
        return rc;
    ftm_record_entry e;
    while ((rc = ftm_record_next(r, &e, err)) == 1)
        (*entries)++;
    ftm_record_close_reader(r);
    return rc;
}

static void round_trip(void **state)
{
    (void)state;
    write_sample();
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_open(path, &h, &r, &err), FTM_OK);
    assert_string_equal(h.scene_id, "default");
    assert_int_equal(h.digest_len, 32);
    assert_int_equal(h.digest[31], 31);
    assert_int_equal(h.tick_rate_hz, 1000);
    assert_int_equal(h.depth_max, 8);
    assert_int_equal(h.depth_min, 2);
    assert_int_equal(h.node_count, 1728);
    assert_true(h.max_penetration == 0.0125);
    assert_string_equal(h.session, "ward-3");
    ftm_record_entry e;
    for (int i = 0; i < 10; i++) {
        assert_int_equal(ftm_record_next(r, &e, &err), 1);
        assert_int_equal(e.tick, (uint64_t)i);
        assert_int_equal(e.kind, 3);
        assert_int_equal(e.incoming, i % 2);
        assert_int_equal(e.gone, i == 9);
        assert_int_equal(e.index, (uint64_t)i + 1);
        assert_int_equal(e.size, (size_t)(i == 9 ? 0 : 1 + i * 30));
        for (size_t k = 0; k < e.size; k++)
            assert_int_equal(e.payload[k], (uint8_t)(k * 7));
    }
    assert_int_equal(ftm_record_next(r, &e, &err), 0);
    ftm_record_close_reader(r);
}

static void truncated_everywhere(void **state)
{
    (void)state;
    write_sample();
    long n = file_size(path);
    int entries = 0;
    ftm_error err = {0, ""};
    assert_int_equal(read_all(path, &entries, &err), 0);
    assert_int_equal(entries, 10);
    /* every cut is an error, except those that fall between two entries,
     * which leave fewer entries (a recording stopped by a crash is usable up
     * to its last whole entry) */
    int clean_cuts = 0;
    for (long cut = 0; cut < n; cut++) {
        copy_bad(cut, -1, 0);
        memset(&err, 0, sizeof err);
        int rc = read_all(bad, &entries, &err);
        if (rc == 0) {
            clean_cuts++;
            assert_true(entries < 10);
            continue;
        }
        assert_int_equal(rc, FTM_EPARSE);
        assert_non_null(strstr(err.message, bad));
        if (cut == 0) /* what a server killed before its first write leaves */
            assert_non_null(strstr(err.message, "empty file (0 bytes)"));
        else
            assert_true(strstr(err.message, "truncated") != NULL);
    }
    assert_int_equal(clean_cuts, 10); /* after the header and after entries 1..9 */
}

static void corrupted(void **state)
{
    (void)state;
    write_sample();
    long n = file_size(path);
    int entries = 0;
    ftm_error err = {0, ""};
    /* the magic */
    copy_bad(n, 0, 0x20);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "not an FTM recording"));
    /* the header's length prefix: now far too long for the file */
    copy_bad(n, 8, 0x40);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    /* an overlong varint length */
    FILE *f = fopen(bad, "wb");
    fwrite(FTM_RECORD_MAGIC "\xff\xff\xff\xff\xff\xff\x01", 1, 15, f);
    fclose(f);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "length prefix too long"));
    /* a 4 GiB length */
    f = fopen(bad, "wb");
    fwrite(FTM_RECORD_MAGIC "\x80\x80\x80\x80\x10", 1, 13, f);
    fclose(f);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "out of range"));
    /* flipping any single byte never crashes; it is an error or changes data */
    int errors = 0;
    for (long at = 8; at < n; at++) {
        copy_bad(n, at, 0xa5);
        if (read_all(bad, &entries, &err) != 0) {
            errors++;
            assert_true(err.message[0] != '\0');
        }
    }
    assert_true(errors > 0);
    /* an entry of a kind this build does not know (a newer server's) */
    ftm_record_header h;
    sample_header(&h);
    ftm_record_writer *w = NULL;
    assert_int_equal(ftm_record_create(bad, &h, &w, &err), FTM_OK);
    ftm_record_entry e = {.tick = 1, .kind = 3, .sender = 1, .payload = (const uint8_t *)"x",
                          .size = 1};
    assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    e.kind = 99;
    assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    assert_int_equal(ftm_record_close(w, &err), FTM_OK);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_int_equal(entries, 1);
    if (!strstr(err.message, "entry 2 at byte ") ||
        !strstr(err.message, "kind 99 is unknown to this build (1..7): recorded by a newer"))
        fail_msg("unknown kind: %s", err.message);
    /* a directory: the read fails, said as such */
    assert_int_equal(read_all(".", &entries, &err), FTM_EIO);
    if (!strstr(err.message, ".: cannot read: Is a directory"))
        fail_msg("directory: %s", err.message);
    /* a missing file */
    assert_int_equal(read_all("/nonexistent/ftm.rec", &entries, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "cannot open"));
}

/* A header deeper than any server runs (depth_ctl.h) is refused at the
 * header, by file and field, not later by the depth controller. */
static void depth_beyond_the_controller(void **state)
{
    (void)state;
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    ftm_error err = {0, ""};
    for (int32_t depth = FTM_DEPTH_CTL_MAX; depth <= FTM_DEPTH_CTL_MAX + 1; depth++) {
        sample_header(&h);
        h.depth_max = depth;
        ftm_record_writer *w = NULL;
        assert_int_equal(ftm_record_create(path, &h, &w, &err), FTM_OK);
        assert_int_equal(ftm_record_close(w, &err), FTM_OK);
        int rc = ftm_record_open(path, &h, &r, &err);
        ftm_record_close_reader(r);
        r = NULL;
        if (depth == FTM_DEPTH_CTL_MAX) {
            assert_int_equal(rc, FTM_OK);
            assert_int_equal(h.depth_max, FTM_DEPTH_CTL_MAX);
            continue;
        }
        assert_int_equal(rc, FTM_EPARSE);
        assert_non_null(strstr(err.message, path));
        assert_non_null(strstr(err.message, "header: depth_max 1000001 is above 1000000"));
    }
}

/* Entries stay in the 1 MiB buffer: nothing reaches the file before a MiB
 * is written (glibc ignores the size of a buffer it allocates itself and
 * writes every 4 KiB), all of it after closing. */
static void one_write_per_mib(void **state)
{
    (void)state;
    ftm_record_header h;
    sample_header(&h);
    ftm_record_writer *w = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_create(path, &h, &w, &err), FTM_OK);
    static uint8_t payload[1000];
    for (int i = 0; i < 500; i++) { /* about 0.5 MiB */
        ftm_record_entry e = {.tick = (uint64_t)i, .kind = 3, .sender = 1, .payload = payload,
                              .size = sizeof payload};
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    uint64_t bytes = ftm_record_bytes(w);
    assert_true(bytes > 500000 && bytes < (1u << 20));
    assert_int_equal(file_size(path), 0);
    assert_int_equal(ftm_record_close(w, &err), FTM_OK);
    assert_int_equal(file_size(path), (long)bytes);
}

/* ftm_record_flush hands the buffer to the file; a write that fails later
 * (here a file size limit, as a full disk) stops the writer, and closing it
 * cuts the file back to the last flush: whole entries, readable to the end. */
static void write_error_cuts_back(void **state)
{
    (void)state;
    ftm_record_header h;
    sample_header(&h);
    ftm_record_writer *w = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_create(path, &h, &w, &err), FTM_OK);
    static uint8_t payload[1000];
    ftm_record_entry e = {.kind = 3, .sender = 1, .payload = payload, .size = sizeof payload};
    for (int i = 0; i < 20; i++) {
        e.tick = (uint64_t)i;
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    assert_int_equal(ftm_record_flush(w, &err), FTM_OK);
    uint64_t flushed = ftm_record_bytes(w);
    assert_int_equal(file_size(path), (long)flushed); /* on disk now, not at 1 MiB */
    /* room for about 15 more entries: the write of the next 40 fails in one */
    struct rlimit was, lim;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &was), 0);
    lim = was;
    lim.rlim_cur = (rlim_t)flushed + 15500;
    void (*old)(int) = signal(SIGXFSZ, SIG_IGN);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    int rc = FTM_OK;
    for (int i = 20; i < 60 && rc == FTM_OK; i++) {
        e.tick = (uint64_t)i;
        rc = ftm_record_write(w, &e, &err);
    }
    if (rc == FTM_OK)
        rc = ftm_record_flush(w, &err);
    assert_int_equal(rc, FTM_EIO);
    assert_non_null(strstr(err.message, "write failed: File too large"));
    assert_int_equal(ftm_record_write(w, &e, &err), FTM_EIO); /* stopped */
    assert_int_equal(ftm_record_close(w, &err), FTM_EIO);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &was), 0);
    signal(SIGXFSZ, old);
    assert_int_equal(file_size(path), (long)flushed);
    int entries = 0;
    assert_int_equal(read_all(path, &entries, &err), 0);
    assert_int_equal(entries, 20);
}

int main(void)
{
    snprintf(path, sizeof path, "/tmp/ftm-test-record-%d.rec", (int)getpid());
    snprintf(bad, sizeof bad, "/tmp/ftm-test-record-%d.bad", (int)getpid());
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(round_trip),
        cmocka_unit_test(truncated_everywhere),
        cmocka_unit_test(corrupted),
        cmocka_unit_test(depth_beyond_the_controller),
        cmocka_unit_test(one_write_per_mib),
        cmocka_unit_test(write_error_cuts_back),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    unlink(path);
    unlink(bad);
    return rc;
}
