/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A small sparse symmetric positive definite solver on CHOLMOD, for implicit
 * models other than the FEM reference (the backward-Euler mass-spring model
 * of `ftm bench accuracy`): the pattern is analysed once (fill-reducing
 * ordering), then each new set of values is a numeric factorisation only. */
#include "ftm/fem.h"

#include "fem_internal.h"

#include <cholmod.h>

#include <limits.h>
#include <stdlib.h>
#include <string.h>

struct ftm_spd {
    cholmod_common cc;
    cholmod_sparse *a;
    cholmod_factor *factor;
    cholmod_dense *rhs, *x, *y, *e;
    int32_t n;
    bool factored;
};

void ftm_spd_destroy(ftm_spd *s)
{
    if (!s)
        return;
    cholmod_free_sparse(&s->a, &s->cc);
    cholmod_free_factor(&s->factor, &s->cc);
    cholmod_free_dense(&s->rhs, &s->cc);
    cholmod_free_dense(&s->x, &s->cc);
    cholmod_free_dense(&s->y, &s->cc);
    cholmod_free_dense(&s->e, &s->cc);
    cholmod_finish(&s->cc);
    free(s);
}

int ftm_spd_create(int32_t n, const int32_t *col_start, const int32_t *row, ftm_spd **out,
                   ftm_error *err)
{
    if (n <= 0 || !col_start || !row || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_spd_create: empty matrix or NULL argument");
    int32_t nnz = col_start[n];
    if (col_start[0] != 0 || nnz <= 0)
        return ftm_error_set(err, FTM_EINVAL, "ftm_spd_create: bad column starts");
    for (int32_t j = 0; j < n; j++) {
        if (col_start[j + 1] < col_start[j])
            return ftm_error_set(err, FTM_EINVAL, "ftm_spd_create: column %d: starts decrease",
                                (int)j);
        for (int32_t q = col_start[j]; q < col_start[j + 1]; q++)
            if (row[q] < 0 || row[q] > j || (q > col_start[j] && row[q] <= row[q - 1]))
                return ftm_error_set(err, FTM_EINVAL,
                                    "ftm_spd_create: column %d: rows must ascend within 0..%d "
                                    "(upper triangle)",
                                    (int)j, (int)j);
    }
    ftm_spd *s = calloc(1, sizeof *s);
    if (!s)
        return ftm_error_set(err, FTM_ENOMEM, "ftm_spd_create: out of memory");
    cholmod_start(&s->cc);
    s->cc.print = 0;
    s->cc.error_handler = NULL;
    s->n = n;
    s->a = cholmod_allocate_sparse((size_t)n, (size_t)n, (size_t)nnz, 1, 1, 1, CHOLMOD_REAL, &s->cc);
    s->rhs = cholmod_allocate_dense((size_t)n, 1, (size_t)n, CHOLMOD_REAL, &s->cc);
    if (!s->a || !s->rhs) {
        ftm_spd_destroy(s);
        return ftm_error_set(err, FTM_ENOMEM, "ftm_spd_create: CHOLMOD out of memory");
    }
    int *ap = s->a->p, *ai = s->a->i;
    for (int32_t j = 0; j <= n; j++)
        ap[j] = col_start[j];
    for (int32_t q = 0; q < nnz; q++)
        ai[q] = row[q];
    memset(s->a->x, 0, (size_t)nnz * sizeof(double));
    s->factor = cholmod_analyze(s->a, &s->cc);
    if (!s->factor) {
        int st = s->cc.status;
        ftm_spd_destroy(s);
        return ftm_error_set(err, FTM_ENOMEM, "ftm_spd_create: CHOLMOD analysis failed (status %d)",
                            st);
    }
    *out = s;
    return FTM_OK;
}

int ftm_spd_factor(ftm_spd *s, const double *values, ftm_error *err)
{
    if (!s || !values)
        return ftm_error_set(err, FTM_EINVAL, "ftm_spd_factor: NULL argument");
    int *ap = s->a->p;
    memcpy(s->a->x, values, (size_t)ap[s->n] * sizeof(double));
    s->factored = false;
    int ok = cholmod_factorize(s->a, s->factor, &s->cc);
    if (!ok || s->cc.status == CHOLMOD_OUT_OF_MEMORY)
        return ftm_error_set(err, FTM_ENOMEM, "ftm_spd_factor: CHOLMOD factorisation failed "
                                             "(status %d)",
                            s->cc.status);
    if (s->cc.status == CHOLMOD_NOT_POSDEF)
        return ftm_error_set(err, FTM_EINVAL,
                            "ftm_spd_factor: matrix is not positive definite (pivot %d of %d)",
                            (int)s->factor->minor, (int)s->n);
    s->factored = true;
    return FTM_OK;
}

int ftm_spd_solve(ftm_spd *s, const double *b, double *x, ftm_error *err)
{
    if (!s || !b || !x)
        return ftm_error_set(err, FTM_EINVAL, "ftm_spd_solve: NULL argument");
    if (!s->factored)
        return ftm_error_set(err, FTM_EINVAL, "ftm_spd_solve: no valid factorisation");
    memcpy(s->rhs->x, b, (size_t)s->n * sizeof(double));
    if (!cholmod_solve2(CHOLMOD_A, s->factor, s->rhs, NULL, &s->x, NULL, &s->y, &s->e, &s->cc))
        return ftm_error_set(err, FTM_ENOMEM, "ftm_spd_solve: CHOLMOD solve failed (status %d)",
                            s->cc.status);
    memcpy(x, s->x->x, (size_t)s->n * sizeof(double));
    return FTM_OK;
}

int64_t ftm_spd_factor_nnz(const ftm_spd *s) { return s && s->factored ? (int64_t)s->cc.lnz : 0; }
