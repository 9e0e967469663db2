/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The session's recording (record.h, docs/server.md "Recording and
 * replay"), its report (report.h, --report) and --reactions: what a run
 * leaves behind. A write error stops the recording, not the session. */
#include "rooms.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* A write error stops the recording, not the session, and for good: the
 * file keeps its whole chunks (what fitted of the last one too), which
 * replay to where it stopped; no new segment is begun when space returns.
 * The exit status says the recording is incomplete (3, as when closing it
 * fails); the closing lines, the report and the metrics say when and why. */
void srv_record_failed(server *s, const ftm_error *err)
{
    srv_rec *r = &s->rec;
    r->errors++;
    r->failed = true;
    r->stop_tick = s->tk.tick;
    r->stop_s = (double)(srv_now() - s->t_start_ns) * 1e-9;
    r->kept = ftm_record_kept(r->w);
    r->kept_tick = ftm_record_kept_tick(r->w);
    snprintf(r->why, sizeof r->why, "%s", err->message);
    ftm_record_close(r->w, NULL);
    r->w = NULL;
    srv_log(s, "error",
            "%s; recording stopped for good at tick %" PRIu64 " (%.3f s): the file keeps %" PRIu64
            " bytes, replayable to tick %" PRIu64 "; it does not resume",
            err->message, r->stop_tick, r->stop_s, r->kept, r->kept_tick);
}

void srv_record_entry(server *s, bool incoming, int kind, uint32_t sender, const uint8_t *buf,
                      size_t size, bool gone, bool lost)
{
    if (!s->rec.w)
        return;
    ftm_record_entry e = {.tick = s->tk.tick, .kind = kind, .sender = sender, .incoming = incoming,
                          .gone = gone, .lost = lost, .time_ns = srv_now() - s->t_start_ns,
                          .payload = buf, .size = size};
    ftm_error err = {0, ""};
    if (ftm_record_write(s->rec.w, &e, &err))
        srv_record_failed(s, &err);
}

/* --reactions FILE (--offline, --replay, --inputs): one line per probe in
 * contact per tick. Returns 0, or 3 after saying why it cannot be written. */
int srv_open_reactions(server *s)
{
    if (!s->o.reactions_csv)
        return 0;
    if (!(s->tk.reactions_csv = fopen(s->o.reactions_csv, "w"))) {
        fprintf(stderr, "ftm-server: cannot open %s: %s\n", s->o.reactions_csv, strerror(errno));
        return 3;
    }
    fprintf(s->tk.reactions_csv, "tick,participant,probe,fx,fy,fz,time_s,push_m,push_limited\n");
    return 0;
}

int srv_close_reactions(server *s)
{
    if (!s->tk.reactions_csv)
        return 0;
    int bad = ferror(s->tk.reactions_csv);
    bad |= fclose(s->tk.reactions_csv) != 0;
    s->tk.reactions_csv = NULL;
    if (bad)
        fprintf(stderr, "ftm-server: --reactions %s: write failed (disk full?)\n",
                s->o.reactions_csv);
    return bad ? 3 : 0;
}

/* --record-dir: DIR/SESSION-YYYYMMDDTHHMMSSZ.rec, claimed with O_EXCL so that
 * no earlier session's recording is overwritten (a restart within the same
 * second gets -2, -3, ...). */
static int claim_record_path(server *s, ftm_error *err)
{
    char name[128], stamp[32];
    size_t n = 0;
    for (const char *c = s->o.session; *c && n + 1 < 64; c++) /* the session as a file name */
        name[n++] = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') ||
                            (*c >= '0' && *c <= '9') || *c == '-' || *c == '_' || *c == '.'
                        ? *c
                        : '_';
    name[n] = '\0';
    time_t now = (time_t)((uint64_t)ftm_clock_real_ns() / 1000000000u);
    struct tm tm;
    gmtime_r(&now, &tm);
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
    for (int k = 1; k <= 100; k++) {
        char suffix[8] = "";
        if (k > 1)
            snprintf(suffix, sizeof suffix, "-%d", k);
        int len = snprintf(s->rec.path, sizeof s->rec.path, "%s/%s-%s%s.rec",
                           s->o.record_dir, name[0] && name[0] != '.' ? name : "session", stamp,
                           suffix);
        if (len < 0 || (size_t)len >= sizeof s->rec.path) {
            err->code = FTM_EINVAL;
            snprintf(err->message, sizeof err->message, "--record-dir %.200s: path too long",
                     s->o.record_dir);
            return FTM_EINVAL;
        }
        int fd = open(s->rec.path, O_WRONLY | O_CREAT | O_EXCL, 0644);
        if (fd >= 0) {
            close(fd);
            s->o.record = s->rec.path;
            return FTM_OK;
        }
        if (errno != EEXIST) {
            err->code = FTM_EIO;
            snprintf(err->message, sizeof err->message, "--record-dir: cannot create %.300s: %s",
                     s->rec.path, strerror(errno));
            return FTM_EIO;
        }
    }
    err->code = FTM_EIO;
    snprintf(err->message, sizeof err->message, "--record-dir %.300s: 100 recordings of '%s' "
             "this second already", s->o.record_dir, name);
    return FTM_EIO;
}

int srv_open_recording(server *s, ftm_error *err)
{
    if (s->o.record_dir && !s->o.record && claim_record_path(s, err))
        return err->code;
    ftm_record_header rh;
    memset(&rh, 0, sizeof rh);
    snprintf(rh.scene_id, sizeof rh.scene_id, "%s", s->o.scene);
    snprintf(rh.session, sizeof rh.session, "%s", s->o.session);
    memcpy(rh.digest, s->digest, FTM_REPLAY_DIGEST_SIZE);
    rh.digest_len = FTM_REPLAY_DIGEST_SIZE;
    rh.tick_rate_hz = (uint32_t)(s->o.rate + 0.5);
    rh.depth_max = s->per.ctl.def.max;
    rh.depth_min = s->per.ctl.def.floor;
    rh.node_count = ftm_mesh_node_count(s->mesh);
    rh.max_penetration = isfinite(s->tk.max_push) ? s->tk.max_push : 0.0;
    rh.start_unix_ns = (uint64_t)ftm_clock_real_ns();
    int rc = ftm_record_create(s->o.record, &rh, &s->rec.w, err);
    if (rc == FTM_OK)
        srv_log(s, "info", "recording the session to %s", s->o.record);
    return rc;
}

/* The session report: a closing log line per trainee probe that touched
 * the tissue, and --report FILE. Returns 0, or 3 if the file fails. */
int srv_finish_report(server *s)
{
    for (int32_t i = 0; i < s->rec.report.count; i++) {
        const ftm_report_part *p = &s->rec.report.parts[i];
        for (int k = 0; k < FTM_REPORT_PROBES; k++) {
            const ftm_report_probe *q = &p->probes[k];
            if (!q->contact_ticks)
                continue;
            srv_log(s, "info",
                    "participant %u (%s '%s') probe %d: %u touch%s, %.2f s in contact, peak %.3g N "
                    "at tick %" PRIu64 ", mean %.3g N, deepest push %.1f mm%s",
                    p->id, p->role, p->name, k, q->touches, q->touches == 1 ? "" : "es",
                    (double)q->contact_ticks / s->o.rate, q->peak_force, q->peak_tick,
                    q->force_sum / (double)q->contact_ticks, q->max_push * 1e3,
                    q->limited_ticks ? " (push limited)" : "");
        }
    }
    /* --record-dir: each run's report beside its recording, NAME.json */
    const char *path = s->o.report;
    char beside[sizeof s->rec.path + 8];
    if (!path && s->rec.path[0]) {
        size_t n = strlen(s->rec.path);
        snprintf(beside, sizeof beside, "%.*s.json", (int)(n > 4 ? n - 4 : n), s->rec.path);
        path = beside;
    }
    if (!path)
        return 0;
    ftm_report_session rs = {s->o.session, s->o.scene, s->digest, FTM_REPLAY_DIGEST_SIZE,
                             s->tk.tick, s->o.rate, s->tk.depth_lo, s->tk.depth_hi, s->tk.unstable,
                             s->rec.tissue_changes, NULL, false};
    const ftm_report_recording stopped = {s->rec.stop_tick, s->rec.stop_s, s->rec.why,
                                          s->rec.kept, s->rec.kept_tick};
    rs.recording = s->o.record && !s->o.replay ? &stopped : NULL;
    rs.recording_stopped = s->rec.failed;
    /* written whole beside it, then renamed over it: a reader (a course's
     * records, a watcher of the directory) never sees half a report, and a
     * failure (a full disk, a crash) leaves the previous file or none */
    char tmp[4096 + 32];
    int len = snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    int fd = len > 0 && (size_t)len < sizeof tmp
                 ? open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666)
                 : (errno = ENAMETOOLONG, -1);
    if (fd < 0 && errno == EEXIST && unlink(tmp) == 0) /* left by a killed run of this pid */
        fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    FILE *f = fd >= 0 ? fdopen(fd, "w") : NULL;
    if (fd >= 0 && !f)
        close(fd);
    int rc = f ? ftm_report_write_json(&s->rec.report, &rs, f) : -1;
    if (f && (fflush(f) != 0 || fsync(fileno(f)) != 0))
        rc = -1;
    if (f && fclose(f) != 0)
        rc = -1;
    if (rc == 0 && rename(tmp, path) != 0)
        rc = -1;
    if (rc) {
        int e = errno;
        if (fd >= 0)
            unlink(tmp);
        srv_log(s, "error", "report %s: cannot write: %s", path, strerror(e));
        return 3;
    }
    srv_log(s, "info", "report: %s (%d participants)", path, (int)s->rec.report.count);
    return 0;
}


/* The end of a run's recording; 0, or 3 if it is incomplete (said again
 * here, with the closing lines: an operator reads the end of the log). */
int srv_close_recording(server *s)
{
    int rc = s->rec.failed ? 3 : 0;
    if (s->rec.failed)
        srv_log(s, "error",
                "recording %s incomplete: stopped for good at tick %" PRIu64 " (%.3f s into the "
                "session) on a write error: %s; %" PRIu64 " bytes kept, replayable to tick %" PRIu64,
                s->o.record, s->rec.stop_tick, s->rec.stop_s, s->rec.why, s->rec.kept,
                s->rec.kept_tick);
    if (!s->rec.w)
        return rc;
    const uint64_t bytes = ftm_record_bytes(s->rec.w);
    ftm_error err = {0, ""};
    if (ftm_record_close(s->rec.w, &err)) {
        srv_log(s, "error", "%s", err.message);
        rc = 3;
    } else if (s->loop_start_ns) { /* (a session's; a run without DDS says less) */
        srv_log(s, "info", "recording %s: %" PRIu64 " bytes", s->o.record, bytes);
    }
    s->rec.w = NULL;
    return rc;
}
