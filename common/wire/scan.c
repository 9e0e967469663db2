/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A structural check of a protobuf encoding against its descriptor, used to
 * say where and why a payload is malformed (protobuf-c's unpack only says
 * that it failed). Allocates nothing; bounded recursion. */
#include "wire_internal.h"

#include <stdio.h>
#include <string.h>

#define SCAN_MAX_DEPTH 32

typedef struct scan_ctx {
    const uint8_t *base; /* start of the whole payload, for offsets */
    const char *what;    /* message kind name */
    ftm_error *err;
} scan_ctx;

/* Reads a varint at *p (< end). Returns 0 on success, -1 if truncated,
 * -2 if longer than 10 bytes. */
static int read_varint(const uint8_t **p, const uint8_t *end, uint64_t *value)
{
    uint64_t v = 0;
    for (int i = 0; i < 10; i++) {
        if (*p >= end)
            return -1;
        uint8_t b = *(*p)++;
        v |= (uint64_t)(b & 0x7f) << (7 * i);
        if (!(b & 0x80)) {
            *value = v;
            return 0;
        }
    }
    return -2;
}

/* Wire type a field must have (repeated numeric fields may also be 2). */
static int expected_wire_type(ProtobufCType type)
{
    switch (type) {
    case PROTOBUF_C_TYPE_INT32:
    case PROTOBUF_C_TYPE_SINT32:
    case PROTOBUF_C_TYPE_UINT32:
    case PROTOBUF_C_TYPE_INT64:
    case PROTOBUF_C_TYPE_SINT64:
    case PROTOBUF_C_TYPE_UINT64:
    case PROTOBUF_C_TYPE_BOOL:
    case PROTOBUF_C_TYPE_ENUM: return 0;
    case PROTOBUF_C_TYPE_SFIXED64:
    case PROTOBUF_C_TYPE_FIXED64:
    case PROTOBUF_C_TYPE_DOUBLE: return 1;
    case PROTOBUF_C_TYPE_SFIXED32:
    case PROTOBUF_C_TYPE_FIXED32:
    case PROTOBUF_C_TYPE_FLOAT: return 5;
    default: return 2; /* string, bytes, message */
    }
}

static const char *wire_type_name(int wt)
{
    switch (wt) {
    case 0: return "varint";
    case 1: return "64-bit";
    case 2: return "length-delimited";
    case 3: return "start-group";
    case 4: return "end-group";
    case 5: return "32-bit";
    default: return "invalid";
    }
}

static int fail(const scan_ctx *c, const uint8_t *at, const char *path, const char *fmt,
                const char *detail)
{
    char where[256];
    if (path[0])
        snprintf(where, sizeof where, "byte %zu, field %.200s", (size_t)(at - c->base), path);
    else
        snprintf(where, sizeof where, "byte %zu", (size_t)(at - c->base));
    char msg[256];
    snprintf(msg, sizeof msg, fmt, detail);
    return ftm_error_set(c->err, FTM_EPARSE, "%s: malformed at %s: %s", c->what, where, msg);
}

static int scan_message(const scan_ctx *c, const ProtobufCMessageDescriptor *desc,
                        const uint8_t *p, const uint8_t *end, const char *parent, int depth)
{
    if (depth > SCAN_MAX_DEPTH)
        return fail(c, p, parent, "%snesting deeper than 32 levels", "");
    while (p < end) {
        const uint8_t *field_start = p;
        uint64_t key;
        int rc = read_varint(&p, end, &key);
        if (rc)
            return fail(c, field_start, parent, "%s field key", rc == -1 ? "truncated" : "overlong");
        uint64_t number = key >> 3;
        int wt = (int)(key & 7);
        const ProtobufCFieldDescriptor *fd =
            (number >= 1 && number <= 0x1fffffff)
                ? protobuf_c_message_descriptor_get_field(desc, (unsigned)number)
                : NULL;
        char path[160];
        if (fd)
            snprintf(path, sizeof path, "%.100s%s%.40s", parent, parent[0] ? "." : "", fd->name);
        else
            snprintf(path, sizeof path, "%.100s%s#%llu", parent, parent[0] ? "." : "",
                     (unsigned long long)number);
        if (number == 0 || number > 0x1fffffff)
            return fail(c, field_start, parent, "%sinvalid field number", "");
        if (wt == 3 || wt == 4)
            return fail(c, field_start, path, "wire type %s (groups are not supported)",
                        wire_type_name(wt));
        if (wt > 5)
            return fail(c, field_start, path, "invalid wire type%s", "");
        if (fd) {
            int want = expected_wire_type(fd->type);
            bool packable = want != 2 && fd->label == PROTOBUF_C_LABEL_REPEATED;
            if (wt != want && !(packable && wt == 2)) {
                char d[96];
                snprintf(d, sizeof d, "wire type %s, expected %s", wire_type_name(wt),
                         wire_type_name(want));
                return fail(c, field_start, path, "%s", d);
            }
        }
        const uint8_t *value_start = p;
        uint64_t v;
        switch (wt) {
        case 0:
            rc = read_varint(&p, end, &v);
            if (rc)
                return fail(c, value_start, path, "%s varint", rc == -1 ? "truncated" : "overlong");
            break;
        case 1:
            if ((size_t)(end - p) < 8)
                return fail(c, value_start, path, "truncated 64-bit value%s", "");
            p += 8;
            break;
        case 5:
            if ((size_t)(end - p) < 4)
                return fail(c, value_start, path, "truncated 32-bit value%s", "");
            p += 4;
            break;
        case 2: {
            rc = read_varint(&p, end, &v);
            if (rc)
                return fail(c, value_start, path, "%s length", rc == -1 ? "truncated" : "overlong");
            if (v > (uint64_t)(end - p)) {
                char d[96];
                snprintf(d, sizeof d, "length %llu runs past the end (%zu bytes left)",
                         (unsigned long long)v, (size_t)(end - p));
                return fail(c, value_start, path, "%s", d);
            }
            const uint8_t *sub = p, *sub_end = p + v;
            p = sub_end;
            if (!fd)
                break;
            if (fd->type == PROTOBUF_C_TYPE_MESSAGE) {
                rc = scan_message(c, fd->descriptor, sub, sub_end, path, depth + 1);
                if (rc)
                    return rc;
            } else if (fd->label == PROTOBUF_C_LABEL_REPEATED &&
                       expected_wire_type(fd->type) != 2) {
                /* packed numbers */
                int want = expected_wire_type(fd->type);
                size_t n = (size_t)(sub_end - sub);
                if (want == 1 && n % 8)
                    return fail(c, sub, path, "packed 64-bit values: %s",
                                "length is not a multiple of 8");
                if (want == 5 && n % 4)
                    return fail(c, sub, path, "packed 32-bit values: %s",
                                "length is not a multiple of 4");
                if (want == 0) {
                    while (sub < sub_end) {
                        const uint8_t *at = sub;
                        rc = read_varint(&sub, sub_end, &v);
                        if (rc)
                            return fail(c, at, path, "packed varints: %s value",
                                        rc == -1 ? "truncated" : "overlong");
                    }
                }
            }
            break;
        }
        default: break;
        }
    }
    return FTM_OK;
}

int wire_scan(const ProtobufCMessageDescriptor *desc, const uint8_t *data, size_t size,
              const char *what, ftm_error *err)
{
    scan_ctx c = {data, what, err};
    return scan_message(&c, desc, data, data + size, "", 0);
}
