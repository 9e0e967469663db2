/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench net`: a whole session on loopback DDS, measured from outside
 * (docs/bench-net.md). It runs the real programs — ftm-server and N ftm-bot
 * trainees, plus Cyclone's ddsperf ping/pong beside them — and reads what
 * they report:
 *
 *  1. rate: a 1000-node scene, N trainees pressing on a ring around its
 *     centre, the server at 1 kHz for --duration s: ticks, missed ticks, tick
 *     period p50/p99 (server summary), frame bytes per tick, server-to-bot
 *     latency (TickFrame.send_time_ns to reception, from every bot's log),
 *     and ddsperf's one-way latency (round trip / 2) measured meanwhile on
 *     the same loopback configuration with a 100-byte payload at 1 kHz;
 *  2. size: the same trainee scripts on a 100 000-node slab for
 *     --size-duration s: frame bytes per tick again;
 *  3. adaptive: the 1k scene with half the bots, the server's adaptive
 *     depth on (--adaptive 1) and Cyclone's loss injection (the lossy
 *     loopback configuration); one bot is stopped (SIGSTOP) for 2 s twice:
 *     the depth over time (server log), that bot's lag over time (its frame
 *     latency in ticks) and whether the tick rate holds.
 * Phases 1 and 2 run at the scene's fixed depth (--adaptive 0).
 * For both scenes, the bytes per tick of the alternative — streaming every
 * node that moved in a tick (index + position, protobuf-packed as the
 * keyframe does) — follow from the updated-node counts the bots log. Every
 * bot must end on the server's final tick and hash (exit status 1 if not). */
#include "bench_net.h"
#include "commands.h"
#include "proc.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifndef FTM_SOURCE_DIR
#define FTM_SOURCE_DIR "."
#endif

#define MAX_BOTS 32

typedef struct net_options {
    double duration, size_duration, rate;
    int bots;
    const char *server, *bot, *config, *keep, *plot;
    bool json, ddsperf;
    int domain;
    double adaptive_duration; /* 0: no adaptive phase */
    const char *lossy_config;
} net_options;

/* How a session is run (phase 3 differs). */
typedef struct session_plan {
    const char *config;
    bool adaptive;
    int bots;
    int stop_bot;        /* -1: none; else SIGSTOP it at stop_at[k] for stop_for s */
    double stop_at[2], stop_for;
} session_plan;

typedef struct run_result {
    /* server */
    uint64_t ticks, missed, keyframes, keyframe_bytes;
    double seconds, bytes_per_tick, tick_p50, tick_p99, late_p50, late_p99, step_mean_us;
    char final[96];
    /* bots */
    int synced;          /* bots that ended synced on the server's tick and hash */
    /* over the first bot's synced ticks: frame payload (its frame_bytes) and
     * what streaming the moved nodes would take, per tick */
    double frame_bytes_per_tick, stream_bytes_per_tick, moved_per_tick;
    double *lat;         /* all latency samples [us]: server hand-off to arrival */
    double *dds;         /* ... of them, dds_write to arrival */
    double *pick;        /* ... arrival to the bot thread taking the frame */
    uint64_t *lat_tick;  /* their ticks */
    size_t nlat, caplat;
    /* adaptive phase */
    int depth_min, depth_changes;
    double max_lag_ticks;
} run_result;

/* Files this run could not write, each reported when it happened. The run
 * goes on (its sessions are what it measures) and then exits 2. */
static int output_errors;

static FILE *open_output(const char *path)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "ftm bench net: %s: cannot write: %s\n", path, strerror(errno));
        output_errors++;
    }
    return f;
}

/* Closes a file from open_output(); a write that failed now or earlier (the
 * stream remembers it) is reported. 0 or -1. */
static int close_output(FILE *f, const char *path)
{
    if (ftm_close_output(f, "ftm bench net", path) == 0)
        return 0;
    output_errors++;
    return -1;
}

/* Copies a text file (plot data into --plot DIR); a missing source is skipped. */
static void copy_text(const char *src, const char *dst)
{
    char *d = ftm_proc_slurp(src);
    FILE *g = d ? open_output(dst) : NULL;
    if (g) {
        fputs(d, g);
        close_output(g, dst);
    }
    free(d);
}

/* ---- inputs: scenes and trainee scripts --------------------------------------------- */

static int write_scene(const char *path, const char *name, int nx, int ny)
{
    FILE *f = open_output(path);
    if (!f)
        return -1;
    fprintf(f,
            "# ftm bench net: %dx%dx10 nodes of 1 cm, bottom fixed, top face at z = 0.09 m\n"
            "[scene]\nname = %s\n[mesh]\ngenerator = lattice3d\nnx = %d\nny = %d\nnz = 10\n"
            "spacing = 0.01\nstencil = 18\nfixed_faces = zmin\n[material]\nmass = 0.001\n"
            "damping = 0.3\nstiffness = 50\n[sim]\ntime_step = 1e-3\ndepth = 8\nsteps = 2000\n",
            nx, ny, name, nx, ny);
    return close_output(f, path);
}

#define TOP_Z 0.09

/* Trainee i of n: presses every 2 s at a point on a 2.5 cm ring around the
 * scene's centre (cx, cy), phase-shifted by i/n of the period: from 6 mm
 * above the top face down to 4 mm into it (0.4 s), a 5 mm slide (0.6 s),
 * back up (0.4 s), 0.6 s away. */
static int write_script(const char *path, int i, int n, double cx, double cy, double length)
{
    FILE *f = open_output(path);
    if (!f)
        return -1;
    double a = 6.283185307179586 * i / n, x = cx + 0.025 * cos(a), y = cy + 0.025 * sin(a);
    double tx = -sin(a) * 0.005, ty = cos(a) * 0.005, up = TOP_Z + 0.006, down = TOP_Z - 0.004;
    double phase = 2.0 * i / n;
    fprintf(f, "# ftm bench net trainee %d of %d\n0 %.5f %.5f %.5f\n", i, n, x, y, up);
    for (double t = phase + 0.5; t < length; t += 2.0) {
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t, x, y, up);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 0.4, x, y, down);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.0, x + tx, y + ty, down);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.4, x + tx, y + ty, up);
        fprintf(f, "%.3f %.5f %.5f %.5f\n", t + 1.45, x, y, up);
    }
    return close_output(f, path);
}

/* ---- reading what the programs report --------------------------------------------------- */

static void parse_server(const char *log, run_result *r)
{
    char *s = ftm_proc_slurp(log);
    if (!s)
        return;
    const char *p = ftm_proc_server_ticks(s, &r->ticks, &r->seconds, &r->missed);
    if (p) {
        const char *q = strstr(p, "bytes/frame, ");
        if (q)
            sscanf(q, "bytes/frame, %lf bytes/tick; %" SCNu64 " keyframes (%" SCNu64 " bytes)",
                   &r->bytes_per_tick, &r->keyframes, &r->keyframe_bytes);
        q = strstr(p, "step mean ");
        if (q)
            sscanf(q, "step mean %lf", &r->step_mean_us);
    }
    p = strstr(s, "tick period p50 ");
    if (p)
        sscanf(p, "tick period p50 %lf ms p99 %lf ms; start after due p50 %lf ms p99 %lf ms",
               &r->tick_p50, &r->tick_p99, &r->late_p50, &r->late_p99);
    free(s);
}

static int varint_size(uint64_t v)
{
    int n = 1;
    while (v >= 128) {
        v >>= 7;
        n++;
    }
    return n;
}

/* Bytes of a message streaming u moved nodes for one tick: tick (field 1),
 * packed node indices (field 2, each as wide as the largest index) and
 * packed double positions (field 3). */
static double stream_bytes(uint64_t tick, int64_t u, int32_t nodes)
{
    if (u <= 0)
        return 0.0;
    int64_t li = u * varint_size((uint64_t)(nodes - 1)), lp = 24 * u;
    return (double)(1 + varint_size(tick) + 1 + varint_size((uint64_t)li) + li + 1 +
                    varint_size((uint64_t)lp) + lp);
}

/* One bot's CSV log (docs/bot-script.md): latency samples into r; the
 * streaming estimate from the first bot only (every replica steps alike). */
static int read_bot_csv(const char *path, run_result *r, bool stream, int32_t nodes)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    char line[512];
    uint64_t first = 0, last = 0;
    double sbytes = 0, moved = 0, fsum = 0;
    bool any = false;
    while (fgets(line, sizeof line, f)) {
        double t, fx, fy, fz, lat;
        uint64_t tick;
        char h1[32], h2[32];
        int state, contacts, upd = 0;
        double ddslat = NAN, fbytes = 0, pick = NAN;
        if (sscanf(line, "%lf,%" SCNu64 ",%31[^,],%31[^,],%d,%d,%lf,%lf,%lf,%lf,%d,%lf,%lf,%lf", &t,
                   &tick, h1, h2, &state, &contacts, &fx, &fy, &fz, &lat, &upd, &ddslat,
                   &fbytes, &pick) < 10 ||
            state != 2)
            continue;
        if (r->nlat == r->caplat) {
            size_t cap = r->caplat ? 2 * r->caplat : 65536;
            double *l = realloc(r->lat, cap * sizeof *l);
            if (l)
                r->lat = l;
            double *d = l ? realloc(r->dds, cap * sizeof *d) : NULL;
            if (d)
                r->dds = d;
            double *pk = d ? realloc(r->pick, cap * sizeof *pk) : NULL;
            if (pk)
                r->pick = pk;
            uint64_t *lt = pk ? realloc(r->lat_tick, cap * sizeof *lt) : NULL;
            if (!lt) {
                fclose(f);
                return -1; /* what was grown stays owned by r */
            }
            r->lat_tick = lt;
            r->caplat = cap;
        }
        r->dds[r->nlat] = ddslat;
        r->pick[r->nlat] = pick;
        r->lat[r->nlat] = lat;
        r->lat_tick[r->nlat++] = tick;
        if (!any)
            first = tick;
        any = true;
        last = tick;
        sbytes += stream_bytes(tick, upd, nodes);
        fsum += fbytes;
        moved += upd;
    }
    fclose(f);
    if (stream && any && last > first) {
        r->stream_bytes_per_tick = sbytes / (double)(last - first + 1);
        r->frame_bytes_per_tick = fsum / (double)(last - first + 1);
        r->moved_per_tick = moved / (double)(last - first + 1);
    }
    return 0;
}

/* Median over 1 s windows (by server tick) of each window's q-quantile;
 * windows with fewer than 100 samples are skipped. */
static double windowed(const run_result *r, double rate, double q)
{
    if (r->nlat == 0)
        return NAN;
    uint64_t wmax = 0;
    for (size_t i = 0; i < r->nlat; i++)
        if (r->lat_tick[i] / (uint64_t)rate > wmax)
            wmax = r->lat_tick[i] / (uint64_t)rate;
    double *per = malloc((wmax + 1) * sizeof *per), *buf = malloc(r->nlat * sizeof *buf);
    size_t nper = 0;
    for (uint64_t w = 0; per && buf && w <= wmax; w++) {
        size_t n = 0;
        for (size_t i = 0; i < r->nlat; i++)
            if (r->lat_tick[i] / (uint64_t)rate == w)
                buf[n++] = r->lat[i];
        if (n >= 100)
            per[nper++] = ftm_proc_quantile(buf, n, q);
    }
    double m = nper ? ftm_proc_quantile(per, nper, 0.5) : NAN;
    free(per);
    free(buf);
    return m;
}

/* p50 and p99 of x[i] - (sub ? sub[i] : 0) over the samples where that is
 * finite (older bot logs lack the columns), using buf (n doubles). */
static void pooled_part(const double *x, const double *sub, size_t n, double *buf, double *p50,
                        double *p99)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        double v = sub ? x[i] - sub[i] : x[i];
        if (isfinite(v))
            buf[k++] = v;
    }
    *p50 = ftm_proc_quantile(buf, k, 0.5);
    *p99 = ftm_proc_quantile(buf, k, 0.99);
}

/* ddsperf ping's per-second lines: "... 50% Xus 90% Yus 99% Zus ...". */
static int parse_ddsperf(const char *path, double *p50, double *p99, FILE *series)
{
    char *s = ftm_proc_slurp(path);
    if (!s)
        return -1;
    double a[4096], b[4096];
    int n = 0;
    for (char *line = strtok(s, "\n"); line && n < 4096; line = strtok(NULL, "\n")) {
        const char *m50 = strstr(line, " 50% "), *m99 = strstr(line, " 99% ");
        double t;
        if (!m50 || !m99 || sscanf(m50, " 50%% %lfus", &a[n]) != 1 ||
            sscanf(m99, " 99%% %lfus", &b[n]) != 1)
            continue;
        const char *ts = strchr(line, ']');
        if (series && ts && sscanf(ts + 1, "%lf", &t) == 1)
            fprintf(series, "%.0f %.2f %.2f\n", t, a[n], b[n]);
        n++;
    }
    free(s);
    /* the first second includes discovery */
    int skip = n > 3 ? 1 : 0;
    *p50 = n > skip ? ftm_proc_quantile(a + skip, (size_t)(n - skip), 0.5) : NAN;
    *p99 = n > skip ? ftm_proc_quantile(b + skip, (size_t)(n - skip), 0.5) : NAN;
    return n > skip ? 0 : -1;
}

/* Phase 3's traces: the depth after every change (server log lines
 * `[ t] info: depth A -> B: reason (tick T)`) and the stopped bot's lag in
 * ticks (frame latency x rate, by server tick), into SUB/depth.dat and
 * SUB/lag.dat (and the --plot directory). */
static void adaptive_traces(const net_options *o, const session_plan *pl, const char *sub,
                            const char *slog, run_result *r)
{
    char path[700];
    char *s = ftm_proc_slurp(slog);
    r->depth_min = -1;
    int cur = -1;
    const char *end = s ? strstr(s, "info: depth ") : NULL;
    for (const char *q = end; q; q = strstr(q + 1, "info: depth "))
        end = q; /* the last one: "depth N at the end, range [a, b]: ..." */
    int final = -1;
    if (end && sscanf(end, "info: depth %d at the end", &final) != 1)
        final = -1;
    snprintf(path, sizeof path, "%s/depth.dat", sub);
    FILE *f = open_output(path);
    for (char *line = s ? strtok(s, "\n") : NULL; line; line = strtok(NULL, "\n")) {
        const char *d = strstr(line, "info: depth ");
        const char *tk = d ? strstr(d, "(tick ") : NULL;
        int from, to;
        uint64_t tick;
        if (!tk || sscanf(d, "info: depth %d -> %d", &from, &to) != 2 ||
            sscanf(tk, "(tick %" SCNu64 ")", &tick) != 1)
            continue;
        if (r->depth_changes++ == 0 && f)
            fprintf(f, "0 %d\n", from);
        if (f)
            fprintf(f, "%.3f %d\n", (double)tick / o->rate, to);
        cur = to;
        if (r->depth_min < 0 || to < r->depth_min)
            r->depth_min = to;
        if (from < r->depth_min)
            r->depth_min = from;
    }
    if (cur < 0)
        cur = final;
    if (f && cur >= 0) {
        if (r->depth_changes == 0)
            fprintf(f, "0 %d\n", cur);
        fprintf(f, "%.3f %d\n", (double)r->ticks / o->rate, cur); /* to the end */
    }
    if (r->depth_min < 0)
        r->depth_min = cur;
    if (f)
        close_output(f, path);
    free(s);
    snprintf(path, sizeof path, "%s/bot%d.csv", sub, pl->stop_bot);
    FILE *in = fopen(path, "r");
    snprintf(path, sizeof path, "%s/lag.dat", sub);
    FILE *out = in ? open_output(path) : NULL;
    char line[512];
    while (in && out && fgets(line, sizeof line, in)) {
        double t, fx, fy, fz, lat, dds, bytes, pick = 0;
        uint64_t tick;
        char h1[32], h2[32];
        int state, contacts, upd;
        if (sscanf(line, "%lf,%" SCNu64 ",%31[^,],%31[^,],%d,%d,%lf,%lf,%lf,%lf,%d,%lf,%lf,%lf", &t,
                   &tick, h1, h2, &state, &contacts, &fx, &fy, &fz, &lat, &upd, &dds, &bytes,
                   &pick) < 10)
            continue;
        /* how far behind the server the bot's replay is: the frame's latency
         * to arrival plus the wait until the bot's thread took it */
        double lag = (lat + pick) * 1e-6 * o->rate;
        if (lag > r->max_lag_ticks)
            r->max_lag_ticks = lag;
        fprintf(out, "%.3f %.1f\n", (double)tick / o->rate, lag);
    }
    if (in)
        fclose(in);
    if (out)
        close_output(out, path);
    if (o->plot) {
        const char *names[] = {"depth.dat", "lag.dat"};
        for (int k = 0; k < 2; k++) {
            char src[700], dst[1200];
            snprintf(src, sizeof src, "%s/%s", sub, names[k]);
            snprintf(dst, sizeof dst, "%s/adaptive-%s", o->plot, names[k]);
            copy_text(src, dst);
        }
    }
}

/* ---- one session ----------------------------------------------------------------------- */

static int run_session(const net_options *o, const session_plan *pl, const char *dir,
                       const char *tag, const char *scene, int32_t nodes, double cx, double cy,
                       double duration, int domain, bool with_ddsperf, run_result *r,
                       double *dp50, double *dp99)
{
    char sub[512], path[640], slog[640], sout[640], serr[640];
    snprintf(sub, sizeof sub, "%s/%s", dir, tag);
    if (mkdir(sub, 0755) && errno != EEXIST) {
        fprintf(stderr, "ftm bench net: cannot create %s: %s\n", sub, strerror(errno));
        return -1;
    }
    char session[64], dom[16], rate[32], dur[32];
    snprintf(session, sizeof session, "bench-%s-%d", tag, (int)getpid());
    snprintf(dom, sizeof dom, "%d", domain);
    snprintf(rate, sizeof rate, "%g", o->rate);
    /* the bots start about a second after the server; they leave when it does */
    snprintf(dur, sizeof dur, "%g", duration + 1.5);
    snprintf(slog, sizeof slog, "%s/server.log", sub);
    snprintf(sout, sizeof sout, "%s/server.out", sub);
    snprintf(serr, sizeof serr, "%s/server.err", sub);
    char sctl[4096]; /* the controller's view every 100 ms (kept with --keep) */
    snprintf(sctl, sizeof sctl, "%s/control.csv", sub);
    char *sargv[] = {(char *)o->server, "--scene", (char *)scene, "--session", session,
                     "--domain", dom, "--config", (char *)pl->config, "--rate", rate,
                     "--duration", dur, "--log", slog, "--adaptive", pl->adaptive ? "1" : "0",
                     "--control-log", sctl, NULL};
    pid_t server = ftm_proc_spawn(sargv, sout, serr, NULL, -1);
    if (server < 0 || !ftm_proc_wait_text(slog, "session '", 20.0)) {
        fprintf(stderr, "ftm bench net: %s: the server did not start (see %s)\n", tag, serr);
        if (server > 0)
            kill(server, SIGKILL), waitpid(server, NULL, 0);
        return -1;
    }
    pid_t bots[MAX_BOTS];
    for (int i = 0; i < pl->bots; i++) {
        char script[640], log[640], out[640], err[640], id[16], bdur[32];
        snprintf(script, sizeof script, "%s/bot%d.bot", sub, i);
        snprintf(log, sizeof log, "%s/bot%d.csv", sub, i);
        snprintf(out, sizeof out, "%s/bot%d.out", sub, i);
        snprintf(err, sizeof err, "%s/bot%d.err", sub, i);
        snprintf(id, sizeof id, "%d", 100 + i);
        snprintf(bdur, sizeof bdur, "%g", duration + 30);
        if (write_script(script, i, pl->bots, cx, cy, duration + 30)) {
            bots[i] = -1; /* reported by write_script() */
            continue;
        }
        char *bargv[] = {(char *)o->bot, "--role", "trainee", "--script", script, "--scene",
                         (char *)scene, "--session", session, "--domain", dom, "--config",
                         (char *)pl->config, "--id", id, "--duration", bdur, "--log", log, NULL};
        bots[i] = ftm_proc_spawn(bargv, out, err, NULL, -1);
    }
    pid_t ping = -1, pong = -1;
    char ping_out[640];
    snprintf(ping_out, sizeof ping_out, "%s/ddsperf-ping.out", sub);
    static char uri[1100];
    if (with_ddsperf) {
        char pdom[16], pdur[32], pong_out[640], e1[640], e2[640];
        snprintf(uri, sizeof uri, "file://%s", o->config);
        snprintf(pdom, sizeof pdom, "%d", domain + 1);
        snprintf(pdur, sizeof pdur, "%g", duration);
        snprintf(pong_out, sizeof pong_out, "%s/ddsperf-pong.out", sub);
        snprintf(e1, sizeof e1, "%s/ddsperf-pong.err", sub);
        snprintf(e2, sizeof e2, "%s/ddsperf-ping.err", sub);
        char *pongv[] = {"/usr/bin/ddsperf", "-i", pdom, "-D", pdur, "pong", NULL};
        char *pingv[] = {"/usr/bin/ddsperf", "-i", pdom, "-D", pdur, "-Qminmatch:1",
                         "-Qinitwait:10", "ping", "1000Hz", "size", "100", NULL};
        pong = ftm_proc_spawn(pongv, pong_out, e1, uri, -1);
        ping = ftm_proc_spawn(pingv, ping_out, e2, uri, -1);
    }
    if (pl->stop_bot >= 0 && pl->stop_bot < pl->bots && bots[pl->stop_bot] > 0) {
        double t0 = ftm_proc_now_s();
        for (int k = 0; k < 2; k++) {
            double wait = t0 + pl->stop_at[k] - ftm_proc_now_s();
            if (wait > 0)
                ftm_proc_sleep_s(wait);
            kill(bots[pl->stop_bot], SIGSTOP);
            ftm_proc_sleep_s(pl->stop_for);
            kill(bots[pl->stop_bot], SIGCONT);
        }
    }
    int rc = ftm_proc_wait(server, duration + 30);
    for (int i = 0; i < pl->bots; i++)
        if (bots[i] > 0)
            ftm_proc_wait(bots[i], 20);
    if (with_ddsperf) {
        ftm_proc_wait(ping, 20);
        ftm_proc_wait(pong, 20);
    }
    parse_server(slog, r);
    char *fin = ftm_proc_slurp(sout);
    if (fin) {
        const char *p = strstr(fin, "final tick ");
        if (p)
            snprintf(r->final, sizeof r->final, "%.*s", (int)strcspn(p, "\n"), p);
        free(fin);
    }
    for (int i = 0; i < pl->bots; i++) {
        snprintf(path, sizeof path, "%s/bot%d.out", sub, i);
        char *b = ftm_proc_slurp(path);
        char want[160];
        snprintf(want, sizeof want, "%s synced", r->final);
        if (b && r->final[0] && strstr(b, want))
            r->synced++;
        free(b);
        snprintf(path, sizeof path, "%s/bot%d.csv", sub, i);
        read_bot_csv(path, r, i == 0, nodes);
    }
    if (pl->adaptive)
        adaptive_traces(o, pl, sub, slog, r);
    if (with_ddsperf) {
        snprintf(path, sizeof path, "%s/ddsperf.dat", sub);
        FILE *series = o->plot ? open_output(path) : NULL;
        if (parse_ddsperf(ping_out, dp50, dp99, series))
            fprintf(stderr, "ftm bench net: no ddsperf latency in %s\n", ping_out);
        if (series)
            close_output(series, path);
    }
    return rc == 0 ? 0 : -1;
}

/* ---- command --------------------------------------------------------------------------- */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm bench net [options]\n\n"
            "A session on loopback DDS: ftm-server at --rate with --bots ftm-bot trainees on a\n"
            "1000-node scene for --duration s (tick rate, missed ticks, tick period, frame\n"
            "bytes, server-to-bot latency beside ddsperf's), then on a 100 000-node scene for\n"
            "--size-duration s (frame bytes), both against streaming every moved node.\n\n"
            "options:\n"
            "  --duration S        the 1k-node run (default 60)\n"
            "  --size-duration S   the 100k-node run (default 15)\n"
            "  --bots N            trainee bots (default 8, at most %d)\n"
            "  --rate HZ           tick rate (default 1000)\n"
            "  --server PATH       ftm-server (default: beside this ftm, ../server/ftm-server)\n"
            "  --bot PATH          ftm-bot (default: ../bot/ftm-bot)\n"
            "  --config FILE       Cyclone DDS configuration (default: %s/deploy/"
            "cyclonedds-loopback.xml)\n"
            "  --domain N          first DDS domain to use (default 150; uses N .. N+4)\n"
            "  --adaptive-duration S  the adaptive-depth run (default 20; 0: skip it)\n"
            "  --lossy-config FILE its configuration (default: %s/deploy/"
            "cyclonedds-loopback-lossy.xml)\n"
            "  --no-ddsperf        do not run ddsperf\n"
            "  --keep DIR          keep logs, scripts and scenes in DIR (default: a temporary\n"
            "                      directory, removed)\n"
            "  --plot DIR          write gnuplot data (latency per second, bytes) to DIR\n"
            "  --json              print one JSON object (the table goes to standard error)\n\n"
            "exit status: 0 every bot ended on the server's tick and hash; 1 not; 2 usage, or\n"
            "an output (--plot, --keep, standard output) that cannot be written\n",
            MAX_BOTS, FTM_SOURCE_DIR, FTM_SOURCE_DIR);
}

/* A long option value as an int for the range checks after it: values
 * beyond int become its limits (out of every range) instead of wrapping
 * into one (--bots 4294967297 as 1). */
static int clamp_int(long v)
{
    return v > INT_MAX ? INT_MAX : v < INT_MIN ? INT_MIN : (int)v;
}

static int parse(int argc, char **argv, net_options *o)
{
    static char config[1024], lossy[1024];
    snprintf(config, sizeof config, "%s/deploy/cyclonedds-loopback.xml", FTM_SOURCE_DIR);
    snprintf(lossy, sizeof lossy, "%s/deploy/cyclonedds-loopback-lossy.xml", FTM_SOURCE_DIR);
    *o = (net_options){60.0, 15.0, 1000.0, 8, NULL, NULL, config, NULL, NULL, false, true, 150,
                       20.0, lossy};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 1;
        }
        if (strcmp(a, "--json") == 0) {
            o->json = true;
            continue;
        }
        if (strcmp(a, "--no-ddsperf") == 0) {
            o->ddsperf = false;
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "ftm bench net: %s needs a value (or is unknown)\n", a);
            return 2;
        }
        const char *v = argv[++i];
        char *end = NULL;
        errno = 0;
        if (strcmp(a, "--duration") == 0)
            o->duration = strtod(v, &end);
        else if (strcmp(a, "--size-duration") == 0)
            o->size_duration = strtod(v, &end);
        else if (strcmp(a, "--rate") == 0)
            o->rate = strtod(v, &end);
        else if (strcmp(a, "--bots") == 0) /* (long: not cut to int before the range check) */
            o->bots = clamp_int(strtol(v, &end, 10));
        else if (strcmp(a, "--domain") == 0)
            o->domain = clamp_int(strtol(v, &end, 10));
        else if (strcmp(a, "--server") == 0)
            o->server = v;
        else if (strcmp(a, "--bot") == 0)
            o->bot = v;
        else if (strcmp(a, "--config") == 0)
            o->config = v;
        else if (strcmp(a, "--keep") == 0)
            o->keep = v;
        else if (strcmp(a, "--plot") == 0)
            o->plot = v;
        else if (strcmp(a, "--adaptive-duration") == 0)
            o->adaptive_duration = strtod(v, &end);
        else if (strcmp(a, "--lossy-config") == 0)
            o->lossy_config = v;
        else {
            fprintf(stderr, "ftm bench net: unknown option '%s' (try --help)\n", a);
            return 2;
        }
        if (end && (*end || errno)) {
            fprintf(stderr, "ftm bench net: %s: bad number '%s'\n", a, v);
            return 2;
        }
    }
    /* One message per option, stating the range it really accepts. */
    const char *bad = NULL;
    if (!(o->duration >= 3))
        bad = "--duration must be at least 3 s";
    else if (!(o->size_duration >= 3))
        bad = "--size-duration must be at least 3 s";
    else if (!(o->rate > 0 && o->rate <= 10000))
        bad = "--rate must be above 0 and at most 10000 Hz";
    else if (o->domain < 0 || o->domain > 226)
        bad = "--domain must be in 0..226";
    else if (!(o->adaptive_duration == 0 || o->adaptive_duration >= 12))
        bad = "--adaptive-duration must be 0 or at least 12 s";
    if (bad) {
        fprintf(stderr, "ftm bench net: %s\n", bad);
        return 2;
    }
    if (o->bots < 1 || o->bots > MAX_BOTS) {
        fprintf(stderr, "ftm bench net: --bots must be in 1..%d\n", MAX_BOTS);
        return 2;
    }
    if (ftm_proc_find_programs("ftm bench net", &o->server, &o->bot))
        return 2;
    if (access(o->config, R_OK) || (o->adaptive_duration > 0 && access(o->lossy_config, R_OK))) {
        fprintf(stderr, "ftm bench net: cannot read %s or %s\n", o->config, o->lossy_config);
        return 2;
    }
    return 0;
}

static void json_num(FILE *f, const char *key, double v, bool last)
{
    if (isfinite(v))
        fprintf(f, "\"%s\":%.6g%s", key, v, last ? "" : ",");
    else
        fprintf(f, "\"%s\":null%s", key, last ? "" : ",");
}

int ftm_bench_net(int argc, char **argv)
{
    net_options o;
    int prc = parse(argc, argv, &o);
    if (prc)
        return prc == 1 ? 0 : 2;
    char dir[1024];
    if (o.keep) {
        snprintf(dir, sizeof dir, "%s", o.keep);
        if (mkdir(dir, 0755) && errno != EEXIST) {
            fprintf(stderr, "ftm bench net: cannot create %s: %s\n", dir, strerror(errno));
            return 2;
        }
    } else {
        snprintf(dir, sizeof dir, "%s/ftm-bench-net.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
        if (!mkdtemp(dir)) {
            fprintf(stderr, "ftm bench net: cannot create a temporary directory: %s\n", strerror(errno));
            return 2;
        }
    }
    char s1k[1100], s100k[1100];
    snprintf(s1k, sizeof s1k, "%s/net-1k.scene", dir);
    snprintf(s100k, sizeof s100k, "%s/net-100k.scene", dir);
    if (write_scene(s1k, "net-1k", 10, 10) || write_scene(s100k, "net-100k", 100, 100))
        return 2; /* reported by write_scene() */
    if (!o.json)
        fprintf(stderr, "ftm bench net: %d bots at %g Hz, %g s on 1k nodes, %g s on 100k; logs in %s\n",
                o.bots, o.rate, o.duration, o.size_duration, dir);
    run_result a, b, c;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    memset(&c, 0, sizeof c);
    double dp50 = NAN, dp99 = NAN, dummy50, dummy99;
    session_plan fixed = {o.config, false, o.bots, -1, {0, 0}, 0};
    int ra = run_session(&o, &fixed, dir, "1k", s1k, 1000, 0.045, 0.045, o.duration, o.domain,
                         o.ddsperf, &a, &dp50, &dp99);
    int rb = run_session(&o, &fixed, dir, "100k", s100k, 100000, 0.495, 0.495, o.size_duration,
                         o.domain + 2, false, &b, &dummy50, &dummy99);
    int rc3 = 0;
    /* half the bots (at least 2); bot 1 is the one stopped */
    session_plan adapt = {o.lossy_config, true, o.bots > 3 ? (o.bots + 1) / 2 : 2, 1,
                          {0.3 * o.adaptive_duration, 0.6 * o.adaptive_duration}, 2.0};
    if (o.adaptive_duration > 0)
        rc3 = run_session(&o, &adapt, dir, "adaptive", s1k, 1000, 0.045, 0.045,
                          o.adaptive_duration, o.domain + 3, false, &c, &dummy50, &dummy99);

    double lat50 = windowed(&a, o.rate, 0.50), lat99 = windowed(&a, o.rate, 0.99);
    double *all = a.nlat ? malloc(a.nlat * sizeof *all) : NULL;
    double pooled99 = NAN, latmax = NAN;
    /* where the latency goes (pooled over the run; NaN-free samples only):
     * the server's hand-off to its publishing thread, dds_write to arrival
     * in the bot process, and the bot thread's pickup after that */
    double hand50 = NAN, hand99 = NAN, dds50 = NAN, dds99 = NAN, pick50 = NAN, pick99 = NAN;
    if (all) {
        memcpy(all, a.lat, a.nlat * sizeof *all);
        pooled99 = ftm_proc_quantile(all, a.nlat, 0.99);
        latmax = all[a.nlat - 1];
        pooled_part(a.lat, a.dds, a.nlat, all, &hand50, &hand99); /* lat - dds */
        pooled_part(a.dds, NULL, a.nlat, all, &dds50, &dds99);
        pooled_part(a.pick, NULL, a.nlat, all, &pick50, &pick99);
    }
    if (o.plot && all) {
        char path[1200];
        snprintf(path, sizeof path, "%s/latency.dat", o.plot);
        FILE *f = open_output(path);
        if (f) {
            /* per-second p50/p99 by server tick, beside ddsperf's */
            uint64_t w = (uint64_t)o.rate;
            uint64_t wmax = 0;
            for (size_t i = 0; i < a.nlat; i++)
                wmax = a.lat_tick[i] / w > wmax ? a.lat_tick[i] / w : wmax;
            for (uint64_t k = 0; k <= wmax; k++) {
                size_t n = 0;
                for (size_t i = 0; i < a.nlat; i++)
                    if (a.lat_tick[i] / w == k)
                        all[n++] = a.lat[i];
                if (n >= 100)
                    fprintf(f, "%" PRIu64 " %.1f %.1f\n", k, ftm_proc_quantile(all, n, 0.5),
                            ftm_proc_quantile(all, n, 0.99));
            }
            close_output(f, path);
        }
        snprintf(path, sizeof path, "%s/bytes.dat", o.plot);
        f = open_output(path);
        if (f) {
            fprintf(f, "# scene frames_bytes_per_tick streaming_bytes_per_tick\n"
                       "1k %.1f %.1f\n100k %.1f %.1f\n",
                    a.frame_bytes_per_tick, a.stream_bytes_per_tick, b.frame_bytes_per_tick,
                    b.stream_bytes_per_tick);
            close_output(f, path);
        }
        char src[1200], dst[1200];
        snprintf(src, sizeof src, "%s/1k/ddsperf.dat", dir);
        snprintf(dst, sizeof dst, "%s/ddsperf.dat", o.plot);
        copy_text(src, dst);
    }
    free(all);
    double ratio1k = a.frame_bytes_per_tick > 0 ? a.stream_bytes_per_tick / a.frame_bytes_per_tick : NAN;
    double ratio100k =
        b.frame_bytes_per_tick > 0 ? b.stream_bytes_per_tick / b.frame_bytes_per_tick : NAN;
    bool ok = ra == 0 && rb == 0 && a.synced == o.bots && b.synced == o.bots &&
              (o.adaptive_duration == 0 || (rc3 == 0 && c.synced == adapt.bots));

    if (o.json) {
        printf("{");
        json_num(stdout, "bots", o.bots, false);
        json_num(stdout, "rate_hz", o.rate, false);
        json_num(stdout, "duration_s", a.seconds, false);
        json_num(stdout, "ticks", (double)a.ticks, false);
        json_num(stdout, "missed_ticks", (double)a.missed, false);
        json_num(stdout, "ticks_per_s", a.seconds > 0 ? (double)a.ticks / a.seconds : NAN, false);
        json_num(stdout, "tick_p50_ms", a.tick_p50, false);
        json_num(stdout, "tick_p99_ms", a.tick_p99, false);
        json_num(stdout, "late_p99_ms", a.late_p99, false);
        json_num(stdout, "step_mean_us", a.step_mean_us, false);
        json_num(stdout, "bytes_per_tick_1k", a.frame_bytes_per_tick, false);
        json_num(stdout, "bytes_per_tick_100k", b.frame_bytes_per_tick, false);
        json_num(stdout, "server_bytes_per_tick_1k", a.bytes_per_tick, false);
        json_num(stdout, "server_bytes_per_tick_100k", b.bytes_per_tick, false);
        json_num(stdout, "stream_bytes_per_tick_1k", a.stream_bytes_per_tick, false);
        json_num(stdout, "stream_bytes_per_tick_100k", b.stream_bytes_per_tick, false);
        json_num(stdout, "stream_ratio_1k", ratio1k, false);
        json_num(stdout, "stream_ratio_100k", ratio100k, false);
        json_num(stdout, "moved_nodes_per_tick_1k", a.moved_per_tick, false);
        json_num(stdout, "moved_nodes_per_tick_100k", b.moved_per_tick, false);
        json_num(stdout, "latency_p50_us", lat50, false);
        json_num(stdout, "latency_p99_us", lat99, false);
        json_num(stdout, "latency_p99_pooled_us", pooled99, false);
        json_num(stdout, "latency_max_us", latmax, false);
        json_num(stdout, "ddsperf_p50_us", dp50, false);
        json_num(stdout, "ddsperf_p99_us", dp99, false);
        json_num(stdout, "latency_ratio_p99", lat99 / dp99, false);
        json_num(stdout, "handoff_p50_us", hand50, false);
        json_num(stdout, "handoff_p99_us", hand99, false);
        json_num(stdout, "dds_p50_us", dds50, false);
        json_num(stdout, "dds_p99_us", dds99, false);
        json_num(stdout, "pickup_p50_us", pick50, false);
        json_num(stdout, "pickup_p99_us", pick99, false);
        json_num(stdout, "bots_synced_1k", a.synced, false);
        json_num(stdout, "bots_synced_100k", b.synced, false);
        if (o.adaptive_duration > 0) {
            json_num(stdout, "adaptive_ticks_per_s", c.seconds > 0 ? (double)c.ticks / c.seconds : NAN, false);
            json_num(stdout, "adaptive_missed_ticks", (double)c.missed, false);
            json_num(stdout, "adaptive_tick_p99_ms", c.tick_p99, false);
            json_num(stdout, "adaptive_depth_changes", c.depth_changes, false);
            json_num(stdout, "adaptive_depth_min", c.depth_min, false);
            json_num(stdout, "adaptive_max_lag_ticks", c.max_lag_ticks, false);
            json_num(stdout, "adaptive_bots_synced", c.synced, false);
        }
        json_num(stdout, "ok", ok, true);
        printf("}\n");
    }
    FILE *t = o.json ? stderr : stdout;
    fprintf(t, "ftm bench net: %d trainee bots, %g Hz, loopback (%s)\n\n", o.bots, o.rate, o.config);
    fprintf(t, "1k-node scene, fixed depth, %.1f s\n", a.seconds);
    fprintf(t, "  ticks run / missed            %" PRIu64 " / %" PRIu64 " (%.1f ticks/s)\n",
            a.ticks, a.missed, a.seconds > 0 ? (double)a.ticks / a.seconds : 0.0);
    fprintf(t, "  tick period p50 / p99         %.2f / %.2f ms (start after due p99 %.2f ms)\n",
            a.tick_p50, a.tick_p99, a.late_p99);
    fprintf(t, "  server step mean              %.1f us\n", a.step_mean_us);
    fprintf(t, "  latency p50 / p99 (FTM)       %.0f / %.0f us (median of 1 s windows; pooled "
               "p99 %.0f, max %.0f)\n",
            lat50, lat99, pooled99, latmax);
    fprintf(t, "  latency p50 / p99 (ddsperf)   %.0f / %.0f us (one way = round trip / 2, 100 B, "
               "1 kHz, meanwhile)\n",
            dp50, dp99);
    fprintf(t, "  latency p99 ratio FTM/raw     %.2f\n", lat99 / dp99);
    fprintf(t, "  FTM latency, pooled p50/p99:  server hand-off %.0f / %.0f us, dds_write to "
               "arrival %.0f / %.0f us\n",
            hand50, hand99, dds50, dds99);
    fprintf(t, "  (then the bot thread took the frame after %.0f / %.0f us more)\n", pick50,
            pick99);
    fprintf(t, "  bots on the server's hash     %d of %d\n\n", a.synced, o.bots);
    fprintf(t, "bytes per tick (protobuf payload)   frames   streaming moved nodes   ratio   "
               "(server, whole run)\n");
    fprintf(t, "  1k nodes                          %6.1f   %9.1f                %6.1f   (%.1f)\n",
            a.frame_bytes_per_tick, a.stream_bytes_per_tick, ratio1k, a.bytes_per_tick);
    fprintf(t, "  100k nodes                        %6.1f   %9.1f                %6.1f   (%.1f)\n",
            b.frame_bytes_per_tick, b.stream_bytes_per_tick, ratio100k, b.bytes_per_tick);
    fprintf(t, "  (nodes moved per tick: %.0f on 1k, %.0f on 100k; keyframes add %.1f and %.1f "
               "bytes/tick)\n",
            a.moved_per_tick, b.moved_per_tick,
            a.ticks ? (double)a.keyframe_bytes / (double)a.ticks : 0.0,
            b.ticks ? (double)b.keyframe_bytes / (double)b.ticks : 0.0);
    fprintf(t, "  bots on the server's hash (100k)  %d of %d\n", b.synced, o.bots);
    if (o.adaptive_duration > 0) {
        fprintf(t, "\nadaptive depth: 1k nodes, %d bots, 5 %% loss injected, bot 1 stopped for "
                   "%.0f s at %.0f s and %.0f s, %.1f s\n",
                adapt.bots, adapt.stop_for, adapt.stop_at[0], adapt.stop_at[1], c.seconds);
        fprintf(t, "  ticks/s, missed, period p99   %.1f, %" PRIu64 ", %.2f ms\n",
                c.seconds > 0 ? (double)c.ticks / c.seconds : 0.0, c.missed, c.tick_p99);
        fprintf(t, "  depth changes, lowest depth   %d, %d (trace: depth.dat in the logs)\n",
                c.depth_changes, c.depth_min);
        fprintf(t, "  stopped bot's largest lag     %.0f ticks\n", c.max_lag_ticks);
        fprintf(t, "  bots on the server's hash     %d of %d\n", c.synced, adapt.bots);
    }
    fprintf(t, "\nresult: %s\n", ok ? "every bot replayed every session bit-identically"
                                     : "NOT every bot ended on the server's state (see the logs)");
    if (!o.keep && ok) {
        /* remove the temporary directory: the files this run wrote */
        const char *subs[] = {"1k", "100k", "adaptive"};
        for (int k = 0; k < 3; k++) {
            char sub[1200];
            snprintf(sub, sizeof sub, "%s/%s", dir, subs[k]);
            DIR *d = opendir(sub);
            for (struct dirent *e; d && (e = readdir(d));) {
                char f[1500];
                if (e->d_name[0] != '.' && snprintf(f, sizeof f, "%s/%s", sub, e->d_name) < (int)sizeof f)
                    unlink(f);
            }
            if (d)
                closedir(d);
            rmdir(sub);
        }
        remove(s1k);
        remove(s100k);
        rmdir(dir);
    } else if (!ok) {
        fprintf(stderr, "ftm bench net: logs kept in %s\n", dir);
    }
    run_result *rs[3] = {&a, &b, &c};
    for (int i = 0; i < 3; i++) {
        free(rs[i]->lat);
        free(rs[i]->dds);
        free(rs[i]->pick);
        free(rs[i]->lat_tick);
    }
    if (output_errors)
        fprintf(stderr, "ftm bench net: %d output file%s could not be written (see above)\n",
                output_errors, output_errors == 1 ? "" : "s");
    return !ok ? 1 : output_errors ? 2 : 0;
}
