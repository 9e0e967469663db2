/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The protocol codec: ftm_wire_msg <-> protobuf bytes (proto/ftm.proto).
 *
 * Decoding never trusts the input: the size is capped per kind, the bytes are
 * checked structurally first (scan.c, to name the offset and field of a
 * problem), protobuf-c unpacks with an allocator that has a byte budget (its
 * unpack has no limits of its own: 1 MB of empty submessages would become
 * ~49 MB), and the unpacked message is validated field by field before it is
 * copied into the caller's plain C structs. Encoding converts to the
 * protobuf-c structs and runs the same validation, so a sender finds out
 * before its peers do.
 *
 * What is particular to a kind is its descriptor (msg_<kind>.c): the field
 * table that codec_fields.c walks and the hooks for the rest; this file is
 * the same for every kind. */
#include "codec_internal.h"

#include <stdalign.h>
#include <stdlib.h>
#include <string.h>

/* ---- budget allocator --------------------------------------------------- */

typedef struct budget {
    ProtobufCAllocator allocator;
    size_t used, limit;
    bool exceeded;
} budget;

#define BUDGET_HEADER (sizeof(max_align_t) > 16 ? sizeof(max_align_t) : 16)

static void *budget_alloc(void *data, size_t size)
{
    budget *b = data;
    if (size > b->limit || size + BUDGET_HEADER > b->limit - b->used) {
        b->exceeded = true;
        return NULL;
    }
    unsigned char *p = malloc(size + BUDGET_HEADER);
    if (!p)
        return NULL;
    memcpy(p, &size, sizeof size);
    b->used += size + BUDGET_HEADER;
    return p + BUDGET_HEADER;
}

static void budget_free(void *data, void *ptr)
{
    if (!ptr)
        return;
    budget *b = data;
    unsigned char *p = (unsigned char *)ptr - BUDGET_HEADER;
    size_t size;
    memcpy(&size, p, sizeof size);
    b->used -= size + BUDGET_HEADER;
    free(p);
}

size_t wire_payload_cap(const ftm_wire_limits *limits, int kind)
{
    return limits && limits->max_payload ? limits->max_payload : ftm_wire_default_cap(kind);
}

/* ---- the steps every kind takes ------------------------------------------- */

/* Every top-level message has `version` as field 1; the codec speaks one. */
static const ProtobufCFieldDescriptor *version_field(const wire_kind_def *k, ftm_error *err)
{
    const ProtobufCFieldDescriptor *fd = protobuf_c_message_descriptor_get_field(k->pb, 1);
    if (fd && fd->type == PROTOBUF_C_TYPE_UINT32 && strcmp(fd->name, "version") == 0)
        return fd;
    ftm_error_set(err, FTM_EINVAL, "%s: internal: %s has no uint32 version as field 1", k->name,
                  k->pb->name);
    return NULL;
}

static int check_message(const wire_kind_def *k, const vctx *v, const ProtobufCMessage *pm)
{
    const ProtobufCFieldDescriptor *fd = version_field(k, v->err);
    if (!fd)
        return FTM_EINVAL;
    const char *base = (const char *)pm;
    if (!*(const protobuf_c_boolean *)(base + fd->quantifier_offset))
        return wire_missing(v, "version");
    const uint32_t version = *(const uint32_t *)(base + fd->offset);
    if (version != FTM_WIRE_VERSION)
        return ftm_error_set(v->err, FTM_EVERSION,
                             "%s: protocol version %u, this side speaks version %u (ftm.v%u)",
                             v->what, version, FTM_WIRE_VERSION, FTM_WIRE_VERSION);
    int rc = wire_fields_check(v, k->pb, k->fields, k->nfields, pm);
    if (rc == FTM_OK && k->check)
        rc = k->check(v, pm);
    return rc;
}

static int convert(const wire_kind_def *k, const ProtobufCMessage *pm, ftm_wire_msg *out,
                   ftm_error *err)
{
    memset(out, 0, sizeof *out);
    out->kind = k->kind;
    int rc = wire_fields_from(k->pb, k->fields, k->nfields, pm, &out->u, k->name, err);
    if (rc == FTM_OK && k->from)
        rc = k->from(pm, out, err);
    if (rc)
        ftm_wire_msg_free(out);
    return rc;
}

static int build(const wire_kind_def *k, const ftm_wire_msg *msg, scratch *s,
                 ProtobufCMessage **out, ftm_error *err)
{
    const ProtobufCFieldDescriptor *fd = version_field(k, err);
    if (!fd)
        return FTM_EINVAL;
    ProtobufCMessage *pm = wire_scratch_alloc(s, k->pb->sizeof_message);
    if (!pm)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", k->name);
    protobuf_c_message_init(k->pb, pm);
    char *base = (char *)pm;
    *(protobuf_c_boolean *)(base + fd->quantifier_offset) = 1;
    *(uint32_t *)(base + fd->offset) = FTM_WIRE_VERSION;
    int rc = wire_fields_to(s, k->pb, k->fields, k->nfields, &msg->u, pm, k->name, err);
    if (rc == FTM_OK && k->to)
        rc = k->to(msg, s, pm, err);
    if (rc == FTM_OK)
        *out = pm;
    return rc;
}

/* ---- public ------------------------------------------------------------------- */

void ftm_wire_msg_free(ftm_wire_msg *msg)
{
    if (!msg)
        return;
    free(msg->storage);
    memset(msg, 0, sizeof *msg);
}

int ftm_wire_decode(int kind, const void *data, size_t size, const ftm_wire_limits *limits,
                    ftm_wire_msg *out, ftm_error *err)
{
    if (!out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_decode: out is NULL");
    memset(out, 0, sizeof *out);
    const wire_kind_def *k = wire_kind(kind);
    if (!k)
        return ftm_error_set(err, FTM_EINVAL, "unknown message kind %d", kind);
    const char *what = k->name;
    if (!data && size)
        return ftm_error_set(err, FTM_EINVAL, "%s: payload is NULL", what);
    size_t cap = wire_payload_cap(limits, kind);
    if (size > cap)
        return ftm_error_set(err, FTM_ETOOBIG, "%s: payload of %zu bytes exceeds the %zu-byte cap",
                             what, size, cap);
    if (size == 0)
        return ftm_error_set(err, FTM_EPARSE, "%s: empty payload", what);
    int rc = wire_scan(k->pb, data, size, what, err);
    if (rc)
        return rc;

    budget b = {{budget_alloc, budget_free, NULL}, 0, 0, false};
    b.allocator.allocator_data = &b;
    b.limit = limits && limits->max_memory ? limits->max_memory : (size_t)64 * 1024 + 16 * size;
    ProtobufCMessage *pm = protobuf_c_message_unpack(k->pb, &b.allocator, size, data);
    if (!pm) {
        if (b.exceeded)
            return ftm_error_set(err, FTM_EBUDGET,
                                 "%s: decoding the %zu-byte payload needs more than its %zu-byte "
                                 "memory budget (e.g. many empty repeated submessages)",
                                 what, size, b.limit);
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: malformed payload of %zu bytes (protobuf-c rejected it)", what,
                             size);
    }
    vctx v = {what, err, (uint32_t)INT32_MAX, 0};
    if (limits && limits->node_count > 0) {
        v.node_limit = (uint32_t)limits->node_count;
        v.scene_nodes = (uint32_t)limits->node_count;
    }
    rc = check_message(k, &v, pm);
    if (rc == FTM_OK)
        rc = convert(k, pm, out, err);
    protobuf_c_message_free_unpacked(pm, &b.allocator);
    return rc;
}

int ftm_wire_encode(const ftm_wire_msg *msg, uint8_t **out, size_t *size, ftm_error *err)
{
    if (!msg || !out || !size)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_encode: NULL argument");
    const wire_kind_def *k = wire_kind(msg->kind);
    if (!k)
        return ftm_error_set(err, FTM_EINVAL, "unknown message kind %d", (int)msg->kind);
    scratch s;
    memset(&s, 0, sizeof s);
    ProtobufCMessage *pm = NULL;
    int rc = build(k, msg, &s, &pm, err);
    if (rc == FTM_OK) {
        const vctx v = {k->name, err, (uint32_t)INT32_MAX, 0};
        rc = check_message(k, &v, pm);
    }
    if (rc == FTM_OK) {
        const size_t n = protobuf_c_message_get_packed_size(pm);
        uint8_t *buf = NULL;
        if (n > k->cap)
            rc = ftm_error_set(err, FTM_ETOOBIG,
                               "%s: encoding of %zu bytes exceeds the %zu-byte cap", k->name, n,
                               k->cap);
        else if (!(buf = malloc(n ? n : 1)))
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", k->name);
        else {
            protobuf_c_message_pack(pm, buf);
            *out = buf;
            *size = n;
        }
    }
    wire_scratch_free(&s);
    return rc;
}
