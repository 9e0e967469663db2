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
            if (sscanf(p, "%31s %lf %n", word, &v[0], &n) < 2) {
                fprintf(stderr, "%s:%d: expected '<keyword> <time>'\n", path, lineno);
                goto bad;
            }
            if (p[n] != '\0') {
                fprintf(stderr, "%s:%d: extra text after '%s <time>'\n", path, lineno, word);
                goto bad;
            }
            if (!(v[0] >= 0) || !isfinite(v[0])) {
                fprintf(stderr, "%s:%d: time must be >= 0\n", path, lineno);
                goto bad;
            }
            if (strcmp(word, "join") == 0) {
                sc->join = v[0];
            } else if (strcmp(word, "leave") == 0) {
                sc->leave = v[0];
            } else if (strcmp(word, "pause") == 0 || strcmp(word, "resume") == 0 ||
                       strcmp(word, "reset") == 0) {
                if (sc->ncmds == FTM_SCRIPT_COMMANDS_MAX) {
                    fprintf(stderr, "%s:%d: more than 64 commands\n", path, lineno);
                    goto bad;
                }
                ftm_wire_command c = strcmp(word, "pause") == 0   ? FTM_WIRE_CMD_PAUSE
                                     : strcmp(word, "reset") == 0 ? FTM_WIRE_CMD_RESET
                                                                  : FTM_WIRE_CMD_RESUME;
                sc->cmds[sc->ncmds++] = (ftm_script_command){v[0], c, false};
            } else {
                fprintf(stderr, "%s:%d: unknown keyword '%s' (join, leave, pause, resume, reset)\n",
                        path, lineno, word);
                goto bad;
            }
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
