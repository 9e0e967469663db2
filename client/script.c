/* ftm-bot scripts: parsing and interpolation (script.h, docs/bot-script.md). */
#include "script.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>

int ftm_script_load(const char *path, ftm_script *sc)
{
    memset(sc, 0, sizeof *sc);
    sc->leave = -1.0;
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "cannot open script %s: %s\n", path, strerror(errno));
        return -1;
    }
    char line[512];
    int lineno = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *p = line;
        while (isspace((unsigned char)*p))
            p++;
        if (!*p)
            continue;
        char word[32];
        double v[4];
        int n;
        if (isalpha((unsigned char)*p)) {
            int got = sscanf(p, "%31s %lf %n", word, &v[0], &n);
            if (got < 2) {
                fprintf(stderr, "%s:%d: expected '<keyword> <time> [values]'\n", path, lineno);
                goto bad;
            }
            if (!(v[0] >= 0) || !isfinite(v[0])) {
                fprintf(stderr, "%s:%d: time must be >= 0\n", path, lineno);
                goto bad;
            }
            /* the keyword's values after the time */
            int want = strcmp(word, "depth") == 0 ? 2
                       : strcmp(word, "stiffness") == 0 || strcmp(word, "damping") == 0 ||
                               strcmp(word, "mass") == 0
                           ? 1
                           : 0;
            const char *q = p + n;
            for (int k = 1; k <= want; k++) {
                int m = 0;
                if (sscanf(q, "%lf %n", &v[k], &m) < 1 || !isfinite(v[k])) {
                    fprintf(stderr, "%s:%d: '%s' needs %d finite number(s) after the time\n",
                            path, lineno, word, want);
                    goto bad;
                }
                q += m;
            }
            if (*q != '\0') {
                fprintf(stderr, "%s:%d: extra text after '%s'\n", path, lineno, word);
                goto bad;
            }
            ftm_script_command c = {v[0], 0, 0, {0, 0}, false};
            if (strcmp(word, "join") == 0) {
                sc->join = v[0];
                continue;
            } else if (strcmp(word, "leave") == 0) {
                sc->leave = v[0];
                continue;
            } else if (strcmp(word, "pause") == 0) {
                c.cmd = FTM_WIRE_CMD_PAUSE;
            } else if (strcmp(word, "resume") == 0) {
                c.cmd = FTM_WIRE_CMD_RESUME;
            } else if (strcmp(word, "reset") == 0) {
                c.cmd = FTM_WIRE_CMD_RESET;
            } else if (want == 1) {
                bool damping = strcmp(word, "damping") == 0;
                if (!(v[1] > 0) && !(damping && v[1] == 0)) {
                    fprintf(stderr, "%s:%d: %s must be %s\n", path, lineno, word,
                            damping ? ">= 0" : "> 0");
                    goto bad;
                }
                c.cmd = FTM_WIRE_CMD_TISSUE;
                c.param = strcmp(word, "stiffness") == 0 ? FTM_SCRIPT_STIFFNESS
                          : damping                       ? FTM_SCRIPT_DAMPING
                                                          : FTM_SCRIPT_MASS;
                c.value[0] = v[1];
            } else if (want == 2) {
                if (!(v[1] >= 0 && v[2] >= v[1] && v[2] <= 1e6 && v[1] == floor(v[1]) &&
                      v[2] == floor(v[2]))) {
                    fprintf(stderr, "%s:%d: depth limits must be whole numbers 0 <= min <= max\n",
                            path, lineno);
                    goto bad;
                }
                c.cmd = FTM_WIRE_CMD_DEPTH_LIMITS;
                c.value[0] = v[1];
                c.value[1] = v[2];
            } else {
                fprintf(stderr,
                        "%s:%d: unknown keyword '%s' (join, leave, pause, resume, reset, "
                        "stiffness, damping, mass, depth)\n",
                        path, lineno, word);
                goto bad;
            }
            if (sc->ncmds == FTM_SCRIPT_COMMANDS_MAX) {
                fprintf(stderr, "%s:%d: more than 64 commands\n", path, lineno);
                goto bad;
            }
            sc->cmds[sc->ncmds++] = c;
            continue;
        }
        if (sscanf(p, "%lf %lf %lf %lf %n", &v[0], &v[1], &v[2], &v[3], &n) < 4 || p[n] != '\0') {
            fprintf(stderr, "%s:%d: expected 't x y z' (4 numbers)\n", path, lineno);
            goto bad;
        }
        for (int i = 0; i < 4; i++)
            if (!isfinite(v[i])) {
                fprintf(stderr, "%s:%d: not a finite number\n", path, lineno);
                goto bad;
            }
        if (!(v[0] >= 0)) {
            fprintf(stderr, "%s:%d: time must be >= 0\n", path, lineno);
            goto bad;
        }
        if (sc->npts > 0 && !(v[0] > sc->pts[sc->npts - 1].t)) {
            fprintf(stderr, "%s:%d: times must increase\n", path, lineno);
            goto bad;
        }
        if (sc->npts == sc->cap) {
            int32_t cap = sc->cap ? 2 * sc->cap : 64;
            ftm_script_point *q = realloc(sc->pts, (size_t)cap * sizeof *q);
            if (!q)
                goto bad;
            sc->pts = q;
            sc->cap = cap;
        }
        sc->pts[sc->npts++] = (ftm_script_point){v[0], {v[1], v[2], v[3]}};
    }
    fclose(f);
    return 0;
bad:
    fclose(f);
    free(sc->pts);
    sc->pts = NULL;
    return -1;
}

const char *ftm_script_control(const ftm_script_command *c, const ftm_wire_tissue *now,
                               ftm_wire_control *out)
{
    memset(out, 0, sizeof *out);
    out->command = c->cmd;
    out->tissue = *now;
    switch (c->cmd) {
    case FTM_WIRE_CMD_PAUSE: return "pause";
    case FTM_WIRE_CMD_RESUME: return "resume";
    case FTM_WIRE_CMD_RESET: return "reset";
    case FTM_WIRE_CMD_DEPTH_LIMITS:
        out->depth_min = (int32_t)c->value[0];
        out->depth_max = (int32_t)c->value[1];
        return "depth limits";
    case FTM_WIRE_CMD_TISSUE: break;
    }
    if (c->param == FTM_SCRIPT_STIFFNESS) {
        out->tissue.stiffness = c->value[0];
        return "stiffness";
    }
    if (c->param == FTM_SCRIPT_DAMPING) {
        out->tissue.node_damping = c->value[0];
        return "damping";
    }
    out->tissue.node_mass = c->value[0];
    return "mass";
}

/* Linear interpolation; held before the first and after the last point. */
ftm_vec3 ftm_script_at(const ftm_script *sc, double t)
{
    if (t <= sc->pts[0].t)
        return sc->pts[0].p;
    for (int32_t i = 1; i < sc->npts; i++)
        if (t <= sc->pts[i].t) {
            const ftm_script_point *a = &sc->pts[i - 1], *b = &sc->pts[i];
            double w = (t - a->t) / (b->t - a->t);
            return (ftm_vec3){a->p.x + w * (b->p.x - a->p.x), a->p.y + w * (b->p.y - a->p.y),
                              a->p.z + w * (b->p.z - a->p.z)};
        }
    return sc->pts[sc->npts - 1].p;
}

void ftm_script_free(ftm_script *sc)
{
    free(sc->pts);
    sc->pts = NULL;
    sc->npts = sc->cap = 0;
}
