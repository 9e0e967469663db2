/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file: writer and bounded reader (record.h). */
#include "record.h"
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
#include <unistd.h> /* truncate */

struct ftm_record_writer {
    FILE *f;
    char *path;
    uint64_t bytes;
    uint64_t flushed; /* bytes known to be in the file: whole entries, up to the last flush */
    int error; /* first write error */
    char message[FTM_ERROR_MESSAGE_MAX];
    uint8_t *buf;
    size_t cap;
    char *iobuf; /* the stream's buffer: freed after fclose */
};

/* One write(2) per MiB, not per tick. The buffer must be ours: with NULL,
 * glibc ignores the size and writes every 4 KiB (st_blksize). */
#define RECORD_IOBUF (1u << 20)

struct ftm_record_reader {
    FILE *f;
    char *path;
    uint64_t offset, index;
    Ftm__V1__RecordEntry *cur; /* the entry handed out last */
    uint8_t *buf;
    size_t cap;
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

/* ---- writing ------------------------------------------------------------------ */

static int put_entry(ftm_record_writer *w, const Ftm__V1__RecordEntry *m, ftm_error *err)
{
    if (w->error)
        return rec_err(err, w->error, "%s", w->message);
    size_t n = ftm__v1__record_entry__get_packed_size(m);
    if (n > FTM_RECORD_ENTRY_MAX)
        return rec_err(err, FTM_ERANGE, "recording %s: entry of %zu bytes is too large", w->path, n);
    if (grow(&w->buf, &w->cap, n + 10))
        return rec_err(err, FTM_ENOMEM, "recording %s: out of memory", w->path);
    size_t h = 0;
    uint64_t v = n;
    do {
        w->buf[h++] = (uint8_t)((v & 0x7f) | (v > 0x7f ? 0x80 : 0));
        v >>= 7;
    } while (v);
    ftm__v1__record_entry__pack(m, w->buf + h);
    if (fwrite(w->buf, 1, h + n, w->f) != h + n) {
        w->error = FTM_EIO;
        snprintf(w->message, sizeof w->message, "recording %s: write failed: %s", w->path,
                 strerror(errno));
        return rec_err(err, FTM_EIO, "%s", w->message);
    }
    w->bytes += h + n;
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
    if (!(w->iobuf = malloc(RECORD_IOBUF))) {
        free(w->path);
        free(w);
        return rec_err(err, FTM_ENOMEM, "recording: out of memory");
    }
    w->f = fopen(path, "wb");
    if (!w->f) {
        int e = errno;
        free(w->iobuf);
        free(w->path);
        free(w);
        return rec_err(err, FTM_EIO, "recording %s: cannot create: %s", path, strerror(e));
    }
    setvbuf(w->f, w->iobuf, _IOFBF, RECORD_IOBUF);
    fwrite(FTM_RECORD_MAGIC, 1, 8, w->f);
    w->bytes = 8;
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
    Ftm__V1__RecordEntry m = FTM__V1__RECORD_ENTRY__INIT;
    m.header = &hd;
    int rc = put_entry(w, &m, err);
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
    return put_entry(w, &m, err);
}

int ftm_record_flush(ftm_record_writer *w, ftm_error *err)
{
    if (w->error)
        return rec_err(err, w->error, "%s", w->message);
    if (fflush(w->f) != 0) {
        w->error = FTM_EIO;
        snprintf(w->message, sizeof w->message, "recording %s: write failed: %s", w->path,
                 strerror(errno));
        return rec_err(err, FTM_EIO, "%s", w->message);
    }
    w->flushed = w->bytes;
    return FTM_OK;
}

uint64_t ftm_record_bytes(const ftm_record_writer *w) { return w ? w->bytes : 0; }

int ftm_record_close(ftm_record_writer *w, ftm_error *err)
{
    if (!w)
        return FTM_OK;
    int rc = w->error;
    if (fclose(w->f) != 0 && !rc) {
        rc = FTM_EIO;
        snprintf(w->message, sizeof w->message, "recording %s: close failed: %s", w->path,
                 strerror(errno));
    }
    if (rc) {
        /* a failed write (a full disk) leaves part of an entry at the end:
         * cut back to the last flush, so that the file ends on a whole entry
         * and replays to there (best effort: truncating needs no space) */
        if (truncate(w->path, (off_t)w->flushed) != 0)
            fprintf(stderr, "recording %s: cannot cut back to its last whole entry: %s\n",
                    w->path, strerror(errno));
        rec_err(err, rc, "%s", w->message);
    }
    free(w->iobuf); /* only now: fclose flushed from it */
    free(w->buf);
    free(w->path);
    free(w);
    return rc;
}

/* ---- reading ------------------------------------------------------------------ */

/* Reads the next entry's bytes into r->buf: 1, 0 at a clean end, < 0. */
static int get_raw(ftm_record_reader *r, size_t *size, ftm_error *err)
{
    uint64_t len = 0;
    int shift = 0, c;
    uint64_t start = r->offset;
    for (int i = 0;; i++) {
        c = fgetc(r->f);
        if (c == EOF) {
            if (ferror(r->f))
                return rec_err(err, FTM_EIO, "%s: read error at byte %llu: %s", r->path,
                               (unsigned long long)r->offset, strerror(errno));
            if (i == 0)
                return 0;
            return rec_err(err, FTM_EPARSE,
                           "%s: truncated: entry %llu at byte %llu ends inside its length prefix",
                           r->path, (unsigned long long)r->index, (unsigned long long)start);
        }
        r->offset++;
        if (i == 5)
            return rec_err(err, FTM_EPARSE, "%s: entry %llu at byte %llu: length prefix too long",
                           r->path, (unsigned long long)r->index, (unsigned long long)start);
        len |= (uint64_t)(c & 0x7f) << shift;
        shift += 7;
        if (!(c & 0x80))
            break;
    }
    if (len == 0 || len > FTM_RECORD_ENTRY_MAX)
        return rec_err(err, FTM_EPARSE,
                       "%s: entry %llu at byte %llu: length %llu out of range 1..%u (corrupt file?)",
                       r->path, (unsigned long long)r->index, (unsigned long long)start,
                       (unsigned long long)len, FTM_RECORD_ENTRY_MAX);
    if (grow(&r->buf, &r->cap, (size_t)len))
        return rec_err(err, FTM_ENOMEM, "%s: out of memory", r->path);
    size_t got = fread(r->buf, 1, (size_t)len, r->f);
    r->offset += got;
    if (got != len)
        return rec_err(err, FTM_EPARSE,
                       "%s: truncated: entry %llu at byte %llu needs %llu bytes, the file has %zu",
                       r->path, (unsigned long long)r->index, (unsigned long long)start,
                       (unsigned long long)len, got);
    *size = (size_t)len;
    return 1;
}

static int unpack(ftm_record_reader *r, size_t size, uint64_t start, ftm_error *err)
{
    if (r->cur)
        ftm__v1__record_entry__free_unpacked(r->cur, NULL);
    /* no repeated fields in a RecordEntry: it cannot inflate beyond its size */
    r->cur = ftm__v1__record_entry__unpack(NULL, size, r->buf);
    if (!r->cur)
        return rec_err(err, FTM_EPARSE, "%s: entry %llu at byte %llu: not a valid RecordEntry",
                       r->path, (unsigned long long)r->index, (unsigned long long)start);
    return FTM_OK;
}

int ftm_record_open(const char *path, ftm_record_header *h, ftm_record_reader **out,
                    ftm_error *err)
{
    *out = NULL;
    memset(h, 0, sizeof *h);
    ftm_record_reader *r = calloc(1, sizeof *r);
    if (!r || !(r->path = strdup(path))) {
        free(r);
        return rec_err(err, FTM_ENOMEM, "recording: out of memory");
    }
    int rc = FTM_OK;
    char magic[8];
    size_t sz = 0;
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
    else if (nmagic < 8 || memcmp(magic, FTM_RECORD_MAGIC, 8) != 0)
        rc = rec_err(err, FTM_EPARSE, "%s: not an FTM recording (no \"FTMREC1\" magic)", path);
    if (!rc) {
        r->offset = 8;
        int got = get_raw(r, &sz, err);
        if (got == 0)
            rc = rec_err(err, FTM_EPARSE, "%s: truncated: no header entry", path);
        else if (got < 0)
            rc = got;
        else
            rc = unpack(r, sz, 8, err);
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
            r->index = 1;
        }
    }
    if (rc) {
        ftm_record_close_reader(r);
        return rc;
    }
    *out = r;
    return FTM_OK;
}

int ftm_record_next(ftm_record_reader *r, ftm_record_entry *e, ftm_error *err)
{
    memset(e, 0, sizeof *e);
    uint64_t start = r->offset;
    size_t size = 0;
    int got = get_raw(r, &size, err);
    if (got <= 0)
        return got;
    int rc = unpack(r, size, start, err);
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
    return 1;
}

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
    free(r);
}
