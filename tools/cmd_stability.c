/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm stability`: the numerical stability sweep (docs/stability.md).
 * For each configuration: the theoretical critical step (the Gershgorin bound
 * the core uses, and the spectral limit 2/sqrt(lambda_max)), the measured
 * boundary (largest stable h/h_crit with the guard off, by bisection), the
 * damping against the core's low-damping warning (which the core itself
 * reports: column warn), and what the guard does at the
 * unstable steps. Exit status 1 if a NaN was ever observable with the guard
 * on; "missed" (slow growth the guard never saw) is reported, not an error;
 * 2 for bad arguments or a CSV file that cannot be written. */
#include "commands.h"
#include "experiments.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static void usage(FILE *f)
{
    fprintf(f, "usage: ftm stability [--quick] [--json] [--csv FILE]\n\n"
               "Sweeps time step, stiffness, mass, damping, depth and mesh irregularity; prints\n"
               "the measured stability boundary against the critical time step and what the\n"
               "stability guard does beyond it.\n"
               "  --quick      a reduced sweep (small lattices, short runs; as the test uses)\n"
               "  --json       one JSON object with a row per configuration\n"
               "  --csv FILE   the rows as CSV (for docs/bench/experiments.sh)\n\n"
               "exit status: 0 success, 1 a NaN was observable with the guard on (or a run\n"
               "failed), 2 bad arguments or an output that cannot be written\n");
}

static void jnum(FILE *f, double v)
{
    if (isfinite(v))
        fprintf(f, "%.6g", v);
    else
        fprintf(f, "null");
}

int ftm_cmd_stability(int argc, char **argv)
{
    bool quick = false, json = false;
    const char *csv = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(argv[i], "--quick") == 0) {
            quick = true;
        } else if (strcmp(argv[i], "--json") == 0) {
            json = true;
        } else if (strcmp(argv[i], "--csv") == 0) {
            if (i + 1 >= argc) {
                fprintf(stderr, "ftm stability: --csv needs a value\n");
                return 2;
            }
            csv = argv[++i];
        } else {
            fprintf(stderr, "ftm stability: unknown option '%s'\n", argv[i]);
            usage(stderr);
            return 2;
        }
    }
    ftm_stab_def def = ftm_stab_default_def(quick);
    ftm_stab_config configs[32];
    int count = ftm_stab_configs(quick, configs, 32);
    ftm_stab_row rows[32];
    FILE *cf = NULL;
    if (csv) {
        cf = fopen(csv, "w");
        if (!cf) {
            fprintf(stderr, "ftm stability: %s: cannot write: %s\n", csv, strerror(errno));
            return 2;
        }
        fprintf(cf, "index,name,nodes,max_degree,h_crit,h_spectral_ratio,damping_ratio,warned,"
                    "measured,unstable_anywhere,probe1,outcome1,events1,substeps1,probe2,outcome2,"
                    "events2,substeps2,max_u1,max_u2,stable_ratio,stable_events,stable_long\n");
    }
    if (!json) {
        printf("stability sweep: simulated time %g x h_crit per run, guard off, bisection %d steps "
               "in [%g, %g] x h_crit\nh_crit = the core's Gershgorin bound; spectral = "
               "2/sqrt(lambda_max) at rest;\ndamping = d/2m / (0.025 w_max), the sweep's unit "
               "(\"x threshold\": the core's warning before\n2026-11-25). The core now warns when "
               "d/2m < 0.11 w_max h/h_crit, i.e. damping < 4.4 h/h_crit;\nwarn = the core's "
               "warning at h = %g h_crit; nowarn = the largest h/h_crit without it (damping/4.4)"
               "\n\n",
               def.sim_time_factor, def.bisect_iters, def.lo, def.hi, def.lo);
        printf("%-26s %5s %4s %10s %8s %8s %5s %7s %9s %6s | %-28s | %-28s\n", "configuration",
               "nodes", "deg", "h_crit[s]", "spectral", "damping", "warn", "nowarn", "measured",
               "falsea", "guard at 1st unstable", "guard at 2x");
        printf("%-26s %5s %4s %10s %8s %8s %5s %7s %9s %6s | %-28s | %-28s\n", "", "", "", "", "", "",
               "", "", "", "", "h/h_crit outcome ev/sub u", "h/h_crit outcome ev/sub u");
    }
    bool bad = false;
    uint64_t false_alarms = 0;
    int marginal = 0;
    int outcomes[5] = {0}; /* recovered reported caught missed stable */
    static const char *const outcome_names[5] = {"recovered", "reported", "caught", "missed",
                                                 "stable"};
    for (int i = 0; i < count; i++) {
        ftm_stab_row *r = &rows[i];
        int rc = ftm_stab_run(&def, &configs[i], r);
        if (rc) {
            fprintf(stderr, "ftm stability: '%s' failed (%d)\n", configs[i].name, rc);
            if (cf)
                fclose(cf);
            return 1;
        }
        if (r->stable_long)
            false_alarms += r->stable_events;
        else if (r->stable_ratio > 0)
            marginal++;
        for (int p = 0; p < 2; p++) {
            if (r->nan_seen[p])
                bad = true;
            for (int o = 0; o < 5 && r->unstable_anywhere; o++)
                if (strcmp(r->outcome[p], outcome_names[o]) == 0)
                    outcomes[o]++;
        }
        char meas[32], probe[2][64], fa[24];
        if (r->stable_ratio > 0)
            snprintf(fa, sizeof fa, "%llu%s", (unsigned long long)r->stable_events,
                     r->stable_long ? "" : "*");
        else
            snprintf(fa, sizeof fa, "-");
        if (r->measured < 0)
            snprintf(meas, sizeof meas, "< %g", def.lo);
        else if (!r->unstable_anywhere)
            snprintf(meas, sizeof meas, ">= %g", def.hi);
        else
            snprintf(meas, sizeof meas, "%.3f", r->measured);
        for (int p = 0; p < 2; p++) {
            if (!r->unstable_anywhere)
                snprintf(probe[p], sizeof probe[p], "-");
            else
                snprintf(probe[p], sizeof probe[p], "%.2f %s %llu/%d %.2g%s", r->probe_ratio[p],
                         r->outcome[p], (unsigned long long)r->guard_events[p], r->max_substeps[p],
                         r->max_u[p] / r->spacing, r->nan_seen[p] ? " NaN!" : "");
        }
        if (!json)
            printf("%-26s %5d %4d %10.4g %8.3f %8.3g %5s %7.3g %9s %6s | %-28s | %-28s\n",
                   configs[i].name, r->nodes, r->max_degree, r->h_crit, r->h_spectral / r->h_crit,
                   r->damping_ratio, r->warned ? "yes" : "no", r->damping_ratio / 4.4, meas, fa,
                   probe[0], probe[1]);
        if (!json)
            fflush(stdout);
        if (cf)
            fprintf(cf, "%d,\"%s\",%d,%d,%.6g,%.6g,%.6g,%d,%.6g,%d,%.6g,%s,%llu,%d,%.6g,%s,%llu,%d,"
                        "%.4g,%.4g,%.6g,%llu,%d\n",
                    i, configs[i].name, r->nodes, r->max_degree, r->h_crit, r->h_spectral / r->h_crit,
                    r->damping_ratio, r->warned, r->measured, r->unstable_anywhere,
                    r->probe_ratio[0], r->outcome[0], (unsigned long long)r->guard_events[0],
                    r->max_substeps[0], r->probe_ratio[1], r->outcome[1],
                    (unsigned long long)r->guard_events[1], r->max_substeps[1],
                    r->max_u[0] / r->spacing, r->max_u[1] / r->spacing, r->stable_ratio,
                    (unsigned long long)r->stable_events, r->stable_long);
    }
    int csv_status = cf && ftm_close_output(cf, "ftm stability", csv) ? 2 : 0;
    if (!json) {
        printf("\nguarded runs at unstable steps:");
        for (int o = 0; o < 4; o++)
            printf(" %s %d%s", outcome_names[o], outcomes[o], o < 3 ? "," : "");
        printf(", stable %d; NaN observed: %s\n", outcomes[4], bad ? "YES" : "never");
        printf("false alarms (guard events at the largest stable step, column falsea): %llu;\n"
               "%d configurations marked * grow slowly there over the guarded runs' longer time\n"
               "(not counted)\n",
               (unsigned long long)false_alarms, marginal);
        printf("ev/sub: guard events / substeps at the end; u: largest displacement / mean "
               "spacing\n(the load alone gives about 0.02). reported = FTM_EUNSTABLE; caught = "
               "guard events,\nstill above one spacing at the end; missed = no guard event, "
               "unbounded growth.\n");
    }
    if (json) {
        printf("{\"sim_time_factor\":");
        jnum(stdout, def.sim_time_factor);
        printf(",\"rows\":[");
        for (int i = 0; i < count; i++) {
            const ftm_stab_row *r = &rows[i];
            printf("%s{\"name\":\"%s\",\"nodes\":%d,\"max_degree\":%d,\"h_crit\":", i ? "," : "",
                   r->config.name, r->nodes, r->max_degree);
            jnum(stdout, r->h_crit);
            printf(",\"h_spectral\":");
            jnum(stdout, r->h_spectral);
            printf(",\"damping\":");
            jnum(stdout, r->damping);
            printf(",\"damping_ratio\":");
            jnum(stdout, r->damping_ratio);
            printf(",\"warned\":%s,\"measured\":", r->warned ? "true" : "false");
            jnum(stdout, r->measured);
            printf(",\"stable_ratio\":");
            jnum(stdout, r->stable_ratio);
            printf(",\"stable_guard_events\":%llu,\"stable_long\":%s",
                   (unsigned long long)r->stable_events, r->stable_long ? "true" : "false");
            printf(",\"unstable_anywhere\":%s,\"guard\":[", r->unstable_anywhere ? "true" : "false");
            for (int p = 0; p < 2 && r->unstable_anywhere; p++) {
                printf("%s{\"ratio\":", p ? "," : "");
                jnum(stdout, r->probe_ratio[p]);
                printf(",\"outcome\":\"%s\",\"guard_events\":%llu,\"substeps\":%d,"
                       "\"unstable_steps\":%llu,\"reported\":%s,\"nan\":%s,\"max_u\":%s}",
                       r->outcome[p], (unsigned long long)r->guard_events[p], r->max_substeps[p],
                       (unsigned long long)r->unstable_steps[p], r->reported[p] ? "true" : "false",
                       r->nan_seen[p] ? "true" : "false", FTM_JN("%.4g", r->max_u[p]));
            }
            printf("]}");
        }
        printf("]}\n");
    }
    /* Unwritten rows are the bigger loss: the sweep is run for them. */
    return csv_status ? csv_status : bad ? 1 : 0;
}
