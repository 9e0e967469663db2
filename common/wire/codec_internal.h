/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internals of the codec: the descriptor of a message kind and the field
 * tables the codec walks (docs/protocol.md, "The codec").
 *
 * A kind is one wire_kind_def (msg_<kind>.c, listed in kinds.c): its name,
 * DDS topic, size cap, protobuf-c descriptor, a table of its plain fields
 * and up to three hooks for what a table cannot say. For every kind the
 * codec (codec.c) decodes by checking the version, then each table field in
 * table order, then the kind's check hook; it converts the table fields and
 * then runs the from hook. It encodes by setting the version, converting
 * the table fields, running the to hook and then the decoder's checks. */
#ifndef FTM_WIRE_CODEC_INTERNAL_H
#define FTM_WIRE_CODEC_INTERNAL_H

#include "wire_internal.h"

#include "ftm/v1/ftm.pb-c.h"

#include <stddef.h>

#define WIRE_DEPTH_MAX 1000000u /* as ftm_sim_set_depth */

/* What the checks of a decoded (or about to be encoded) message know. */
typedef struct vctx {
    const char *what; /* the kind's name: every message starts with it */
    ftm_error *err;
    uint32_t node_limit;  /* node indices must be below this */
    uint32_t scene_nodes; /* the announced mesh's nodes; 0: unknown */
} vctx;

/* Everything one encoding needs besides the top-level struct, freed at
 * once: the sub-messages a message has at most one of, and blocks. */
typedef struct scratch {
    Ftm__V1__Vec3 axis_scale;
    Ftm__V1__TissueParams tissue;
    Ftm__V1__IntegratorMode mode;
    Ftm__V1__DepthLimits limits;
    Ftm__V1__Pause pause;
    Ftm__V1__Resume resume;
    Ftm__V1__Reset reset;
    void *blocks[8];
    int nblocks;
} scratch;

/* A zeroed block freed with the scratch; NULL when out of memory. */
void *wire_scratch_alloc(scratch *s, size_t size);
void wire_scratch_free(scratch *s);

/* ---- field tables ---------------------------------------------------------- */

/* How a field is held in C and on the wire. The protobuf side (name,
 * offsets, presence flag, wire type) comes from protobuf-c's descriptor, by
 * the field's number. */
typedef enum wire_ftype {
    WF_U32,    /* uint32_t, uint32 */
    WF_I32,    /* int32_t >= 0, uint32 (encoding refuses a negative value) */
    WF_U64,    /* uint64_t, uint64 or fixed64 */
    WF_F64,    /* double, double */
    WF_BOOL,   /* bool, bool */
    WF_ENUM,   /* a C enum of the same values, enum */
    WF_TEXT,   /* char[size], string: shorter than size, NUL-terminated */
    WF_BYTES,  /* uint8_t[size] and int32_t <name>_len at off2, bytes */
    WF_TISSUE, /* ftm_wire_tissue, TissueParams */
    WF_LIMITS, /* int32_t min at off and max at off2, DepthLimits */
    WF_MODE,   /* ftm_sim_mode, IntegratorMode (its errors say mode.*) */
} wire_ftype;

enum {
    /* Absent on the wire means zero in C (and zero, all bytes 0, is not
     * sent); for WF_TISSUE and WF_MODE, the bool at has_off says whether
     * it is there. */
    WF_OPTIONAL = 1 << 0,
    WF_NONEMPTY = 1 << 1, /* text: at least one byte (else "missing field") */
    WF_PLAIN = 1 << 2,    /* text: no control characters (shown on HUDs, logs) */
    /* the kind's check hook checks it, where the order of its checks
     * differs from the table's; the table only converts it */
    WF_HOOK_CHECKED = 1 << 3,
};

/* What a present scalar must hold. Of the rules, doubles take only
 * WR_POSITIVE (finite and > 0); a hook checks those that need more. */
typedef enum wire_rule {
    WR_ANY = 0,
    WR_NONZERO,  /* > 0 */
    WR_POSITIVE, /* a double > 0 */
    WR_DEPTH,    /* 0..WIRE_DEPTH_MAX */
    WR_NODES,    /* 1..INT32_MAX */
    WR_ENUM,     /* lo..hi, else "unknown <name>" */
} wire_rule;

typedef struct wire_field {
    uint16_t id;       /* the field's number in proto/ftm.proto */
    const char *cname; /* the C member (encoding errors speak of the caller's struct) */
    uint16_t off;      /* the C member's offset in the kind's struct */
    uint16_t size;     /* and its size */
    uint8_t type;      /* wire_ftype */
    uint8_t flags;     /* WF_OPTIONAL, ... */
    uint8_t rule;      /* wire_rule */
    int8_t lo, hi;     /* WR_ENUM's range */
    uint16_t off2;     /* WF_BYTES: the length; WF_LIMITS: the max */
    uint16_t has_off;  /* WF_OPTIONAL WF_TISSUE, WF_MODE: their bool */
} wire_field;

/* The name, offset and size of member m of the kind's C struct T: a table
 * line reads {number, WIRE_C(T, m), WF_type, .more = ...}. */
#define WIRE_C(T, m)                                                                               \
    .cname = #m, .off = (uint16_t)offsetof(T, m), .size = (uint16_t)sizeof(((T *)0)->m)

/* Checks the table fields of a decoded message, in table order. */
int wire_fields_check(const vctx *v, const ProtobufCMessageDescriptor *desc, const wire_field *f,
                      size_t n, const ProtobufCMessage *pm);
/* Copies them into the kind's C struct c. */
int wire_fields_from(const ProtobufCMessageDescriptor *desc, const wire_field *f, size_t n,
                     const ProtobufCMessage *pm, void *c, const char *what, ftm_error *err);
/* Sets them in pm from the kind's C struct c (sub-messages in s). */
int wire_fields_to(scratch *s, const ProtobufCMessageDescriptor *desc, const wire_field *f,
                   size_t n, const void *c, ProtobufCMessage *pm, const char *what, ftm_error *err);

/* ---- kinds ----------------------------------------------------------------- */

typedef struct wire_kind_def {
    ftm_wire_kind kind;
    const char *name;  /* "tick frame": ftm_wire_kind_name, first words of errors */
    const char *topic; /* "ftm_v1_tick_frame": ftm_wire_topic_name */
    size_t cap;        /* FTM_WIRE_CAP_*: ftm_wire_default_cap */
    const ProtobufCMessageDescriptor *pb;
    const wire_field *fields; /* in the order of the decoder's checks */
    size_t nfields;
    /* What the table cannot say; each may be NULL. check: after the table's
     * checks. from: after the table's conversion (arrays go in
     * out->storage). to: after the table's conversion. */
    int (*check)(const vctx *v, const ProtobufCMessage *pm);
    int (*from)(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err);
    int (*to)(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err);
} wire_kind_def;

/* The descriptor of a kind, NULL for an unknown kind (kinds.c). */
const wire_kind_def *wire_kind(int kind);

extern const wire_kind_def wire_kind_announce, wire_kind_probe_input, wire_kind_tick,
    wire_kind_keyframe, wire_kind_status, wire_kind_control, wire_kind_control_reply;

/* ---- shared parts (codec_parts.c) -------------------------------------------- */

int wire_missing(const vctx *v, const char *field);
int wire_check_finite(const vctx *v, const char *field, double x);
int wire_check_vec3(const vctx *v, const char *field, const Ftm__V1__Vec3 *p);
int wire_check_depth(const vctx *v, const char *field, uint32_t depth);
int wire_check_tissue(const vctx *v, const char *field, const Ftm__V1__TissueParams *t);
int wire_check_limits(const vctx *v, const char *field, const Ftm__V1__DepthLimits *d);
int wire_check_mode(const vctx *v, const Ftm__V1__IntegratorMode *m);
/* Text shorter than cap bytes; WF_NONEMPTY, WF_PLAIN as in flags. */
int wire_check_text(const vctx *v, const char *field, const char *text, size_t cap, int flags);
/* The contact columns of a TickFrame or Keyframe m, for the three calls
 * below: their lengths and arrays, or (SET) pointers to them. */
#define WIRE_CONTACTS_OF(m)                                                                        \
    (m)->n_contact_node, (m)->contact_node, (m)->n_contact_group, (m)->contact_group,              \
        (m)->n_contact_kind, (m)->contact_kind, (m)->n_contact_value, (m)->contact_value
#define WIRE_CONTACTS_SET(m)                                                                       \
    &(m)->n_contact_node, &(m)->contact_node, &(m)->n_contact_group, &(m)->contact_group,          \
        &(m)->n_contact_kind, &(m)->contact_kind, &(m)->n_contact_value, &(m)->contact_value

/* Contact columns: equal lengths, nodes below limit, known kinds, finite
 * values. */
int wire_check_contacts(const vctx *v, size_t n, const uint32_t *node, size_t n_group,
                        const uint32_t *group, size_t n_kind, const Ftm__V1__ContactKind *kind,
                        size_t n_value, const double *value, uint32_t limit);

ftm_vec3 wire_vec_from(const Ftm__V1__Vec3 *p);
ftm_wire_tissue wire_tissue_from(const Ftm__V1__TissueParams *t);
/* Checked columns (n of each) into out[n]. */
void wire_contacts_from(size_t n, const uint32_t *node, size_t n_group, const uint32_t *group,
                        size_t n_kind, const Ftm__V1__ContactKind *kind, size_t n_value,
                        const double *value, ftm_contact *out);
ftm_sim_mode wire_mode_from(const Ftm__V1__IntegratorMode *m);
/* One allocation holding up to three arrays, each 16-byte aligned. */
void *wire_alloc_arrays(size_t a, size_t b, size_t c, void **pa, void **pb, void **pc);

void wire_vec_to(Ftm__V1__Vec3 *p, ftm_vec3 v);
/* Into s->tissue (with s->axis_scale). */
Ftm__V1__TissueParams *wire_tissue_to(scratch *s, const ftm_wire_tissue *t);
/* Into s->limits; refuses negative limits. */
int wire_limits_to(scratch *s, const char *what, int32_t lo, int32_t hi, ftm_error *err);
/* Into s->mode; refuses substeps < 1 and negative counters. */
int wire_mode_to(scratch *s, const char *what, const ftm_sim_mode *md, ftm_error *err);
/* The count contacts at c as the protocol's columns, in blocks of s. */
int wire_contacts_to(scratch *s, const char *what, const ftm_contact *c, int32_t count,
                     size_t *n_node, uint32_t **node, size_t *n_group, uint32_t **group,
                     size_t *n_kind, Ftm__V1__ContactKind **kind, size_t *n_value, double **value,
                     ftm_error *err);

#endif
