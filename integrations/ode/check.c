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

/* M's diagonal entry i (0 when absent). */
static double diagonal(const cadmm_csc *M, size_t i) {
    for (int64_t k = M->colptr[i]; k < M->colptr[i + 1]; k++)
        if ((size_t)M->rowind[k] == i) return M->values[k];
    return 0.0;
}

/* The joint term: ||rho_J|| over its scale. */
static double joint_term(const cadmm_ode_problem *p, const double *r, const double *v,
                         const double *lambda) {
    size_t nr = p->n_joint_rows;
    double res = 0.0, gv2 = 0.0, free2 = 0.0, b2 = 0.0, lb2 = 0.0;
    for (size_t k = 0; k < nr; k++) {
        double gv = 0.0, fv = 0.0;
        for (int64_t i = p->G.colptr[k]; i < p->G.colptr[k + 1]; i++) {
            size_t row = (size_t)p->G.rowind[i];
            double d = diagonal(&p->M, row);
            gv += p->G.values[i] * v[row];
            fv += fabs(p->G.values[i] * (d > 0 ? p->f[row] / d : 0.0));
        }
        double y = gv + p->b[k] + p->c[k] * lambda[k], rho = y, lo = p->lo[k], hi = p->hi[k];
        int64_t c = p->friction_contact ? p->friction_contact[k] : -1;
        if (c >= 0) { /* also bounded by -+ e r_n of its contact */
            double t = p->friction[k] * fmax(r[3 * c], 0.0);
            lo = fmax(lo, -t);
            hi = fmin(hi, t);
        }
        if (c >= 0 || lo > -INFINITY || hi < INFINITY) {
            rho = lambda[k] - fmin(fmax(lambda[k] - y, lo), hi);
            lb2 += lambda[k] * lambda[k];
        }
        res += rho * rho;
        gv2 += gv * gv;
        free2 += fv * fv;
        b2 += p->b[k] * p->b[k];
    }
    return relative(sqrt(res), sqrt(fmax(fmax(gv2, b2), fmax(free2, lb2))));
}

double check_error(const cadmm_ode_problem *p, const double *r, const double *v,
                   const double *lambda) {
    size_t n = p->n, m = 3 * p->n_contacts, nr = p->n_joint_rows;
    if (m == 0 && nr == 0) return 0.0;
    if (nr > 0 && !lambda) return INFINITY;
    double *mv = calloc(n, sizeof *mv), *hr = calloc(n, sizeof *hr),
           *u = malloc((m + 1) * sizeof *u), *res = malloc((n > m ? n : m) * sizeof *res);
    double e = INFINITY;
    if (mv && hr && u && res) {
        mul_add(&p->M, v, mv);
        mul_add(&p->H, r, hr);
        if (nr > 0) mul_add(&p->G, lambda, hr);
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
        if (nr > 0) e += joint_term(p, r, v, lambda);
        if (!isfinite(e)) e = INFINITY;
    }
    free(mv);
    free(hr);
    free(u);
    free(res);
    return e;
}
