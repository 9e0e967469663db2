/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file (server/record.h): round trip, the reader's
 * clear errors on truncated, oversized, damaged and corrupted files and
 * headers (every bit flip detected), the writer's chunks of < 100 ms,
 * what it keeps when a write fails, and a lesson in several files. */
#include "crc32c.h"
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
                              .gone = i == 9, .time_ns = (uint64_t)i * 30000000u, /* 30 ms */
                              .payload = payload,
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

/* bad: the magic, then one chunk of one entry whose bytes are body[0..n),
 * the checksums right. */
static void forge(const char *body, size_t n)
{
    uint8_t head[FTM_RECORD_CHUNK_HEAD] = {'F', 'T', 'M', 'C', (uint8_t)n, 0, 0, 0, 1, 0, 0, 0};
    uint32_t c = ftm_crc32c(0, body, n);
    for (int i = 0; i < 4; i++)
        head[12 + i] = (uint8_t)(c >> (8 * i));
    c = ftm_crc32c(0, head, 32);
    for (int i = 0; i < 4; i++)
        head[32 + i] = (uint8_t)(c >> (8 * i));
    FILE *f = fopen(bad, "wb");
    assert_non_null(f);
    fwrite(FTM_RECORD_MAGIC, 1, 8, f);
    fwrite(head, 1, sizeof head, f);
    fwrite(body, 1, n, f);
    fclose(f);
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
    /* every cut is an error, except those that fall between two chunks,
     * which leave fewer entries (a recording stopped by a crash or a full
     * disk is usable up to its last whole chunk) */
    int clean_cuts = 0;
    for (long cut = 0; cut < n; cut++) {
        copy_bad(cut, -1, 0);
        memset(&err, 0, sizeof err);
        int rc = read_all(bad, &entries, &err);
        if (rc == 0) {
            clean_cuts++;
            assert_true(entries == 0 || entries == 4 || entries == 8);
            continue;
        }
        assert_int_equal(rc, FTM_EPARSE);
        assert_non_null(strstr(err.message, bad));
        if (cut == 0) /* what a server killed before its first write leaves */
            assert_non_null(strstr(err.message, "empty file (0 bytes)"));
        else if (cut > 8 && !strstr(err.message, "truncated: ") &&
                 !strstr(err.message, "cut while it was written"))
            fail_msg("cut at %ld: %s", cut, err.message);
        else if (cut <= 8)
            assert_non_null(strstr(err.message, "truncated"));
    }
    /* after the header's chunk and the chunks of 30 ms entries 0..3, 4..7 */
    assert_int_equal(clean_cuts, 3);
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
    /* a recording of format 1 (before checksums): refused by its version */
    FILE *f = fopen(bad, "wb");
    fwrite("FTMREC1\n\x05", 1, 9, f);
    fclose(f);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EVERSION);
    if (!strstr(err.message, "recording format version 1 (no checksums); this build reads "
                             "version 2 only"))
        fail_msg("format 1: %s", err.message);
    /* the header's length prefix: now far too long for its chunk (damage) */
    copy_bad(n, 8 + FTM_RECORD_CHUNK_HEAD, 0x40);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "damaged"));
    /* chunks whose checksums are right but whose entries are not (a
     * writer's bug or a forgery): an overlong varint length, a 4 GiB one */
    forge("\xff\xff\xff\xff\xff\xff\x01", 7);
    assert_int_equal(read_all(bad, &entries, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "malformed: entry 0 at byte 44"));
    assert_non_null(strstr(err.message, "length prefix too long"));
    forge("\x80\x80\x80\x80\x10\x00\x00", 7);
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

/* The CRC-32C check value, and one flipped bit changes it. */
static void crc32c_check_value(void **state)
{
    (void)state;
    assert_int_equal(ftm_crc32c(0, "123456789", 9), 0xe3069283u);
    assert_int_equal(ftm_crc32c(ftm_crc32c(0, "1234", 4), "56789", 5), 0xe3069283u);
    assert_int_equal(ftm_crc32c(0, "", 0), 0);
    assert_true(ftm_crc32c(0, "123456789", 9) != ftm_crc32c(0, "023456789", 9));
    /* the instruction (where there is one) and the table agree, at every
     * length and alignment */
    static uint8_t b[4099];
    for (size_t i = 0; i < sizeof b; i++)
        b[i] = (uint8_t)(i * 2654435761u >> 13);
    for (size_t at = 0; at < 9; at++)
        for (size_t n = 0; at + n <= sizeof b; n += n < 40 ? 1 : 509)
            assert_int_equal(ftm_crc32c(7, b + at, n), ftm_crc32c_table(7, b + at, n));
    assert_int_equal(ftm_crc32c_table(0, "123456789", 9), 0xe3069283u);
}

/* Every single bit flipped, one at a time, in a recording of 3 chunks: each
 * one is refused (100 %), after the magic as damage naming the entry or
 * chunk and its byte; and the entries before a damaged one in its chunk are
 * handed out first (what --upto-damage replays). */
static void every_bit_flip_detected(void **state)
{
    (void)state;
    write_sample();
    const long n = file_size(path);
    long detected = 0, damaged = 0, named = 0;
    for (long at = 0; at < n; at++) {
        for (int bit = 0; bit < 8; bit++) {
            copy_bad(n, at, (uint8_t)(1u << bit));
            ftm_error err = {0, ""};
            ftm_record_header h;
            ftm_record_reader *r = NULL;
            int rc = ftm_record_open(bad, &h, &r, &err);
            int entries = 0;
            bool dmg = false;
            if (rc == FTM_OK) {
                ftm_record_entry e;
                while ((rc = ftm_record_next(r, &e, &err)) == 1)
                    entries++;
                dmg = ftm_record_damaged(r);
                ftm_record_close_reader(r);
            }
            if (rc == 0)
                fail_msg("byte %ld bit %d flipped: read as intact (%d entries)", at, bit, entries);
            detected++;
            assert_non_null(strstr(err.message, bad));
            if (at < 8)
                continue; /* the magic: "not an FTM recording" or its version */
            assert_non_null(strstr(err.message, "damaged"));
            damaged++;
            if (rc != FTM_OK && r) /* in an entry's chunk: said by the reader as damage */
                assert_true(dmg);
            if (strstr(err.message, " at byte "))
                named++;
        }
    }
    assert_int_equal(detected, n * 8);
    print_message("every bit flip detected: %ld of %ld\n", detected, n * 8);
    assert_int_equal(damaged, (n - 8) * 8);
    assert_int_equal(named, damaged);
    /* a flip in the third entry of the second chunk: entries 1..4 (the
     * first chunk) and 5, 6 come before it */
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_open(path, &h, &r, &err), FTM_OK);
    ftm_record_entry e;
    uint64_t at7 = 0;
    while (ftm_record_next(r, &e, &err) == 1)
        if (e.index == 7)
            at7 = e.offset;
    ftm_record_close_reader(r);
    assert_true(at7 > 0);
    copy_bad(n, (long)at7 + 3, 0x10);
    assert_int_equal(ftm_record_open(bad, &h, &r, &err), FTM_OK);
    int entries = 0;
    int rc;
    while ((rc = ftm_record_next(r, &e, &err)) == 1)
        entries++;
    assert_int_equal(rc, FTM_EPARSE);
    assert_true(ftm_record_damaged(r));
    if (entries != 6)
        fail_msg("%d entries before the damage: %s", entries, err.message);
    char want[128];
    snprintf(want, sizeof want, "damaged: entry 7 at byte %llu (chunk 3, ticks 4..7, after tick 5): "
             "its checksum differs", (unsigned long long)at7);
    if (!strstr(err.message, want))
        fail_msg("want '%s', got '%s'", want, err.message);
    ftm_record_close_reader(r);
}

/* Entries stay in the open chunk until it would span 100 ms of session (or
 * 1 MiB): one write(2) per chunk; ftm_record_tick writes a chunk that is
 * due without a next entry, ftm_record_flush at once. */
static void chunks_of_100ms(void **state)
{
    (void)state;
    ftm_record_header h;
    sample_header(&h);
    ftm_record_writer *w = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_create(path, &h, &w, &err), FTM_OK);
    const long head = file_size(path); /* the magic and the header's chunk */
    assert_int_equal(head, (long)ftm_record_kept(w));
    static uint8_t payload[1000];
    ftm_record_entry e = {.kind = 3, .sender = 1, .payload = payload, .size = sizeof payload};
    for (int i = 0; i < 100; i++) { /* 0 .. 99 ms */
        e.tick = (uint64_t)i;
        e.time_ns = (uint64_t)i * 1000000u;
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    assert_int_equal(file_size(path), head);
    assert_int_equal(ftm_record_tick(w, 99999999u, &err), FTM_OK);
    assert_int_equal(file_size(path), head);
    e.tick = 100;
    e.time_ns = 100000000u; /* the 100th ms: the chunk of 0..99 goes out */
    assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    const long one = file_size(path);
    assert_true(one > head + 100 * 1000 && one < head + 100 * 1100);
    assert_int_equal(ftm_record_tick(w, 200000000u, &err), FTM_OK); /* entry 100 is due */
    assert_true(file_size(path) > one);
    assert_int_equal((long)ftm_record_bytes(w), file_size(path));
    /* no more than 1 MiB of entries in a chunk, whatever their time */
    const long before = file_size(path);
    for (int i = 0; i < 1100; i++) {
        e.tick = 300;
        e.time_ns = 300000000u;
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    const long mib = file_size(path) - before;
    assert_true(mib > (1 << 20) - 1100 && mib <= (1 << 20) + (long)FTM_RECORD_CHUNK_HEAD);
    assert_int_equal(ftm_record_close(w, &err), FTM_OK);
    int entries = 0;
    assert_int_equal(read_all(path, &entries, &err), 0);
    assert_int_equal(entries, 1201);
}

/* A write that fails (here a file size limit, as a full disk) stops the
 * writer; the file keeps its whole chunks and as many of the failed
 * chunk's entries as fit, each a chunk of its own: readable to the end. */
static void write_error_keeps_what_fits(void **state)
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
    assert_int_equal(file_size(path), (long)flushed); /* on disk now */
    /* room for about 14 more entries (each ~1060 bytes as a chunk of its
     * own): the chunk of the next 40 does not fit */
    struct rlimit was, lim;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &was), 0);
    lim = was;
    const long room = 15500;
    lim.rlim_cur = (rlim_t)flushed + (rlim_t)room;
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
    const uint64_t kept = ftm_record_kept(w);
    assert_int_equal(ftm_record_close(w, &err), FTM_EIO);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &was), 0);
    signal(SIGXFSZ, old);
    const long size = file_size(path);
    assert_int_equal(size, (long)kept);
    const long per = (long)(flushed - 8 - FTM_RECORD_CHUNK_HEAD) / 20; /* an entry, about */
    /* what fitted is kept, less than one entry's chunk short of the room */
    if (size <= (long)flushed + room - per - 2 * (long)FTM_RECORD_CHUNK_HEAD - 64 ||
        size > (long)flushed + room)
        fail_msg("kept %ld bytes of %ld", size - (long)flushed, room);
    int entries = 0;
    assert_int_equal(read_all(path, &entries, &err), 0);
    assert_int_equal(entries, 20 + 14);
}

/* A lesson's file: header h, `n` entries from tick t0, 30 ms apart (a
 * chunk every 4 entries or so). */
static void write_segment(const char *p, const ftm_record_header *h, int n, uint64_t t0)
{
    ftm_record_writer *w = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_record_create(p, h, &w, &err), FTM_OK);
    uint8_t payload[64] = {1, 2, 3};
    for (int i = 0; i < n; i++) {
        ftm_record_entry e = {.tick = t0 + (uint64_t)i, .kind = 3, .sender = 11, .incoming = true,
                              .time_ns = (uint64_t)i * 30000000u, .payload = payload,
                              .size = sizeof payload};
        assert_int_equal(ftm_record_write(w, &e, &err), FTM_OK);
    }
    assert_int_equal(ftm_record_close(w, &err), FTM_OK);
}

/* Reads a lesson: its entries' count and how many were in its later files. */
static int read_lesson(const char *p, int *entries, int *later, ftm_error *err)
{
    ftm_record_header h;
    ftm_record_reader *r = NULL;
    int rc = ftm_record_open(p, &h, &r, err);
    *entries = *later = 0;
    if (rc)
        return rc;
    ftm_record_entry e;
    uint64_t tick = 0;
    while ((rc = ftm_record_next(r, &e, err)) == 1) {
        assert_true(e.tick >= tick); /* in order across the files */
        tick = e.tick;
        (*entries)++;
        *later += e.segment > 0;
    }
    ftm_record_close_reader(r);
    return rc;
}

/* A lesson in two files (a resumed server's): read as one, in order; a
 * later file of another lesson refused by name; a later file given alone
 * refused; the first file cut short by a crash passed over when the next
 * file says it goes on from there, damage otherwise. */
static void segments(void **state)
{
    (void)state;
    char first[300], second[320];
    snprintf(first, sizeof first, "%s-lesson.rec", path);
    snprintf(second, sizeof second, "%s.1", first);
    ftm_record_header h0, h1;
    sample_header(&h0);
    h0.start_unix_ns = 1000;
    write_segment(first, &h0, 20, 0);
    ftm_error err = {0, ""};
    int n = 0, later = 0;
    assert_int_equal(read_lesson(first, &n, &later, &err), 0);
    assert_int_equal(n, 20);
    h1 = h0;
    h1.start_unix_ns = 2000;
    h1.lesson_start_ns = 1000; /* the first file's start: the lesson's */
    h1.segment = 1;
    write_segment(second, &h1, 7, 19);
    assert_int_equal(read_lesson(first, &n, &later, &err), 0);
    assert_int_equal(n, 27);
    assert_int_equal(later, 7);
    /* given alone */
    assert_int_equal(read_lesson(second, &n, &later, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "segment 1 of a lesson"));
    /* another lesson's */
    h1.lesson_start_ns = 999;
    write_segment(second, &h1, 7, 19);
    assert_int_equal(read_lesson(first, &n, &later, &err), FTM_EPARSE);
    assert_int_equal(n, 20);
    assert_non_null(strstr(err.message, "not segment 1 of the lesson"));
    assert_non_null(strstr(err.message, "its lesson's start differs"));
    /* the first file cut 5 bytes short: damage at its end */
    FILE *f = fopen(first, "rb");
    assert_non_null(f);
    uint8_t buf[65536];
    size_t len = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(len > 100 && len < sizeof buf);
    f = fopen(first, "wb");
    fwrite(buf, 1, len - 5, f);
    fclose(f);
    unlink(second);
    ftm_record_reader *r = NULL;
    ftm_record_entry e;
    assert_int_equal(ftm_record_open(first, &h0, &r, &err), FTM_OK);
    int intact = 0;
    int rc;
    while ((rc = ftm_record_next(r, &e, &err)) == 1)
        intact++;
    assert_true(rc < 0);
    assert_true(ftm_record_damaged_at_end(r));
    const uint64_t cut = ftm_record_damage_offset(r);
    ftm_record_close_reader(r);
    assert_true(intact < 20 && cut > 8 && cut < len);
    /* a resumed server's next file that goes on from the cut: passed over */
    h1.lesson_start_ns = 1000;
    h1.previous_cut = cut;
    write_segment(second, &h1, 7, 19);
    assert_int_equal(ftm_record_open(first, &h0, &r, &err), FTM_OK);
    n = 0;
    while ((rc = ftm_record_next(r, &e, &err)) == 1)
        n++;
    assert_int_equal(rc, 0);
    assert_int_equal(n, intact + 7);
    assert_int_equal(ftm_record_cuts_passed(r), 1);
    ftm_record_close_reader(r);
    /* one that says another byte: the cut stays damage */
    h1.previous_cut = cut + 1;
    write_segment(second, &h1, 7, 19);
    assert_int_equal(read_lesson(first, &n, &later, &err), FTM_EPARSE);
    assert_int_equal(n, intact);
    assert_non_null(strstr(err.message, "truncated"));
    unlink(first);
    unlink(second);
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
        cmocka_unit_test(crc32c_check_value),
        cmocka_unit_test(every_bit_flip_detected),
        cmocka_unit_test(chunks_of_100ms),
        cmocka_unit_test(write_error_keeps_what_fits),
        cmocka_unit_test(segments),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    unlink(path);
    unlink(bad);
    return rc;
}
