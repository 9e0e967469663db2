/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-haptic-bench: haptic benchmarks (docs/haptics.md).
 *
 *   timing     the haptic loop thread against a scripted device for S
 *              seconds while another thread pushes a sample every 1 ms:
 *              achieved rate, period p50 / p99 / p99.9 / max, overruns.
 *   renderers  ground truth: the server's contact logic and libftm run
 *              offline at the scene's tick (1 kHz) along a closed probe
 *              path, recording the reaction force, the HIP and the contact
 *              stiffness each tick. Each renderer (hold, extrapolate, model)
 *              then runs at the same 1 kHz ticks on samples delayed by D ms
 *              and is compared with the ground truth at the current HIP:
 *              RMS and peak force error, and the work the rendered force
 *              does on the hand over the closed path (> 0: energy injected).
 *
 * Not a test: figures depend on the machine and its load. */
#include "cli.h"
#include "haptic.h"
#include "script_text.h"
#include "step.h"

#include "ftm/clock.h"
#include "ftm/options.h"
#include "ftm/scene.h"
#include "ftm/sim.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define MAX_DELAYS 16
/* the longest probe path [s]: its truth is held tick by tick (about 200 B a
 * tick, more with --trace) and computed at about 5 ms per simulated second */
#define MAX_PATH_S 600.0
#define NREND 4

/* model: what the server sends (held-tissue K, passive, secant-scaled);
 * model-held: the same without the secant scale */
static const char *const rend_names[NREND] = {"hold", "extrapolate", "model", "model-held"};

/* press 4 mm, drag 4 mm sideways, withdraw, return above: twice */
static const char default_path[] = "# t x y z (ftm-bot script format)\n"
                                   "0.0 0.035 0.035 0.115\n"
                                   "0.2 0.035 0.035 0.115\n"
                                   "0.6 0.035 0.035 0.106\n"
                                   "1.0 0.039 0.035 0.106\n"
                                   "1.4 0.039 0.035 0.115\n"
                                   "1.8 0.035 0.035 0.115\n"
                                   "2.2 0.035 0.035 0.106\n"
                                   "2.6 0.039 0.035 0.106\n"
                                   "3.0 0.039 0.035 0.115\n"
                                   "3.4 0.035 0.035 0.115\n"
                                   "3.7 0.035 0.035 0.115\n";

typedef struct options {
    const char *what;
    double seconds;
    int repeat;
    int ndelays;
    double delays[MAX_DELAYS]; /* ms */
    const char *scene;
    const char *script;
    const char *path; /* built-in path: press or circle */
    const char *trace;
    double kscale;
    bool json;
    bool no_fifo;
} options;

/* --delays: a comma list of up to MAX_DELAYS delays in ms, each 0..10000 */
static int parse_delays(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    options *op = (options *)((char *)field - offsetof(options, ndelays));
    int n = 0;
    for (const char *p = v; *p;) {
        if (n == MAX_DELAYS) {
            snprintf(why, cap, "has more than %d delays (got '%s')", MAX_DELAYS, v);
            return -1;
        }
        char *e;
        double d = strtod(p, &e);
        if (e == p || !(d >= 0 && d <= 10000) || (*e && *e != ',')) {
            snprintf(why, cap, "must be a comma list of delays in ms, each 0..10000 (got '%s')", v);
            return -1;
        }
        op->delays[n++] = d;
        p = *e == ',' ? e + 1 : e;
    }
    if (n == 0) {
        snprintf(why, cap, "must be a comma list of delays in ms, each 0..10000 (got '%s')", v);
        return -1;
    }
    op->ndelays = n;
    return 0;
}

static int parse_path(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    if (strcmp(v, "press") && strcmp(v, "circle")) {
        snprintf(why, cap, "must be press or circle (got '%s')", v);
        return -1;
    }
    memcpy(field, &v, sizeof v);
    return 0;
}

#define O options
static const ftm_option option_table[] = {
    FTM_OPT_DOUBLE("seconds", "S", O, seconds, 0, 3600, FTM_OPTION_ABOVE_LO, "seconds",
                   "timing: run the loop S seconds (default 10)"),
    FTM_OPT_INT("repeat", "N", O, repeat, 1, 100, "timing: N runs, medians reported (default 1)"),
    FTM_OPT_FLAG("no-fifo", O, no_fifo, "timing: do not ask for SCHED_FIFO (default scheduling)"),
    FTM_OPT_CUSTOM("delays", "LIST", O, ndelays, parse_delays,
                   "renderers: injected delays in ms (default 0,20,50,100)"),
    FTM_OPT_STRING("scene", "NAME", O, scene, "renderers: scene (default: default)"),
    FTM_OPT_CUSTOM("path", "NAME", O, path, parse_path,
                   "renderers: built-in closed path: press (default) or circle"),
    FTM_OPT_STRING("script", "FILE", O, script,
                   "renderers: closed probe path, ftm-bot format, instead\n(at most 600 s long)"),
    FTM_OPT_STRING("trace", "FILE", O, trace, "renderers: CSV of truth and rendered force per tick"),
    FTM_OPT_DOUBLE("stiffness-scale", "S", O, kscale, 0, 100, 0, NULL,
                   "renderers: multiply the model's K by S (experiment; default 1)"),
    FTM_OPT_FLAG("json", O, json, "JSON instead of tables"),
    {0}};
#undef O

static const ftm_option_set option_set = {
    "ftm-haptic-bench", "usage: ftm-haptic-bench [timing|renderers|all] [options]", option_table,
    NULL};

/* 0 to go on, or the exit status: -1 after --help (0), 2 refused. */
static int parse_args(int argc, char **argv, options *o)
{
    *o = (options){.what = "all", .seconds = 10, .repeat = 1, .ndelays = 4,
                   .delays = {0, 20, 50, 100}, .scene = "default", .kscale = 1.0,
                   .path = "press"};
    int first = argc;
    int rc = ftm_options_parse(&option_set, argc, argv, o, NULL, &first);
    if (rc == FTM_OPTIONS_HELP)
        return -1;
    if (rc != FTM_OPTIONS_OK)
        return 2;
    for (int i = first; i < argc; i++) {
        const char *a = argv[i];
        if (i > first || (strcmp(a, "timing") && strcmp(a, "renderers") && strcmp(a, "all"))) {
            fprintf(stderr, "ftm-haptic-bench: unexpected argument '%s' (one of timing, "
                            "renderers, all; options start with --)\n", a);
            return 2;
        }
        o->what = a;
    }
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* ---- timing ---- */

typedef struct feeder {
    ftm_haptic *h;
    atomic_bool stop;
} feeder;

static void *feed(void *arg)
{
    feeder *f = arg;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    while (!atomic_load(&f->stop)) {
        ftm_haptic_sample s;
        memset(&s, 0, sizeof s);
        s.time = ftm_haptic_clock();
        s.force = (ftm_vec3){0, 0, 0.5};
        s.hip = (ftm_vec3){0.035, 0.035, 0.106};
        s.has_stiffness = true;
        s.stiffness[8] = -300;
        ftm_haptic_push(f->h, &s);
        next.tv_nsec += 1000000;
        if (next.tv_nsec >= 1000000000L) {
            next.tv_nsec -= 1000000000L;
            next.tv_sec++;
        }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    }
    return NULL;
}

typedef struct timing_result {
    double rate, p50, p99, p999, max, overruns;
    bool realtime;
} timing_result;

static int run_timing(const options *o, timing_result *out)
{
    ftm_error err = {0, ""};
    ftm_device *dev = NULL;
    if (ftm_script_device_parse(default_path, sizeof default_path - 1, "built-in path", NULL, &dev,
                                &err)) {
        fprintf(stderr, "ftm-haptic-bench: %s\n", err.message);
        return 1;
    }
    double v[6][100];
    bool rt = false;
    for (int r = 0; r < o->repeat; r++) {
        ftm_haptic *h = NULL;
        ftm_haptic_def def = ftm_default_haptic_def();
        def.realtime = !o->no_fifo;
        if (ftm_haptic_create(&def, dev, &h, &err) || ftm_haptic_start(h, &err)) {
            fprintf(stderr, "ftm-haptic-bench: %s\n", err.message);
            ftm_haptic_destroy(h);
            ftm_device_destroy(dev);
            return 1;
        }
        feeder f = {.h = h};
        atomic_init(&f.stop, false);
        pthread_t th;
        bool fed = pthread_create(&th, NULL, feed, &f) == 0;
        struct timespec ts = {(time_t)o->seconds,
                              (long)((o->seconds - floor(o->seconds)) * 1e9)};
        nanosleep(&ts, NULL);
        atomic_store(&f.stop, true);
        if (fed)
            pthread_join(th, NULL);
        ftm_haptic_timing t;
        ftm_haptic_state st;
        ftm_haptic_get_timing(h, &t);
        ftm_haptic_get_state(h, &st);
        ftm_haptic_destroy(h);
        v[0][r] = t.rate_hz;
        v[1][r] = t.p50 * 1e3;
        v[2][r] = t.p99 * 1e3;
        v[3][r] = t.p999 * 1e3;
        v[4][r] = t.max * 1e3;
        v[5][r] = (double)st.overruns;
        rt = st.realtime;
        if (!o->json)
            fprintf(stderr, "run %d: %.1f Hz, p50 %.3f ms, p99 %.3f ms, max %.3f ms, %s\n", r + 1,
                    v[0][r], v[1][r], v[2][r], v[4][r], rt ? "SCHED_FIFO" : "default policy");
    }
    ftm_device_destroy(dev);
    *out = (timing_result){median(v[0], o->repeat), median(v[1], o->repeat),
                           median(v[2], o->repeat), median(v[3], o->repeat),
                           median(v[4], o->repeat), median(v[5], o->repeat), rt};
    return 0;
}

/* ---- ground truth: the server's probe contact, offline ---- */

static ftm_vec3 vsub(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static double vdot(ftm_vec3 a, ftm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static ftm_vec3 vcross(ftm_vec3 a, ftm_vec3 b)
{
    return (ftm_vec3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
static ftm_vec3 node_x(const double *x, int32_t i)
{
    return (ftm_vec3){x[3 * i], x[3 * i + 1], x[3 * i + 2]};
}

/* First surface triangle (smallest t) the segment a -> b crosses at the
 * current positions, either side; what server/collide.c answers, by brute
 * force. */
static int32_t first_crossing(const ftm_mesh *m, const double *x, ftm_vec3 a, ftm_vec3 b,
                              double w[3])
{
    const int32_t *tri = ftm_mesh_triangles(m);
    int32_t best = -1;
    double best_t = INFINITY;
    ftm_vec3 d = vsub(b, a);
    for (int32_t i = 0; i < ftm_mesh_triangle_count(m); i++) {
        ftm_vec3 p0 = node_x(x, tri[3 * i]), p1 = node_x(x, tri[3 * i + 1]),
                 p2 = node_x(x, tri[3 * i + 2]);
        ftm_vec3 e1 = vsub(p1, p0), e2 = vsub(p2, p0);
        ftm_vec3 p = vcross(d, e2);
        double det = vdot(e1, p);
        if (fabs(det) < 1e-30)
            continue;
        ftm_vec3 s = vsub(a, p0);
        double u = vdot(s, p) / det;
        if (u < 0 || u > 1)
            continue;
        ftm_vec3 q = vcross(s, e1);
        double v = vdot(d, q) / det;
        if (v < 0 || u + v > 1)
            continue;
        double t = vdot(e2, q) / det;
        if (t < 0 || t > 1 || t >= best_t)
            continue;
        best_t = t;
        best = i;
        w[0] = 1 - u - v;
        w[1] = u;
        w[2] = v;
    }
    return best;
}

/* Hand-like motion: descend 6 mm into the top face, then three turns of a
 * 3 mm circle at 1 Hz while the depth breathes +-1.5 mm at 1.5 Hz, then back
 * up to the start: a closed path, points every 5 ms. */
static char *circle_path(void)
{
    size_t cap = 64 * 1024, n = 0;
    char *t = malloc(cap);
    if (!t)
        return NULL;
    const double cx = 0.035, cy = 0.035, top = 0.115, depth = 0.106, r = 0.003;
    n += (size_t)snprintf(t + n, cap - n, "0.0 %.6f %.6f %.6f\n0.2 %.6f %.6f %.6f\n", cx, cy,
                          top, cx, cy, top);
    /* down to the circle's start point over 0.5 s */
    n += (size_t)snprintf(t + n, cap - n, "0.7 %.6f %.6f %.6f\n", cx + r, cy, depth);
    for (int k = 1; k <= 600; k++) {
        double s = 0.005 * k, a = 2 * M_PI * 1.0 * s;
        n += (size_t)snprintf(t + n, cap - n, "%.3f %.6f %.6f %.6f\n", 0.7 + s, cx + r * cos(a),
                              cy + r * sin(a), depth - 0.0015 * sin(2 * M_PI * 1.5 * s));
    }
    n += (size_t)snprintf(t + n, cap - n, "4.2 %.6f %.6f %.6f\n4.5 %.6f %.6f %.6f\n", cx, cy, top,
                          cx, cy, top);
    return t;
}

typedef struct truth {
    int32_t n;      /* ticks */
    double h;       /* tick [s] */
    ftm_vec3 *x;    /* HIP at tick k */
    ftm_vec3 *f;    /* reaction after tick k */
    double *K;      /* 9 per tick: passive held-tissue contact stiffness */
    double *alpha;  /* per tick: the server's secant scale of K */
    ftm_vec3 *plane; /* per tick: contact point and unit outward normal (2 each) */
    bool *contact;
    double step_ms; /* mean simulation step */
} truth;

static void truth_free(truth *t)
{
    free(t->x);
    free(t->f);
    free(t->K);
    free(t->alpha);
    free(t->plane);
    free(t->contact);
}

static int make_truth(const options *o, truth *tr)
{
    ftm_error err = {0, ""};
    ftm_scene *scene = NULL;
    ftm_device *path = NULL;
    ftm_sim *sim = NULL;
    int rc = ftm_scene_open(o->scene, &scene, &err);
    if (!rc && o->script) {
        rc = ftm_script_device_open(o->script, NULL, &path, &err);
    } else if (!rc && !strcmp(o->path, "circle")) {
        char *text = circle_path();
        rc = text ? ftm_script_device_parse(text, strlen(text), "circle path", NULL, &path, &err)
                  : FTM_ENOMEM;
        free(text);
    } else if (!rc) {
        rc = ftm_script_device_parse(default_path, sizeof default_path - 1, "press path", NULL,
                                     &path, &err);
    }
    const ftm_mesh *m = scene ? ftm_scene_mesh(scene) : NULL;
    ftm_sim_def def = {0};
    if (!rc) {
        def = ftm_replay_sim_def(scene); /* as the server runs a session */
        rc = ftm_sim_create(m, &def, &sim, &err);
    }
    if (rc) {
        fprintf(stderr, "ftm-haptic-bench: %s\n", err.message);
        ftm_device_destroy(path);
        ftm_scene_destroy(scene);
        return 1;
    }
    memset(tr, 0, sizeof *tr);
    tr->h = def.time_step;
    /* (a double out of int32's range is no tick count: refused, not cast) */
    const double dur = ftm_script_device_duration(path), ticks = dur / tr->h;
    if (!(dur <= MAX_PATH_S) || !(ticks < (double)INT32_MAX - 1)) {
        fprintf(stderr, "ftm-haptic-bench: renderers: the probe path %s lasts %g s: at most %g s\n",
                o->script ? o->script : o->path, dur, MAX_PATH_S);
        ftm_sim_destroy(sim);
        ftm_device_destroy(path);
        ftm_scene_destroy(scene);
        return 2;
    }
    tr->n = (int32_t)ticks + 1;
    tr->x = calloc((size_t)tr->n, sizeof *tr->x);
    tr->f = calloc((size_t)tr->n, sizeof *tr->f);
    tr->K = calloc((size_t)tr->n * 9, sizeof *tr->K);
    tr->contact = calloc((size_t)tr->n, sizeof *tr->contact);
    tr->alpha = calloc((size_t)tr->n, sizeof *tr->alpha);
    tr->plane = calloc(2 * (size_t)tr->n, sizeof *tr->plane);
    if (!tr->x || !tr->f || !tr->K || !tr->contact || !tr->alpha || !tr->plane) {
        fprintf(stderr, "ftm-haptic-bench: out of memory\n");
        truth_free(tr);
        ftm_sim_destroy(sim);
        ftm_device_destroy(path);
        ftm_scene_destroy(scene);
        return 1;
    }
    const int32_t *tri = ftm_mesh_triangles(m);
    bool contact = false, have_prev = false;
    ftm_vec3 prev = {0, 0, 0}, anchor = {0, 0, 0}, normal = {0, 0, 0};
    int32_t ct = -1;
    double t_sim = 0;
    for (int32_t k = 0; k < tr->n && !rc; k++) {
        ftm_vec3 hip;
        ftm_script_device_position(path, k * tr->h, &hip);
        tr->x[k] = hip;
        const double *x = ftm_sim_positions(sim);
        /* server/tick.c probe_contacts: sticky contact on the collided
         * triangle, released when the HIP is back on the side it came from */
        if (contact) {
            if (vdot(vsub(hip, anchor), normal) >= 0.0)
                contact = false;
        } else if (have_prev) {
            double w[3];
            int32_t t = first_crossing(m, x, prev, hip, w);
            if (t >= 0) {
                ftm_vec3 X[3];
                for (int q = 0; q < 3; q++)
                    X[q] = ftm_mesh_rest_position(m, tri[3 * t + q]);
                ftm_vec3 n = vcross(vsub(X[1], X[0]), vsub(X[2], X[0]));
                if (vdot(n, vsub(hip, prev)) < 0.0) { /* entering */
                    anchor = (ftm_vec3){w[0] * X[0].x + w[1] * X[1].x + w[2] * X[2].x,
                                        w[0] * X[0].y + w[1] * X[1].y + w[2] * X[2].y,
                                        w[0] * X[0].z + w[1] * X[1].z + w[2] * X[2].z};
                    normal = n;
                    ct = t;
                    contact = true;
                }
            }
        }
        prev = hip;
        have_prev = true;
        ftm_contact c[3];
        int32_t nc = 0;
        if (contact) {
            ftm_vec3 pen = vsub(hip, anchor);
            for (int q = 0; q < 3; q++)
                if (!ftm_mesh_fixed(m, tri[3 * ct + q]))
                    c[nc++] = (ftm_contact){tri[3 * ct + q], 0, FTM_CONTACT_DISPLACEMENT, pen};
        }
        rc = ftm_sim_set_contacts(sim, c, nc, &err);
        const int64_t t0 = ftm_clock_mono_ns();
        if (!rc)
            rc = ftm_sim_step(sim);
        t_sim += (double)(ftm_clock_mono_ns() - t0) * 1e-9;
        tr->contact[k] = contact;
        if (contact) {
            tr->f[k] = ftm_sim_reaction(sim, 0);
            /* exactly what the server sends (server/tick.c fill_reactions) */
            if (ftm_sim_contact_stiffness(sim, 0, tr->K + 9 * k) > 0) {
                ftm_stiffness_make_passive(tr->K + 9 * k);
                double S[9];
                memcpy(S, tr->K + 9 * k, sizeof S);
                tr->alpha[k] = ftm_stiffness_secant_scale(S, tr->f[k], vsub(hip, anchor));
            }
            double nl = sqrt(vdot(normal, normal));
            tr->plane[2 * k] = anchor;
            tr->plane[2 * k + 1] = (ftm_vec3){normal.x / nl, normal.y / nl, normal.z / nl};
        }
    }
    tr->step_ms = 1e3 * t_sim / tr->n;
    if (rc)
        fprintf(stderr, "ftm-haptic-bench: simulation failed: %s\n",
                err.message[0] ? err.message : ftm_strerror(rc));
    ftm_sim_destroy(sim);
    ftm_device_destroy(path);
    ftm_scene_destroy(scene);
    if (rc)
        truth_free(tr);
    return rc ? 1 : 0;
}

/* ---- renderers against the truth ---- */

typedef struct rend_result {
    double rms, rms_contact, peak_err, work_mj, clamped_frac;
} rend_result;

/* Renderer r (0 hold, 1 extrapolate, 2 model, 3 model-held) fed with the truth's samples
 * `lag` ticks late; the rendered force per tick into out (may be NULL). */
static rend_result run_renderer(const truth *tr, int r, int32_t lag, double kscale, ftm_vec3 *out)
{
    ftm_haptic_def def = ftm_default_haptic_def();
    def.renderer = r == 1 ? FTM_HAPTIC_EXTRAPOLATE : FTM_HAPTIC_FORCE_MODEL;
    ftm_force_renderer fr;
    ftm_force_renderer_init(&fr, &def);
    double se = 0, se_c = 0, peak = 0, work = 0;
    int32_t clamped = 0, nc = 0;
    for (int32_t k = 0; k < tr->n; k++) {
        double now = k * tr->h;
        int32_t j = k - lag; /* the newest sample that has arrived */
        if (j >= 0) {
            ftm_haptic_sample s;
            memset(&s, 0, sizeof s);
            s.time = j * tr->h; /* server tick time; the bench's clocks agree */
            s.force = tr->f[j];
            s.hip = tr->x[j];
            s.has_stiffness = r >= 2;
            /* the contact plane goes with every renderer's samples (the
             * server sends it); no plane while out of contact */
            s.has_plane = tr->contact[j];
            s.plane_point = tr->plane[2 * j];
            s.plane_normal = tr->plane[2 * j + 1];
            double a = kscale * (r == 2 ? tr->alpha[j] : 1.0);
            for (int q = 0; r >= 2 && q < 9; q++)
                s.stiffness[q] = a * tr->K[9 * j + q];
            ftm_force_renderer_push(&fr, &s, now);
        }
        int fl = 0;
        ftm_vec3 f = ftm_force_renderer_eval(&fr, now, tr->x[k], &fl);
        if (fl & FTM_HAPTIC_CLAMPED)
            clamped++;
        if (out)
            out[k] = f;
        ftm_vec3 e = vsub(f, tr->f[k]);
        double e2 = vdot(e, e);
        se += e2;
        if (tr->contact[k]) { /* the server's probe is in contact */
            se_c += e2;
            nc++;
        }
        if (sqrt(e2) > peak)
            peak = sqrt(e2);
        if (k + 1 < tr->n) /* the force is held over the tick (zero-order hold) */
            work += vdot(f, vsub(tr->x[k + 1], tr->x[k]));
    }
    return (rend_result){sqrt(se / tr->n), nc ? sqrt(se_c / nc) : 0.0, peak, 1e3 * work,
                         (double)clamped / tr->n};
}

static int run_renderers(const options *o, bool json_open)
{
    /* --trace opened first: a path that cannot be written is said before
     * the work, not after it (and fails the run) */
    FILE *tf = NULL;
    const ftm_option_path in = {"--script", o->script}, out = {"--trace", o->trace};
    int ii, oi;
    if (o->trace && o->script && ftm_option_output_is_input(&in, 1, &out, 1, &ii, &oi)) {
        fprintf(stderr, "ftm-haptic-bench: --trace %s is the file --script %s reads: it would be "
                        "overwritten; write to another file\n", o->trace, o->script);
        return 2;
    }
    /* opened without truncating it: a run refused below (a script too
     * long, say) leaves an earlier trace as it was */
    if (o->trace && !(tf = fopen(o->trace, "a"))) {
        fprintf(stderr, "ftm-haptic-bench: --trace %s: %s\n", o->trace, strerror(errno));
        return 2;
    }
    truth tr;
    int rc = make_truth(o, &tr);
    if (rc) {
        if (tf)
            fclose(tf);
        return rc;
    }
    if (tf && (fflush(tf) != 0 || ftruncate(fileno(tf), 0) != 0)) {
        fprintf(stderr, "ftm-haptic-bench: --trace %s: %s\n", o->trace, strerror(errno));
        fclose(tf);
        truth_free(&tr);
        return 1;
    }
    double peak = 0, work = 0, asum = 0;
    int32_t in_contact = 0;
    for (int32_t k = 0; k < tr.n; k++) {
        if (tr.contact[k])
            asum += tr.alpha[k];
        double f = sqrt(vdot(tr.f[k], tr.f[k]));
        if (f > peak)
            peak = f;
        in_contact += tr.contact[k];
        if (k + 1 < tr.n)
            work += vdot(tr.f[k], vsub(tr.x[k + 1], tr.x[k]));
    }
    ftm_vec3 closure = vsub(tr.x[tr.n - 1], tr.x[0]);
    rend_result res[MAX_DELAYS][NREND];
    ftm_vec3 *traces = o->trace ? calloc((size_t)tr.n * (size_t)o->ndelays * NREND,
                                         sizeof *traces)
                                : NULL;
    for (int d = 0; d < o->ndelays; d++) {
        int32_t lag = (int32_t)floor(o->delays[d] * 1e-3 / tr.h + 0.5);
        for (int r = 0; r < NREND; r++)
            res[d][r] = run_renderer(&tr, r, lag, o->kscale,
                                     traces ? traces + ((size_t)d * NREND + (size_t)r) * (size_t)tr.n
                                            : NULL);
    }
    if (tf && !traces) {
        fprintf(stderr, "ftm-haptic-bench: --trace %s: out of memory\n", o->trace);
        rc = 1;
    }
    if (traces) {
        FILE *f = tf;
        tf = NULL;
        fprintf(f, "# t_s,hip_x,hip_z,truth_fx,truth_fz");
        for (int d = 0; d < o->ndelays; d++)
            for (int r = 0; r < NREND; r++)
                fprintf(f, ",%s_%gms_fx,%s_%gms_fz", rend_names[r], o->delays[d],
                        rend_names[r], o->delays[d]);
        fprintf(f, "\n");
        for (int32_t k = 0; k < tr.n; k++) {
            fprintf(f, "%.4f,%.6f,%.6f,%.6f,%.6f", k * tr.h, tr.x[k].x, tr.x[k].z, tr.f[k].x,
                    tr.f[k].z);
            for (int d = 0; d < o->ndelays; d++)
                for (int r = 0; r < NREND; r++) {
                    ftm_vec3 v = traces[((size_t)d * NREND + (size_t)r) * (size_t)tr.n +
                                        (size_t)k];
                    fprintf(f, ",%.6f,%.6f", v.x, v.z);
                }
            fprintf(f, "\n");
        }
        int bad = ferror(f);
        if (fclose(f) != 0 || bad) {
            fprintf(stderr, "ftm-haptic-bench: --trace %s: write error\n", o->trace);
            rc = 1;
        }
        free(traces);
    }
    if (tf)
        fclose(tf);
    if (o->json) {
        printf("%s\"renderers\": {\"scene\": \"%s\", \"path\": \"%s\", \"ticks\": %d, "
               "\"tick_s\": %g, \"contact_ticks\": %d, \"path_closure_m\": %.3g, "
               "\"sim_step_ms\": %.4f, \"stiffness_scale\": %g, \"alpha_mean\": %.4f, "
               "\"truth_peak_N\": %.6f, "
               "\"truth_work_mJ\": %.6f, "
               "\"rows\": [",
               json_open ? ", " : "{", o->scene, o->script ? o->script : o->path, tr.n, tr.h,
               in_contact, sqrt(vdot(closure, closure)), tr.step_ms, o->kscale,
               in_contact ? asum / in_contact : 0.0, peak, 1e3 * work);
        for (int d = 0; d < o->ndelays; d++)
            for (int r = 0; r < NREND; r++)
                printf("%s{\"delay_ms\": %g, \"renderer\": \"%s\", \"rms_N\": %.6f, "
                       "\"rms_contact_N\": %.6f, \"peak_err_N\": %.6f, \"work_mJ\": %.6f, "
                       "\"rms_ratio_to_hold\": %.4f}",
                       d || r ? ", " : "", o->delays[d], rend_names[r], res[d][r].rms,
                       res[d][r].rms_contact, res[d][r].peak_err, res[d][r].work_mj,
                       res[d][0].rms > 0 ? res[d][r].rms / res[d][0].rms : 0.0);
        printf("]}");
    } else {
        printf("renderers vs ground truth: scene %s, path %s, %d ticks of %g s (%d in contact), "
               "simulation step %.3f ms, model stiffness x %g\n",
               o->scene, o->script ? o->script : o->path, tr.n, tr.h, in_contact, tr.step_ms,
               o->kscale);
        printf("ground truth: peak force %.3f N, work on the hand over the closed path %.3f mJ; "
               "secant scale of K: mean %.3f in contact\n",
               peak, 1e3 * work, in_contact ? asum / in_contact : 0.0);
        printf("%9s  %-12s %10s %13s %12s %10s %9s\n", "delay ms", "renderer", "RMS N",
               "RMS contact N", "peak err N", "work mJ", "RMS/hold");
        for (int d = 0; d < o->ndelays; d++)
            for (int r = 0; r < NREND; r++)
                printf("%9g  %-12s %10.4f %13.4f %12.4f %10.3f %9.3f\n", o->delays[d],
                       rend_names[r], res[d][r].rms, res[d][r].rms_contact, res[d][r].peak_err,
                       res[d][r].work_mj,
                       res[d][0].rms > 0 ? res[d][r].rms / res[d][0].rms : 0.0);
    }
    truth_free(&tr);
    return rc;
}

int main(int argc, char **argv)
{
    options o;
    int rc = parse_args(argc, argv, &o);
    if (rc)
        return rc < 0 ? 0 : rc;
    bool timing = strcmp(o.what, "renderers") != 0, rend = strcmp(o.what, "timing") != 0;
    if (timing) {
        timing_result t;
        if (run_timing(&o, &t))
            return 1;
        if (o.json)
            printf("{\"timing\": {\"seconds\": %g, \"repeat\": %d, \"target_hz\": 1000, "
                   "\"rate_hz\": %.3f, \"period_p50_ms\": %.4f, \"period_p99_ms\": %.4f, "
                   "\"period_p999_ms\": %.4f, \"period_max_ms\": %.4f, \"overruns\": %g, "
                   "\"sched_fifo\": %s}",
                   o.seconds, o.repeat, t.rate, t.p50, t.p99, t.p999, t.max, t.overruns,
                   t.realtime ? "true" : "false");
        else
            printf("haptic loop, %g s x %d (medians): %.1f Hz (target 1000), period p50 %.3f ms, "
                   "p99 %.3f ms, p99.9 %.3f ms, max %.3f ms, %g overruns, %s\n",
                   o.seconds, o.repeat, t.rate, t.p50, t.p99, t.p999, t.max, t.overruns,
                   t.realtime ? "SCHED_FIFO" : "default scheduling");
    }
    if (rend && (rc = run_renderers(&o, o.json && timing)))
        return rc; /* 2: a bad argument found on the way (the path's length) */
    if (o.json)
        printf("%s}\n", timing || rend ? "" : "{");
    return 0;
}
