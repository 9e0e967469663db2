/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The server's log (rooms.h): stderr, and --log FILE, every line with the
 * time since the start. */
#include "rooms.h"

#include <stdarg.h>

void srv_log(server *s, const char *level, const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    double t = (double)(srv_now() - s->t_start_ns) * 1e-9;
    fprintf(stderr, "ftm-server [%8.3f] %s: %s\n", t, level, buf);
    if (s->logf) {
        fprintf(s->logf, "[%8.3f] %s: %s\n", t, level, buf);
        fflush(s->logf);
    }
}

void srv_log_hook(void *user, ftm_log_level level, const char *message)
{
    server *s = user; /* every hook is registered with its server */
    static const char *const names[] = {"debug", "info", "warn", "error"};
    srv_log(s, names[level < 4 ? level : 3], "%s", message);
}
