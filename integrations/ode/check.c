#include "check.h"

#include <math.h>
#include <stdlib.h>


/* No floor (docs/algorithms.md §3): a zero denominator leaves the residual as it is. */
static double relative(double num, double den) { return den > 0.0 ? num / den : num; }

static double norm(const double *x, size_t n) {
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += x[i] * x[i];
    return sqrt(s);
}

/* y += A x (A in compressed columns). */
static void mul_add(const cadmm_csc *A, const double *x, double *y) {
    for (size_t j = 0; j < A->ncols; j++)
        for (int64_t k = A->colptr[j]; k < A->colptr[j + 1]; k++)
            y[A->rowind[k]] += A->values[k] * x[j];
}

/* y += A^T x. */
static void mul_trans_add(const cadmm_csc *A, const double *x, double *y) {
    for (size_t j = 0; j < A->ncols; j++)
        for (int64_t k = A->colptr[j]; k < A->colptr[j + 1]; k++)
            y[j] += A->values[k] * x[A->rowind[k]];
}

/* Projection of z onto K_mu = {||z_T|| <= mu z_N} (z_N >= 0 too, which matters for mu = 0). */
static void project_cone(double mu, const double z[3], double out[3]) {
    double t = hypot(z[1], z[2]);
    if (z[0] >= 0.0 && t <= mu * z[0]) {
        out[0] = z[0], out[1] = z[1], out[2] = z[2];
    } else if (mu * t + z[0] <= 0.0) {
        out[0] = out[1] = out[2] = 0.0;
    } else { /* t > 0 here: t = 0 falls in one of the two cases above */
        double a = (z[0] + mu * t) / (1.0 + mu * mu);
        out[0] = a, out[1] = mu * a * z[1] / t, out[2] = mu * a * z[2] / t;
    }
}

double check_error(const cadmm_ode_problem *p, const double *r, const double *v) {
    size_t n = p->n, m = 3 * p->n_contacts;
    if (m == 0) return 0.0;
    double *mv = calloc(n, sizeof *mv), *hr = calloc(n, sizeof *hr), *u = malloc(m * sizeof *u),
           *res = malloc((n > m ? n : m) * sizeof *res);
    double e = INFINITY;
    if (mv && hr && u && res) {
        mul_add(&p->M, v, mv);
        mul_add(&p->H, r, hr);
        for (size_t i = 0; i < m; i++) u[i] = p->w[i];
        mul_trans_add(&p->H, v, u);

        for (size_t i = 0; i < n; i++) res[i] = -mv[i] + hr[i] + p->f[i];
        double scale = fmax(norm(p->f, n), fmax(norm(mv, n), norm(hr, n)));
        e = relative(norm(res, n), scale);

        for (size_t c = 0; c < p->n_contacts; c++) {
            const double *uc = &u[3 * c], *rc = &r[3 * c];
            double z[3] = {rc[0] - (uc[0] + p->mu[c] * hypot(uc[1], uc[2])), rc[1] - uc[1],
                           rc[2] - uc[2]},
                   proj[3];
            project_cone(p->mu[c], z, proj);
            for (int k = 0; k < 3; k++) res[3 * c + k] = rc[k] - proj[k];
        }
        e += relative(norm(res, m), fmax(norm(u, m), norm(r, m)));
        if (!isfinite(e)) e = INFINITY;
    }
    free(mv);
    free(hr);
    free(u);
    free(res);
    return e;
}
