/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file (docs/server.md, "Session recording"): the magic
 * "FTMREC1\n", then length-delimited ftm.v1.RecordEntry messages; the first
 * holds the RecordHeader. Writer for ftm-server --record, reader for
 * ftm-server --replay. The reader never trusts the file: every length is
 * bounded and a short, oversized or malformed entry is an FTM_EPARSE error
 * naming the entry number and byte offset. */
#ifndef FTM_SERVER_RECORD_H
#define FTM_SERVER_RECORD_H

#include "ftm/base.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FTM_RECORD_MAGIC "FTMREC1\n"
#define FTM_RECORD_VERSION 1u
/* Largest entry: the biggest payload (a 16 MiB keyframe) plus the envelope. */
#define FTM_RECORD_ENTRY_MAX (16u * 1024u * 1024u + 1024u)

typedef struct ftm_record_header {
    char scene_id[128];
    uint8_t digest[64];
    int32_t digest_len;
    uint32_t tick_rate_hz;
    int32_t depth_max, depth_min;
    int32_t node_count;
    uint64_t start_unix_ns;
    double max_penetration; /* probe push limit [m]; 0: none (recordings made before it) */
    char session[128];      /* the session's name; "" in recordings made before it */
    uint32_t arithmetic;    /* read: the recording core's ftm_arithmetic_revision() (1 in
                               recordings made before it); written: always this build's */
} ftm_record_header;

typedef struct ftm_record_entry {
    uint64_t tick;
    int kind;            /* ftm_wire_kind */
    uint32_t sender;
    bool incoming, gone, lost;
    uint64_t time_ns;
    const uint8_t *payload; /* owned by the reader; valid until the next call */
    size_t size;
    uint64_t index;      /* entry number, header = 0 */
    uint64_t offset;     /* byte offset of the entry's length prefix */
} ftm_record_entry;

typedef struct ftm_record_writer ftm_record_writer;

/* Creates (truncates) path and writes the magic and the header. */
int ftm_record_create(const char *path, const ftm_record_header *h, ftm_record_writer **out,
                      ftm_error *err);
/* Appends one entry (e->payload/size, tick, kind, ...; index/offset unused). */
int ftm_record_write(ftm_record_writer *w, const ftm_record_entry *e, ftm_error *err);
/* Hands what is buffered to the kernel (one write), so that a server killed
 * afterwards leaves a recording of whole entries up to here. A failure stops
 * the writer as a failed ftm_record_write does. */
int ftm_record_flush(ftm_record_writer *w, ftm_error *err);
/* Bytes written so far. */
uint64_t ftm_record_bytes(const ftm_record_writer *w);
/* Flushes and closes; returns the first write error if any. NULL is fine. */
int ftm_record_close(ftm_record_writer *w, ftm_error *err);

typedef struct ftm_record_reader ftm_record_reader;

/* Opens path and reads the magic and the header entry. */
int ftm_record_open(const char *path, ftm_record_header *h, ftm_record_reader **out,
                    ftm_error *err);
/* The next entry: 1, 0 at a clean end of file, or a negative error. */
int ftm_record_next(ftm_record_reader *r, ftm_record_entry *e, ftm_error *err);
void ftm_record_close_reader(ftm_record_reader *r);

#endif
