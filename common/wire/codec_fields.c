/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The field tables at work: checks, decoding and encoding of the fields a
 * kind lists in its table (codec_internal.h, wire_field). The protobuf side
 * of a field (its name, where protobuf-c keeps it and its presence flag, its
 * type) comes from protobuf-c's descriptor of the message, by field number
 * (a lookup in its ranges of numbers, not a search by name); a table line
 * that disagrees with proto/ftm.proto is an error that names it
 * (test_wire_golden encodes every field). */
#include "codec_internal.h"

#include <stdio.h>
#include <string.h>

/* A field of protobuf-c's struct pm, at offset off. */
#define PB(pm, off, T) (*(T *)((char *)(pm) + (off)))
#define PB_CONST(pm, off, T) (*(const T *)((const char *)(pm) + (off)))

static bool agrees(const wire_field *f, const ProtobufCFieldDescriptor *fd)
{
    if (fd->label != PROTOBUF_C_LABEL_OPTIONAL)
        return false;
    switch ((wire_ftype)f->type) {
    case WF_U32:
    case WF_I32: return fd->type == PROTOBUF_C_TYPE_UINT32 && f->size == sizeof(uint32_t);
    case WF_U64:
        return (fd->type == PROTOBUF_C_TYPE_UINT64 || fd->type == PROTOBUF_C_TYPE_FIXED64) &&
               f->size == sizeof(uint64_t);
    case WF_F64: return fd->type == PROTOBUF_C_TYPE_DOUBLE && f->size == sizeof(double);
    case WF_BOOL: return fd->type == PROTOBUF_C_TYPE_BOOL && f->size == sizeof(bool);
    case WF_ENUM: return fd->type == PROTOBUF_C_TYPE_ENUM && f->size == sizeof(int);
    case WF_TEXT: return fd->type == PROTOBUF_C_TYPE_STRING && f->size > 0;
    case WF_BYTES: return fd->type == PROTOBUF_C_TYPE_BYTES && f->size > 0;
    case WF_TISSUE:
        return fd->type == PROTOBUF_C_TYPE_MESSAGE &&
               fd->descriptor == &ftm__v1__tissue_params__descriptor &&
               f->size == sizeof(ftm_wire_tissue);
    case WF_LIMITS:
        return fd->type == PROTOBUF_C_TYPE_MESSAGE &&
               fd->descriptor == &ftm__v1__depth_limits__descriptor && f->size == sizeof(int32_t);
    case WF_MODE:
        return fd->type == PROTOBUF_C_TYPE_MESSAGE &&
               fd->descriptor == &ftm__v1__integrator_mode__descriptor &&
               f->size == sizeof(ftm_sim_mode);
    }
    return false;
}

/* The protobuf-c field of table line f, or NULL (and err) if the table
 * does not match the schema. */
static const ProtobufCFieldDescriptor *pb_field(const ProtobufCMessageDescriptor *desc,
                                                const wire_field *f, const char *what,
                                                ftm_error *err)
{
    const ProtobufCFieldDescriptor *fd = protobuf_c_message_descriptor_get_field(desc, f->id);
    if (!fd || !agrees(f, fd)) {
        ftm_error_set(err, FTM_EINVAL, "%s: internal: the codec's field %u (%s) disagrees with %s",
                      what, f->id, f->cname, desc->name);
        return NULL;
    }
    return fd;
}

static bool is_scalar(const wire_field *f)
{
    return f->type <= WF_ENUM;
}

/* A present scalar as a wider value (doubles apart). */
static uint64_t scalar_bits(const wire_field *f, const void *p)
{
    switch ((wire_ftype)f->type) {
    case WF_U64: return *(const uint64_t *)p;
    case WF_BOOL: return *(const protobuf_c_boolean *)p != 0;
    case WF_ENUM: return (uint64_t)(int64_t)(*(const int *)p);
    default: return *(const uint32_t *)p;
    }
}

/* ---- checks ------------------------------------------------------------------ */

static int check_rule(const vctx *v, const wire_field *f, const char *name, const void *p)
{
    if (f->type == WF_F64) {
        const double x = *(const double *)p;
        if (f->rule != WR_POSITIVE)
            return FTM_OK;
        int rc = wire_check_finite(v, name, x);
        if (rc)
            return rc;
        if (!(x > 0))
            return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be > 0 (got %g)", v->what, name,
                                 x);
        return FTM_OK;
    }
    const uint64_t x = scalar_bits(f, p);
    switch ((wire_rule)f->rule) {
    case WR_NONZERO:
        if (x == 0)
            return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be > 0", v->what, name);
        return FTM_OK;
    case WR_DEPTH: return wire_check_depth(v, name, (uint32_t)x);
    case WR_NODES:
        if (x == 0 || x > INT32_MAX)
            return ftm_error_set(v->err, FTM_ERANGE, "%s: %s %u out of range (1..%d)", v->what,
                                 name, (unsigned)x, INT32_MAX);
        return FTM_OK;
    case WR_ENUM:
        if ((int64_t)x < f->lo || (int64_t)x > f->hi)
            return ftm_error_set(v->err, FTM_EINVAL, "%s: unknown %s %d", v->what, name,
                                 (int)(int64_t)x);
        return FTM_OK;
    default: return FTM_OK;
    }
}

static int check_field(const vctx *v, const wire_field *f, const ProtobufCFieldDescriptor *fd,
                       const ProtobufCMessage *pm)
{
    const void *p = (const char *)pm + fd->offset;
    if (is_scalar(f)) {
        if (!PB_CONST(pm, fd->quantifier_offset, protobuf_c_boolean))
            return (f->flags & WF_OPTIONAL) ? FTM_OK : wire_missing(v, fd->name);
        return check_rule(v, f, fd->name, p);
    }
    switch ((wire_ftype)f->type) {
    case WF_TEXT: return wire_check_text(v, fd->name, *(char *const *)p, f->size, f->flags);
    case WF_BYTES: {
        const ProtobufCBinaryData *b = p;
        if (!PB_CONST(pm, fd->quantifier_offset, protobuf_c_boolean) || b->len == 0)
            return wire_missing(v, fd->name);
        if (b->len > f->size)
            return ftm_error_set(v->err, FTM_EINVAL, "%s: %s of %zu bytes (at most %d)", v->what,
                                 fd->name, b->len, (int)f->size);
        return FTM_OK;
    }
    case WF_TISSUE: {
        const Ftm__V1__TissueParams *t = *(Ftm__V1__TissueParams *const *)p;
        return !t && (f->flags & WF_OPTIONAL) ? FTM_OK : wire_check_tissue(v, fd->name, t);
    }
    case WF_LIMITS: return wire_check_limits(v, fd->name, *(Ftm__V1__DepthLimits *const *)p);
    case WF_MODE: {
        const Ftm__V1__IntegratorMode *m = *(Ftm__V1__IntegratorMode *const *)p;
        if (!m)
            return (f->flags & WF_OPTIONAL) ? FTM_OK : wire_missing(v, fd->name);
        return wire_check_mode(v, m);
    }
    default: return FTM_OK;
    }
}

int wire_fields_check(const vctx *v, const ProtobufCMessageDescriptor *desc, const wire_field *f,
                      size_t n, const ProtobufCMessage *pm)
{
    for (size_t i = 0; i < n; i++) {
        const ProtobufCFieldDescriptor *fd = pb_field(desc, &f[i], v->what, v->err);
        if (!fd)
            return FTM_EINVAL;
        if (f[i].flags & WF_HOOK_CHECKED)
            continue;
        int rc = check_field(v, &f[i], fd, pm);
        if (rc)
            return rc;
    }
    return FTM_OK;
}

/* ---- protobuf-c -> plain C ------------------------------------------------------ */

/* Copies n bytes of value into the C member of f. */
static void put(void *c, const wire_field *f, const void *value, size_t n)
{
    memcpy((char *)c + f->off, value, n);
}

static void put_flag(void *c, uint16_t off, bool value)
{
    memcpy((char *)c + off, &value, sizeof value);
}

/* Scalars other than bool have the same size and bits in C and in
 * protobuf-c (agrees() checks it): a copy. */
static void from_field(const wire_field *f, const ProtobufCFieldDescriptor *fd,
                       const ProtobufCMessage *pm, void *c)
{
    const void *p = (const char *)pm + fd->offset;
    if (is_scalar(f)) {
        /* an absent optional field reads as 0 */
        const bool has = PB_CONST(pm, fd->quantifier_offset, protobuf_c_boolean) != 0;
        if (f->type == WF_BOOL)
            put_flag(c, f->off, has && *(const protobuf_c_boolean *)p);
        else if (has)
            put(c, f, p, f->size);
        else
            memset((char *)c + f->off, 0, f->size);
        return;
    }
    switch ((wire_ftype)f->type) {
    case WF_TEXT: {
        const char *text = *(char *const *)p;
        snprintf((char *)c + f->off, f->size, "%s", text ? text : "");
        break;
    }
    case WF_BYTES: {
        const ProtobufCBinaryData *b = p;
        const int32_t len = (int32_t)b->len;
        put(c, f, b->data, b->len);
        memcpy((char *)c + f->off2, &len, sizeof len);
        break;
    }
    case WF_TISSUE: {
        const Ftm__V1__TissueParams *t = *(Ftm__V1__TissueParams *const *)p;
        if (f->flags & WF_OPTIONAL)
            put_flag(c, f->has_off, t != NULL);
        if (t) {
            const ftm_wire_tissue x = wire_tissue_from(t);
            put(c, f, &x, sizeof x);
        }
        break;
    }
    case WF_LIMITS: {
        const Ftm__V1__DepthLimits *d = *(Ftm__V1__DepthLimits *const *)p;
        const int32_t lo = (int32_t)d->min, hi = (int32_t)d->max;
        put(c, f, &lo, sizeof lo);
        memcpy((char *)c + f->off2, &hi, sizeof hi);
        break;
    }
    case WF_MODE: {
        const Ftm__V1__IntegratorMode *m = *(Ftm__V1__IntegratorMode *const *)p;
        if (f->flags & WF_OPTIONAL)
            put_flag(c, f->has_off, m != NULL);
        if (m) {
            const ftm_sim_mode x = wire_mode_from(m);
            put(c, f, &x, sizeof x);
        }
        break;
    }
    default: break;
    }
}

int wire_fields_from(const ProtobufCMessageDescriptor *desc, const wire_field *f, size_t n,
                     const ProtobufCMessage *pm, void *c, const char *what, ftm_error *err)
{
    for (size_t i = 0; i < n; i++) {
        const ProtobufCFieldDescriptor *fd = pb_field(desc, &f[i], what, err);
        if (!fd)
            return FTM_EINVAL;
        from_field(&f[i], fd, pm, c);
    }
    return FTM_OK;
}

/* ---- plain C -> protobuf-c ------------------------------------------------------ */

/* The C member of f. */
static const void *member(const void *c, const wire_field *f)
{
    return (const char *)c + f->off;
}

static bool flag_at(const void *c, uint16_t off)
{
    bool b;
    memcpy(&b, (const char *)c + off, sizeof b);
    return b;
}

static bool all_zero(const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        if (b[i])
            return false;
    return true;
}

/* A scalar: present unless optional and zero. */
static int scalar_to(const wire_field *f, const ProtobufCFieldDescriptor *fd, const void *c,
                     ProtobufCMessage *pm, const char *what, ftm_error *err)
{
    void *p = (char *)pm + fd->offset;
    if (f->type == WF_I32) {
        int32_t x;
        memcpy(&x, member(c, f), sizeof x);
        if (x < 0)
            return ftm_error_set(err, FTM_EINVAL, "%s: %s is negative (%lld)", what, f->cname,
                                 (long long)x);
    }
    if (f->type == WF_BOOL)
        *(protobuf_c_boolean *)p = flag_at(c, f->off);
    else
        memcpy(p, member(c, f), f->size);
    const bool zero = all_zero(member(c, f), f->size);
    PB(pm, fd->quantifier_offset, protobuf_c_boolean) = !(zero && (f->flags & WF_OPTIONAL));
    return FTM_OK;
}

static int field_to(scratch *s, const wire_field *f, const ProtobufCFieldDescriptor *fd,
                    const void *c, ProtobufCMessage *pm, const char *what, ftm_error *err)
{
    if (is_scalar(f))
        return scalar_to(f, fd, c, pm, what, err);
    void *p = (char *)pm + fd->offset;
    switch ((wire_ftype)f->type) {
    case WF_TEXT: {
        const char *text = member(c, f);
        if (!memchr(text, '\0', f->size))
            return ftm_error_set(err, FTM_EINVAL, "%s: %s is not NUL-terminated", what, f->cname);
        *(char **)p = text[0] ? (char *)text : NULL; /* only read while packing */
        return FTM_OK;
    }
    case WF_BYTES: {
        int32_t len;
        memcpy(&len, (const char *)c + f->off2, sizeof len);
        if (len < 0 || len > (int32_t)f->size)
            return ftm_error_set(err, FTM_EINVAL, "%s: %s_len %d out of range (1..%d)", what,
                                 f->cname, len, (int)f->size);
        PB(pm, fd->quantifier_offset, protobuf_c_boolean) = 1;
        *(ProtobufCBinaryData *)p = (ProtobufCBinaryData){(size_t)len, (uint8_t *)member(c, f)};
        return FTM_OK;
    }
    case WF_TISSUE:
        if (!(f->flags & WF_OPTIONAL) || flag_at(c, f->has_off))
            *(Ftm__V1__TissueParams **)p = wire_tissue_to(s, member(c, f));
        return FTM_OK;
    case WF_LIMITS: {
        int32_t lo, hi;
        memcpy(&lo, member(c, f), sizeof lo);
        memcpy(&hi, (const char *)c + f->off2, sizeof hi);
        int rc = wire_limits_to(s, what, lo, hi, err);
        if (rc == FTM_OK)
            *(Ftm__V1__DepthLimits **)p = &s->limits;
        return rc;
    }
    case WF_MODE: {
        if ((f->flags & WF_OPTIONAL) && !flag_at(c, f->has_off))
            return FTM_OK;
        ftm_sim_mode md;
        memcpy(&md, member(c, f), sizeof md);
        int rc = wire_mode_to(s, what, &md, err);
        if (rc == FTM_OK)
            *(Ftm__V1__IntegratorMode **)p = &s->mode;
        return rc;
    }
    default: return FTM_OK;
    }
}

int wire_fields_to(scratch *s, const ProtobufCMessageDescriptor *desc, const wire_field *f,
                   size_t n, const void *c, ProtobufCMessage *pm, const char *what, ftm_error *err)
{
    for (size_t i = 0; i < n; i++) {
        const ProtobufCFieldDescriptor *fd = pb_field(desc, &f[i], what, err);
        if (!fd)
            return FTM_EINVAL;
        int rc = field_to(s, &f[i], fd, c, pm, what, err);
        if (rc)
            return rc;
    }
    return FTM_OK;
}
