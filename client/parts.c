/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Participant rows; see parts.h. */
#include "parts.h"

#include <string.h>

ftm_client_part *ftm_parts_find(ftm_client_part *parts, int32_t *n, uint32_t id, bool add)
{
    int32_t departed = -1;
    for (int32_t i = 0; i < *n; i++) {
        if (parts[i].id == id)
            return &parts[i];
        if (parts[i].left && departed < 0)
            departed = i;
    }
    if (!add)
        return NULL;
    ftm_client_part *p;
    if (*n < FTM_CLIENT_MAX_PARTS)
        p = &parts[(*n)++];
    else if (departed >= 0) /* the earliest departed row makes room */
        p = &parts[departed];
    else
        return NULL;
    memset(p, 0, sizeof *p);
    p->id = id;
    return p;
}

void ftm_parts_gone(ftm_client_part *parts, int32_t *n, uint32_t id, bool keep)
{
    ftm_client_part *p = ftm_parts_find(parts, n, id, false);
    if (!p)
        return;
    if (keep)
        p->left = true;
    else
        *p = parts[--*n];
}

void ftm_parts_forget_departed(ftm_client_part *parts, int32_t *n)
{
    int32_t w = 0;
    for (int32_t i = 0; i < *n; i++)
        if (!parts[i].left)
            parts[w++] = parts[i];
    *n = w;
}
