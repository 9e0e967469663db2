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
#include <dirent.h>
#include <stdlib.h>
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
    const int e = ftm_record_errno(r->w);
    /* a full disk (or quota) may get space again; a file size limit, an I/O
     * error or a file system gone read-only are not waited out */
    r->may_retry = e == ENOSPC || e == EDQUOT;
    ftm_record_close(r->w, NULL);
    r->w = NULL;
    if (r->may_retry)
        srv_log(s, "error",
                "%s; recording stopped at tick %" PRIu64 " (%.3f s): the file keeps %" PRIu64
                " bytes, replayable to tick %" PRIu64 "; it goes on into a new file of the "
                "lesson once %u bytes are free there",
                err->message, r->stop_tick, r->stop_s, r->kept, r->kept_tick,
                (unsigned)FTM_RECORD_RESUME_FREE);
    else
        srv_log(s, "error",
                "%s; recording stopped for good at tick %" PRIu64 " (%.3f s): the file keeps "
                "%" PRIu64 " bytes, replayable to tick %" PRIu64 "; it does not resume",
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

/* The next file of the lesson this run records: FILE.N after --resume (a
 * file there that holds no whole header, a server killed as it began it,
 * is begun again), or after a write error. */
static int claim_segment_path(server *s, ftm_error *err)
{
    srv_rec *r = &s->rec;
    if (ftm_record_segment_path(r->lesson, r->segment, r->seg_path, sizeof r->seg_path)) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message, "recording %.300s: path too long", r->lesson);
        return FTM_EINVAL;
    }
    s->o.record = r->seg_path;
    return FTM_OK;
}

int srv_open_recording(server *s, ftm_error *err)
{
    srv_rec *r = &s->rec;
    if (s->o.resume) {
        if (s->o.resume != r->lesson) /* (--resume-recent picked it there) */
            snprintf(r->lesson, sizeof r->lesson, "%s", s->o.resume);
        if (claim_segment_path(s, err))
            return err->code;
    } else if (s->o.record_dir && !s->o.record && claim_record_path(s, err)) {
        return err->code;
    }
    if (!r->lesson[0])
        snprintf(r->lesson, sizeof r->lesson, "%s", s->o.record);
    if (!r->lesson_start_ns) /* this server begins the lesson */
        r->lesson_start_ns = s->start_unix_ns;
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
    rh.start_unix_ns = s->start_unix_ns;
    rh.lesson_start_ns = r->lesson_start_ns;
    rh.segment = r->segment;
    rh.after_gap = r->failed;
    rh.previous_cut = r->previous_cut;
    r->previous_cut = 0; /* (a file after a gap goes on from a whole one) */
    int rc = ftm_record_create(s->o.record, &rh, &r->w, err);
    if (rc == FTM_OK && r->segment)
        srv_log(s, "info", "recording the lesson on to %s (its file %u)", s->o.record,
                r->segment + 1);
    else if (rc == FTM_OK)
        srv_log(s, "info", "recording the session to %s", s->o.record);
    return rc;
}

/* Whether name is a lesson's first file in --record-dir for this session:
 * SESSION-YYYYMMDDTHHMMSSZ[-k].rec */
static bool lesson_name(const char *name, const char *prefix)
{
    size_t n = strlen(name), p = strlen(prefix);
    return n > p + 4 && strncmp(name, prefix, p) == 0 && strcmp(name + n - 4, ".rec") == 0;
}

/* Whether a lesson's server ended it: its final LEAVING status is the last
 * status it published (a scan of the entries, without the physics). */
static bool lesson_ended(const char *path)
{
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(path, &h, &rd, &err))
        return false;
    const ftm_wire_limits lim = {0, 0, h.node_count};
    bool leaving = false;
    ftm_record_entry e;
    while (ftm_record_next(rd, &e, &err) > 0) {
        if (e.incoming || e.kind != FTM_WIRE_STATUS)
            continue;
        ftm_wire_msg m;
        if (ftm_wire_decode(e.kind, e.payload, e.size, &lim, &m, &err) == FTM_OK) {
            leaving = m.u.status.state == FTM_WIRE_STATE_LEAVING;
            ftm_wire_msg_free(&m);
        }
    }
    ftm_record_close_reader(rd);
    return leaving;
}

void srv_pick_recent_lesson(server *s)
{
    char prefix[80];
    size_t n = 0;
    for (const char *c = s->o.session; *c && n + 1 < 64; c++) /* as claim_record_path names it */
        prefix[n++] = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') ||
                              (*c >= '0' && *c <= '9') || *c == '-' || *c == '_' || *c == '.'
                          ? *c
                          : '_';
    prefix[n] = '\0';
    if (!prefix[0] || prefix[0] == '.')
        snprintf(prefix, sizeof prefix, "session");
    strcat(prefix, "-");
    DIR *d = opendir(s->o.record_dir);
    if (!d)
        return; /* (--check and the recording say why) */
    char best[sizeof s->rec.lesson] = "";
    double best_t = -1.0;
    struct dirent *de;
    while ((de = readdir(d))) {
        if (!lesson_name(de->d_name, prefix))
            continue;
        char first[sizeof s->rec.lesson], seg[sizeof s->rec.seg_path];
        if (snprintf(first, sizeof first, "%s/%s", s->o.record_dir, de->d_name) >= (int)sizeof first)
            continue;
        double t = -1.0; /* the newest write of any of its files */
        struct stat st;
        for (uint32_t k = 0; k < 100000 &&
                             ftm_record_segment_path(first, k, seg, sizeof seg) == 0 &&
                             stat(seg, &st) == 0;
             k++)
            if ((double)st.st_mtim.tv_sec + st.st_mtim.tv_nsec * 1e-9 > t)
                t = (double)st.st_mtim.tv_sec + st.st_mtim.tv_nsec * 1e-9;
        if (t > best_t) {
            best_t = t;
            snprintf(best, sizeof best, "%s", first);
        }
    }
    closedir(d);
    const double now = (double)ftm_clock_real_ns() * 1e-9;
    if (!best[0]) {
        srv_log(s, "info", "--resume-recent: no lesson of '%s' in %s: a new lesson",
                s->o.session, s->o.record_dir);
        return;
    }
    if (now - best_t >= s->o.resume_recent) {
        srv_log(s, "info", "--resume-recent: the newest lesson %s was last written %.0f s ago "
                "(not less than %g s): a new lesson", best, now - best_t, s->o.resume_recent);
        return;
    }
    if (lesson_ended(best)) {
        srv_log(s, "info", "--resume-recent: the newest lesson %s ended cleanly: a new lesson",
                best);
        return;
    }
    srv_log(s, "info", "--resume-recent: the newest lesson %s did not end (last written %.1f s "
            "ago): resuming it", best, now - best_t);
    snprintf(s->rec.lesson, sizeof s->rec.lesson, "%s", best);
    s->o.resume = s->rec.lesson;
    s->resume_if_unended = true;
}

/* After a write error, once space has returned: the lesson's next file
 * (FILE.N, after_gap), opened. 0, or an error with r->segment as it was. */
int srv_open_next_file(server *s, ftm_error *err)
{
    srv_rec *r = &s->rec;
    r->segment++;
    if (claim_segment_path(s, err) == 0 && srv_open_recording(s, err) == 0) {
        r->segments_after_gap++;
        r->no_resume_why[0] = '\0';
        r->gap_tick = s->tk.tick;
        snprintf(r->gap_file, sizeof r->gap_file, "%s", r->seg_path);
        return FTM_OK;
    }
    r->segment--;
    return err->code ? err->code : FTM_EIO;
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
    /* --record-dir's recording, or the first file of a resumed lesson:
     * NAME.rec -> NAME.json (the lesson's one report) */
    const char *rec = s->rec.path[0] ? s->rec.path : s->o.resume;
    if (!path && rec) {
        size_t n = strlen(rec);
        if (n > 4 && strcmp(rec + n - 4, ".rec") == 0)
            n -= 4;
        snprintf(beside, sizeof beside, "%.*s.json", (int)(n < 1000 ? n : 1000), rec);
        path = beside;
    }
    if (!path)
        return 0;
    ftm_report_session rs = {s->o.session, s->o.scene, s->digest, FTM_REPLAY_DIGEST_SIZE,
                             s->tk.tick, s->o.rate, s->tk.depth_lo, s->tk.depth_hi, s->tk.unstable,
                             s->rec.tissue_changes, NULL, false};
    const char *not_resumed = s->rec.no_resume_why[0] ? s->rec.no_resume_why
                              : s->rec.may_retry      ? "no space came back"
                                                      : "the error was not a full disk";
    const ftm_report_recording stopped = {
        s->rec.stop_tick, s->rec.stop_s, s->rec.why, s->rec.kept, s->rec.kept_tick,
        s->rec.segments_after_gap ? s->rec.gap_file : NULL, s->rec.gap_tick, not_resumed};
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
    if (s->rec.failed && s->rec.segments_after_gap)
        srv_log(s, "error",
                "recording %s incomplete: stopped at tick %" PRIu64 " (%.3f s into the session) "
                "on a write error: %s; recorded on from tick %" PRIu64 " into %s: ticks %" PRIu64
                "..%" PRIu64 " are missing", s->rec.lesson, s->rec.stop_tick, s->rec.stop_s,
                s->rec.why, s->rec.gap_tick, s->rec.gap_file, s->rec.kept_tick, s->rec.gap_tick);
    else if (s->rec.failed)
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
