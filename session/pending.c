/* SPDX-License-Identifier: GPL-3.0-or-later */
/* An instructor's commands waiting for their replies (pending.h). */
#include "pending.h"

#include <inttypes.h>
#include <stdio.h>
#include <string.h>

static void pending_drop(ftm_pending *p, int32_t i)
{
    memmove(&p->cmd[i], &p->cmd[i + 1], (size_t)(p->n - i - 1) * sizeof p->cmd[0]);
    p->n--;
}

static void unanswered_text(const ftm_pending_cmd *c, int64_t waited_ns, char *text, size_t cap)
{
    snprintf(text, cap, "%s: no reply from the server in %.0f s (not heard: lost, or no server)",
             c->what, (double)waited_ns * 1e-9);
}

bool ftm_pending_add(ftm_pending *p, uint64_t id, const char *what, int64_t now_ns, char *text,
                     size_t cap)
{
    bool gave_up = false;
    if (cap)
        text[0] = '\0';
    if (p->n == FTM_PENDING_MAX) {
        unanswered_text(&p->cmd[0], now_ns - p->cmd[0].sent_ns, text, cap);
        pending_drop(p, 0);
        gave_up = true;
    }
    ftm_pending_cmd *c = &p->cmd[p->n++];
    c->id = id;
    c->sent_ns = now_ns;
    snprintf(c->what, sizeof c->what, "%s", what);
    return gave_up;
}

void ftm_pending_forget(ftm_pending *p, uint64_t id)
{
    for (int32_t i = 0; i < p->n; i++)
        if (p->cmd[i].id == id) {
            pending_drop(p, i);
            return;
        }
}

bool ftm_pending_reply(ftm_pending *p, const ftm_wire_control_reply *r, char *text, size_t cap)
{
    char what[FTM_PENDING_WHAT + 32];
    int32_t i = 0;
    while (i < p->n && p->cmd[i].id != r->command_id)
        i++;
    bool known = i < p->n;
    if (known)
        snprintf(what, sizeof what, "%s", p->cmd[i].what);
    else
        snprintf(what, sizeof what, "command %" PRIu64, r->command_id);
    const char *sep = r->reason[0] ? ": " : "";
    switch (r->outcome) {
    case FTM_WIRE_OUTCOME_REFUSED: snprintf(text, cap, "%s: refused: %s", what, r->reason); break;
    case FTM_WIRE_OUTCOME_CHANGED:
    case FTM_WIRE_OUTCOME_APPLIED:
    default:
        snprintf(text, cap, "%s: %s after tick %" PRIu64 "%s%s", what,
                 ftm_wire_outcome_name(r->outcome), r->tick, sep, r->reason);
        break;
    }
    if (known)
        pending_drop(p, i);
    return known;
}

bool ftm_pending_expired(ftm_pending *p, int64_t now_ns, int64_t timeout_ns, char *text,
                         size_t cap)
{
    if (p->n == 0 || now_ns - p->cmd[0].sent_ns <= timeout_ns)
        return false; /* oldest first: none later is due either */
    unanswered_text(&p->cmd[0], now_ns - p->cmd[0].sent_ns, text, cap);
    pending_drop(p, 0);
    return true;
}
