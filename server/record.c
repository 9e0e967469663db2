/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file: writer and bounded reader (record.h). */
#include "record.h"
#include "crc32c.h"
#include "depth_ctl.h" /* FTM_DEPTH_CTL_MAX */

#include "ftm/sim.h"
#include "ftm/wire.h" /* FTM_WIRE_KIND_MIN, FTM_WIRE_KIND_MAX */
#include "ftm/v1/ftm.pb-c.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>

struct ftm_record_writer {
    int fd;
    char *path;
    uint64_t kept;  /* bytes in the file: the magic and whole chunks */
    uint64_t kept_tick; /* the tick of the last entry in the file */
    int error;      /* first write error: stopped for good */
    int sys_errno;  /* its errno (ENOSPC, EFBIG, ...) */
    char message[FTM_ERROR_MESSAGE_MAX];
    uint8_t *buf;   /* the open chunk: its head's room, then the body */
    size_t cap, len; /* len: head room + body bytes so far */
    size_t *ends;   /* where each entry of the open chunk ends in buf */
    uint64_t *ticks; /* and its tick */
    bool *optional;  /* and whether the recording replays without it (a keyframe sent) */
    size_t ncap;
    /* the disk is full (or the file at its size limit): every entry goes as a
     * chunk of its own while it fits; a keyframe that does not fit is left
     * out (the replay checks the keyframes it finds, and needs none), any
     * other entry that does not fit stops the recording for good */
    bool tight;
    uint64_t keyframes_left_out;
    uint32_t count; /* entries in the open chunk */
    uint32_t body_crc; /* of the open chunk's body so far: sealing it needs no pass over it */
    uint64_t first_ns, first_tick, last_tick;
};

struct ftm_record_reader {
    FILE *f;
    char *path;     /* the file being read */
    char *base;     /* the lesson's first file */
    uint32_t segment;
    ftm_record_header first, hdr; /* the first segment's header, the current one's */
    uint64_t offset, index; /* of the next entry, when one is read */
    Ftm__V1__RecordEntry *cur; /* the entry handed out last */
    uint8_t *buf;   /* the current chunk's body */
    size_t cap, len, pos;
    uint32_t left;  /* entries of the chunk not yet handed out */
    uint64_t chunks, chunk_at, first_tick, last_tick, body_at;
    uint64_t next_at; /* byte offset of the next chunk */
    bool body_bad;  /* the body's checksum differs: damage inside, found entry by entry */
    uint64_t last_good_tick;
    bool damaged;
    bool damage_at_end; /* the damage is the file's last chunk: cut while written */
    uint64_t damage_from; /* where that chunk begins */
    uint32_t cuts;      /* crash cuts passed over (previous_cut) */
};

static int rec_err(ftm_error *err, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static int rec_err(ftm_error *err, int code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
        err->code = code;
    }
    return code;
}

static int grow(uint8_t **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return 0;
    size_t c = *cap ? *cap : 4096;
    while (c < need)
        c *= 2;
    uint8_t *b = realloc(*buf, c);
    if (!b)
        return -1;
    *buf = b;
    *cap = c;
    return 0;
}

/* ---- chunks ------------------------------------------------------------------- */

#define HEAD FTM_RECORD_CHUNK_HEAD
/* a chunk's body: up to FTM_RECORD_CHUNK_BYTES, or one entry if larger */
#define BODY_MAX (FTM_RECORD_ENTRY_MAX + 5u + 4u)

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void put64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get64(const uint8_t *p) { return get32(p) | (uint64_t)get32(p + 4) << 32; }

/* The head of a chunk of `count` entries, n bytes whose CRC-32C is crc. */
static void seal(uint8_t *head, size_t n, uint32_t crc, uint32_t count, uint64_t t0, uint64_t t1)
{
    memcpy(head, "FTMC", 4);
    put32(head + 4, (uint32_t)n);
    put32(head + 8, count);
    put32(head + 12, crc);
    put64(head + 16, t0);
    put64(head + 24, t1);
    put32(head + 32, ftm_crc32c(0, head, 32));
}

/* ---- writing ------------------------------------------------------------------ */

/* All n bytes: 0, or the errno of the write that stopped short. */
static int write_all(int fd, const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t k = write(fd, p, n);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0)
            return errno;
        if (k == 0)
            return ENOSPC;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static int stop(ftm_record_writer *w, int e, ftm_error *err)
{
    w->error = FTM_EIO;
    if (!w->sys_errno)
        w->sys_errno = e;
    snprintf(w->message, sizeof w->message, "recording %s: write failed: %s", w->path,
             strerror(e));
    return rec_err(err, FTM_EIO, "%s", w->message);
}

/* Back to the end of the last whole chunk, to write from there. */
static bool cut_back(ftm_record_writer *w)
{
    return ftruncate(w->fd, (off_t)w->kept) == 0 && lseek(w->fd, (off_t)w->kept, SEEK_SET) >= 0;
}

/* Writes the open chunk with one write(2). If it does not fit (a full disk,
 * a file size limit), the file is cut back to the chunk before and its
 * entries are written one per chunk, as many as fit: the recording keeps
 * what the disk held, to the entry. Either way the writer then stops. */
static int write_chunk(ftm_record_writer *w, ftm_error *err)
{
    if (!w->count)
        return FTM_OK;
    const uint32_t count = w->count;
    w->count = 0;
    int e = 0;
    if (!w->tight) {
        seal(w->buf, w->len - HEAD, w->body_crc, count, w->first_tick, w->last_tick);
        e = write_all(w->fd, w->buf, w->len);
        if (!e) {
            w->kept += w->len;
            w->kept_tick = w->last_tick;
            w->len = HEAD;
            return FTM_OK;
        }
    }
    bool stopped = !w->tight && !cut_back(w);
    uint8_t head[HEAD];
    size_t at = HEAD;
    for (uint32_t i = 0; !stopped && i < count; at = w->ends[i], i++) {
        size_t n = w->ends[i] - at;
        seal(head, n, ftm_crc32c(0, w->buf + at, n), 1, w->ticks[i], w->ticks[i]);
        int ei = write_all(w->fd, head, HEAD);
        if (!ei)
            ei = write_all(w->fd, w->buf + at, n);
        if (ei) {
            e = ei;
            cut_back(w); /* (best effort: cutting needs no space) */
            if (w->optional[i]) {
                w->keyframes_left_out++;
                continue;
            }
            stopped = true;
            break;
        }
        w->kept += HEAD + n;
        w->kept_tick = w->ticks[i];
    }
    w->len = HEAD;
    if (!stopped) {
        w->tight = true; /* every entry fitted but keyframes: go on, entry by entry */
        return FTM_OK;
    }
    return stop(w, e ? e : ENOSPC, err);
}

static int put_entry(ftm_record_writer *w, const Ftm__V1__RecordEntry *m, uint64_t tick,
                     uint64_t time_ns, bool optional, ftm_error *err)
{
    if (w->error)
        return rec_err(err, w->error, "%s", w->message);
    size_t n = ftm__v1__record_entry__get_packed_size(m);
    if (n > FTM_RECORD_ENTRY_MAX)
        return rec_err(err, FTM_ERANGE, "recording %s: entry of %zu bytes is too large", w->path, n);
    const size_t need = 5 + n + 4;
    if (w->count && (time_ns >= w->first_ns + FTM_RECORD_CHUNK_NS ||
                     w->len - HEAD + need > FTM_RECORD_CHUNK_BYTES)) {
        int rc = write_chunk(w, err);
        if (rc)
            return rc;
    }
    if (grow(&w->buf, &w->cap, w->len + need))
        return rec_err(err, FTM_ENOMEM, "recording %s: out of memory", w->path);
    if (w->count == w->ncap) {
        size_t c = w->ncap ? 2 * w->ncap : 256;
        size_t *ends = realloc(w->ends, c * sizeof *ends);
        if (ends)
            w->ends = ends;
        uint64_t *ticks = ends ? realloc(w->ticks, c * sizeof *ticks) : NULL;
        if (ticks)
            w->ticks = ticks;
        bool *opt = ticks ? realloc(w->optional, c * sizeof *opt) : NULL;
        if (!opt)
            return rec_err(err, FTM_ENOMEM, "recording %s: out of memory", w->path);
        w->optional = opt;
        w->ncap = c;
    }
    uint8_t *p = w->buf + w->len;
    size_t h = 0;
    uint64_t v = n;
    do {
        p[h++] = (uint8_t)((v & 0x7f) | (v > 0x7f ? 0x80 : 0));
        v >>= 7;
    } while (v);
    ftm__v1__record_entry__pack(m, p + h);
    put32(p + h + n, ftm_crc32c(0, p + h, n));
    w->len += h + n + 4;
    if (!w->count) {
        w->first_ns = time_ns;
        w->first_tick = tick;
        w->body_crc = 0;
    }
    w->body_crc = ftm_crc32c(w->body_crc, p, h + n + 4);
    w->last_tick = tick;
    w->ends[w->count] = w->len;
    w->ticks[w->count] = tick;
    w->optional[w->count] = optional;
    w->count++;
    return FTM_OK;
}

int ftm_record_create(const char *path, const ftm_record_header *h, ftm_record_writer **out,
                      ftm_error *err)
{
    *out = NULL;
    ftm_record_writer *w = calloc(1, sizeof *w);
    if (!w || !(w->path = strdup(path))) {
        free(w);
        return rec_err(err, FTM_ENOMEM, "recording: out of memory");
    }
    w->len = HEAD;
    w->fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (w->fd < 0) {
        int e = errno;
        free(w->path);
        free(w);
        return rec_err(err, FTM_EIO, "recording %s: cannot create: %s", path, strerror(e));
    }
    int e = write_all(w->fd, (const uint8_t *)FTM_RECORD_MAGIC, 8);
    if (e) {
        int rc = stop(w, e, err);
        ftm_record_close(w, NULL);
        return rc;
    }
    w->kept = 8;
    Ftm__V1__RecordHeader hd = FTM__V1__RECORD_HEADER__INIT;
    hd.has_version = true;
    hd.version = FTM_RECORD_VERSION;
    hd.scene_id = (char *)h->scene_id;
    hd.has_content_digest = true;
    hd.content_digest.len = (size_t)h->digest_len;
    hd.content_digest.data = (uint8_t *)h->digest;
    hd.has_tick_rate_hz = true;
    hd.tick_rate_hz = h->tick_rate_hz;
    hd.has_depth_max = true;
    hd.depth_max = (uint32_t)h->depth_max;
    hd.has_depth_min = true;
    hd.depth_min = (uint32_t)h->depth_min;
    hd.has_node_count = true;
    hd.node_count = (uint32_t)h->node_count;
    hd.has_start_unix_ns = true;
    hd.start_unix_ns = h->start_unix_ns;
    hd.has_max_penetration = h->max_penetration > 0;
    hd.max_penetration = h->max_penetration;
    hd.session = h->session[0] ? (char *)h->session : NULL;
    hd.has_arithmetic = true;
    hd.arithmetic = ftm_arithmetic_revision();
    if (h->segment) {
        hd.has_lesson_start_ns = true;
        hd.lesson_start_ns = h->lesson_start_ns;
        hd.has_segment = true;
        hd.segment = h->segment;
        hd.has_after_gap = h->after_gap;
        hd.after_gap = h->after_gap;
        hd.has_previous_cut = h->previous_cut > 0;
        hd.previous_cut = h->previous_cut;
    }
    Ftm__V1__RecordEntry m = FTM__V1__RECORD_ENTRY__INIT;
    m.header = &hd;
    /* the header in a chunk of its own, in the file at once */
    int rc = put_entry(w, &m, 0, 0, false, err);
    if (!rc)
        rc = write_chunk(w, err);
    if (rc) {
        ftm_record_close(w, NULL);
        return rc;
    }
    *out = w;
    return FTM_OK;
}

int ftm_record_write(ftm_record_writer *w, const ftm_record_entry *e, ftm_error *err)
{
    Ftm__V1__RecordEntry m = FTM__V1__RECORD_ENTRY__INIT;
    m.has_tick = true;
    m.tick = e->tick;
    m.has_kind = true;
    m.kind = (Ftm__V1__Kind)e->kind;
    if (e->size) {
        m.has_payload = true;
        m.payload.len = e->size;
        m.payload.data = (uint8_t *)e->payload;
    }
    m.has_sender = true;
    m.sender = e->sender;
    m.has_incoming = true;
    m.incoming = e->incoming;
    if (e->gone) {
        m.has_gone = true;
        m.gone = true;
    }
    if (e->lost) {
        m.has_lost = true;
        m.lost = true;
    }
    m.has_time_ns = true;
    m.time_ns = e->time_ns;
    /* a keyframe the server sent: the replay checks it if it is there */
    const bool optional = e->kind == FTM_WIRE_KEYFRAME && !e->incoming;
    return put_entry(w, &m, e->tick, e->time_ns, optional, err);
}

int ftm_record_tick(ftm_record_writer *w, uint64_t time_ns, ftm_error *err)
{
    if (w->error)
        return rec_err(err, w->error, "%s", w->message);
    if (w->count && time_ns >= w->first_ns + FTM_RECORD_CHUNK_NS)
        return write_chunk(w, err);
    return FTM_OK;
}

int ftm_record_flush(ftm_record_writer *w, ftm_error *err)
{
    if (w->error)
        return rec_err(err, w->error, "%s", w->message);
    return write_chunk(w, err);
}

uint64_t ftm_record_bytes(const ftm_record_writer *w)
{
    return w ? w->kept + (w->count ? w->len : 0) : 0;
}

uint64_t ftm_record_kept(const ftm_record_writer *w) { return w ? w->kept : 0; }

int ftm_record_errno(const ftm_record_writer *w) { return w ? w->sys_errno : 0; }

uint64_t ftm_record_kept_tick(const ftm_record_writer *w) { return w ? w->kept_tick : 0; }

int ftm_record_close(ftm_record_writer *w, ftm_error *err)
{
    if (!w)
        return FTM_OK;
    if (!w->error && w->fd >= 0)
        write_chunk(w, NULL);
    int rc = w->error;
    if (w->fd >= 0 && close(w->fd) != 0 && !rc) {
        rc = FTM_EIO;
        snprintf(w->message, sizeof w->message, "recording %s: close failed: %s", w->path,
                 strerror(errno));
    }
    if (rc)
        rec_err(err, rc, "%s", w->message);
    free(w->buf);
    free(w->ends);
    free(w->ticks);
    free(w->optional);
    free(w->path);
    free(w);
    return rc;
}

/* ---- reading ------------------------------------------------------------------ */

/* An error in the chunk being read: damage if `damage` (a checksum that
 * differs, a chunk cut short), a malformed file otherwise. */
static int bad(ftm_record_reader *r, bool damage, ftm_error *err, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int bad(ftm_record_reader *r, bool damage, ftm_error *err, const char *fmt, ...)
{
    char what[FTM_ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    r->damaged = damage;
    return rec_err(err, FTM_EPARSE, "%s: %s", r->path, what);
}

/* Reads the next chunk into r->buf: 1, 0 at a clean end (between two
 * chunks), < 0. */
static int next_chunk(ftm_record_reader *r, ftm_error *err)
{
    uint8_t head[HEAD];
    const uint64_t at = r->next_at;
    size_t got = fread(head, 1, HEAD, r->f);
    if (got == 0 && ferror(r->f))
        return rec_err(err, FTM_EIO, "%s: cannot read: %s", r->path, strerror(errno));
    if (got == 0)
        return 0;
    const uint64_t k = ++r->chunks;
    char after[96] = "the header's";
    if (r->index > 1)
        snprintf(after, sizeof after, "after entry %llu (tick %llu)",
                 (unsigned long long)(r->index - 1), (unsigned long long)r->last_good_tick);
    else if (r->index == 1)
        snprintf(after, sizeof after, "after the header");
    r->damage_at_end = got < HEAD;
    r->damage_from = at;
    if (got < HEAD)
        return bad(r, true, err,
                   "truncated: the file ends inside the head of chunk %llu at byte %llu (%zu of "
                   "%u bytes), %s: cut while it was written (a crash?)",
                   (unsigned long long)k, (unsigned long long)at, got, HEAD, after);
    if (memcmp(head, "FTMC", 4) != 0 || get32(head + 32) != ftm_crc32c(0, head, 32))
        return bad(r, true, err,
                   "damaged: the head of chunk %llu at byte %llu, %s: its checksum differs",
                   (unsigned long long)k, (unsigned long long)at, after);
    const uint32_t len = get32(head + 4), count = get32(head + 8);
    r->first_tick = get64(head + 16);
    r->last_tick = get64(head + 24);
    r->chunk_at = at;
    if (len > BODY_MAX || count == 0 || count > len / 6) /* an entry: >= 6 bytes */
        return bad(r, false, err,
                   "chunk %llu at byte %llu: %u entries in %u bytes, out of range (1 entry per "
                   "6..%u bytes)",
                   (unsigned long long)k, (unsigned long long)at, count, len, BODY_MAX);
    if (grow(&r->buf, &r->cap, len))
        return rec_err(err, FTM_ENOMEM, "%s: out of memory", r->path);
    got = fread(r->buf, 1, len, r->f);
    r->damage_at_end = got != len;
    if (got != len)
        return bad(r, true, err,
                   "truncated: chunk %llu at byte %llu (entries %llu.., ticks %llu..%llu) needs "
                   "%u bytes after its head, the file has %zu: cut while it was written (a "
                   "crash?)",
                   (unsigned long long)k, (unsigned long long)at, (unsigned long long)r->index,
                   (unsigned long long)r->first_tick, (unsigned long long)r->last_tick, len, got);
    r->offset = r->body_at = at + HEAD;
    r->next_at = at + HEAD + len;
    r->len = len;
    r->pos = 0;
    r->left = count;
    /* damage inside: found entry by entry below, so that what comes
     * before it is handed out (--replay-upto-damage) */
    r->body_bad = get32(head + 12) != ftm_crc32c(0, r->buf, len);
    if (r->body_bad) { /* the last chunk of the file? */
        int c = fgetc(r->f);
        r->damage_at_end = c == EOF;
        if (c != EOF)
            ungetc(c, r->f);
    }
    return 1;
}

/* The next entry's bytes (at r->buf + *at, *size of them): 1, 0 at a clean
 * end, < 0. Its checksum is checked. */
static int get_raw(ftm_record_reader *r, size_t *at, size_t *size, ftm_error *err)
{
    if (!r->left) {
        if (r->pos != r->len || r->body_bad)
            return bad(r, r->body_bad, err,
                       "%s: chunk %llu at byte %llu (ticks %llu..%llu): %s",
                       r->body_bad ? "damaged" : "malformed", (unsigned long long)r->chunks,
                       (unsigned long long)r->chunk_at, (unsigned long long)r->first_tick,
                       (unsigned long long)r->last_tick,
                       r->body_bad ? "its checksum differs"
                                   : "its entries end before its body does");
        int got = next_chunk(r, err);
        if (got <= 0)
            return got;
    }
    const uint64_t start = r->body_at + r->pos;
    uint64_t len = 0;
    size_t i = r->pos;
    for (int shift = 0;; shift += 7) {
        if (i >= r->len || shift == 35)
            return bad(r, r->body_bad, err,
                       "%s: entry %llu at byte %llu (chunk %llu, ticks %llu..%llu): length "
                       "prefix %s",
                       r->body_bad ? "damaged" : "malformed", (unsigned long long)r->index,
                       (unsigned long long)start, (unsigned long long)r->chunks,
                       (unsigned long long)r->first_tick, (unsigned long long)r->last_tick,
                       i >= r->len ? "past the chunk's end" : "too long");
        uint8_t c = r->buf[i++];
        len |= (uint64_t)(c & 0x7f) << shift;
        if (!(c & 0x80))
            break;
    }
    if (len == 0 || len > FTM_RECORD_ENTRY_MAX || i + len + 4 > r->len)
        return bad(r, r->body_bad, err,
                   "%s: entry %llu at byte %llu (chunk %llu, ticks %llu..%llu): length %llu out "
                   "of range 1..%llu",
                   r->body_bad ? "damaged" : "malformed", (unsigned long long)r->index,
                   (unsigned long long)start, (unsigned long long)r->chunks,
                   (unsigned long long)r->first_tick, (unsigned long long)r->last_tick,
                   (unsigned long long)len,
                   (unsigned long long)(r->len - i >= 4 ? r->len - i - 4 : 0));
    if (get32(r->buf + i + len) != ftm_crc32c(0, r->buf + i, (size_t)len))
        return bad(r, true, err,
                   "damaged: entry %llu at byte %llu (chunk %llu, ticks %llu..%llu, after tick "
                   "%llu): its checksum differs",
                   (unsigned long long)r->index, (unsigned long long)start,
                   (unsigned long long)r->chunks, (unsigned long long)r->first_tick,
                   (unsigned long long)r->last_tick, (unsigned long long)r->last_good_tick);
    *at = i;
    *size = (size_t)len;
    r->offset = start;
    r->pos = i + (size_t)len + 4;
    r->left--;
    return 1;
}

static int unpack(ftm_record_reader *r, size_t at, size_t size, uint64_t start, ftm_error *err)
{
    if (r->cur)
        ftm__v1__record_entry__free_unpacked(r->cur, NULL);
    /* no repeated fields in a RecordEntry: it cannot inflate beyond its size */
    r->cur = ftm__v1__record_entry__unpack(NULL, size, r->buf + at);
    if (!r->cur)
        return rec_err(err, FTM_EPARSE, "%s: entry %llu at byte %llu: not a valid RecordEntry",
                       r->path, (unsigned long long)r->index, (unsigned long long)start);
    return FTM_OK;
}

/* Opens one file of the lesson into r (its per-file state afresh) and reads
 * its magic and header into *h. */
static int open_file(ftm_record_reader *r, const char *path, ftm_record_header *h,
                     ftm_error *err)
{
    memset(h, 0, sizeof *h);
    if (r->f)
        fclose(r->f);
    if (r->cur)
        ftm__v1__record_entry__free_unpacked(r->cur, NULL);
    r->f = NULL;
    r->cur = NULL;
    free(r->path);
    r->offset = r->index = r->chunks = r->chunk_at = r->first_tick = r->last_tick = 0;
    r->body_at = r->next_at = r->last_good_tick = 0;
    r->len = r->pos = 0;
    r->left = 0;
    r->body_bad = r->damaged = r->damage_at_end = false;
    if (!(r->path = strdup(path)))
        return rec_err(err, FTM_ENOMEM, "recording: out of memory");
    int rc = FTM_OK;
    char magic[8];
    size_t sz = 0, at = 0;
    size_t nmagic = 0;
    r->f = fopen(path, "rb");
    if (!r->f)
        rc = rec_err(err, FTM_EIO, "%s: cannot open: %s", path, strerror(errno));
    else if ((nmagic = fread(magic, 1, 8, r->f)) != 8 && ferror(r->f)) /* a directory: EISDIR */
        rc = rec_err(err, FTM_EIO, "%s: cannot read: %s", path, strerror(errno));
    else if (nmagic == 0) /* what a server killed before its first write leaves */
        rc = rec_err(err, FTM_EPARSE, "%s: empty file (0 bytes), not an FTM recording", path);
    else if (nmagic < 8 && memcmp(magic, FTM_RECORD_MAGIC, nmagic) == 0)
        rc = rec_err(err, FTM_EPARSE, "%s: truncated: the file ends inside the magic (%zu of 8 "
                     "bytes)", path, nmagic);
    else if (nmagic == 8 && memcmp(magic, "FTMREC1\n", 8) == 0)
        rc = rec_err(err, FTM_EVERSION, "%s: recording format version 1 (no checksums); this "
                     "build reads version %u only: replay it with the ftm-server that recorded "
                     "it", path, FTM_RECORD_VERSION);
    else if (nmagic < 8 || memcmp(magic, FTM_RECORD_MAGIC, 8) != 0)
        rc = rec_err(err, FTM_EPARSE, "%s: not an FTM recording (no \"FTMREC2\" magic)", path);
    if (!rc) {
        r->offset = r->next_at = 8;
        int got = get_raw(r, &at, &sz, err);
        if (got == 0)
            rc = rec_err(err, FTM_EPARSE, "%s: truncated: no header entry", path);
        else if (got < 0)
            rc = got;
        else
            rc = unpack(r, at, sz, 8 + HEAD, err);
    }
    if (!rc) {
        const Ftm__V1__RecordHeader *hd = r->cur->header;
        if (!hd)
            rc = rec_err(err, FTM_EPARSE, "%s: the first entry is not a header", path);
        else if (!hd->has_version || hd->version != FTM_RECORD_VERSION)
            rc = rec_err(err, FTM_EPARSE, "%s: recording format version %u, this build reads %u",
                         path, hd->has_version ? hd->version : 0u, FTM_RECORD_VERSION);
        else if (!hd->scene_id || !hd->scene_id[0] || strlen(hd->scene_id) >= sizeof h->scene_id)
            rc = rec_err(err, FTM_EPARSE, "%s: header: scene_id missing or longer than 127 bytes", path);
        else if (!hd->has_content_digest || hd->content_digest.len == 0 ||
                 hd->content_digest.len > sizeof h->digest)
            rc = rec_err(err, FTM_EPARSE, "%s: header: content_digest missing or over 64 bytes", path);
        else if (hd->has_depth_max && hd->depth_max > FTM_DEPTH_CTL_MAX)
            /* no server runs deeper (depth_ctl.h); --inputs would fail later, naming neither */
            rc = rec_err(err, FTM_EPARSE, "%s: header: depth_max %u is above %d, the deepest a "
                         "server runs", path, hd->depth_max, FTM_DEPTH_CTL_MAX);
        else if (!hd->has_tick_rate_hz || hd->tick_rate_hz == 0 || !hd->has_node_count ||
                 hd->node_count == 0 || hd->node_count > INT32_MAX || !hd->has_depth_max ||
                 hd->depth_max > INT32_MAX || hd->depth_min > hd->depth_max)
            rc = rec_err(err, FTM_EPARSE,
                         "%s: header: tick_rate_hz, node_count or depth limits missing or invalid",
                         path);
        else if (hd->has_max_penetration &&
                 !(isfinite(hd->max_penetration) && hd->max_penetration > 0))
            rc = rec_err(err, FTM_EPARSE, "%s: header: max_penetration %g is not a positive length",
                         path, hd->max_penetration);
        else if (hd->session && strlen(hd->session) >= sizeof h->session)
            rc = rec_err(err, FTM_EPARSE, "%s: header: session name longer than 127 bytes", path);
        else {
            snprintf(h->scene_id, sizeof h->scene_id, "%s", hd->scene_id);
            memcpy(h->digest, hd->content_digest.data, hd->content_digest.len);
            h->digest_len = (int32_t)hd->content_digest.len;
            h->tick_rate_hz = hd->tick_rate_hz;
            h->depth_max = (int32_t)hd->depth_max;
            h->depth_min = (int32_t)hd->depth_min;
            h->node_count = (int32_t)hd->node_count;
            h->start_unix_ns = hd->start_unix_ns;
            h->max_penetration = hd->has_max_penetration ? hd->max_penetration : 0.0;
            snprintf(h->session, sizeof h->session, "%s", hd->session ? hd->session : "");
            h->arithmetic = hd->has_arithmetic && hd->arithmetic ? hd->arithmetic : 1;
            h->lesson_start_ns = hd->has_lesson_start_ns ? hd->lesson_start_ns : 0;
            h->segment = hd->has_segment ? hd->segment : 0;
            h->after_gap = hd->has_after_gap && hd->after_gap;
            h->previous_cut = hd->has_previous_cut ? hd->previous_cut : 0;
            r->index = 1;
        }
    }
    return rc;
}

int ftm_record_segment_path(const char *path, uint32_t k, char *buf, size_t cap)
{
    int n = k ? snprintf(buf, cap, "%s.%u", path, k) : snprintf(buf, cap, "%s", path);
    return n < 0 || (size_t)n >= cap ? FTM_EINVAL : FTM_OK;
}

int ftm_record_open(const char *path, ftm_record_header *h, ftm_record_reader **out,
                    ftm_error *err)
{
    *out = NULL;
    memset(h, 0, sizeof *h);
    ftm_record_reader *r = calloc(1, sizeof *r);
    if (!r || !(r->base = strdup(path))) {
        free(r);
        return rec_err(err, FTM_ENOMEM, "recording: out of memory");
    }
    int rc = open_file(r, path, h, err);
    if (!rc && h->segment)
        rc = rec_err(err, FTM_EPARSE, "%s: segment %u of a lesson (a server that resumed it or "
                     "recorded on after a write error): give the lesson's first file", path,
                     h->segment);
    if (rc) {
        ftm_record_close_reader(r);
        return rc;
    }
    if (!h->lesson_start_ns) /* the lesson began with this file */
        h->lesson_start_ns = h->start_unix_ns;
    r->first = r->hdr = *h;
    *out = r;
    return FTM_OK;
}

/* Whether the file being read, damaged in its last chunk, is what a crash
 * left of a lesson that a server resumed: the next file's header says the
 * lesson goes on from the start of that chunk. */
static bool cut_resumed(const ftm_record_reader *r)
{
    char next[4096];
    if (ftm_record_segment_path(r->base, r->segment + 1, next, sizeof next) ||
        access(next, F_OK) != 0)
        return false;
    ftm_record_reader *t = calloc(1, sizeof *t);
    if (!t)
        return false;
    ftm_record_header h;
    bool yes = open_file(t, next, &h, NULL) == FTM_OK && h.segment == r->segment + 1 &&
               h.previous_cut && h.previous_cut == r->damage_from;
    ftm_record_close_reader(t);
    return yes;
}

/* At the clean end of a segment: the next one, if its file exists. 1: opened
 * (its header checked), 0: none, < 0: an error (damage if the file cannot
 * be read as a recording: a server killed as it began it). */
static int next_segment(ftm_record_reader *r, ftm_error *err)
{
    char next[4096];
    if (ftm_record_segment_path(r->base, r->segment + 1, next, sizeof next))
        return 0;
    if (access(next, F_OK) != 0)
        return 0;
    ftm_record_header h;
    int rc = open_file(r, next, &h, err);
    if (rc) {
        /* cut as it was begun (a server killed then): what came before is whole */
        r->damaged = r->damage_at_end = rc == FTM_EPARSE;
        return rc;
    }
    const ftm_record_header *f = &r->first;
    const char *why = NULL;
    if (h.segment != r->segment + 1)
        why = "its segment number";
    else if (h.lesson_start_ns != f->lesson_start_ns)
        why = "its lesson's start";
    else if (strcmp(h.scene_id, f->scene_id) != 0 || h.digest_len != f->digest_len ||
             memcmp(h.digest, f->digest, (size_t)h.digest_len) != 0)
        why = "its scene";
    else if (h.tick_rate_hz != f->tick_rate_hz || h.node_count != f->node_count ||
             h.arithmetic != f->arithmetic)
        why = "its tick rate, node count or arithmetic revision";
    if (why)
        return rec_err(err, FTM_EPARSE,
                       "%s: header: not segment %u of the lesson %s (%s differs): move it "
                       "away to read the lesson without it", next, r->segment + 1, r->base, why);
    r->segment++;
    r->hdr = h;
    return 1;
}

int ftm_record_next(ftm_record_reader *r, ftm_record_entry *e, ftm_error *err)
{
    memset(e, 0, sizeof *e);
    r->damaged = false;
    size_t size = 0, at = 0;
    int got = get_raw(r, &at, &size, err);
    for (;;) {
        if (got < 0 && r->damaged && r->damage_at_end && cut_resumed(r)) {
            r->cuts++; /* a crash's unfinished chunk, which the next file goes on from */
            got = 0;
        }
        if (got != 0)
            break;
        /* the clean end of a segment: the next one, if any */
        got = next_segment(r, err);
        if (got <= 0)
            return got;
        got = get_raw(r, &at, &size, err);
    }
    if (got < 0)
        return got;
    const uint64_t start = r->offset;
    int rc = unpack(r, at, size, start, err);
    if (rc)
        return rc;
    const Ftm__V1__RecordEntry *m = r->cur;
    if (m->has_kind && (m->kind < FTM_WIRE_KIND_MIN || m->kind > FTM_WIRE_KIND_MAX))
        return rec_err(err, FTM_EPARSE,
                       "%s: entry %llu at byte %llu: kind %d is unknown to this build (%d..%d): "
                       "recorded by a newer ftm-server?",
                       r->path, (unsigned long long)r->index, (unsigned long long)start,
                       (int)m->kind, FTM_WIRE_KIND_MIN, FTM_WIRE_KIND_MAX);
    if (m->header || !m->has_tick || !m->has_kind || !m->has_sender || !m->has_incoming)
        return rec_err(err, FTM_EPARSE,
                       "%s: entry %llu at byte %llu: %s", r->path, (unsigned long long)r->index,
                       (unsigned long long)start,
                       m->header ? "a second header" : "tick, kind (1..7), sender or incoming missing");
    e->tick = m->tick;
    e->kind = (int)m->kind;
    e->sender = m->sender;
    e->incoming = m->incoming;
    e->gone = m->has_gone && m->gone;
    e->lost = m->has_lost && m->lost;
    e->time_ns = m->time_ns;
    e->payload = m->has_payload ? m->payload.data : NULL;
    e->size = m->has_payload ? m->payload.len : 0;
    e->index = r->index++;
    e->offset = start;
    e->segment = r->segment;
    r->last_good_tick = e->tick;
    return 1;
}

bool ftm_record_damaged(const ftm_record_reader *r) { return r && r->damaged; }

uint64_t ftm_record_damage_offset(const ftm_record_reader *r) { return r->damage_from; }

uint32_t ftm_record_cuts_passed(const ftm_record_reader *r) { return r->cuts; }

bool ftm_record_damaged_at_end(const ftm_record_reader *r)
{
    return r && r->damaged && r->damage_at_end;
}

const char *ftm_record_reader_path(const ftm_record_reader *r) { return r->path; }

const ftm_record_header *ftm_record_reader_header(const ftm_record_reader *r) { return &r->hdr; }

void ftm_record_close_reader(ftm_record_reader *r)
{
    if (!r)
        return;
    if (r->cur)
        ftm__v1__record_entry__free_unpacked(r->cur, NULL);
    if (r->f)
        fclose(r->f);
    free(r->buf);
    free(r->path);
    free(r->base);
    free(r);
}
