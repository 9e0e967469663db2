/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm experiment NAME`: the paper's mechanical experiments (Figs. 9-12),
 * printed as tables (or JSON) and written as CSV for docs/bench/experiments.sh.
 * See docs/experiments.md. */
#include "commands.h"
#include "experiments.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct exp_opts {
    const char *csv_dir;
    bool json, quick;
    double observe_time; /* depth: < 0 both modes (default), 0 equilibrium, > 0 that time */
} exp_opts;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm experiment NAME [--csv-dir DIR] [--json] [--quick] [--observe T]\n\n"
            "experiments (Choi, Sun, Heng 2004, sections 4.1, 4.2 and 4.4):\n"
            "  depth       optimum penetration depth by calibration, k = 0.5, 2, 5 (Figs. 9-10)\n"
            "  tissue      creep, hysteresis, load-deformation for three dampings (Fig. 11)\n"
            "  anisotropy  transversely isotropic lattices A, B and an isotropic control (Fig. 12)\n"
            "  volume      a volume deformed through its control lattice (section 4.2; its own\n"
            "              options: ftm experiment volume --help)\n"
            "  organs      surface organs pressed by a probe (section 4.4; its own options:\n"
            "              ftm experiment organs --help)\n\n"
            "options:\n"
            "  --csv-dir DIR    write the experiment's CSV files into DIR\n"
            "  --json           print the results as one JSON object\n"
            "  --quick          smaller lattices and shorter runs (as the tests use)\n"
            "  --observe T      depth: calibrate on the shape at time T [s] after the load\n"
            "                   (0: at equilibrium); default: both, equilibrium and T = 8 s\n\n"
            "exit status: 0 success, 1 the experiment failed, 2 bad arguments or an output\n"
            "that cannot be written\n");
}

/* Exit status for a CSV file that cannot be written. */
enum { EXIT_OUTPUT = 2 };

/* Opens DIR/name when --csv-dir is given (else *f = NULL), before the
 * experiment runs, so that a bad directory fails at once. 0 or -1. */
static int open_csv(const exp_opts *o, const char *name, FILE **f)
{
    *f = NULL;
    if (!o->csv_dir)
        return 0;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", o->csv_dir, name);
    *f = fopen(path, "w");
    if (!*f) {
        fprintf(stderr, "ftm experiment: %s: cannot write: %s\n", path, strerror(errno));
        return -1;
    }
    return 0;
}

/* Closes a file from open_csv(); a write that failed now or earlier (the
 * stream remembers it) is reported. 0 or -1. */
static int close_csv(const exp_opts *o, const char *name, FILE *f)
{
    if (!f)
        return 0;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", o->csv_dir, name);
    return ftm_close_output(f, "ftm experiment", path);
}

static void jnum(double v)
{
    ftm_json_number(stdout, v, 6);
}

/* ---- depth ---- */

static const double default_observe = 8.0;

static int run_depth(const exp_opts *o)
{
    double modes[2];
    int nmodes = 0;
    if (o->observe_time < 0) {
        modes[nmodes++] = 0.0;
        modes[nmodes++] = default_observe;
    } else {
        modes[nmodes++] = o->observe_time;
    }
    FILE *fc, *fp;
    if (open_csv(o, "depth_change.csv", &fc))
        return EXIT_OUTPUT;
    if (open_csv(o, "depth_profiles.csv", &fp)) {
        if (fc)
            fclose(fc);
        return EXIT_OUTPUT;
    }
    ftm_exp_depth_result *r[2] = {NULL, NULL};
    ftm_exp_depth_def def = ftm_exp_default_depth_def(o->quick);
    for (int m = 0; m < nmodes; m++) {
        r[m] = malloc(sizeof *r[m]);
        def.observe_time = modes[m];
        int rc = r[m] ? ftm_exp_depth(&def, r[m]) : -2;
        if (rc) {
            fprintf(stderr, "ftm experiment depth: failed (%d)\n", rc);
            free(r[0]);
            free(r[1]);
            if (fc)
                fclose(fc);
            if (fp)
                fclose(fp);
            return 1;
        }
    }
    FILE *f = fc;
    if (f) {
        fprintf(f, "mode,k,depth,change,max_disp\n");
        for (int m = 0; m < nmodes; m++)
            for (int k = 0; k < r[m]->k_count; k++)
                for (int n = 1; n <= r[m]->depth_count; n++)
                    fprintf(f, "%g,%g,%d,%.6g,%.6g\n", modes[m], r[m]->stiffness[k], n,
                            r[m]->change[k][n], r[m]->max_disp[k][n]);
    }
    f = fp;
    if (f) {
        /* top-row vertical displacement normalised by the loaded node's at
         * the deepest depth, per mode, k and depth */
        fprintf(f, "mode,k,depth,x,u_norm\n");
        for (int m = 0; m < nmodes; m++)
            for (int k = 0; k < r[m]->k_count; k++) {
                double ref = 0.0;
                for (int i = 0; i < r[m]->nx; i++)
                    ref = fmin(ref, r[m]->profile[k][r[m]->depth_count][i]);
                for (int n = 1; n <= r[m]->depth_count; n++)
                    for (int i = 0; i < r[m]->nx; i++)
                        fprintf(f, "%g,%g,%d,%g,%.6g\n", modes[m], r[m]->stiffness[k], n, r[m]->x[i],
                                ref < 0 ? r[m]->profile[k][n][i] / -ref : 0.0);
            }
    }
    int status = 0;
    if (close_csv(o, "depth_change.csv", fc) || close_csv(o, "depth_profiles.csv", fp))
        status = EXIT_OUTPUT;
    if (o->json) {
        printf("{\"experiment\":\"depth\",\"threshold\":");
        jnum(def.threshold);
        printf(",\"modes\":[");
        for (int m = 0; m < nmodes; m++) {
            printf("%s{\"observe_time\":", m ? "," : "");
            jnum(modes[m]);
            printf(",\"results\":[");
            for (int k = 0; k < r[m]->k_count; k++) {
                printf("%s{\"k\":", k ? "," : "");
                jnum(r[m]->stiffness[k]);
                printf(",\"depth\":%d,\"change\":[", r[m]->calibrated[k]);
                for (int n = 1; n <= r[m]->depth_count; n++) {
                    printf(n > 1 ? "," : "");
                    jnum(r[m]->change[k][n]);
                }
                printf("]}");
            }
            printf("]}");
        }
        printf("]}\n");
    } else {
        printf("optimum penetration depth (paper 3.1.3, Figs. 9-10): %dx%d triangular lattice, "
               "bottom fixed,\nforce %g N down on the top centre node, m = %g kg, d = %g N s/m, "
               "h = %g s;\nchange(n) = max nodal position change from depth n to n+1 / max "
               "displacement, threshold %g\n",
               def.nx, def.ny, def.force, def.mass, def.damping, def.time_step, def.threshold);
        for (int m = 0; m < nmodes; m++) {
            if (modes[m] > 0)
                printf("\nshape at t = %g s after the load (%d steps)\n", modes[m],
                       (int)lround(modes[m] / def.time_step));
            else
                printf("\nshape at equilibrium\n");
            printf("%6s", "depth");
            for (int k = 0; k < r[m]->k_count; k++)
                printf("   change k=%-4g", r[m]->stiffness[k]);
            printf("\n");
            for (int n = 1; n <= r[m]->depth_count; n++) {
                printf("%6d", n);
                for (int k = 0; k < r[m]->k_count; k++)
                    printf("   %13.4g", r[m]->change[k][n]);
                printf("\n");
            }
            printf("%6s", "optimum");
            for (int k = 0; k < r[m]->k_count; k++)
                printf("   %13d", r[m]->calibrated[k]);
            printf("   (paper: 4, 6, 8)\n");
        }
    }
    free(r[0]);
    free(r[1]);
    return status;
}

/* ---- tissue ---- */

/* Writes and closes f (from open_csv(), may be NULL); 0 or -1. */
static int write_curves(const exp_opts *o, FILE *f, const char *name, const char *cols,
                        const ftm_exp_curve *c, const double *damping)
{
    if (!f)
        return 0;
    fprintf(f, "damping,%s\n", cols);
    for (int d = 0; d < FTM_EXP_TISSUE_DAMPINGS; d++)
        for (int i = 0; i < c[d].count; i++)
            fprintf(f, "%g,%.6g,%.6g\n", damping[d], c[d].a[i], c[d].b[i]);
    return close_csv(o, name, f);
}

static int run_tissue(const exp_opts *o)
{
    static const char *const names[3] = {"tissue_creep.csv", "tissue_hysteresis.csv",
                                         "tissue_rate.csv"};
    FILE *f[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
        if (open_csv(o, names[k], &f[k])) {
            for (int j = 0; j < k; j++)
                if (f[j])
                    fclose(f[j]);
            return EXIT_OUTPUT;
        }
    }
    ftm_exp_tissue_def def = ftm_exp_default_tissue_def(o->quick);
    ftm_exp_tissue_result r;
    int rc = ftm_exp_tissue(&def, &r);
    if (rc) {
        fprintf(stderr, "ftm experiment tissue: failed (%d)\n", rc);
        for (int k = 0; k < 3; k++)
            if (f[k])
                fclose(f[k]);
        return 1;
    }
    int status = 0;
    if (write_curves(o, f[0], names[0], "time,strain", r.creep, def.damping))
        status = EXIT_OUTPUT;
    if (write_curves(o, f[1], names[1], "force,strain", r.hyst, def.damping))
        status = EXIT_OUTPUT;
    if (write_curves(o, f[2], names[2], "force,strain", r.rate, def.damping))
        status = EXIT_OUTPUT;
    const int D = FTM_EXP_TISSUE_DAMPINGS;
    if (o->json) {
        printf("{\"experiment\":\"tissue\",\"cases\":[");
        for (int d = 0; d < D; d++) {
            printf("%s{\"damping\":", d ? "," : "");
            jnum(def.damping[d]);
            printf(",\"creep_final\":");
            jnum(r.creep_final[d]);
            printf(",\"creep_static\":");
            jnum(r.creep_static[d]);
            printf(",\"creep_t63\":");
            jnum(r.creep_t63[d]);
            printf(",\"creep_max_drop\":");
            jnum(r.creep_max_drop[d]);
            printf(",\"hyst_area\":");
            jnum(r.hyst_area[d]);
            printf(",\"hyst_max_gap\":");
            jnum(r.hyst_max_gap[d]);
            printf(",\"hyst_residual\":");
            jnum(r.hyst_residual[d]);
            printf(",\"rate_compliance_start\":");
            jnum(r.rate_slope_start[d]);
            printf(",\"rate_compliance_end\":");
            jnum(r.rate_slope_end[d]);
            printf("}");
        }
        printf("],\"static_strain_half\":");
        jnum(r.static_strain_half);
        printf(",\"static_strain_full\":");
        jnum(r.static_strain_full);
        printf("}\n");
    } else {
        printf("tissue responses (paper 4.1.2, Fig. 11): %dx%d triangular lattice, bottom fixed, "
               "top row pulled up;\nm = %g kg, k = %g N/m, h = %g s, full depth; strain = mean "
               "top-row displacement / height\n\n",
               def.nx, def.ny, def.mass, def.stiffness, def.time_step);
        printf("(a) creep, F = %g N for %g s\n%10s %12s %12s %12s %14s\n", def.creep_force,
               def.creep_time, "damping", "strain(end)", "static", "t63 [s]", "largest drop");
        for (int d = 0; d < D; d++)
            printf("%10g %12.5g %12.5g %12.4g %14.3g\n", def.damping[d], r.creep_final[d],
                   r.creep_static[d], r.creep_t63[d], r.creep_max_drop[d]);
        printf("\n(b) hysteresis, F 0 -> %g N -> 0, %g s each way\n%10s %12s %12s %12s\n",
               def.hyst_force, def.ramp_time, "damping", "loop area", "max gap", "residual");
        for (int d = 0; d < D; d++)
            printf("%10g %12.5g %12.5g %12.5g\n", def.damping[d], r.hyst_area[d],
                   r.hyst_max_gap[d], r.hyst_residual[d]);
        printf("\n(c) load-deformation, F = %g N/s x t up to %g N\n%10s %16s %16s %10s\n", def.rate,
               def.rate_force, "damping", "strain/F start", "dstrain/dF end", "end/start");
        for (int d = 0; d < D; d++)
            printf("%10g %16.5g %16.5g %10.3g\n", def.damping[d], r.rate_slope_start[d],
                   r.rate_slope_end[d], r.rate_slope_end[d] / r.rate_slope_start[d]);
        printf("static strain at F = %g N: %.5g, at %g N: %.5g (ratio %.3f; linear would be 2)\n",
               def.rate_force / 2, r.static_strain_half, def.rate_force, r.static_strain_full,
               r.static_strain_full / r.static_strain_half);
    }
    ftm_exp_tissue_free(&r);
    return status;
}

/* ---- anisotropy ---- */

static int run_aniso(const exp_opts *o)
{
    FILE *f;
    if (open_csv(o, "anisotropy_profiles.csv", &f))
        return EXIT_OUTPUT;
    ftm_exp_aniso_def def = ftm_exp_default_aniso_def(o->quick);
    ftm_exp_aniso_result r;
    int rc = ftm_exp_aniso(&def, &r);
    if (rc) {
        fprintf(stderr, "ftm experiment anisotropy: failed (%d)\n", rc);
        if (f)
            fclose(f);
        return 1;
    }
    static const char *load_name[FTM_EXP_LOADS] = {"vertical", "horizontal"};
    int status = 0;
    if (f) {
        fprintf(f, "model,load,line,position,u\n");
        for (int m = 0; m < FTM_EXP_MODELS; m++)
            for (int l = 0; l < FTM_EXP_LOADS; l++)
                for (int i = 0; i < r.n; i++) {
                    fprintf(f, "%d,%s,across,%g,%.6g\n", m, load_name[l], (i - r.n / 2) * def.spacing,
                            r.across[m][l][i]);
                    fprintf(f, "%d,%s,into,%g,%.6g\n", m, load_name[l], i * def.spacing,
                            r.into[m][l][i]);
                }
        if (close_csv(o, "anisotropy_profiles.csv", f))
            status = EXIT_OUTPUT;
    }
    if (o->json) {
        printf("{\"experiment\":\"anisotropy\",\"models\":[");
        for (int m = 0; m < FTM_EXP_MODELS; m++) {
            printf("%s{\"model\":\"%s\"", m ? "," : "", r.model_name[m]);
            for (int l = 0; l < FTM_EXP_LOADS; l++) {
                printf(",\"%s\":{\"peak\":", load_name[l]);
                jnum(r.peak[m][l]);
                printf(",\"width\":");
                jnum(r.width[m][l]);
                printf(",\"across\":[");
                for (int i = 0; i < r.n; i++) {
                    printf(i ? "," : "");
                    jnum(r.across[m][l][i]);
                }
                printf("]}");
            }
            printf("}");
        }
        printf("]}\n");
    } else {
        printf("anisotropy (paper 4.1.3, Fig. 12): %d^3 cubic lattice, 18 neighbours, k = %g N/m "
               "vertical,\nhorizontal x%g (A) or x%g (B); force %g N vertical on the top centre "
               "(bottom fixed)\nor horizontal on the x-min face centre (x-max face fixed); "
               "equilibrium\n\n",
               r.n, def.stiffness, 1 / def.ratio, def.ratio, def.force);
        printf("%-22s %12s %12s %10s %12s %12s %10s\n", "model", "peak vert", "width vert",
               "steps", "peak horiz", "width horiz", "horiz/vert");
        for (int m = 0; m < FTM_EXP_MODELS; m++)
            printf("%-22s %12.5g %12.4g %10d %12.5g %12.4g %10.3g\n", r.model_name[m],
                   r.peak[m][0], r.width[m][0], r.steps[m][0], r.peak[m][1], r.width[m][1],
                   r.peak[m][1] / r.peak[m][0]);
        printf("\nprofiles across the loaded face (displacement along the load, node offset "
               "from the loaded node)\n%-22s %-10s", "model", "load");
        for (int i = 0; i < r.n; i++)
            printf(" %7d", i - r.n / 2);
        printf("\n");
        for (int m = 0; m < FTM_EXP_MODELS; m++)
            for (int l = 0; l < FTM_EXP_LOADS; l++) {
                printf("%-22s %-10s", r.model_name[m], load_name[l]);
                for (int i = 0; i < r.n; i++)
                    printf(" %7.4f", r.across[m][l][i]);
                printf("\n");
            }
    }
    return status;
}

int ftm_cmd_experiment(int argc, char **argv)
{
    exp_opts o = {.csv_dir = NULL, .json = false, .quick = false, .observe_time = -1.0};
    const char *name = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--json") == 0) {
            o.json = true;
        } else if (strcmp(a, "--quick") == 0) {
            o.quick = true;
        } else if (strcmp(a, "--csv-dir") == 0 || strcmp(a, "--observe") == 0) {
            if (i + 1 >= argc) {
                fprintf(stderr, "ftm experiment: %s needs a value\n", a);
                return 2;
            }
            if (strcmp(a, "--csv-dir") == 0) {
                o.csv_dir = argv[++i];
            } else {
                char *end;
                o.observe_time = strtod(argv[++i], &end);
                if (*end || !(o.observe_time >= 0) || !isfinite(o.observe_time)) {
                    fprintf(stderr, "ftm experiment: --observe needs a time >= 0\n");
                    return 2;
                }
            }
        } else if (a[0] == '-') {
            fprintf(stderr, "ftm experiment: unknown option '%s'\n", a);
            usage(stderr);
            return 2;
        } else if (!name && (strcmp(a, "volume") == 0 || strcmp(a, "organs") == 0)) {
            if (o.csv_dir || o.quick || o.observe_time >= 0) {
                fprintf(stderr, "ftm experiment: %s takes its own options after its name "
                                "(ftm experiment %s --help)\n", a, a);
                return 2;
            }
            return a[0] == 'v' ? ftm_experiment_volume(argc - i, argv + i, o.json)
                               : ftm_experiment_organs(argc - i, argv + i, o.json);
        } else if (!name) {
            name = a;
        } else {
            fprintf(stderr, "ftm experiment: more than one experiment named\n");
            return 2;
        }
    }
    if (!name) {
        usage(stderr);
        return 2;
    }
    if (strcmp(name, "depth") == 0)
        return run_depth(&o);
    if (strcmp(name, "tissue") == 0)
        return run_tissue(&o);
    if (strcmp(name, "anisotropy") == 0)
        return run_aniso(&o);
    fprintf(stderr, "ftm experiment: unknown experiment '%s'\n", name);
    usage(stderr);
    return 2;
}
