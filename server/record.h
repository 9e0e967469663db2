/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Session recording file (docs/server.md, "Session recording"), format 2:
 * the magic "FTMREC2\n", then chunks, each a 36-byte head and a body of
 * entries. Head: "FTMC", body length, entry count, CRC-32C of the body
 * (u32 each), first and last tick of its entries (u64 each), CRC-32C of
 * the 32 bytes before it (u32); all little-endian. Entry: a varint byte
 * count, an ftm.v1.RecordEntry, the CRC-32C of those entry bytes (u32). The
 * first chunk holds only the RecordHeader entry. A chunk holds < 100 ms of
 * session (FTM_RECORD_CHUNK_NS) and is written whole, with one write(2), so
 * that a crash or a full disk leaves whole chunks: a file that ends between
 * two chunks is a recording cut short, a file that ends inside one was cut
 * while writing it, and a checksum that differs is damage, named by entry,
 * byte offset and tick.
 * Writer for ftm-server --record, reader for ftm-server --replay. The
 * reader never trusts the file: every length is bounded and a short,
 * oversized, damaged or malformed entry is an FTM_EPARSE error naming the
 * entry number and byte offset. */
#ifndef FTM_SERVER_RECORD_H
#define FTM_SERVER_RECORD_H

#include "ftm/base.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FTM_RECORD_MAGIC "FTMREC2\n"
#define FTM_RECORD_VERSION 2u
/* A chunk is sealed and written before it would span this much session
 * time (entries' time_ns), or grow over FTM_RECORD_CHUNK_BYTES. */
#define FTM_RECORD_CHUNK_NS 100000000ull
#define FTM_RECORD_CHUNK_BYTES (1u << 20)
#define FTM_RECORD_CHUNK_HEAD 36u
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
    /* Segments (a lesson in several files: FILE, FILE.1, FILE.2, ...): */
    uint64_t lesson_start_ns; /* the first segment's start_unix_ns (read: filled in for it) */
    uint32_t segment;         /* 0: the first file */
    bool after_gap;           /* entries before this segment were lost (a write error) */
    uint64_t previous_cut;    /* the previous file was cut by a crash at this byte; 0: whole */
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
    uint32_t segment;    /* the file it is in: 0 the first, k FILE.k; index and offset are
                            that file's */
} ftm_record_entry;

typedef struct ftm_record_writer ftm_record_writer;

/* Creates (truncates) path and writes the magic and the header. */
int ftm_record_create(const char *path, const ftm_record_header *h, ftm_record_writer **out,
                      ftm_error *err);
/* Appends one entry (e->payload/size, tick, kind, ...; index/offset unused)
 * to the open chunk, first writing that chunk out if e->time_ns is
 * FTM_RECORD_CHUNK_NS or more after its first entry's. A write that fails
 * (a full disk, a file size limit) stops the writer for good: the file is
 * cut back to its last whole chunk, after as many of the failed chunk's
 * entries as still fit (each then a chunk of its own). */
int ftm_record_write(ftm_record_writer *w, const ftm_record_entry *e, ftm_error *err);
/* Writes the open chunk out if its first entry is FTM_RECORD_CHUNK_NS or
 * more before time_ns (the session's clock, as the entries' time_ns): for
 * a loop whose entries may pause. */
int ftm_record_tick(ftm_record_writer *w, uint64_t time_ns, ftm_error *err);
/* Writes the open chunk out now, so that a server killed afterwards leaves
 * a recording of whole chunks up to here. */
int ftm_record_flush(ftm_record_writer *w, ftm_error *err);
/* Bytes accepted so far (in the file and in the open chunk). */
uint64_t ftm_record_bytes(const ftm_record_writer *w);
/* Bytes in the file: whole chunks (after a failure, what it kept). */
uint64_t ftm_record_kept(const ftm_record_writer *w);
/* The tick of the last entry in the file (0: none yet). */
uint64_t ftm_record_kept_tick(const ftm_record_writer *w);
/* The errno of the write that stopped the writer (0: none). */
int ftm_record_errno(const ftm_record_writer *w);
/* Free bytes a server waits for, after a full disk stopped its recording,
 * before it records on into a new file of the lesson. */
#define FTM_RECORD_RESUME_FREE (1u << 20)
/* Flushes and closes; returns the first write error if any. NULL is fine. */
int ftm_record_close(ftm_record_writer *w, ftm_error *err);

typedef struct ftm_record_reader ftm_record_reader;

/* The name of a lesson's segment k: path itself for 0, "path.k" after. */
int ftm_record_segment_path(const char *path, uint32_t k, char *buf, size_t cap);

/* Opens path and reads the magic and the header entry. The reader reads
 * the whole lesson: at the clean end of a segment it goes on to the next
 * one if that file exists (path.1, path.2, ...), whose header must be the
 * same lesson's (its lesson_start_ns, segment number, scene and rate); its
 * entries carry their segment. */
int ftm_record_open(const char *path, ftm_record_header *h, ftm_record_reader **out,
                    ftm_error *err);
/* The next entry: 1, 0 at a clean end of file (after a whole chunk), or a
 * negative error. */
int ftm_record_next(ftm_record_reader *r, ftm_record_entry *e, ftm_error *err);
/* After ftm_record_next failed: true if the failure was damage (a checksum
 * that differs, a chunk cut short): the entries handed out before it passed
 * their checks, and a replay may stop there (--replay-upto-damage). */
bool ftm_record_damaged(const ftm_record_reader *r);
/* And the damage is in the file's last chunk (cut short, or its checksum
 * differs and no byte follows it): what a crash while writing leaves. */
bool ftm_record_damaged_at_end(const ftm_record_reader *r);
/* The byte where the damaged chunk begins (its head). */
uint64_t ftm_record_damage_offset(const ftm_record_reader *r);
/* Crash cuts passed over: a file cut short whose next file, a resumed
 * server's, says it goes on from there (previous_cut). */
uint32_t ftm_record_cuts_passed(const ftm_record_reader *r);
/* The file being read (the last segment opened) and its header. */
const char *ftm_record_reader_path(const ftm_record_reader *r);
const ftm_record_header *ftm_record_reader_header(const ftm_record_reader *r);
void ftm_record_close_reader(ftm_record_reader *r);

#endif
