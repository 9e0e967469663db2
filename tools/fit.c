/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Parameter identification: optimisers and the mass-spring cost (fit.h). */
#include "fit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- PRNG: xoshiro256** seeded through splitmix64 ------------------------ */

static uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void ftm_fit_rng_seed(ftm_fit_rng *rng, uint64_t seed)
{
    uint64_t s = seed;
    for (int i = 0; i < 4; i++)
        rng->s[i] = splitmix64(&s);
}

static uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

uint64_t ftm_fit_rng_next(ftm_fit_rng *rng)
{
    uint64_t *s = rng->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double ftm_fit_rng_uniform(ftm_fit_rng *rng)
{
    return (double)(ftm_fit_rng_next(rng) >> 11) * 0x1.0p-53;
}

/* ---- helpers ------------------------------------------------------------ */

static double clampd(double v, const double *lo, const double *hi, int i)
{
    if (lo && v < lo[i])
        v = lo[i];
    if (hi && v > hi[i])
        v = hi[i];
    return v;
}

static double eval_cost(ftm_fit_cost_fn f, void *user, const double *x, int *evals)
{
    double v = f(user, x);
    (*evals)++;
    return isfinite(v) ? v : INFINITY;
}

/* ---- simulated annealing (paper Fig. 7) --------------------------------- */

double ftm_fit_lundy_mees(double t, double beta)
{
    return t / (1.0 + beta * t);
}

double ftm_fit_lundy_mees_beta(double t0, double t_final, int steps)
{
    if (!(t0 > 0) || !(t_final > 0) || steps <= 0 || t_final >= t0)
        return 0.0;
    return (1.0 / t_final - 1.0 / t0) / steps;
}

ftm_fit_anneal_def ftm_fit_default_anneal_def(void)
{
    ftm_fit_anneal_def d;
    memset(&d, 0, sizeof d);
    d.seed = 1;
    d.iterations = 200;
    d.prerun = 20;
    d.accept_start = 0.8;
    d.accept_final = 1e-3;
    d.min_step_fraction = 0.05;
    return d;
}

static void neighbour(ftm_fit_rng *rng, int dim, const double *x, const double *step,
                      double frac, const double *lo, const double *hi, double *y)
{
    for (int i = 0; i < dim; i++) {
        double u = 2.0 * ftm_fit_rng_uniform(rng) - 1.0;
        y[i] = clampd(x[i] + step[i] * frac * u, lo, hi, i);
    }
}

int ftm_fit_anneal(const ftm_fit_anneal_def *def, ftm_fit_cost_fn f, void *user, double *x_best,
                   ftm_fit_result *result)
{
    if (!def || !f || !x_best || !result || def->dim < 1 || def->dim > FTM_FIT_MAX_DIM ||
        !def->x0 || !def->step || def->iterations < 0 || def->prerun < 0 ||
        !(def->accept_start > 0 && def->accept_start < 1) ||
        !(def->accept_final > 0 && def->accept_final < def->accept_start) ||
        !(def->min_step_fraction > 0 && def->min_step_fraction <= 1))
        return FTM_EINVAL;
    if (def->prerun == 0 && !(def->t0 > 0))
        return FTM_EINVAL; /* nothing to derive T0 from */
    int n = def->dim;
    ftm_fit_rng rng;
    ftm_fit_rng_seed(&rng, def->seed);
    ftm_fit_result r;
    memset(&r, 0, sizeof r);
    double x[FTM_FIT_MAX_DIM], y[FTM_FIT_MAX_DIM], best[FTM_FIT_MAX_DIM];
    for (int i = 0; i < n; i++)
        x[i] = clampd(def->x0[i], def->lo, def->hi, i);
    double fx = eval_cost(f, user, x, &r.evaluations);
    if (!isfinite(fx))
        return FTM_EINVAL;
    memcpy(best, x, sizeof(double) * (size_t)n);
    double fbest = fx;

    /* Pre-run: a random walk that takes every move, recording the uphill
     * differences: they set the useful temperature range. */
    double up_sum = 0;
    int up_n = 0;
    for (int it = 0; it < def->prerun; it++) {
        neighbour(&rng, n, x, def->step, 1.0, def->lo, def->hi, y);
        double fy = eval_cost(f, user, y, &r.evaluations);
        if (!isfinite(fy))
            continue;
        if (fy > fx) {
            up_sum += fy - fx;
            up_n++;
        }
        memcpy(x, y, sizeof(double) * (size_t)n);
        fx = fy;
        if (fy < fbest) {
            fbest = fy;
            memcpy(best, y, sizeof(double) * (size_t)n);
        }
    }
    /* the annealing proper starts from the best point seen so far */
    memcpy(x, best, sizeof(double) * (size_t)n);
    fx = fbest;
    double mean_up = up_n > 0 ? up_sum / up_n : (fabs(fbest) > 0 ? 0.01 * fabs(fbest) : 1e-12);
    r.t0 = def->t0 > 0 ? def->t0 : -mean_up / log(def->accept_start);
    r.t_final = def->t_final > 0 ? def->t_final : -mean_up / log(def->accept_final);
    if (r.t_final >= r.t0)
        r.t_final = r.t0 * 1e-3;
    r.beta = def->beta > 0 ? def->beta : ftm_fit_lundy_mees_beta(r.t0, r.t_final, def->iterations);
    double t = r.t0;
    if (def->trace) {
        ftm_fit_trace tr = {0, t, fx, fbest, best, r.evaluations};
        def->trace(def->trace_user, &tr);
    }
    for (int it = 1; it <= def->iterations; it++) {
        double frac = sqrt(t / r.t0);
        if (frac < def->min_step_fraction)
            frac = def->min_step_fraction;
        neighbour(&rng, n, x, def->step, frac, def->lo, def->hi, y);
        double fy = eval_cost(f, user, y, &r.evaluations);
        double u = ftm_fit_rng_uniform(&rng); /* drawn every iteration: same stream */
        double df = fy - fx;
        bool accept = isfinite(fy) && (df <= 0 || u < exp(-df / t));
        if (accept) {
            memcpy(x, y, sizeof(double) * (size_t)n);
            fx = fy;
            r.accepted++;
            if (df > 0)
                r.uphill_accepted++;
        }
        if (fy < fbest) {
            fbest = fy;
            memcpy(best, y, sizeof(double) * (size_t)n);
        }
        t = ftm_fit_lundy_mees(t, r.beta);
        r.iterations = it;
        if (def->trace) {
            ftm_fit_trace tr = {it, t, fx, fbest, best, r.evaluations};
            def->trace(def->trace_user, &tr);
        }
    }
    r.f = fbest;
    memcpy(x_best, best, sizeof(double) * (size_t)n);
    *result = r;
    return FTM_OK;
}

/* ---- Nelder-Mead ---------------------------------------------------------- */

ftm_fit_nm_def ftm_fit_default_nm_def(void)
{
    ftm_fit_nm_def d;
    memset(&d, 0, sizeof d);
    d.max_evaluations = 500;
    d.ftol = 1e-6;
    d.ftol_abs = 1e-300;
    d.xtol = 1e-6;
    return d;
}

int ftm_fit_nelder_mead(const ftm_fit_nm_def *def, ftm_fit_cost_fn f, void *user, double *x_best,
                        ftm_fit_result *result)
{
    if (!def || !f || !x_best || !result || def->dim < 1 || def->dim > FTM_FIT_MAX_DIM ||
        !def->x0 || !def->step || def->max_evaluations < def->dim + 1)
        return FTM_EINVAL;
    int n = def->dim;
    const double *lo = def->lo, *hi = def->hi;
    double s[FTM_FIT_MAX_DIM + 1][FTM_FIT_MAX_DIM], fs[FTM_FIT_MAX_DIM + 1];
    double c[FTM_FIT_MAX_DIM], xr[FTM_FIT_MAX_DIM], xe[FTM_FIT_MAX_DIM], xc[FTM_FIT_MAX_DIM];
    ftm_fit_result r;
    memset(&r, 0, sizeof r);
    for (int j = 0; j <= n; j++) {
        for (int i = 0; i < n; i++) {
            double v = def->x0[i] + (j == i + 1 ? def->step[i] : 0.0);
            s[j][i] = clampd(v, lo, hi, i);
        }
        fs[j] = eval_cost(f, user, s[j], &r.evaluations);
    }
    for (;;) {
        /* insertion sort by cost; ties keep their order (deterministic) */
        for (int a = 1; a <= n; a++) {
            double fa = fs[a], xa[FTM_FIT_MAX_DIM];
            memcpy(xa, s[a], sizeof(double) * (size_t)n);
            int b = a - 1;
            while (b >= 0 && fs[b] > fa) {
                fs[b + 1] = fs[b];
                memcpy(s[b + 1], s[b], sizeof(double) * (size_t)n);
                b--;
            }
            fs[b + 1] = fa;
            memcpy(s[b + 1], xa, sizeof(double) * (size_t)n);
        }
        r.iterations++;
        if (def->trace) {
            ftm_fit_trace tr = {r.iterations, 0.0, fs[0], fs[0], s[0], r.evaluations};
            def->trace(def->trace_user, &tr);
        }
        double spread = 0;
        for (int i = 0; i < n; i++)
            for (int j = 1; j <= n; j++) {
                double dx = fabs(s[j][i] - s[0][i]);
                if (dx > spread)
                    spread = dx;
            }
        bool fconv = isfinite(fs[n]) && fs[n] - fs[0] <= def->ftol * (fabs(fs[0]) + def->ftol_abs);
        if (fconv && spread <= def->xtol) {
            r.converged = true;
            break;
        }
        if (r.evaluations >= def->max_evaluations)
            break;
        for (int i = 0; i < n; i++) {
            c[i] = 0;
            for (int j = 0; j < n; j++)
                c[i] += s[j][i];
            c[i] /= n;
        }
        for (int i = 0; i < n; i++)
            xr[i] = clampd(c[i] + (c[i] - s[n][i]), lo, hi, i);
        double fr = eval_cost(f, user, xr, &r.evaluations);
        if (fr < fs[0]) {
            for (int i = 0; i < n; i++)
                xe[i] = clampd(c[i] + 2.0 * (c[i] - s[n][i]), lo, hi, i);
            double fe = eval_cost(f, user, xe, &r.evaluations);
            if (fe < fr) {
                memcpy(s[n], xe, sizeof(double) * (size_t)n);
                fs[n] = fe;
            } else {
                memcpy(s[n], xr, sizeof(double) * (size_t)n);
                fs[n] = fr;
            }
            continue;
        }
        if (fr < fs[n - 1]) {
            memcpy(s[n], xr, sizeof(double) * (size_t)n);
            fs[n] = fr;
            continue;
        }
        bool outside = fr < fs[n];
        for (int i = 0; i < n; i++)
            xc[i] = outside ? c[i] + 0.5 * (xr[i] - c[i]) : c[i] + 0.5 * (s[n][i] - c[i]);
        double fc = eval_cost(f, user, xc, &r.evaluations);
        if (outside ? fc <= fr : fc < fs[n]) {
            memcpy(s[n], xc, sizeof(double) * (size_t)n);
            fs[n] = fc;
            continue;
        }
        for (int j = 1; j <= n; j++) {
            for (int i = 0; i < n; i++)
                s[j][i] = s[0][i] + 0.5 * (s[j][i] - s[0][i]);
            fs[j] = eval_cost(f, user, s[j], &r.evaluations);
        }
    }
    r.f = fs[0];
    memcpy(x_best, s[0], sizeof(double) * (size_t)n);
    *result = r;
    return FTM_OK;
}

/* ---- the mass-spring problem ----------------------------------------------- */

typedef struct fit_link {
    int32_t a, b;
    double rest;
    int cls;
} fit_link;

struct ftm_fit_problem {
    ftm_fit_problem_def def;
    int32_t n;
    ftm_vec3 *rest;
    bool *fixed;
    fit_link *links;
    int32_t link_count;
    int32_t class_count[3];
    double mean_len;
    /* per case: contacts */
    ftm_contact *contacts[FTM_FIT_MAX_CASES];
    int32_t contact_count[FTM_FIT_MAX_CASES];
    double *prev; /* 3 per node */
};

ftm_fit_problem_def ftm_fit_default_problem_def(void)
{
    ftm_fit_problem_def d;
    memset(&d, 0, sizeof d);
    d.node_mass = 1e-3;
    d.depth = 10;
    d.tolerance = 1e-8;
    d.max_steps = 200000;
    return d;
}

static int fail(ftm_error *err, int code, const char *msg)
{
    if (err) {
        err->code = code;
        strncpy(err->message, msg, sizeof err->message - 1);
        err->message[sizeof err->message - 1] = '\0';
    }
    return code;
}

int ftm_fit_problem_create(const ftm_fit_problem_def *def, ftm_fit_problem **out, ftm_error *err)
{
    if (!def || !out || !def->mesh || !def->forces)
        return fail(err, FTM_EINVAL, "fit problem: NULL argument");
    if (def->cases < 1 || def->cases > FTM_FIT_MAX_CASES)
        return fail(err, FTM_EINVAL, "fit problem: 1..16 load cases");
    if (!(def->node_mass > 0) || def->depth < 0 || def->time_step < 0 || def->fixed_steps < 0 ||
        !(def->tolerance > 0) || def->max_steps < 1)
        return fail(err, FTM_EINVAL, "fit problem: bad mass, depth, time step or run control");
    ftm_fit_problem *p = calloc(1, sizeof *p);
    if (!p)
        return fail(err, FTM_ENOMEM, "fit problem: out of memory");
    p->def = *def;
    const ftm_mesh *m = def->mesh;
    p->n = ftm_mesh_node_count(m);
    p->link_count = ftm_mesh_link_count(m);
    p->rest = malloc(sizeof *p->rest * (size_t)p->n);
    p->fixed = malloc(sizeof *p->fixed * (size_t)p->n);
    p->prev = malloc(sizeof *p->prev * 3 * (size_t)p->n);
    p->links = malloc(sizeof *p->links * (size_t)(p->link_count > 0 ? p->link_count : 1));
    if (!p->rest || !p->fixed || !p->prev || !p->links) {
        ftm_fit_problem_destroy(p);
        return fail(err, FTM_ENOMEM, "fit problem: out of memory");
    }
    for (int32_t i = 0; i < p->n; i++) {
        p->rest[i] = ftm_mesh_rest_position(m, i);
        p->fixed[i] = ftm_mesh_fixed(m, i);
    }
    double len_sum = 0;
    for (int32_t l = 0; l < p->link_count; l++) {
        fit_link *fl = &p->links[l];
        double k;
        ftm_mesh_link(m, l, &fl->a, &fl->b, &k, &fl->rest);
        ftm_vec3 a = p->rest[fl->a], b = p->rest[fl->b];
        double dv[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
        double len = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
        int nz = 0;
        for (int c = 0; c < 3; c++)
            if (fabs(dv[c]) > 1e-9 * len)
                nz++;
        fl->cls = nz >= 1 ? nz - 1 : 0;
        p->class_count[fl->cls]++;
        len_sum += fl->rest;
    }
    p->mean_len = p->link_count > 0 ? len_sum / p->link_count : 1.0;
    for (int32_t c = 0; c < def->cases; c++) {
        const double *fc = def->forces[c];
        int32_t cnt = 0;
        for (int32_t i = 0; i < p->n; i++)
            if (fc[3 * i] != 0 || fc[3 * i + 1] != 0 || fc[3 * i + 2] != 0)
                cnt++;
        p->contacts[c] = malloc(sizeof(ftm_contact) * (size_t)(cnt > 0 ? cnt : 1));
        if (!p->contacts[c]) {
            ftm_fit_problem_destroy(p);
            return fail(err, FTM_ENOMEM, "fit problem: out of memory");
        }
        cnt = 0;
        for (int32_t i = 0; i < p->n; i++)
            if (fc[3 * i] != 0 || fc[3 * i + 1] != 0 || fc[3 * i + 2] != 0) {
                ftm_contact ct;
                memset(&ct, 0, sizeof ct);
                ct.node = i;
                ct.group = 0;
                ct.kind = FTM_CONTACT_FORCE;
                ct.value = (ftm_vec3){fc[3 * i], fc[3 * i + 1], fc[3 * i + 2]};
                p->contacts[c][cnt++] = ct;
            }
        p->contact_count[c] = cnt;
    }
    *out = p;
    return FTM_OK;
}

void ftm_fit_problem_destroy(ftm_fit_problem *p)
{
    if (!p)
        return;
    for (int c = 0; c < FTM_FIT_MAX_CASES; c++)
        free(p->contacts[c]);
    free(p->rest);
    free(p->fixed);
    free(p->links);
    free(p->prev);
    free(p);
}

void ftm_fit_problem_set_max_steps(ftm_fit_problem *p, int32_t max_steps)
{
    if (max_steps >= 1)
        p->def.max_steps = max_steps;
}

int32_t ftm_fit_problem_max_steps(const ftm_fit_problem *p)
{
    return p->def.max_steps;
}

void ftm_fit_problem_class_counts(const ftm_fit_problem *p, int32_t counts[3])
{
    for (int c = 0; c < 3; c++)
        counts[c] = p->class_count[c];
}

double ftm_fit_problem_mean_link_length(const ftm_fit_problem *p)
{
    return p->mean_len;
}

void ftm_fit_problem_class_lengths(const ftm_fit_problem *p, double lengths[3])
{
    double sum[3] = {0, 0, 0};
    for (int32_t l = 0; l < p->link_count; l++)
        sum[p->links[l].cls] += p->links[l].rest;
    for (int c = 0; c < 3; c++)
        lengths[c] = p->class_count[c] > 0 ? sum[c] / p->class_count[c] : 0.0;
}

static int build_mesh(const ftm_fit_problem *p, const ftm_fit_params *q, ftm_mesh **out,
                      ftm_error *err)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    if (!b)
        return fail(err, FTM_ENOMEM, "fit: out of memory");
    int rc = FTM_OK;
    for (int32_t i = 0; i < p->n && rc == FTM_OK; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = p->rest[i];
        nd.mass = p->def.node_mass;
        nd.damping = q->d;
        nd.fixed = p->fixed[i];
        int32_t id = ftm_mesh_builder_add_node(b, &nd);
        if (id < 0)
            rc = id;
    }
    for (int32_t l = 0; l < p->link_count && rc == FTM_OK; l++) {
        ftm_link_def ld = ftm_default_link_def();
        ld.a = p->links[l].a;
        ld.b = p->links[l].b;
        ld.stiffness = q->k * q->scale[p->links[l].cls];
        if (p->def.link_weight)
            ld.stiffness *= p->def.link_weight[l];
        ld.rest_length = p->links[l].rest;
        rc = ftm_mesh_builder_add_link(b, &ld);
    }
    if (rc != FTM_OK) {
        ftm_mesh_builder_destroy(b);
        return fail(err, rc, "fit: bad parameters (stiffness and damping must be > 0 and finite)");
    }
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    bd.reorder = false; /* keep the base mesh's indices */
    bd.surface_from_tetrahedra = false;
    rc = ftm_mesh_build(b, &bd, out, err);
    ftm_mesh_builder_destroy(b);
    return rc;
}

static bool params_ok(const ftm_fit_params *q)
{
    if (!(q->k > 0 && isfinite(q->k)) || !(q->d >= 0 && isfinite(q->d)))
        return false;
    for (int c = 0; c < 3; c++)
        if (!(q->scale[c] > 0 && isfinite(q->scale[c])))
            return false;
    return true;
}

int ftm_fit_problem_eval(ftm_fit_problem *p, const ftm_fit_params *params, ftm_fit_eval *out,
                         double *const *positions_out, ftm_error *err)
{
    if (!p || !params || !out)
        return fail(err, FTM_EINVAL, "fit eval: NULL argument");
    if (!params_ok(params))
        return fail(err, FTM_EINVAL, "fit eval: k, d and class scales must be finite, k > 0, d >= 0");
    ftm_mesh *mesh = NULL;
    int rc = build_mesh(p, params, &mesh, err);
    if (rc != FTM_OK)
        return rc;
    ftm_sim_def sd = ftm_default_sim_def();
    sd.depth = p->def.depth;
    double hc = ftm_mesh_critical_time_step(mesh);
    sd.time_step = p->def.time_step > 0 ? p->def.time_step : (isfinite(hc) ? 0.5 * hc : 1e-3);
    ftm_sim *sim = NULL;
    rc = ftm_sim_create(mesh, &sd, &sim, err);
    if (rc != FTM_OK) {
        ftm_mesh_destroy(mesh);
        return rc;
    }
    memset(out, 0, sizeof *out);
    out->converged = true;
    const int32_t n = p->n;
    const double tol = p->def.tolerance * p->mean_len;
    const int check = 4;
    for (int32_t c = 0; c < p->def.cases; c++) {
        ftm_fit_case_eval *ce = &out->c[c];
        ftm_sim_reset(sim);
        rc = ftm_sim_set_contacts(sim, p->contacts[c], p->contact_count[c], err);
        if (rc != FTM_OK)
            break;
        memcpy(p->prev, ftm_sim_positions(sim), sizeof(double) * 3 * (size_t)n);
        int32_t limit = p->def.fixed_steps > 0 ? p->def.fixed_steps : p->def.max_steps;
        int32_t s = 0;
        while (s < limit) {
            if (ftm_sim_step(sim) != FTM_OK) {
                ce->unstable = true;
                break;
            }
            s++;
            if (p->def.fixed_steps > 0 || s % check != 0)
                continue;
            const double *x = ftm_sim_positions(sim);
            double m2 = 0;
            for (int32_t i = 0; i < 3 * n; i += 3) {
                double dx = x[i] - p->prev[i], dy = x[i + 1] - p->prev[i + 1],
                       dz = x[i + 2] - p->prev[i + 2];
                double q2 = dx * dx + dy * dy + dz * dz;
                if (q2 > m2)
                    m2 = q2;
            }
            memcpy(p->prev, x, sizeof(double) * 3 * (size_t)n);
            if (sqrt(m2) / check < tol) {
                ce->converged = true;
                break;
            }
        }
        if (p->def.fixed_steps > 0 && !ce->unstable)
            ce->converged = true;
        ce->steps = s;
        out->steps += s;
        if (!ce->converged)
            out->converged = false;
        const double *x = ftm_sim_positions(sim);
        if (positions_out && positions_out[c])
            memcpy(positions_out[c], x, sizeof(double) * 3 * (size_t)n);
        if (ce->unstable) {
            ce->cost = INFINITY;
            out->cost = INFINITY;
            continue;
        }
        const double *ref = p->def.reference ? p->def.reference[c] : NULL;
        double sum = 0, mx = 0, usum = 0;
        for (int32_t i = 0; ref && i < n; i++) {
            const double *a = x + 3 * i, *b = ref + 3 * i;
            double e = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                            (a[2] - b[2]) * (a[2] - b[2]));
            ftm_vec3 r0 = p->rest[i];
            double u = sqrt((b[0] - r0.x) * (b[0] - r0.x) + (b[1] - r0.y) * (b[1] - r0.y) +
                            (b[2] - r0.z) * (b[2] - r0.z));
            sum += e;
            usum += u;
            if (e > mx)
                mx = e;
        }
        ce->cost = sum;
        ce->avg_err = sum / n;
        ce->max_err = mx;
        ce->mean_ref_u = usum / n;
        out->cost += sum;
    }
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(mesh);
    return rc;
}

int ftm_fit_fem_reference(const ftm_mesh *mesh, const ftm_fem_material *material, int32_t cases,
                          const double *const *forces, double *const *positions_out,
                          ftm_error *err)
{
    return ftm_fit_fem_reference_each(mesh, material, NULL, NULL, cases, forces, positions_out,
                                      err);
}

int ftm_fit_fem_reference_each(const ftm_mesh *mesh, const ftm_fem_material *material,
                               const ftm_fem_material *hex_materials,
                               const ftm_fem_material *tet_materials, int32_t cases,
                               const double *const *forces, double *const *positions_out,
                               ftm_error *err)
{
    ftm_fem_def def = ftm_default_fem_def();
    def.material = *material;
    def.hex_materials = hex_materials;
    def.tet_materials = tet_materials;
    def.factorization = FTM_FEM_FACTOR_SIMPLICIAL; /* same bits on every machine */
    ftm_fem *fem = NULL;
    int rc = ftm_fem_create(mesh, &def, &fem, err);
    if (rc != FTM_OK)
        return rc;
    int32_t n = ftm_mesh_node_count(mesh);
    for (int32_t c = 0; c < cases && rc == FTM_OK; c++) {
        rc = ftm_fem_solve(fem, forces[c], NULL, positions_out[c], err);
        for (int32_t i = 0; rc == FTM_OK && i < n; i++) {
            ftm_vec3 r = ftm_mesh_rest_position(mesh, i);
            positions_out[c][3 * i] += r.x;
            positions_out[c][3 * i + 1] += r.y;
            positions_out[c][3 * i + 2] += r.z;
        }
    }
    ftm_fem_destroy(fem);
    return rc;
}
