/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The ftm-bot script format: one parser for every reader (script_text.h).
 * Lines, tokens and numbers come from libftm's text reader (ftm/internal/text.h),
 * the one the scene and mesh parsers use. */
#include "script_text.h"
#include "ftm/internal/text.h"

#include <ctype.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { KW_JOIN = -1, KW_LEAVE = -2 }; /* set a time of the script, not a command */

static const struct {
    const char *word;
    int values;  /* numbers after the time */
    int keyword; /* ftm_script_keyword, KW_JOIN or KW_LEAVE */
} keywords[] = {
    {"join", 0, KW_JOIN},
    {"leave", 0, KW_LEAVE},
    {"pause", 0, FTM_SCRIPT_KW_PAUSE},
    {"resume", 0, FTM_SCRIPT_KW_RESUME},
    {"reset", 0, FTM_SCRIPT_KW_RESET},
    {"stiffness", 1, FTM_SCRIPT_KW_STIFFNESS},
    {"damping", 1, FTM_SCRIPT_KW_DAMPING},
    {"mass", 1, FTM_SCRIPT_KW_MASS},
    {"depth", 2, FTM_SCRIPT_KW_DEPTH},
};

typedef struct token {
    const char *p;
    size_t n;
} token;

/* A whole token as a finite number ("0+1", "1e999", "nan" are not). */
static bool number(token t, double *out) { return ftm_text_parse_double(t.p, t.n, out); }

static bool token_is(token t, const char *word)
{
    return strlen(word) == t.n && memcmp(word, t.p, t.n) == 0;
}

static int command(ftm_script_text *sc, const token *tok, int ntok, const char *name,
                   int32_t line, ftm_error *err)
{
    size_t k = 0;
    while (k < sizeof keywords / sizeof *keywords && !token_is(tok[0], keywords[k].word))
        k++;
    if (k == sizeof keywords / sizeof *keywords)
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "unknown keyword '%.*s' (join, leave, pause, resume, reset, stiffness, "
                    "damping, mass, depth, expect, clock)",
                    (int)(tok[0].n < 32 ? tok[0].n : 32), tok[0].p);
    const char *word = keywords[k].word;
    double t;
    if (ntok < 2 || !number(tok[1], &t))
        return ftm_text_error(err, FTM_EPARSE, name, line, "expected '<keyword> <time> [values]'");
    if (!(t >= 0))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "time %g is negative (times are seconds from the start)", t);
    int want = keywords[k].values;
    double v[2] = {0, 0};
    for (int i = 0; i < want; i++)
        if (ntok < 3 + i || !number(tok[2 + i], &v[i]))
            return ftm_text_error(err, FTM_EPARSE, name, line,
                        "'%s' needs %d finite number(s) after the time", word, want);
    if (ntok > 2 + want)
        return ftm_text_error(err, FTM_EPARSE, name, line, "extra text after '%s'", word);
    const int kw = keywords[k].keyword;
    if (kw == KW_JOIN || kw == KW_LEAVE) {
        *(kw == KW_JOIN ? &sc->join : &sc->leave) = t;
        return FTM_OK;
    }
    if (kw == FTM_SCRIPT_KW_DAMPING && !(v[0] >= 0))
        return ftm_text_error(err, FTM_EPARSE, name, line, "damping must be >= 0");
    if ((kw == FTM_SCRIPT_KW_STIFFNESS || kw == FTM_SCRIPT_KW_MASS) && !(v[0] > 0))
        return ftm_text_error(err, FTM_EPARSE, name, line, "%s must be > 0", word);
    if (kw == FTM_SCRIPT_KW_DEPTH && !(v[0] >= 0 && v[1] >= v[0] && v[1] <= 1e6 &&
                                    v[0] == floor(v[0]) && v[1] == floor(v[1])))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "depth limits must be whole numbers 0 <= min <= max <= 1000000");
    if (sc->ncmds == FTM_SCRIPT_COMMANDS_MAX)
        return ftm_text_error(err, FTM_EPARSE, name, line, "more than %d commands",
                    FTM_SCRIPT_COMMANDS_MAX);
    sc->cmds[sc->ncmds++] = (ftm_script_entry){(ftm_script_keyword)kw, t, {v[0], v[1]}, line};
    return FTM_OK;
}

/* expect t0 t1 force|peak MIN MAX, expect t0 t1 contact yes|no */
static int expectation(ftm_script_text *sc, const token *tok, int ntok, const char *name,
                       int32_t line, ftm_error *err)
{
    static const struct {
        const char *word;
        ftm_script_expect_kind kind;
        int ntok; /* tokens of the whole line */
    } kinds[] = {
        {"force", FTM_SCRIPT_EXPECT_FORCE, 6},
        {"peak", FTM_SCRIPT_EXPECT_PEAK, 6},
        {"contact", FTM_SCRIPT_EXPECT_CONTACT, 5},
    };
    ftm_script_expect e = {.line = line};
    int want = 0;
    for (size_t k = 0; k < sizeof kinds / sizeof *kinds && ntok >= 4; k++)
        if (token_is(tok[3], kinds[k].word)) {
            e.kind = kinds[k].kind;
            want = kinds[k].ntok;
        }
    if (!want || ntok != want || !number(tok[1], &e.t0) || !number(tok[2], &e.t1) ||
        (want == 6 && (!number(tok[4], &e.lo) || !number(tok[5], &e.hi))) ||
        (want == 5 && !token_is(tok[4], "yes") && !token_is(tok[4], "no")))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "expected 'expect <t0> <t1> force|peak <min> <max>' or "
                    "'expect <t0> <t1> contact yes|no'");
    if (!(e.t0 >= 0))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "time %g is negative (times are seconds from the start)", e.t0);
    if (!(e.t0 <= e.t1))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "the window ends before it starts (%g > %g)", e.t0, e.t1);
    if (want == 6 && !(e.lo >= 0 && e.lo <= e.hi))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "force bounds must be 0 <= min <= max [N] (got %g, %g)", e.lo, e.hi);
    e.contact = want == 5 && token_is(tok[4], "yes");
    if (sc->nexpects == FTM_SCRIPT_EXPECTS_MAX)
        return ftm_text_error(err, FTM_EPARSE, name, line, "more than %d expectations",
                    FTM_SCRIPT_EXPECTS_MAX);
    sc->expects[sc->nexpects++] = e;
    return FTM_OK;
}

/* clock process|session: what a script's times count from */
static int clock_base(ftm_script_text *sc, const token *tok, int ntok, const char *name,
                      int32_t line, ftm_error *err)
{
    if (ntok != 2 || !(token_is(tok[1], "process") || token_is(tok[1], "session")))
        return ftm_text_error(err, FTM_EPARSE, name, line, "expected 'clock process|session'");
    sc->session_clock = token_is(tok[1], "session");
    return FTM_OK;
}

static int point(ftm_script_text *sc, int32_t *cap, const token *tok, int ntok,
                 const char *name, int32_t line, ftm_error *err)
{
    double v[4];
    if (ntok != 4)
        return ftm_text_error(err, FTM_EPARSE, name, line, "expected 't x y z' (4 numbers)");
    for (int i = 0; i < 4; i++)
        if (!number(tok[i], &v[i]))
            return ftm_text_error(err, FTM_EPARSE, name, line, "expected 't x y z' (4 numbers)");
    if (!(v[0] >= 0))
        return ftm_text_error(err, FTM_EPARSE, name, line,
                    "time %g is negative (times are seconds from the start)", v[0]);
    if (sc->npts > 0 && !(v[0] > sc->pts[sc->npts - 1].t))
        return ftm_text_error(err, FTM_EPARSE, name, line, "time %g does not increase (previous point at %g)",
                    v[0], sc->pts[sc->npts - 1].t);
    if (sc->npts == *cap) {
        int32_t nc = *cap ? 2 * *cap : 64;
        ftm_script_point *np = realloc(sc->pts, (size_t)nc * sizeof *np);
        if (!np)
            return ftm_text_error(err, FTM_ENOMEM, name, line, "out of memory");
        sc->pts = np;
        *cap = nc;
    }
    sc->pts[sc->npts++] = (ftm_script_point){v[0], {v[1], v[2], v[3]}};
    return FTM_OK;
}

int ftm_script_text_parse(const char *text, size_t length, const char *name,
                          ftm_script_text *out, ftm_error *err)
{
    if (!name)
        name = "script";
    memset(out, 0, sizeof *out);
    out->leave = -1.0;
    if (!text && length > 0)
        return ftm_text_error(err, FTM_EINVAL, name, 0, "no text");
    ftm_text txt;
    ftm_text_init(&txt, name, text, length);
    int32_t cap = 0;
    int rc = FTM_OK;
    const char *line;
    size_t len;
    while (rc == FTM_OK && ftm_text_next_line(&txt, &line, &len)) {
        if (len > FTM_SCRIPT_LINE_MAX) {
            rc = ftm_text_error(err, FTM_EPARSE, name, txt.line, "line longer than %d bytes",
                      FTM_SCRIPT_LINE_MAX);
            break;
        }
        if (memchr(line, '\0', len)) {
            rc = ftm_text_error(err, FTM_EPARSE, name, txt.line, "NUL byte (not a text file?)");
            break;
        }
        const char *hash = memchr(line, '#', len);
        const char *cur = line, *end = hash ? hash : line + len;
        token tok[7]; /* a seventh means too many for any line */
        int ntok = 0;
        while (ntok < 7 && ftm_text_token(&cur, end, &tok[ntok].p, &tok[ntok].n))
            ntok++;
        if (ntok == 0)
            continue;
        if (token_is(tok[0], "expect"))
            rc = expectation(out, tok, ntok, name, txt.line, err);
        else if (token_is(tok[0], "clock"))
            rc = clock_base(out, tok, ntok, name, txt.line, err);
        else if (isalpha((unsigned char)tok[0].p[0]))
            rc = command(out, tok, ntok, name, txt.line, err);
        else
            rc = point(out, &cap, tok, ntok, name, txt.line, err);
    }
    if (rc != FTM_OK) {
        ftm_script_text_free(out);
        out->leave = -1.0;
    }
    return rc;
}

int ftm_script_text_read(const char *path, ftm_script_text *out, ftm_error *err)
{
    memset(out, 0, sizeof *out);
    out->leave = -1.0;
    char *text;
    size_t length;
    int rc = ftm_text_read_file(path, FTM_SCRIPT_FILE_MAX, &text, &length, err);
    if (rc)
        return rc;
    rc = ftm_script_text_parse(text, length, path, out, err);
    free(text);
    return rc;
}

void ftm_script_text_free(ftm_script_text *s)
{
    free(s->pts);
    s->pts = NULL;
    s->npts = 0;
    s->ncmds = 0;
    s->nexpects = 0;
}

ftm_vec3 ftm_script_points_at(const ftm_script_point *p, int32_t n, double t)
{
    if (t <= p[0].t)
        return p[0].p;
    if (t >= p[n - 1].t)
        return p[n - 1].p;
    int32_t lo = 0, hi = n - 1; /* p[lo].t <= t < p[hi].t */
    while (hi - lo > 1) {
        int32_t mid = lo + (hi - lo) / 2;
        if (p[mid].t <= t)
            lo = mid;
        else
            hi = mid;
    }
    double w = (t - p[lo].t) / (p[hi].t - p[lo].t);
    ftm_vec3 a = p[lo].p, b = p[hi].p;
    return (ftm_vec3){a.x + w * (b.x - a.x), a.y + w * (b.y - a.y), a.z + w * (b.z - a.z)};
}
