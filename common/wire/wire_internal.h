/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internals of ftm_wire shared by the codec, scan.c, security.c and transport.c. */
#ifndef FTM_WIRE_INTERNAL_H
#define FTM_WIRE_INTERNAL_H

#include "ftm/wire.h"

#include <protobuf-c/protobuf-c.h>

#include <limits.h>
#include <stdbool.h>

/* Walks a protobuf encoding against its descriptor without allocating and
 * reports the first structural problem with its byte offset and field:
 * truncated varint/length, wire type that does not fit the field, groups,
 * invalid wire types, nesting deeper than 32. FTM_OK if well-formed. */
int wire_scan(const ProtobufCMessageDescriptor *desc, const uint8_t *data, size_t size,
              const char *what, ftm_error *err);

/* The payload cap of kind under limits: their max_payload if set, else the
 * kind's default cap. limits may be NULL. */
size_t wire_payload_cap(const ftm_wire_limits *limits, int kind);

/* What a transport keeps of its DDS Security bundle. */
typedef struct wire_security {
    char permissions[PATH_MAX + 32]; /* the permissions file, absolute path */
    /* the partition this participant's writers publish in, which its
     * permissions grant it alone: FTM_WIRE_PARTITION_PREFIX ROLE "." ID */
    char partition[64];
    ftm_wire_role role; /* the role it was issued for */
} wire_security;

/* Checks the DDS Security bundle in directory dir (security.c), issued for
 * participant id (if it says), and makes the Cyclone configuration fragment
 * that enables it: *xml (malloc'ed). Errors name the file and the cause. */
int wire_security_config(const char *dir, uint32_t id, char **xml, wire_security *out,
                         ftm_error *err);

/* The role and id a writer's partition certifies ("ftm.trainee.11"): true
 * if name is such a partition. */
bool wire_partition_identity(const char *name, ftm_wire_role *role, uint32_t *id);

#endif
