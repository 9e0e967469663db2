/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench tick`: the server's tick budget per training scene
 * (docs/feel.md, "What each model costs"). For each scene and number of
 * trainees it runs the real programs on loopback DDS — ftm-server bound to
 * one CPU at the scene's own depth (no adaptation), N ftm-bot trainees on
 * the other CPUs pressing the top face 5 mm on a ring around its centre —
 * and reads the server's own closing figures: the work of a tick
 * (collision, step, frame) in the ticks with a probe in contact, median and
 * 99th percentile, the ticks run and missed. The budget is the tick period
 * (1 ms at 1 kHz); the target for the accurate model is a median of
 * 300 us or less, so that eight trainees still fit. Every bot must end on
 * the server's final tick and hash (exit status 1 if not). */
#include "bench_net.h"
#include "commands.h"
#include "proc.h"

#include "ftm/ftm.h"
#include "ftm/options.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stddef.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#ifndef FTM_SOURCE_DIR
#define FTM_SOURCE_DIR "."
#endif

#define MAX_SCENES 8
#define MAX_COUNTS 8
#define MAX_TRAINEES 16

typedef struct tick_options {
    const char *scenes_arg;
    const char *scenes[MAX_SCENES];
    int nscenes;
    int counts[MAX_COUNTS], ncounts;
    double duration, rate, press_mm, press;
    int cpu, domain;
    const char *server, *bot, *config, *keep;
    bool json, adaptive;
} tick_options;

/* What a scene is, from libftm: where its top face is and what it runs. */
typedef struct scene_info {
    char name[64];
    double cx, cy, top, radius;
    ftm_vec3 *rest; /* the nodes' rest positions (malloc) */
    int32_t nodes, depth;
    ftm_forces forces;
    ftm_far_field far;
} scene_info;

typedef struct tick_result {
    const scene_info *sc;
    int trainees, synced;
    uint64_t ticks, missed, work_ticks, contact_ticks;
    double seconds, p50, p99, contact_p50, contact_p99;
    int depth_lo, depth_hi; /* the depths the ticks ran at */
    bool ok; /* the run completed and was read */
} tick_result;

static int scene_info_of(const char *name, scene_info *si)
{
    ftm_scene *sc = NULL;
    ftm_error err;
    if (ftm_scene_open(name, &sc, &err)) {
        fprintf(stderr, "ftm bench tick: scene '%s': %s\n", name, err.message);
        return -1;
    }
    memset(si, 0, sizeof *si);
    snprintf(si->name, sizeof si->name, "%s", name);
    const ftm_mesh *m = ftm_scene_mesh(sc);
    ftm_sim_def d = ftm_scene_sim_def(sc);
    si->nodes = ftm_mesh_node_count(m);
    si->depth = d.depth;
    si->forces = d.forces;
    si->far = d.far_field;
    /* the top face: the nodes within 1 mm of the highest one; on a rounded
     * top (an organ from a scan) the band widens until it is 10 mm across,
     * and each press goes `press` below the surface where it lands */
    double top = -INFINITY;
    for (int32_t i = 0; i < si->nodes; i++)
        top = fmax(top, ftm_mesh_rest_position(m, i).z);
    double lo[2], hi[2];
    for (double band = 1e-3; band <= 0.032; band *= 2) {
        lo[0] = lo[1] = INFINITY, hi[0] = hi[1] = -INFINITY;
        for (int32_t i = 0; i < si->nodes; i++) {
            ftm_vec3 p = ftm_mesh_rest_position(m, i);
            if (p.z < top - band)
                continue;
            lo[0] = fmin(lo[0], p.x), hi[0] = fmax(hi[0], p.x);
            lo[1] = fmin(lo[1], p.y), hi[1] = fmax(hi[1], p.y);
        }
        if (fmin(hi[0] - lo[0], hi[1] - lo[1]) >= 0.01)
            break;
    }
    si->top = top;
    si->cx = 0.5 * (lo[0] + hi[0]);
    si->cy = 0.5 * (lo[1] + hi[1]);
    si->radius = fmin(0.025, 0.3 * fmin(hi[0] - lo[0], hi[1] - lo[1]));
    /* the surface under each press is found when its script is written */
    si->rest = malloc(((size_t)si->nodes + 1) * sizeof *si->rest);
    if (!si->rest) {
        ftm_scene_destroy(sc);
        fprintf(stderr, "ftm bench tick: out of memory\n");
        return -1;
    }
    for (int32_t i = 0; i < si->nodes; i++)
        si->rest[i] = ftm_mesh_rest_position(m, i);
    ftm_scene_destroy(sc);
    if (!(si->radius > 0)) {
        fprintf(stderr, "ftm bench tick: scene '%s' has no flat top face to press\n", name);
        return -1;
    }
    return 0;
}

/* Trainee i of n: a press every 2 s at a point of the ring, phase-shifted by
 * i/n of the period: from 6 mm above the top face down to `press` into it
 * (0.4 s), held while sliding 3 mm (0.6 s), back up (0.4 s), 0.6 s away.
 * Times count from the bot's entry into the session. */
static int write_script(const char *path, const scene_info *si, int i, int n, double press,
                        double length)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "ftm bench tick: %s: cannot write: %s\n", path, strerror(errno));
        return -1;
    }
    double a = 6.283185307179586 * i / n;
    double x = si->cx + si->radius * cos(a), y = si->cy + si->radius * sin(a);
    double tx = -sin(a) * 0.003, ty = cos(a) * 0.003;
    /* the surface where the press lands: the highest node within 3 mm of
     * the vertical through (x, y) (the top itself on a flat face) */
    double land = -INFINITY;
    for (int32_t k = 0; k < si->nodes; k++) {
        const ftm_vec3 p = si->rest[k];
        if ((p.x - x) * (p.x - x) + (p.y - y) * (p.y - y) <= 9e-6)
            land = fmax(land, p.z);
    }
    if (!isfinite(land))
        land = si->top;
    double up = si->top + 0.006, down = land - press;
    fprintf(f, "# ftm bench tick: trainee %d of %d on %s\nclock session\n0 %.5f %.5f %.5f\n", i,
            n, si->name, x, y, up);
    for (double t = 2.0 * i / n + 0.3; t < length; t += 2.0) {
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t, x, y, up);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 0.4, x, y, down);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.0, x + tx, y + ty, down);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.4, x + tx, y + ty, up);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.45, x, y, up);
    }
    return ftm_close_output(f, "ftm bench tick", path);
}

static void parse_log(const char *log, tick_result *r)
{
    char *s = ftm_proc_slurp(log);
    if (!s)
        return;
    r->ok = ftm_proc_server_ticks(s, &r->ticks, &r->seconds, &r->missed) != NULL;
    const char *d = strstr(s, "ticks run at depths ");
    if (d)
        sscanf(d, "ticks run at depths %d..%d", &r->depth_lo, &r->depth_hi);
    const char *p = strstr(s, "tick work p50 ");
    if (!p || sscanf(p,
                     "tick work p50 %lf us p99 %lf us over %" SCNu64
                     " ticks; with a probe in contact p50 %lf us p99 %lf us over %" SCNu64,
                     &r->p50, &r->p99, &r->work_ticks, &r->contact_p50, &r->contact_p99,
                     &r->contact_ticks) != 6)
        r->ok = false;
    free(s);
}

static int run_one(const tick_options *o, const char *dir, const scene_info *si, int n,
                   int domain, tick_result *r)
{
    memset(r, 0, sizeof *r);
    r->sc = si;
    r->trainees = n;
    char sub[1200], slog[1300], sout[1300], serr[1300];
    snprintf(sub, sizeof sub, "%s/%s-%d", dir, si->name, n);
    for (char *c = sub + strlen(dir) + 1; *c; c++)
        if (*c == '/')
            *c = '_'; /* a scene given as a path */
    if (mkdir(sub, 0755) && errno != EEXIST) {
        fprintf(stderr, "ftm bench tick: cannot create %s: %s\n", sub, strerror(errno));
        return -1;
    }
    char session[64], dom[16], rate[32], dur[32];
    snprintf(session, sizeof session, "tick-%d-%d", n, (int)getpid());
    snprintf(dom, sizeof dom, "%d", domain);
    snprintf(rate, sizeof rate, "%g", o->rate);
    snprintf(dur, sizeof dur, "%g", o->duration);
    snprintf(slog, sizeof slog, "%s/server.log", sub);
    snprintf(sout, sizeof sout, "%s/server.out", sub);
    snprintf(serr, sizeof serr, "%s/server.err", sub);
    char *sargv[] = {(char *)o->server, "--scene", (char *)si->name, "--session", session,
                     "--domain", dom, "--config", (char *)o->config, "--rate", rate,
                     "--duration", dur, "--log", slog, "--adaptive", o->adaptive ? "1" : "0",
                     NULL};
    pid_t server = ftm_proc_spawn(sargv, sout, serr, NULL, o->cpu);
    /* an elastic far field may first build its columns (cached afterwards) */
    if (server < 0 || !ftm_proc_wait_text(slog, "session '", 120.0)) {
        fprintf(stderr, "ftm bench tick: %s: the server did not start (see %s)\n", sub, serr);
        if (server > 0)
            kill(server, SIGKILL), waitpid(server, NULL, 0);
        return -1;
    }
    pid_t bots[MAX_TRAINEES];
    for (int i = 0; i < n; i++) {
        char script[1300], out[1300], err[1300], id[16], bdur[32];
        snprintf(script, sizeof script, "%s/bot%d.bot", sub, i);
        snprintf(out, sizeof out, "%s/bot%d.out", sub, i);
        snprintf(err, sizeof err, "%s/bot%d.err", sub, i);
        snprintf(id, sizeof id, "%d", 100 + i);
        snprintf(bdur, sizeof bdur, "%g", o->duration + 30);
        bots[i] = -1;
        if (write_script(script, si, i, n, o->press, o->duration + 30))
            continue;
        char *bargv[] = {(char *)o->bot, "--role", "trainee", "--script", script, "--scene",
                         (char *)si->name, "--session", session, "--domain", dom, "--config",
                         (char *)o->config, "--id", id, "--duration", bdur, NULL};
        bots[i] = ftm_proc_spawn(bargv, out, err, NULL, -2 - o->cpu);
    }
    int rc = ftm_proc_wait(server, o->duration + 150);
    for (int i = 0; i < n; i++)
        if (bots[i] > 0)
            ftm_proc_wait(bots[i], 20);
    parse_log(slog, r);
    char *fin = ftm_proc_slurp(sout), final[128] = "";
    const char *p = fin ? strstr(fin, "final tick ") : NULL;
    if (p)
        snprintf(final, sizeof final, "%.*s synced", (int)strcspn(p, "\n"), p);
    free(fin);
    for (int i = 0; i < n; i++) {
        char out[1300];
        snprintf(out, sizeof out, "%s/bot%d.out", sub, i);
        char *b = ftm_proc_slurp(out);
        if (b && final[0] && strstr(b, final))
            r->synced++;
        free(b);
    }
    if (rc != 0 || !r->ok)
        fprintf(stderr, "ftm bench tick: %s: the server ended with status %d%s (see %s)\n", sub,
                rc, r->ok ? "" : " and no closing figures", serr);
    return rc == 0 && r->ok ? 0 : -1;
}

/* --trainees N,M: the counts, each 1..MAX_TRAINEES, at most MAX_COUNTS. */
static int parse_counts(const ftm_option *opt, const char *v, void *field, char *why, size_t cap)
{
    (void)opt;
    tick_options *o = (tick_options *)((char *)field - offsetof(tick_options, counts));
    int n = 0;
    for (const char *p = v; *p;) {
        size_t len = strcspn(p, ",");
        long long x;
        if (n == MAX_COUNTS || !ftm_option_int(p, len, 1, MAX_TRAINEES, &x)) {
            snprintf(why, cap, "must be a list of 1..%d trainees, at most %d entries (got '%s')",
                     MAX_TRAINEES, MAX_COUNTS, v);
            return -1;
        }
        o->counts[n++] = (int)x;
        p += len + (p[len] == ',');
    }
    if (!n) {
        snprintf(why, cap, "must be a list of 1..%d trainees (got '%s')", MAX_TRAINEES, v);
        return -1;
    }
    o->ncounts = n;
    return 0;
}

static const ftm_option tick_table[] = {
    FTM_OPT_STRING("scenes", "A,B", tick_options, scenes_arg,
                   "built-in names or scene files (default default,palpation)"),
    FTM_OPT_CUSTOM("trainees", "N,M", tick_options, counts, parse_counts,
                   "trainees per run, 1..16 each (default 1,2,8)"),
    FTM_OPT_DOUBLE("duration", "S", tick_options, duration, 4, 3600, 0, "seconds",
                   "each run's server time (default 8)"),
    FTM_OPT_DOUBLE("rate", "HZ", tick_options, rate, 10, 10000, 0, "Hz",
                   "tick rate (default 1000)"),
    FTM_OPT_DOUBLE("press", "MM", tick_options, press_mm, 0.5, 30, 0, "millimetres",
                   "how far each press goes into the top face (default 5)"),
    FTM_OPT_INT("cpu", "N", tick_options, cpu, 0, 1023,
                "the server's CPU (default: the last one; the bots on the others)"),
    FTM_OPT_STRING("server", "PATH", tick_options, server,
                   "ftm-server (default: ../server/ftm-server beside this ftm)"),
    FTM_OPT_STRING("bot", "PATH", tick_options, bot, "ftm-bot (default: ../bot/ftm-bot)"),
    FTM_OPT_STRING("config", "FILE", tick_options, config,
                   "Cyclone DDS configuration (default: deploy/cyclonedds-loopback.xml\n"
                   "of the source tree)"),
    FTM_OPT_INT("domain", "N", tick_options, domain, 0, 226,
                "DDS domain; runs use N .. N+3 (default 170)"),
    FTM_OPT_STRING("keep", "DIR", tick_options, keep,
                   "keep scripts and logs in DIR (default: a temporary directory)"),
    FTM_OPT_FLAG("adaptive", tick_options, adaptive,
                 "the server adapts the depth to its load (--adaptive 1, depths up to\n"
                 "the scene's): how deep the ticks still run, and whether 1 kHz holds"),
    FTM_OPT_FLAG("json", tick_options, json, "one JSON object (the table goes to standard error)"),
    {0},
};

static const ftm_option_set tick_set = {
    .program = "ftm bench tick",
    .usage = "usage: ftm bench tick [options]\n"
             "\n"
             "The server's tick per training scene: ftm-server bound to one CPU at the\n"
             "scene's own depth (--adaptive 0) with N ftm-bot trainees on the other CPUs,\n"
             "each pressing the top face every 2 s; the work of a tick (collision, step,\n"
             "frame) with a probe in contact, median and 99th percentile, from the server's\n"
             "closing figures; ticks run and missed (docs/feel.md).\n",
    .options = tick_table,
    .epilogue = "\nexit status: 0 every run completed with every bot on the server's tick and hash;\n"
                "1 not; 2 usage\n",
};

static int parse(int argc, char **argv, tick_options *o, char *scenes_buf, size_t cap)
{
    static char config[1100];
    snprintf(config, sizeof config, "%s/deploy/cyclonedds-loopback.xml", FTM_SOURCE_DIR);
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    *o = (tick_options){.duration = 8, .rate = 1000, .press_mm = 5, .domain = 170,
                        .cpu = ncpu > 1 ? (int)ncpu - 1 : -1, .config = config,
                        .scenes_arg = "default,palpation", .counts = {1, 2, 8}, .ncounts = 3};
    int rc = ftm_options_parse(&tick_set, argc, argv, o, NULL, NULL);
    if (rc == FTM_OPTIONS_HELP)
        return 1;
    if (rc != FTM_OPTIONS_OK)
        return 2;
    if (o->cpu >= ncpu) {
        fprintf(stderr, "ftm bench tick: --cpu must be a CPU online, 0..%ld (got %d)\n", ncpu - 1,
                o->cpu);
        return 2;
    }
    o->press = o->press_mm * 1e-3;
    snprintf(scenes_buf, cap, "%s", o->scenes_arg);
    char *save = NULL;
    for (char *t = strtok_r(scenes_buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        if (o->nscenes == MAX_SCENES) {
            fprintf(stderr, "ftm bench tick: --scenes takes at most %d scenes\n", MAX_SCENES);
            return 2;
        }
        o->scenes[o->nscenes++] = t;
    }
    if (!o->nscenes) {
        fprintf(stderr, "ftm bench tick: --scenes names no scene\n");
        return 2;
    }
    if (ftm_proc_find_programs("ftm bench tick", &o->server, &o->bot))
        return 2;
    if (access(o->config, R_OK)) {
        fprintf(stderr, "ftm bench tick: cannot read --config %s\n", o->config);
        return 2;
    }
    return 0;
}

static void print_row(FILE *f, const tick_result *r, double budget_us)
{
    const scene_info *si = r->sc;
    char depths[16];
    snprintf(depths, sizeof depths, r->depth_lo == r->depth_hi ? "%d" : "%d..%d", r->depth_lo,
             r->depth_hi);
    fprintf(f, "%-10s %-11s %-7s %6s %8d %9" PRIu64 " %8.0f %8.0f %7.0f %6" PRIu64 " %6.2f %4d/%d%s\n",
            si->name, ftm_forces_name(si->forces), si->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed",
            depths, r->trainees, r->contact_ticks, r->contact_p50, r->contact_p99, r->p50,
            r->missed, r->contact_p50 / budget_us, r->synced, r->trainees,
            r->ok ? "" : "  (failed)");
}

static void json_num(FILE *f, const char *key, double v)
{
    if (isfinite(v))
        fprintf(f, ",\"%s\":%.6g", key, v);
    else
        fprintf(f, ",\"%s\":null", key);
}

int ftm_bench_tick(int argc, char **argv)
{
    tick_options o;
    char scenes_buf[1024];
    int prc = parse(argc, argv, &o, scenes_buf, sizeof scenes_buf);
    if (prc)
        return prc == 1 ? 0 : 2;
    scene_info si[MAX_SCENES] = {0};
    int status = 2;
    for (int k = 0; k < o.nscenes; k++)
        if (scene_info_of(o.scenes[k], &si[k]))
            goto done;
    char tmpl[] = "/tmp/ftm-bench-tick.XXXXXX";
    const char *dir = o.keep;
    if (dir) {
        if (mkdir(dir, 0755) && errno != EEXIST) {
            fprintf(stderr, "ftm bench tick: cannot create --keep %s: %s\n", dir, strerror(errno));
            goto done;
        }
    } else if (!(dir = mkdtemp(tmpl))) {
        fprintf(stderr, "ftm bench tick: cannot create a temporary directory: %s\n",
                strerror(errno));
        goto done;
    }
    double budget_us = 1e6 / o.rate;
    FILE *t = o.json ? stderr : stdout;
    fprintf(t, "ftm bench tick: %g Hz (budget %.0f us), server on cpu %d, %g s a run, %.1f mm "
               "presses, %s depth\n",
            o.rate, budget_us, o.cpu, o.duration, o.press * 1e3,
            o.adaptive ? "adaptive" : "the scene's");
    fprintf(t, "%-10s %-11s %-7s %6s %8s %9s %8s %8s %7s %6s %6s %6s\n", "scene", "model", "far",
            "depth", "trainees", "contact", "p50[us]", "p99[us]", "all[us]", "missed", "budget",
            "synced");
    tick_result res[MAX_SCENES * MAX_COUNTS];
    int nres = 0, failed = 0;
    for (int k = 0; k < o.nscenes; k++)
        for (int c = 0; c < o.ncounts; c++) {
            tick_result *r = &res[nres++];
            if (run_one(&o, dir, &si[k], o.counts[c], o.domain + (nres % 4), r) ||
                r->synced != r->trainees)
                failed++;
            print_row(t, r, budget_us);
            fflush(t);
        }
    fprintf(t, "contact: ticks with a probe in contact; p50/p99: their work; all: the median of "
               "every tick; budget: p50 over the tick period\n");
    if (o.json) {
        printf("{\"rate\":%g,\"cpu\":%d,\"duration\":%g,\"press_mm\":%g,\"adaptive\":%s,"
               "\"runs\":[",
               o.rate, o.cpu, o.duration, o.press * 1e3, o.adaptive ? "true" : "false");
        for (int i = 0; i < nres; i++) {
            const tick_result *r = &res[i];
            printf("%s{\"scene\":\"%s\",\"model\":\"%s\",\"far_field\":\"%s\",\"depth\":%d,"
                   "\"depth_lo\":%d,\"depth_hi\":%d,"
                   "\"nodes\":%d,\"trainees\":%d,\"ticks\":%" PRIu64 ",\"missed\":%" PRIu64
                   ",\"contact_ticks\":%" PRIu64,
                   i ? "," : "", r->sc->name, ftm_forces_name(r->sc->forces),
                   r->sc->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed", (int)r->sc->depth,
                   r->depth_lo, r->depth_hi, (int)r->sc->nodes, r->trainees, r->ticks, r->missed,
                   r->contact_ticks);
            json_num(stdout, "contact_p50_us", r->ok ? r->contact_p50 : NAN);
            json_num(stdout, "contact_p99_us", r->ok ? r->contact_p99 : NAN);
            json_num(stdout, "all_p50_us", r->ok ? r->p50 : NAN);
            printf(",\"synced\":%d,\"ok\":%s}", r->synced, r->ok ? "true" : "false");
        }
        printf("]}\n");
    }
    if (!o.keep) {
        if (ftm_proc_remove_tree(dir))
            fprintf(stderr, "ftm bench tick: could not remove %s: %s\n", dir, strerror(errno));
    }
    status = failed ? 1 : 0;
done:
    for (int k = 0; k < o.nscenes; k++)
        free(si[k].rest);
    return status;
}
