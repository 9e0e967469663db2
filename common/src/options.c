/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm/options.h: one option table for the parser (getopt_long) and --help. */
#include "ftm/options.h"
#include "ftm/internal/text.h"

#include <float.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define HELP_COLUMN 25 /* where the help text of an option starts */
#define VAL_BASE 256   /* getopt_long's value of table entry i: VAL_BASE + i */

bool ftm_option_int(const char *v, size_t len, long long lo, long long hi, long long *out)
{
    int64_t x = 0;
    if (ftm_text_read_int(v, len, &x) != NULL || x < lo || x > hi)
        return false;
    *out = (long long)x;
    return true;
}

static int table_size(const ftm_option *t)
{
    int n = 0;
    while (t[n].type != FTM_OPTION_END)
        n++;
    return n;
}

static bool is_option(const ftm_option *o)
{
    return o->type != FTM_OPTION_SECTION && o->type != FTM_OPTION_END;
}

/* "a number of seconds in (lo, hi]" and the like, for a DOUBLE's refusal. */
static void range_text(const ftm_option *o, char *buf, size_t cap)
{
    int n = snprintf(buf, cap, "%s%s%s", o->flags & FTM_OPTION_WHOLE ? "a whole number" : "a number",
                     o->unit ? " of " : "", o->unit ? o->unit : "");
    if (n < 0 || (size_t)n >= cap)
        return;
    const bool open = o->flags & FTM_OPTION_ABOVE_LO;
    if (o->hi >= DBL_MAX)
        snprintf(buf + n, cap - (size_t)n, " %s %g", open ? ">" : ">=", o->lo);
    else
        snprintf(buf + n, cap - (size_t)n, " in %c%g, %g]", open ? '(' : '[', o->lo, o->hi);
}

/* Stores an integer in a field of 4 or 8 bytes: in range for its type,
 * the low bytes are the value (two's complement) whatever its signedness. */
static void store_int(void *field, size_t size, long long v)
{
    if (size == sizeof(uint32_t)) {
        uint32_t u = (uint32_t)v;
        memcpy(field, &u, sizeof u);
    } else {
        uint64_t u = (uint64_t)v;
        memcpy(field, &u, sizeof u);
    }
}

/* Reads value for o into the struct at values; 0, or -1 with why. */
static int store(const ftm_option *o, const char *value, void *values, char *why, size_t cap)
{
    void *field = (char *)values + o->offset;
    switch (o->type) {
    case FTM_OPTION_FLAG: {
        bool on = true;
        memcpy(field, &on, sizeof on);
        return 0;
    }
    case FTM_OPTION_STRING:
        memcpy(field, &value, sizeof value);
        return 0;
    case FTM_OPTION_INT: {
        long long v = 0;
        if (!ftm_option_int(value, strlen(value), o->min, o->max, &v)) {
            snprintf(why, cap, "must be an integer in %lld..%lld (got '%s')", o->min, o->max, value);
            return -1;
        }
        store_int(field, o->size, v);
        return 0;
    }
    case FTM_OPTION_DOUBLE: {
        double v = 0;
        bool ok = ftm_text_read_double(value, strlen(value), &v) == NULL &&
                  (o->flags & FTM_OPTION_ABOVE_LO ? v > o->lo : v >= o->lo) && v <= o->hi &&
                  (!(o->flags & FTM_OPTION_WHOLE) || v == floor(v));
        if (!ok) {
            char range[96];
            range_text(o, range, sizeof range);
            snprintf(why, cap, "must be %s (got '%s')", range, value);
            return -1;
        }
        memcpy(field, &v, sizeof v);
        return 0;
    }
    case FTM_OPTION_CUSTOM:
        return o->parse(o, value, field, why, cap);
    default:
        snprintf(why, cap, "has no type (a fault of the program's option table)");
        return -1;
    }
}

/* The table entry a refused long option ("--de", "--foo=1") could be:
 * several for an ambiguous prefix (listed in out), none for an unknown one. */
static int candidates(const ftm_option *t, const char *arg, char *out, size_t cap)
{
    const char *name = arg + 2;
    size_t len = strcspn(name, "=");
    int n = 0;
    size_t used = 0;
    out[0] = '\0';
    for (int i = 0; t[i].type != FTM_OPTION_END; i++) {
        if (!is_option(&t[i]) || strncmp(t[i].name, name, len) != 0)
            continue;
        int w = snprintf(out + used, cap - used, "%s--%s", n ? ", " : "", t[i].name);
        if (w > 0 && used + (size_t)w < cap)
            used += (size_t)w;
        n++;
    }
    return n;
}

/* Says why argv[optind - 1] was refused by getopt_long ('?' or ':'). */
static void refusal(const ftm_option_set *set, int rc, int argc, char **argv, int n)
{
    const ftm_option *t = set->options;
    const char *p = set->program;
    const char *arg = optind - 1 < argc && optind >= 1 ? argv[optind - 1] : "";
    if (optopt >= VAL_BASE && optopt < VAL_BASE + n) {
        const ftm_option *o = &t[optopt - VAL_BASE];
        if (rc == ':')
            fprintf(stderr, "%s: --%s needs a value (%s)\n", p, o->name, o->arg ? o->arg : "");
        else
            fprintf(stderr, "%s: --%s takes no value (got '%s')\n", p, o->name, arg);
        return;
    }
    if (optopt > 0) {
        fprintf(stderr, "%s: unknown option -%c\n", p, optopt);
        return;
    }
    char list[512];
    if (strncmp(arg, "--", 2) == 0 && candidates(t, arg, list, sizeof list) > 1)
        fprintf(stderr, "%s: option %.*s is ambiguous: %s\n", p, (int)strcspn(arg, "="), arg, list);
    else
        fprintf(stderr, "%s: unknown option %.*s (%s --help lists them)\n", p,
                (int)strcspn(arg, "="), arg, p);
}

int ftm_options_parse(const ftm_option_set *set, int argc, char **argv, void *values,
                      uint64_t *given, int *first_arg)
{
    const ftm_option *t = set->options;
    const int n = table_size(t);
    if (n > 64) {
        fprintf(stderr, "%s: %d table entries, at most 64 (a fault of the program)\n",
                set->program, n);
        return FTM_OPTIONS_BAD;
    }
    struct option *lo = calloc((size_t)n + 2, sizeof *lo);
    if (!lo) {
        fprintf(stderr, "%s: out of memory\n", set->program);
        return FTM_OPTIONS_BAD;
    }
    int k = 0;
    for (int i = 0; i < n; i++)
        if (is_option(&t[i]))
            lo[k++] = (struct option){t[i].name,
                                      t[i].type == FTM_OPTION_FLAG ? no_argument : required_argument,
                                      NULL, VAL_BASE + i};
    lo[k++] = (struct option){"help", no_argument, NULL, 'h'};
    uint64_t seen = 0;
    int rc = FTM_OPTIONS_OK;
    /* ':' first: a missing value is told apart (':') from an unknown option;
     * optind 0: getopt's state from an earlier parse in this process is reset */
    optind = 0;
    opterr = 0;
    for (int c; rc == FTM_OPTIONS_OK && (c = getopt_long(argc, argv, ":h", lo, NULL)) != -1;) {
        if (c == 'h') {
            ftm_options_help(set, stdout);
            rc = FTM_OPTIONS_HELP;
            break;
        }
        if (c < VAL_BASE || c >= VAL_BASE + n) {
            refusal(set, c, argc, argv, n);
            rc = FTM_OPTIONS_BAD;
            break;
        }
        const ftm_option *o = &t[c - VAL_BASE];
        /* "--scene --duration 2": getopt takes "--duration" for the value */
        if (o->type != FTM_OPTION_FLAG && optarg == argv[optind - 1] &&
            strncmp(optarg, "--", 2) == 0 && optarg[2]) {
            fprintf(stderr, "%s: --%s needs a value (%s), not the option %s (a value that starts "
                            "with -- is written --%s=%s)\n",
                    set->program, o->name, o->arg ? o->arg : "", optarg, o->name, optarg);
            rc = FTM_OPTIONS_BAD;
            break;
        }
        char why[FTM_ERROR_MESSAGE_MAX];
        if (store(o, optarg, values, why, sizeof why)) {
            fprintf(stderr, "%s: --%s %s\n", set->program, o->name, why);
            rc = FTM_OPTIONS_BAD;
            break;
        }
        seen |= (uint64_t)1 << (c - VAL_BASE);
    }
    if (rc == FTM_OPTIONS_OK && optind < argc) {
        if (first_arg) {
            *first_arg = optind;
        } else {
            fprintf(stderr, "%s: unexpected argument '%s' (options start with --)\n", set->program,
                    argv[optind]);
            rc = FTM_OPTIONS_BAD;
        }
    } else if (first_arg) {
        *first_arg = argc;
    }
    free(lo);
    if (given)
        *given = seen;
    return rc;
}

bool ftm_options_given(const ftm_option_set *set, uint64_t given, const char *name)
{
    for (int i = 0; set->options[i].type != FTM_OPTION_END && i < 64; i++)
        if (is_option(&set->options[i]) && strcmp(set->options[i].name, name) == 0)
            return given >> i & 1u;
    return false;
}

/* One option's lines: "  --name ARG", its help from HELP_COLUMN, more
 * lines of it indented as far. */
static void help_entry(const ftm_option *o, FILE *f)
{
    int w = fprintf(f, "  --%s%s%s", o->name, o->arg ? " " : "", o->arg ? o->arg : "");
    const char *h = o->help ? o->help : "";
    if (w > HELP_COLUMN - 2) {
        fputc('\n', f);
        w = 0;
    }
    for (bool first = true;; first = false) {
        size_t len = strcspn(h, "\n");
        fprintf(f, "%*s%.*s\n", (first ? HELP_COLUMN - w : HELP_COLUMN), "", (int)len, h);
        if (!h[len])
            break;
        h += len + 1;
    }
}

void ftm_options_help(const ftm_option_set *set, FILE *f)
{
    fprintf(f, "%s\n", set->usage);
    for (const ftm_option *o = set->options; o->type != FTM_OPTION_END; o++) {
        if (o->type == FTM_OPTION_SECTION)
            fprintf(f, "%s\n", o->help);
        else
            help_entry(o, f);
    }
    fprintf(f, "  -h, --help%*sthis help\n", HELP_COLUMN - 12, "");
    if (set->epilogue)
        fprintf(f, "%s\n", set->epilogue);
}
