/* The scripted device (device.h): a HIP trajectory in the ftm-bot script
 * format, replayed against the haptic clock; records what it is sent. */
#include "device.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct point {
    double t;
    ftm_vec3 x;
} point;

typedef struct script {
    point *p;
    int32_t n;
    bool started; /* haptic thread only */
    double t0;
    pthread_mutex_t lock; /* guards log */
    ftm_script_device_log log;
} script;

static const ftm_device_ops script_ops;

static ftm_vec3 at(const script *s, double t)
{
    if (t <= s->p[0].t)
        return s->p[0].x;
    if (t >= s->p[s->n - 1].t)
        return s->p[s->n - 1].x;
    int32_t lo = 0, hi = s->n - 1; /* p[lo].t <= t < p[hi].t */
    while (hi - lo > 1) {
        int32_t mid = lo + (hi - lo) / 2;
        if (s->p[mid].t <= t)
            lo = mid;
        else
            hi = mid;
    }
    double a = (t - s->p[lo].t) / (s->p[hi].t - s->p[lo].t);
    ftm_vec3 u = s->p[lo].x, v = s->p[hi].x;
    return (ftm_vec3){u.x + a * (v.x - u.x), u.y + a * (v.y - u.y), u.z + a * (v.z - u.z)};
}

static int script_read(void *self, double now, ftm_vec3 *hip)
{
    script *s = self;
    if (!s->started) {
        s->t0 = now;
        s->started = true;
    }
    *hip = at(s, now - s->t0);
    pthread_mutex_lock(&s->lock);
    s->log.reads++;
    pthread_mutex_unlock(&s->lock);
    return FTM_OK;
}

static void script_write(void *self, double now, ftm_vec3 f)
{
    script *s = self;
    double m = sqrt(f.x * f.x + f.y * f.y + f.z * f.z);
    pthread_mutex_lock(&s->lock);
    s->log.writes++;
    s->log.last_force = f;
    s->log.last_write = now;
    if (m > s->log.max_force)
        s->log.max_force = m;
    pthread_mutex_unlock(&s->lock);
}

static int script_start(void *self, ftm_error *err)
{
    script *s = self;
    s->started = false; /* time 0 = first read of this run */
    return FTM_OK;
}

static void script_destroy(void *self)
{
    script *s = self;
    pthread_mutex_destroy(&s->lock);
    free(s->p);
    free(s);
}

static const ftm_device_ops script_ops = {.name = "script",
                                          .start = script_start,
                                          .read = script_read,
                                          .write = script_write,
                                          .destroy = script_destroy};

static int perr(ftm_error *err, int code, const char *name, int line, const char *msg)
{
    if (err) {
        err->code = code;
        if (line > 0)
            snprintf(err->message, sizeof err->message, "%s:%d: %s", name, line, msg);
        else
            snprintf(err->message, sizeof err->message, "%s: %s", name, msg);
    }
    return code;
}

static bool control_word(const char *w, size_t len)
{
    static const char *const words[] = {"join", "leave", "pause", "resume", "reset"};
    for (size_t i = 0; i < sizeof words / sizeof *words; i++)
        if (strlen(words[i]) == len && memcmp(words[i], w, len) == 0)
            return true;
    return false;
}

int ftm_script_device_parse(const char *text, size_t length, const char *name,
                            const ftm_device_def *def, ftm_device **out, ftm_error *err)
{
    if (!name)
        name = "script";
    script *s = calloc(1, sizeof *s);
    if (!s || pthread_mutex_init(&s->lock, NULL)) {
        free(s);
        return perr(err, FTM_ENOMEM, name, 0, "out of memory");
    }
    int32_t cap = 0;
    int line = 0, rc = FTM_OK;
    size_t pos = 0;
    char buf[512];
    while (pos < length && rc == FTM_OK) {
        size_t end = pos;
        while (end < length && text[end] != '\n')
            end++;
        line++;
        size_t len = end - pos;
        if (len >= sizeof buf) {
            rc = perr(err, FTM_EPARSE, name, line, "line too long");
            break;
        }
        memcpy(buf, text + pos, len);
        buf[len] = 0;
        pos = end + 1;
        char *hash = strchr(buf, '#');
        if (hash)
            *hash = 0;
        char *q = buf;
        while (*q == ' ' || *q == '\t' || *q == '\r')
            q++;
        if (!*q)
            continue;
        size_t wl = strcspn(q, " \t\r");
        if (control_word(q, wl))
            continue; /* the bot's session commands: not a device's business */
        double v[4];
        int k = 0;
        bool ok = true;
        char *e = q;
        for (;;) {
            while (*e == ' ' || *e == '\t' || *e == '\r')
                e++;
            if (!*e)
                break;
            char *stop = e;
            errno = 0;
            double x = k < 4 ? strtod(e, &stop) : 0.0;
            if (k == 4 || stop == e || errno == ERANGE || !isfinite(x) ||
                (*stop && *stop != ' ' && *stop != '\t' && *stop != '\r')) {
                ok = false; /* a fifth word, or not a number */
                break;
            }
            v[k++] = x;
            e = stop;
        }
        if (!ok)
            k = -1;
        if (k != 4) {
            rc = perr(err, FTM_EPARSE, name, line, "expected 't x y z' (4 numbers)");
            break;
        }
        if (!(v[0] >= 0)) {
            char msg[96];
            snprintf(msg, sizeof msg, "time %g is negative (times are seconds from the start)",
                     v[0]);
            rc = perr(err, FTM_EPARSE, name, line, msg);
            break;
        }
        if (s->n > 0 && !(v[0] > s->p[s->n - 1].t)) {
            char msg[128];
            snprintf(msg, sizeof msg, "time %g does not increase (previous point at %g)", v[0],
                     s->p[s->n - 1].t);
            rc = perr(err, FTM_EPARSE, name, line, msg);
            break;
        }
        if (s->n == cap) {
            int32_t nc = cap ? 2 * cap : 64;
            point *np = realloc(s->p, (size_t)nc * sizeof *np);
            if (!np) {
                rc = perr(err, FTM_ENOMEM, name, line, "out of memory");
                break;
            }
            s->p = np;
            cap = nc;
        }
        s->p[s->n++] = (point){v[0], {v[1], v[2], v[3]}};
    }
    if (rc == FTM_OK && s->n == 0)
        rc = perr(err, FTM_EPARSE, name, 0, "no trajectory point ('t x y z')");
    if (rc == FTM_OK)
        rc = ftm_device_create(&script_ops, s, def, out, err);
    if (rc)
        script_destroy(s);
    return rc;
}

int ftm_script_device_open(const char *path, const ftm_device_def *def, ftm_device **out,
                           ftm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        char msg[256];
        snprintf(msg, sizeof msg, "cannot open: %s", strerror(errno));
        return perr(err, FTM_EIO, path, 0, msg);
    }
    size_t cap = 4096, n = 0;
    char *text = malloc(cap);
    while (text) {
        n += fread(text + n, 1, cap - n, f);
        if (n < cap)
            break;
        char *t = cap > ((size_t)64 << 20) ? NULL : realloc(text, 2 * cap);
        if (!t) {
            free(text);
            text = NULL;
            break;
        }
        text = t;
        cap *= 2;
    }
    bool bad = ferror(f);
    fclose(f);
    if (!text)
        return perr(err, FTM_ENOMEM, path, 0, "out of memory (or larger than 64 MiB)");
    if (bad) {
        free(text);
        return perr(err, FTM_EIO, path, 0, "read error");
    }
    int rc = ftm_script_device_parse(text, n, path, def, out, err);
    free(text);
    return rc;
}

int ftm_script_device_position(const ftm_device *d, double t, ftm_vec3 *hip)
{
    if (!d || d->ops != &script_ops || !isfinite(t))
        return FTM_EINVAL;
    *hip = at(d->self, t);
    return FTM_OK;
}

double ftm_script_device_duration(const ftm_device *d)
{
    if (!d || d->ops != &script_ops)
        return 0;
    const script *s = d->self;
    return s->p[s->n - 1].t;
}

int ftm_script_device_get_log(ftm_device *d, ftm_script_device_log *log)
{
    if (!d || d->ops != &script_ops)
        return FTM_EINVAL;
    script *s = d->self;
    pthread_mutex_lock(&s->lock);
    *log = s->log;
    pthread_mutex_unlock(&s->lock);
    return FTM_OK;
}
