/* Shared helpers of the cadmm C/C++ tests: checks, the FCLib data directory, a small owned
 * CSC type, an independent implementation of the error measure of docs/algorithms.md §3
 * with and without joints (it does not call the library, so it can be compared with
 * cadmm_problem_error and the solver's statistics) and an estimate of its round-off, a
 * problem container (tu_problem, also the FCLib reader's), a fixed-seed random generator,
 * and (with cadmm.h included first) a solve-and-check helper used by the programs that
 * sweep many problems (tu_solve, tu_check_outcome).
 *
 * Everything is `static inline` so each test program includes it without a separate
 * translation unit and without unused-function warnings. Valid C99 and C++17. */
#ifndef CADMM_TEST_UTIL_H
#define CADMM_TEST_UTIL_H

#include <ctype.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Exit code that CTest reports as "skipped" (SKIP_RETURN_CODE). */
#define TU_SKIP 77

/* ---- failure counting ------------------------------------------------------------------ */

static inline int *tu_failures(void)
{
    static int n = 0;
    return &n;
}

#define TU_FAIL(...)                                                                      \
    do {                                                                                  \
        fprintf(stderr, "%s:%d: FAILED: ", __FILE__, __LINE__);                          \
        fprintf(stderr, __VA_ARGS__);                                                     \
        fprintf(stderr, "\n");                                                            \
        ++*tu_failures();                                                                 \
    } while (0)

#define CHECK(cond)                                                                       \
    do {                                                                                  \
        if (!(cond)) TU_FAIL("%s", #cond);                                                \
    } while (0)

#define CHECK_MSG(cond, ...)                                                              \
    do {                                                                                  \
        if (!(cond)) TU_FAIL(__VA_ARGS__);                                                \
    } while (0)

/* Aborts the program (after printing) when a precondition of the rest of the test fails. */
#define REQUIRE(cond)                                                                     \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "%s:%d: REQUIRED condition failed: %s\n", __FILE__, __LINE__, \
                    #cond);                                                               \
            exit(1);                                                                      \
        }                                                                                 \
    } while (0)

/* Prints the summary line and returns the process exit code. */
static inline int tu_finish(const char *name)
{
    int n = *tu_failures();
    if (n == 0) {
        printf("%s: all checks passed\n", name);
        return 0;
    }
    fprintf(stderr, "%s: %d check(s) FAILED\n", name, n);
    return 1;
}

/* ---- data directory -------------------------------------------------------------------- */

static inline int tu_is_dir(const char *path)
{
    struct stat st;
    return path != NULL && stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static inline int tu_is_file(const char *path)
{
    struct stat st;
    return path != NULL && stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Joins dir + "/" + name into a static-size buffer (tests use short paths). */
static inline const char *tu_join(char *buf, size_t len, const char *dir, const char *name)
{
    int k = snprintf(buf, len, "%s/%s", dir, name);
    REQUIRE(k > 0 && (size_t)k < len);
    return buf;
}

/* ---- small vector helpers -------------------------------------------------------------- */

/* The 2-norm of the entries divided by the largest magnitude, so that no square overflows
 * or vanishes whatever the data's scale (docs/algorithms.md §3). */
static inline double tu_norm(const double *x, size_t n)
{
    double big = 0.0, s = 0.0;
    for (size_t i = 0; i < n; ++i)
        if (!(fabs(x[i]) <= big)) big = fabs(x[i]); /* NaN propagates */
    if (big == 0.0 || !isfinite(big)) return big;
    for (size_t i = 0; i < n; ++i) s += (x[i] / big) * (x[i] / big);
    return big * sqrt(s);
}

static inline double tu_diff_norm(const double *x, const double *y, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; ++i) s += (x[i] - y[i]) * (x[i] - y[i]);
    return sqrt(s);
}

static inline double tu_max(double a, double b) { return a > b ? a : b; }

/* ||x - y|| / max(1, ||y||): the "scaled" difference the tests compare against. */
static inline double tu_rel_diff(const double *x, const double *y, size_t n)
{
    return tu_diff_norm(x, y, n) / tu_max(1.0, tu_norm(y, n));
}

static inline int tu_all_finite(const double *x, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        if (!isfinite(x[i])) return 0;
    return 1;
}

static inline void *tu_calloc(size_t n, size_t size)
{
    void *p = calloc(n == 0 ? 1 : n, size);
    REQUIRE(p != NULL);
    return p;
}

/* ---- owned CSC matrix ------------------------------------------------------------------ */

/* 0-based compressed sparse column, row indices sorted, no duplicates. Same field layout as
 * cadmm_csc (which has const pointers), so tu_csc_view converts trivially. */
typedef struct tu_csc {
    size_t nrows, ncols;
    int64_t *colptr; /* ncols + 1 */
    int64_t *rowind; /* colptr[ncols] */
    double *values;  /* colptr[ncols] */
} tu_csc;

#ifdef CADMM_H
/* A borrowed cadmm_csc view of `a` (needs cadmm.h included first). */
static inline cadmm_csc tu_csc_view(const tu_csc *a)
{
    cadmm_csc c;
    c.nrows = a->nrows;
    c.ncols = a->ncols;
    c.colptr = a->colptr;
    c.rowind = a->rowind;
    c.values = a->values;
    return c;
}
#endif

/* An owned copy of compressed-column arrays (for the independent measure of a problem
 * given as constant arrays); release with tu_csc_free. */
static inline tu_csc tu_csc_copy(size_t nrows, size_t ncols, const int64_t *colptr,
                                 const int64_t *rowind, const double *values)
{
    tu_csc a;
    size_t nnz = (size_t)colptr[ncols];
    a.nrows = nrows;
    a.ncols = ncols;
    a.colptr = (int64_t *)tu_calloc(ncols + 1, sizeof(int64_t));
    a.rowind = (int64_t *)tu_calloc(nnz, sizeof(int64_t));
    a.values = (double *)tu_calloc(nnz, sizeof(double));
    memcpy(a.colptr, colptr, (ncols + 1) * sizeof(int64_t));
    memcpy(a.rowind, rowind, nnz * sizeof(int64_t));
    memcpy(a.values, values, nnz * sizeof(double));
    return a;
}

static inline void tu_csc_free(tu_csc *a)
{
    if (a == NULL) return;
    free(a->colptr);
    free(a->rowind);
    free(a->values);
    a->colptr = a->rowind = NULL;
    a->values = NULL;
    a->nrows = a->ncols = 0;
}

/* y = A x (beta = 0) or y += A x (beta = 1). */
static inline void tu_csc_mul(const tu_csc *a, const double *x, int accumulate, double *y)
{
    if (!accumulate)
        for (size_t i = 0; i < a->nrows; ++i) y[i] = 0.0;
    for (size_t j = 0; j < a->ncols; ++j)
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k)
            y[a->rowind[k]] += a->values[k] * x[j];
}

/* y = A^T x (beta = 0) or y += A^T x (beta = 1). */
static inline void tu_csc_mul_t(const tu_csc *a, const double *x, int accumulate, double *y)
{
    for (size_t j = 0; j < a->ncols; ++j) {
        double s = 0.0;
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k)
            s += a->values[k] * x[a->rowind[k]];
        y[j] = accumulate ? y[j] + s : s;
    }
}

/* Builds a CSC matrix from a dense row-major nrows x ncols array (exact zeros dropped). */
static inline tu_csc tu_csc_from_dense(size_t nrows, size_t ncols, const double *rowmajor)
{
    tu_csc a;
    size_t nnz = 0, k = 0;
    for (size_t i = 0; i < nrows * ncols; ++i) nnz += rowmajor[i] != 0.0;
    a.nrows = nrows;
    a.ncols = ncols;
    a.colptr = (int64_t *)tu_calloc(ncols + 1, sizeof(int64_t));
    a.rowind = (int64_t *)tu_calloc(nnz, sizeof(int64_t));
    a.values = (double *)tu_calloc(nnz, sizeof(double));
    for (size_t j = 0; j < ncols; ++j) {
        a.colptr[j] = (int64_t)k;
        for (size_t i = 0; i < nrows; ++i) {
            double v = rowmajor[i * ncols + j];
            if (v != 0.0) {
                a.rowind[k] = (int64_t)i;
                a.values[k] = v;
                ++k;
            }
        }
    }
    a.colptr[ncols] = (int64_t)k;
    return a;
}

/* ---- cones and the error measure (docs/algorithms.md §2 and §3) ----------------------- */

/* Projection of z = (z_N, z_T) onto K_mu = { ||x_T|| <= mu x_N }. */
static inline void tu_project_cone(const double z[3], double mu, double out[3])
{
    double t = sqrt(z[1] * z[1] + z[2] * z[2]);
    if (t <= mu * z[0]) { /* inside K (includes t = 0, z_N >= 0) */
        out[0] = z[0];
        out[1] = z[1];
        out[2] = z[2];
    } else if (mu * t + z[0] <= 0.0) { /* inside the polar cone */
        out[0] = out[1] = out[2] = 0.0;
    } else {
        double a = (z[0] + mu * t) / (1.0 + mu * mu);
        out[0] = a;
        if (t > 0.0) {
            out[1] = mu * a * z[1] / t;
            out[2] = mu * a * z[2] / t;
        } else {
            out[1] = out[2] = 0.0;
        }
    }
}

/* ||r - P_K(r - (u + Phi(u)))|| over all contacts, Phi(u) = (mu ||u_T||, 0, 0). */
static inline double tu_natural_map(const double *r, const double *u, const double *mu,
                                    size_t nc)
{
    double *res = (double *)tu_calloc(3 * nc, sizeof(double)), e;
    for (size_t c = 0; c < nc; ++c) {
        const double *ri = r + 3 * c, *ui = u + 3 * c;
        double ut = hypot(ui[1], ui[2]);
        double z[3], p[3];
        z[0] = ri[0] - (ui[0] + mu[c] * ut);
        z[1] = ri[1] - ui[1];
        z[2] = ri[2] - ui[2];
        tu_project_cone(z, mu[c], p);
        for (int k = 0; k < 3; ++k) res[3 * c + k] = ri[k] - p[k];
    }
    e = tu_norm(res, 3 * nc);
    free(res);
    return e;
}

/* num / den, or the bare num when den is zero (then every vector in it is zero: there is no
 * floor, docs/algorithms.md §3). A norm beyond double's range makes the term +inf: the
 * measure cannot be evaluated in double precision, which counts like a non-finite
 * candidate (docs/algorithms.md §3.1). */
static inline double tu_relative(double num, double den)
{
    if (!isfinite(num) || !isfinite(den)) return INFINITY;
    return den > 0.0 ? num / den : num;
}

/* Local error: ||r - P_K(r - (u + Phi(u)))|| / ||q||, u = W r + q. */
static inline double tu_local_error(const tu_csc *W, const double *q, const double *mu,
                                    size_t nc, const double *r)
{
    size_t m = 3 * nc;
    double *u = (double *)tu_calloc(m, sizeof(double));
    double e;
    if (!tu_all_finite(r, m)) {
        free(u);
        return INFINITY;
    }
    if (m > 0) memcpy(u, q, m * sizeof(double));
    tu_csc_mul(W, r, 1, u);
    e = tu_relative(tu_natural_map(r, u, mu, nc), tu_norm(q, m));
    free(u);
    return e;
}

/* Bounds and compliance of joint rows (NULL arrays: every row an equality without
 * compliance). */
typedef struct tu_rows {
    const double *lo, *hi, *c;
    /* Rows bounded by a contact's normal impulse (NULL for none): contact[k] >= 0 adds the
     * bounds -+ e[k] r_n(contact[k]) to lo and hi; -1 leaves the row's own. */
    const int64_t *contact;
    const double *e;
} tu_rows;

/* Row k's residual at y = G_k^T v + b_k + c_k lambda_k: y for an equality, the natural map
 * lambda - clamp(lambda - y, lo, hi) for a row with a finite bound or a contact's (whose
 * normal impulse is read in r). */
static inline double tu_row_residual(tu_rows rows, size_t k, double gv, double b, double lambda,
                                     const double *r, int *bounded)
{
    double y = gv + b + (rows.c ? rows.c[k] * lambda : 0.0);
    double lo = rows.lo ? rows.lo[k] : -INFINITY, hi = rows.lo ? rows.hi[k] : INFINITY;
    int by_contact = rows.contact && rows.contact[k] >= 0;
    if (by_contact) {
        double rn = r[3 * rows.contact[k]], t = rows.e[k] * (rn > 0.0 ? rn : 0.0);
        lo = lo > -t ? lo : -t;
        hi = hi < t ? hi : t;
    }
    *bounded = by_contact || isfinite(lo) || isfinite(hi);
    if (!*bounded) return y;
    double z = lambda - y;
    z = z < lo ? lo : (z > hi ? hi : z);
    return lambda - z;
}

/* Global error with joint rows (docs/algorithms.md §3.1):
 *     ||-M v + H r + G lambda + f|| / max(||f||, ||M v||, ||H r + G lambda||)
 *   + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),          u = H^T v + w
 *   + ||rho_J|| / max(||G^T v||, ||b||, || |G|^T |diag(M)^-1 f| ||, ||lambda_B||)
 * with rho_J the rows' residuals (tu_row_residual) and lambda_B the bounded rows'
 * multipliers. G (n x p), b (p) and lambda (p) describe the rows; G == NULL or
 * G->ncols == 0 means none (b and lambda are then not read). A non-finite r, v or lambda
 * gives +inf. */
static inline double tu_global_error_rows(const tu_csc *M, const tu_csc *H, const tu_csc *G,
                                          const double *f, const double *w, const double *b,
                                          tu_rows rows, const double *mu, size_t nc,
                                          const double *r, const double *v, const double *lambda)
{
    size_t n = M->nrows, m = 3 * nc, p = (G != NULL) ? G->ncols : 0;
    double *mv = (double *)tu_calloc(n, sizeof(double));
    double *hr = (double *)tu_calloc(n, sizeof(double));
    double *eq = (double *)tu_calloc(n, sizeof(double));
    double *u = (double *)tu_calloc(m, sizeof(double));
    double *gv = (double *)tu_calloc(p, sizeof(double));
    double e1, e2, e3 = 0.0;
    if (!tu_all_finite(r, m) || !tu_all_finite(v, n) || (p > 0 && !tu_all_finite(lambda, p))) {
        e1 = INFINITY;
        goto done;
    }
    tu_csc_mul(M, v, 0, mv);
    tu_csc_mul(H, r, 0, hr);
    if (p > 0) tu_csc_mul(G, lambda, 1, hr); /* hr = H r + G lambda */
    for (size_t i = 0; i < n; ++i) eq[i] = -mv[i] + hr[i] + f[i];
    e1 = tu_relative(tu_norm(eq, n),
                     tu_max(tu_norm(f, n), tu_max(tu_norm(mv, n), tu_norm(hr, n))));
    if (m > 0) memcpy(u, w, m * sizeof(double));
    tu_csc_mul_t(H, v, 1, u);
    e2 = tu_relative(tu_natural_map(r, u, mu, nc), tu_max(tu_norm(u, m), tu_norm(r, m)));
    if (p > 0) {
        double *res = (double *)tu_calloc(p, sizeof(double));
        double *free_v = (double *)tu_calloc(p, sizeof(double));
        double *lambda_b = (double *)tu_calloc(p, sizeof(double));
        tu_csc_mul_t(G, v, 0, gv); /* G^T v */
        for (size_t k = 0; k < p; ++k) {
            int bounded;
            res[k] = tu_row_residual(rows, k, gv[k], b[k], lambda[k], r, &bounded);
            lambda_b[k] = bounded ? lambda[k] : 0.0;
            /* the velocity row k sees under free motion: sum_i |G_ik f_i / M_ii| */
            for (int64_t e = G->colptr[k]; e < G->colptr[k + 1]; ++e) {
                size_t i = (size_t)G->rowind[e];
                double d = 0.0;
                for (int64_t t = M->colptr[i]; t < M->colptr[i + 1]; ++t)
                    if ((size_t)M->rowind[t] == i) d = M->values[t];
                if (d > 0.0) free_v[k] += fabs(G->values[e] * f[i] / d);
            }
        }
        e3 = tu_relative(tu_norm(res, p),
                         tu_max(tu_max(tu_norm(gv, p), tu_norm(lambda_b, p)),
                                tu_max(tu_norm(b, p), tu_norm(free_v, p))));
        free(res);
        free(free_v);
        free(lambda_b);
    }
    e1 = e1 + e2 + e3;
done:
    free(mv);
    free(hr);
    free(eq);
    free(u);
    free(gv);
    return e1;
}

/* tu_global_error_rows with every joint row an equality without compliance. */
static inline double tu_global_error_joints(const tu_csc *M, const tu_csc *H, const tu_csc *G,
                                            const double *f, const double *w, const double *b,
                                            const double *mu, size_t nc, const double *r,
                                            const double *v, const double *lambda)
{
    tu_rows none = {NULL, NULL, NULL, NULL, NULL};
    return tu_global_error_rows(M, H, G, f, w, b, none, mu, nc, r, v, lambda);
}

/* Global error without joints: ||-M v + H r + f|| / max(||f||, ||M v||, ||H r||)
 *                             + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),
 *                               u = H^T v + w. */
static inline double tu_global_error(const tu_csc *M, const tu_csc *H, const double *f,
                                     const double *w, const double *mu, size_t nc,
                                     const double *r, const double *v)
{
    return tu_global_error_joints(M, H, NULL, f, w, NULL, mu, nc, r, v, NULL);
}

/* ---- a problem owned by the tests ------------------------------------------------------- */

/* A global or local problem held in plain arrays, the library not involved: filled by the
 * independent FCLib reader (fclib_read.h, where it is also called fcr_problem) or by a test's
 * own generator. Zero-initialize before filling; tu_problem_free releases what is set. */
typedef struct tu_problem {
    int is_global;   /* 1: global (M, H, f, w), 0: local (W, q) */
    int has_joints;  /* fclib_read: the file has a G matrix (which it does not read) */
    size_t n;        /* velocities (global), 0 for local */
    size_t nc;       /* contacts */
    tu_csc M, H;     /* global: n x n, n x 3nc */
    tu_csc W;        /* local: 3nc x 3nc */
    double *f, *w;   /* global: n, 3nc */
    double *q;       /* local: 3nc */
    double *mu;      /* nc */
    int encoding[2]; /* fclib_read: nz code seen for (M, H) or (W, -): -1, -2 or >= 0 */
    tu_csc G;        /* joints of a generated global problem: n x p (p = 0: none) */
    double *b;       /* p */
} tu_problem;

static inline void tu_problem_free(tu_problem *p)
{
    if (p == NULL) return;
    tu_csc_free(&p->M);
    tu_csc_free(&p->H);
    tu_csc_free(&p->W);
    tu_csc_free(&p->G);
    free(p->f);
    free(p->w);
    free(p->q);
    free(p->mu);
    free(p->b);
    memset(p, 0, sizeof(*p));
}

/* Number of joints (columns of G) of a problem. */
static inline size_t tu_problem_joints(const tu_problem *p)
{
    return (p->is_global && p->G.colptr != NULL) ? p->G.ncols : 0;
}

/* The independent error of a candidate (r, v, lambda) for `p` (lambda: one entry per joint;
 * not read without joints; v not read for a local problem). */
static inline double tu_problem_error(const tu_problem *p, const double *r, const double *v,
                                      const double *lambda)
{
    if (!p->is_global) return tu_local_error(&p->W, p->q, p->mu, p->nc, r);
    return tu_global_error_joints(&p->M, &p->H, tu_problem_joints(p) ? &p->G : NULL, p->f, p->w,
                                  p->b, p->mu, p->nc, r, v, lambda);
}

/* y += |A| |x| (transposed: y += |A|^T |x|), for round-off bounds. */
static inline void tu_csc_abs_mul(const tu_csc *a, const double *x, int transposed, double *y)
{
    if (a == NULL || a->colptr == NULL) return;
    for (size_t j = 0; j < a->ncols; ++j)
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k) {
            if (transposed)
                y[j] += fabs(a->values[k]) * fabs(x[a->rowind[k]]);
            else
                y[a->rowind[k]] += fabs(a->values[k]) * fabs(x[j]);
        }
}

/* The largest number of entries in a row (transposed: in a column) of A. */
static inline size_t tu_csc_max_terms(const tu_csc *a, int transposed)
{
    size_t best = 0;
    if (a == NULL || a->colptr == NULL) return 0;
    if (transposed) {
        for (size_t j = 0; j < a->ncols; ++j)
            if ((size_t)(a->colptr[j + 1] - a->colptr[j]) > best)
                best = (size_t)(a->colptr[j + 1] - a->colptr[j]);
    } else {
        size_t *count = (size_t *)tu_calloc(a->nrows, sizeof(size_t));
        for (int64_t k = 0; k < a->colptr[a->ncols]; ++k)
            if (++count[a->rowind[k]] > best) best = count[a->rowind[k]];
        free(count);
    }
    return best;
}

/* ||y|| for y = gamma (|A| |x| + |c|) (+ |B| |z| when B is given): the standard bound on the
 * rounding error of A x + B z + c computed in floating point, gamma = (k + 2) eps with k
 * the terms of the longest sum (twice the classical k u / (1 - k u)). */
static inline double tu_residual_roundoff(const tu_csc *A, const double *x, int at,
                                          const tu_csc *B, const double *z, const tu_csc *C,
                                          const double *zc, const double *c, size_t len)
{
    const double eps = 2.220446049250313e-16;
    size_t k = tu_csc_max_terms(A, at) + (B ? tu_csc_max_terms(B, 0) : 0) +
               (C ? tu_csc_max_terms(C, 0) : 0) + 1;
    double *y = (double *)tu_calloc(len, sizeof(double)), e;
    tu_csc_abs_mul(A, x, at, y);
    if (B != NULL) tu_csc_abs_mul(B, z, 0, y);
    if (C != NULL) tu_csc_abs_mul(C, zc, 0, y);
    if (c != NULL)
        for (size_t i = 0; i < len; ++i) y[i] += fabs(c[i]);
    e = (double)(k + 2) * eps * tu_norm(y, len);
    free(y);
    return e;
}

/* An estimate of the round-off in evaluating the measure of (r, v, lambda) for `p`: two
 * correct implementations that sum in different orders can differ by about this much
 * (absolute). The residuals (M v - H r - G lambda - f, u = W r + q or H^T v + w, G^T v + b)
 * carry the rounding errors bounded by tu_residual_roundoff, counted four times (two
 * evaluations, each within the bound, and a margin: on Confeti-ex03 the library's value
 * and this file's differ by 0.8 of the single bound); the natural map moves by at
 * most (1 + mu) times the error in u (the projection is 1-Lipschitz, Phi is mu-Lipschitz);
 * each term is then divided by its denominator. The estimate is tiny for well-scaled
 * answers and grows when the residuals are small differences of large terms (an
 * ill-conditioned file, a huge r in the null space of a singular W): there the two
 * evaluations legitimately differ in their leading digits. */
static inline double tu_problem_error_roundoff(const tu_problem *p, const double *r,
                                               const double *v, const double *lambda)
{
    size_t m = 3 * p->nc, np = tu_problem_joints(p);
    double mu_max = 0.0, e;
    for (size_t c = 0; c < p->nc; ++c) mu_max = tu_max(mu_max, p->mu[c]);
    if (!p->is_global) {
        double nq = tu_norm(p->q, m);
        double du = tu_residual_roundoff(&p->W, r, 0, NULL, NULL, NULL, NULL, p->q, m);
        e = 4.0 * (1.0 + mu_max) * du / (nq > 0.0 ? nq : 1.0);
        return isfinite(e) ? e : INFINITY;
    }
    {
        size_t n = p->n;
        double *mv = (double *)tu_calloc(n, sizeof(double));
        double *hr = (double *)tu_calloc(n, sizeof(double));
        double *u = (double *)tu_calloc(m, sizeof(double));
        double *gv = (double *)tu_calloc(np, sizeof(double));
        double den1, den2, deq, du;
        deq = tu_residual_roundoff(&p->M, v, 0, &p->H, r, np > 0 ? &p->G : NULL, lambda, p->f, n);
        tu_csc_mul(&p->M, v, 0, mv);
        tu_csc_mul(&p->H, r, 0, hr);
        if (np > 0) tu_csc_mul(&p->G, lambda, 1, hr);
        den1 = tu_max(tu_norm(p->f, n), tu_max(tu_norm(mv, n), tu_norm(hr, n)));
        du = tu_residual_roundoff(&p->H, v, 1, NULL, NULL, NULL, NULL, p->w, m);
        if (m > 0) memcpy(u, p->w, m * sizeof(double));
        tu_csc_mul_t(&p->H, v, 1, u);
        den2 = tu_max(tu_norm(u, m), tu_norm(r, m));
        e = deq / (den1 > 0.0 ? den1 : 1.0) +
            (1.0 + mu_max) * du / (den2 > 0.0 ? den2 : 1.0);
        if (np > 0) {
            double dj = tu_residual_roundoff(&p->G, v, 1, NULL, NULL, NULL, NULL, p->b, np), den3;
            tu_csc_mul_t(&p->G, v, 0, gv);
            den3 = tu_max(tu_norm(gv, np), tu_norm(p->b, np));
            e += dj / (den3 > 0.0 ? den3 : 1.0);
        }
        free(mv);
        free(hr);
        free(u);
        free(gv);
        e *= 4.0;
        return isfinite(e) ? e : INFINITY;
    }
}

/* ---- an a priori bound on the impulses of a genuine solution ----------------------------- */

/* Problems up to this size (3 nc and n) get the dense bound below; larger ones none. */
#define TU_DENSE_MAX 60

/* Row-major dense copy of a CSC matrix. */
static inline double *tu_csc_dense(const tu_csc *a)
{
    double *d = (double *)tu_calloc(a->nrows * a->ncols, sizeof(double));
    for (size_t j = 0; j < a->ncols; ++j)
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k)
            d[(size_t)a->rowind[k] * a->ncols + j] += a->values[k];
    return d;
}

/* In-place inverse of a symmetric positive definite n x n row-major matrix (Cholesky, then
 * the n solves of the identity). Returns 0 when a pivot is not positive. */
static inline int tu_spd_inverse(size_t n, double *a)
{
    double *l = (double *)tu_calloc(n * n, sizeof(double));
    double *x = (double *)tu_calloc(n, sizeof(double));
    int ok = 1;
    for (size_t j = 0; j < n && ok; ++j) {
        double d = a[j * n + j];
        for (size_t k = 0; k < j; ++k) d -= l[j * n + k] * l[j * n + k];
        if (!(d > 0.0)) ok = 0;
        else {
            l[j * n + j] = sqrt(d);
            for (size_t i = j + 1; i < n; ++i) {
                double s = a[i * n + j];
                for (size_t k = 0; k < j; ++k) s -= l[i * n + k] * l[j * n + k];
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    for (size_t c = 0; c < n && ok; ++c) {
        for (size_t i = 0; i < n; ++i) { /* L y = e_c */
            double s = i == c ? 1.0 : 0.0;
            for (size_t k = 0; k < i; ++k) s -= l[i * n + k] * x[k];
            x[i] = s / l[i * n + i];
        }
        for (size_t i = n; i-- > 0;) { /* L^T x = y */
            double s = x[i];
            for (size_t k = i + 1; k < n; ++k) s -= l[k * n + i] * x[k];
            x[i] = s / l[i * n + i];
        }
        for (size_t i = 0; i < n; ++i) a[i * n + c] = x[i];
    }
    free(l);
    free(x);
    return ok;
}

/* Smallest and largest eigenvalues of a symmetric n x n row-major matrix (cyclic Jacobi;
 * `a` is overwritten). */
static inline void tu_sym_eig_range(size_t n, double *a, double *lmin, double *lmax)
{
    for (int sweep = 0; sweep < 100; ++sweep) {
        double off = 0.0, diag = 0.0;
        for (size_t i = 0; i < n; ++i) {
            diag += a[i * n + i] * a[i * n + i];
            for (size_t j = i + 1; j < n; ++j) off += a[i * n + j] * a[i * n + j];
        }
        if (off <= 1e-32 * diag || off == 0.0) break;
        for (size_t p = 0; p < n; ++p)
            for (size_t q = p + 1; q < n; ++q) {
                double apq = a[p * n + q], theta, t, c, s;
                if (apq == 0.0) continue;
                theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                s = t * c;
                for (size_t k = 0; k < n; ++k) { /* columns p, q */
                    double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for (size_t k = 0; k < n; ++k) { /* rows p, q */
                    double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
            }
    }
    *lmin = INFINITY;
    *lmax = -INFINITY;
    for (size_t i = 0; i < n; ++i) {
        *lmin = a[i * n + i] < *lmin ? a[i * n + i] : *lmin;
        *lmax = a[i * n + i] > *lmax ? a[i * n + i] : *lmax;
    }
}

/* A bound B, set by the problem's data alone, on ||r|| for every genuine solution, or
 * +inf when there is none to give (W singular or nearly, or the problem too large for
 * dense algebra).
 *
 * Every problem is, in the impulses, u = W r + q: W itself for a local problem; for a
 * global one v = P (H r + f) - M^-1 G S^-1 b (S = G^T M^-1 G, P = M^-1 - M^-1 G S^-1 G^T
 * M^-1; without joints P = M^-1 and the b term is absent), so W = H^T P H and q = H^T (P f -
 * M^-1 G S^-1 b) + w. At a genuine solution r is in K, u + Phi(u) in K* and
 * r . (u + Phi(u)) = 0; since r . Phi(u) = sum r_N mu ||u_T|| >= 0, r . u <= 0, that is
 * r^T W r <= -q . r <= ||q|| ||r||, and when W is positive definite,
 *     ||r|| <= ||q|| / lambda_min(W) = B.
 * The bound is only given when lambda_min(W) > 1e-6 lambda_max(W): for a singular W the
 * solution set can be unbounded (impulses in the null space of W, a body wedged between
 * two contacts), and no bound on ||r|| is sound. */
static inline double tu_problem_solution_bound(const tu_problem *p)
{
    size_t m = 3 * p->nc, n = p->n, np = tu_problem_joints(p);
    double *W, *q, lmin, lmax, bound;
    if (m == 0 || m > TU_DENSE_MAX || n > TU_DENSE_MAX || np > TU_DENSE_MAX) return INFINITY;
    q = (double *)tu_calloc(m, sizeof(double));
    if (!p->is_global) {
        W = tu_csc_dense(&p->W);
        memcpy(q, p->q, m * sizeof(double));
    } else {
        double *Mi = tu_csc_dense(&p->M), *H = tu_csc_dense(&p->H), *P, *v0, *PH;
        P = (double *)tu_calloc(n * n, sizeof(double));
        v0 = (double *)tu_calloc(n, sizeof(double));
        PH = (double *)tu_calloc(n * m, sizeof(double));
        W = (double *)tu_calloc(m * m, sizeof(double));
        if (!tu_spd_inverse(n, Mi)) {
            free(Mi), free(H), free(P), free(v0), free(PH), free(W), free(q);
            return INFINITY;
        }
        memcpy(P, Mi, n * n * sizeof(double));
        for (size_t i = 0; i < n; ++i)
            for (size_t k = 0; k < n; ++k) v0[i] += Mi[i * n + k] * p->f[k];
        if (np > 0) {
            /* MG = M^-1 G (n x np), S = G^T M^-1 G, then P -= MG S^-1 MG^T and
               v0 = P f - MG S^-1 b */
            double *G = tu_csc_dense(&p->G);
            double *MG = (double *)tu_calloc(n * np, sizeof(double));
            double *S = (double *)tu_calloc(np * np, sizeof(double));
            double *y = (double *)tu_calloc(np, sizeof(double));
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j < np; ++j)
                    for (size_t k = 0; k < n; ++k) MG[i * np + j] += Mi[i * n + k] * G[k * np + j];
            for (size_t i = 0; i < np; ++i)
                for (size_t j = 0; j < np; ++j)
                    for (size_t k = 0; k < n; ++k) S[i * np + j] += G[k * np + i] * MG[k * np + j];
            if (!tu_spd_inverse(np, S)) {
                free(G), free(MG), free(S), free(y), free(Mi), free(H), free(P), free(v0);
                free(PH), free(W), free(q);
                return INFINITY;
            }
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j < n; ++j)
                    for (size_t a = 0; a < np; ++a)
                        for (size_t b = 0; b < np; ++b)
                            P[i * n + j] -= MG[i * np + a] * S[a * np + b] * MG[j * np + b];
            for (size_t i = 0; i < n; ++i) v0[i] = 0.0;
            for (size_t i = 0; i < n; ++i)
                for (size_t k = 0; k < n; ++k) v0[i] += P[i * n + k] * p->f[k];
            for (size_t a = 0; a < np; ++a)
                for (size_t b = 0; b < np; ++b) y[a] += S[a * np + b] * p->b[b];
            for (size_t i = 0; i < n; ++i)
                for (size_t a = 0; a < np; ++a) v0[i] -= MG[i * np + a] * y[a];
            free(G), free(MG), free(S), free(y);
        }
        for (size_t i = 0; i < n; ++i)
            for (size_t j = 0; j < m; ++j)
                for (size_t k = 0; k < n; ++k) PH[i * m + j] += P[i * n + k] * H[k * m + j];
        for (size_t i = 0; i < m; ++i)
            for (size_t j = 0; j < m; ++j)
                for (size_t k = 0; k < n; ++k) W[i * m + j] += H[k * m + i] * PH[k * m + j];
        for (size_t i = 0; i < m; ++i) {
            q[i] = p->w[i];
            for (size_t k = 0; k < n; ++k) q[i] += H[k * m + i] * v0[k];
        }
        free(Mi), free(H), free(P), free(v0), free(PH);
    }
    for (size_t i = 0; i < m; ++i) /* the symmetric part: r^T W r only sees it */
        for (size_t j = 0; j < i; ++j)
            W[i * m + j] = W[j * m + i] = 0.5 * (W[i * m + j] + W[j * m + i]);
    tu_sym_eig_range(m, W, &lmin, &lmax);
    bound = (lmax > 0.0 && lmin > 1e-6 * lmax) ? tu_norm(q, m) / lmin : INFINITY;
    free(W);
    free(q);
    return bound;
}

/* ---- status names, messages, random numbers --------------------------------------------- */

/* Name of a cadmm_status value (the CADMM_STATUS_* codes: 0 solved, 1 max iterations,
 * 2 time limit, 3 numerical error, 4 stalled). */
static inline const char *tu_status_name(int status)
{
    switch (status) {
    case 0: return "solved";
    case 1: return "max_iterations";
    case 2: return "time_limit";
    case 3: return "numerical_error";
    case 4: return "stalled";
    case 5: return "infeasible";
    case 6: return "unsolved";
    default: return "(not a status)";
    }
}

/* Does `text` contain `word` delimited by characters that cannot be part of a name (not a
 * letter, digit or '_')? "M" is found in "matrix M: row" and "M + rho H H^T" but not in
 * "Matrix" or "NUM". */
static inline int tu_has_word(const char *text, const char *word)
{
    size_t len = strlen(word);
    const char *p = text;
    if (text == NULL || len == 0) return 0;
    while ((p = strstr(p, word)) != NULL) {
        int before = p == text ? 0 : (p[-1] == '_' || isalnum((unsigned char)p[-1]));
        int after = p[len] == '_' || isalnum((unsigned char)p[len]);
        if (!before && !after) return 1;
        ++p;
    }
    return 0;
}

/* xorshift64* generator with a fixed seed: the same sequence on every platform. */
typedef struct tu_rng {
    uint64_t s;
} tu_rng;

static inline tu_rng tu_rng_new(uint64_t seed)
{
    tu_rng g;
    g.s = seed ? seed : 0x9E3779B97F4A7C15ull;
    return g;
}

static inline uint64_t tu_rng_next(tu_rng *g)
{
    g->s ^= g->s >> 12;
    g->s ^= g->s << 25;
    g->s ^= g->s >> 27;
    return g->s * 0x2545F4914F6CDD1Dull;
}

/* Uniform in [0, 1). */
static inline double tu_rng_uniform(tu_rng *g)
{
    return (double)(tu_rng_next(g) >> 11) * 0x1.0p-53;
}

/* Uniform in [a, b). */
static inline double tu_rng_range(tu_rng *g, double a, double b)
{
    return a + (b - a) * tu_rng_uniform(g);
}

/* Uniform integer in [0, n). */
static inline size_t tu_rng_index(tu_rng *g, size_t n) { return (size_t)(tu_rng_next(g) % n); }

/* ---- generated problems ------------------------------------------------------------------- */

/* A global problem with nb free bodies of 3 velocities (M block diagonal SPD with a coupling
 * inside each block) and nc contacts, contact k between body k mod nb and the body below it
 * (the ground for the first nb contacts when chain != 0, otherwise a random body or the
 * ground), frames the identity plus a perturbation; f pushes the bodies down and sideways. */
static inline tu_problem tu_gen_global(tu_rng *g, size_t nb, size_t nc, double mu, int chain)
{
    tu_problem p;
    size_t n = 3 * nb, m = 3 * nc;
    double *Md = (double *)tu_calloc(n * n, sizeof(double));
    double *Hd = (double *)tu_calloc(n * m, sizeof(double));
    memset(&p, 0, sizeof p);
    p.is_global = 1;
    p.n = n;
    p.nc = nc;
    for (size_t b = 0; b < nb; ++b) {
        double mass = tu_rng_range(g, 0.5, 4.0), c = tu_rng_range(g, -0.2, 0.2);
        for (size_t i = 0; i < 3; ++i) Md[(3 * b + i) * n + 3 * b + i] = mass;
        Md[(3 * b) * n + 3 * b + 1] = Md[(3 * b + 1) * n + 3 * b] = c * mass;
    }
    for (size_t k = 0; k < nc; ++k) {
        size_t b1, b2; /* b2 == nb: the ground */
        if (chain) {
            b1 = k % nb;
            b2 = k < nb ? (k == 0 ? nb : k - 1) : tu_rng_index(g, nb + 1);
        } else {
            b1 = tu_rng_index(g, nb);
            b2 = tu_rng_index(g, nb + 1);
        }
        for (size_t i = 0; i < 3; ++i)
            for (size_t j = 0; j < 3; ++j) {
                double h = (i == j ? 1.0 : 0.0) + tu_rng_range(g, -0.3, 0.3);
                Hd[(3 * b1 + i) * m + 3 * k + j] += h;
                if (b2 < nb && b2 != b1) Hd[(3 * b2 + i) * m + 3 * k + j] -= h;
            }
    }
    p.M = tu_csc_from_dense(n, n, Md);
    p.H = tu_csc_from_dense(n, m, Hd);
    p.f = (double *)tu_calloc(n, sizeof(double));
    p.w = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    for (size_t i = 0; i < n; ++i) p.f[i] = tu_rng_range(g, -1.0, 1.0) - (i % 3 == 0 ? 2.0 : 0.0);
    for (size_t i = 0; i < m; ++i) p.w[i] = tu_rng_range(g, -0.05, 0.05);
    for (size_t k = 0; k < nc; ++k) p.mu[k] = mu;
    free(Md);
    free(Hd);
    return p;
}

/* A local problem W = A^T A + 0.1 I (A random 3nc x 3nc, so W is dense: every entry is a
 * non-zero), q random with q_N < 0. Two calls give the same pattern, other values. */
static inline tu_problem tu_gen_local(tu_rng *g, size_t nc, double mu)
{
    tu_problem p;
    size_t m = 3 * nc;
    double *A = (double *)tu_calloc(m * m, sizeof(double));
    double *Wd = (double *)tu_calloc(m * m, sizeof(double));
    memset(&p, 0, sizeof p);
    p.nc = nc;
    for (size_t i = 0; i < m * m; ++i) A[i] = tu_rng_range(g, -1.0, 1.0);
    for (size_t i = 0; i < m; ++i)
        for (size_t j = 0; j < m; ++j) {
            double s = i == j ? 0.1 : 0.0;
            for (size_t k = 0; k < m; ++k) s += A[k * m + i] * A[k * m + j];
            Wd[i * m + j] = s;
        }
    p.W = tu_csc_from_dense(m, m, Wd);
    REQUIRE((size_t)p.W.colptr[m] == m * m);
    p.q = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    for (size_t i = 0; i < m; ++i) p.q[i] = tu_rng_range(g, -1.0, 1.0) - (i % 3 == 0 ? 1.0 : 0.0);
    for (size_t k = 0; k < nc; ++k) p.mu[k] = mu;
    free(A);
    free(Wd);
    return p;
}

/* ---- solving a tu_problem through the C API (needs cadmm.h included first) ------------- */
#ifdef CADMM_H

/* Name of a cadmm_result code. */
static inline const char *tu_result_name(cadmm_result c)
{
    switch (c) {
    case CADMM_OK: return "CADMM_OK";
    case CADMM_ERR_NULL_POINTER: return "CADMM_ERR_NULL_POINTER";
    case CADMM_ERR_DIMENSION: return "CADMM_ERR_DIMENSION";
    case CADMM_ERR_INVALID_CSC: return "CADMM_ERR_INVALID_CSC";
    case CADMM_ERR_INVALID_VALUE: return "CADMM_ERR_INVALID_VALUE";
    case CADMM_ERR_NOT_POSITIVE_DEFINITE: return "CADMM_ERR_NOT_POSITIVE_DEFINITE";
    case CADMM_ERR_SINGULAR: return "CADMM_ERR_SINGULAR";
    case CADMM_ERR_INVALID_SETTING: return "CADMM_ERR_INVALID_SETTING";
    case CADMM_ERR_IO: return "CADMM_ERR_IO";
    case CADMM_ERR_UNSUPPORTED: return "CADMM_ERR_UNSUPPORTED";
    case CADMM_ERR_PANIC: return "CADMM_ERR_PANIC";
    case CADMM_ERR_PATTERN_CHANGED: return "CADMM_ERR_PATTERN_CHANGED";
    case CADMM_ERR_OUT_OF_MEMORY: return "CADMM_ERR_OUT_OF_MEMORY";
    default: return "(unknown code)";
    }
}

/* A call must return `expected`; the failure names both codes and the last error message. */
#define EXPECT_RC(expr, expected)                                                         \
    do {                                                                                  \
        cadmm_result rc_ = (expr);                                                        \
        if (rc_ != (expected))                                                            \
            TU_FAIL("%s returned %s (%d), expected %s (message: \"%s\")", #expr,          \
                    tu_result_name(rc_), (int)rc_, tu_result_name(expected), cadmm_last_error());   \
    } while (0)

#define REQUIRE_OK(expr) REQUIRE((expr) == CADMM_OK)


/* Builds the library's copy of `p` (global or local, with its joints). On failure returns
 * the code and leaves *out NULL. */
static inline cadmm_result tu_problem_to_cadmm(const tu_problem *p, cadmm_problem **out)
{
    cadmm_result rc;
    *out = NULL;
    if (p->is_global) {
        cadmm_csc M = tu_csc_view(&p->M), H = tu_csc_view(&p->H);
        rc = cadmm_problem_new_global(p->n, p->nc, &M, &H, p->f, p->w, p->mu, out);
        if (rc == CADMM_OK && tu_problem_joints(p) > 0) {
            cadmm_csc G = tu_csc_view(&p->G);
            rc = cadmm_problem_set_joints(*out, &G, p->b);
            if (rc != CADMM_OK) {
                cadmm_problem_free(*out);
                *out = NULL;
            }
        }
    } else {
        cadmm_csc W = tu_csc_view(&p->W);
        rc = cadmm_problem_new_local(p->nc, &W, p->q, p->mu, out);
    }
    return rc;
}

/* tu_problem_to_cadmm that must succeed: a failure stops the test with the library's message. */
static inline cadmm_problem *tu_require_problem(const tu_problem *p)
{
    cadmm_problem *lib = NULL;
    cadmm_result rc = tu_problem_to_cadmm(p, &lib);
    if (rc != CADMM_OK)
        fprintf(stderr, "building a problem failed: %s (%s)\n", tu_result_name(rc), cadmm_last_error());
    REQUIRE(rc == CADMM_OK && lib != NULL);
    return lib;
}

/* What one solve returned. */
typedef struct tu_outcome {
    cadmm_result rc;  /* of cadmm_solver_new, then of cadmm_solver_solve */
    int solved_call;  /* 1 when cadmm_solver_solve was reached and returned CADMM_OK */
    cadmm_status status;
    cadmm_stats stats;
    double *r, *u, *v, *lambda; /* 3nc, 3nc, n, p */
    double e_ind;     /* independent error of (r, v, lambda) */
    double e_lib;     /* cadmm_problem_error of (r, u, v) */
    char message[256]; /* cadmm_last_error() of a failed call */
} tu_outcome;

static inline void tu_outcome_free(tu_outcome *o)
{
    free(o->r);
    free(o->u);
    free(o->v);
    free(o->lambda);
    o->r = o->u = o->v = o->lambda = NULL;
}

/* Creates a solver for `lib` (the library's copy of `p`) with `s`, solves once and reads
 * back everything. */
static inline void tu_solve(const tu_problem *p, const cadmm_problem *lib, const cadmm_settings *s,
                            tu_outcome *o)
{
    cadmm_solver *sv = NULL;
    size_t m = 3 * p->nc, np = tu_problem_joints(p), got = 0;
    memset(o, 0, sizeof(*o));
    o->status = -1;
    o->r = (double *)tu_calloc(m, sizeof(double));
    o->u = (double *)tu_calloc(m, sizeof(double));
    o->v = (double *)tu_calloc(p->n, sizeof(double));
    o->lambda = (double *)tu_calloc(np, sizeof(double));
    o->e_ind = o->e_lib = NAN;
    o->rc = cadmm_solver_new(lib, s, &sv);
    if (o->rc != CADMM_OK) {
        snprintf(o->message, sizeof o->message, "cadmm_solver_new: %s", cadmm_last_error());
        return;
    }
    o->rc = cadmm_solver_solve(sv, &o->status);
    if (o->rc != CADMM_OK) {
        snprintf(o->message, sizeof o->message, "cadmm_solver_solve: %s", cadmm_last_error());
        cadmm_solver_free(sv);
        return;
    }
    o->solved_call = 1;
    o->stats.struct_size = sizeof o->stats;
    REQUIRE(cadmm_solver_get_stats(sv, &o->stats) == CADMM_OK);
    REQUIRE(cadmm_solver_get_solution(sv, o->r, o->u, p->is_global ? o->v : NULL) == CADMM_OK);
    REQUIRE(cadmm_solver_get_joint_multipliers(sv, o->lambda, &got) == CADMM_OK);
    REQUIRE(got == np);
    o->e_ind = tu_problem_error(p, o->r, o->v, o->lambda);
    REQUIRE(cadmm_problem_error(lib, o->r, o->u, o->v, &o->e_lib) == CADMM_OK);
    cadmm_solver_free(sv);
}

/* Largest round-off allowance (times tol) on the error of a SOLVED answer: the estimate
 * R of tu_problem_error_roundoff grows with |W| |r| (and 1 + mu) without bound, so an
 * answer far above tol could otherwise pass as solved. Measured at tol 1e-8: on the FCLib
 * set R is at most 7.2e-4 tol (GFC3D_OneContact); on test_random's SOLVED answers at most
 * 4.9e-5 tol, except with mu = 1e8 where the factor 1 + mu takes it to 1.1e2 tol. Every
 * one of those answers has e <= tol itself (at most 0.96 tol), so the cap takes nothing
 * the library's answers need. */
#define TU_ROUNDOFF_CAP 1e-3

/* A SOLVED answer may exceed the a priori bound of tu_problem_solution_bound (exact for a
 * genuine solution) by this factor: it is only approximately complementary. */
#define TU_SOLUTION_BOUND_FACTOR 2.0

/* The checks every solve must pass, whatever its status (`label` names it in failures):
 *  - r, u (and v, lambda) finite, and u = W r + q (local) or H^T v + w (global);
 *  - stats.status is the status the solve returned;
 *  - the status agrees with the independent error e of the returned answer: SOLVED means
 *    e <= tol (1 + slack) + min(R, TU_ROUNDOFF_CAP tol), any other status e > tol - R,
 *    where R is the round-off estimate of tu_problem_error_roundoff (the library decided on
 *    its own evaluation, which sums in another order);
 *  - SOLVED: ||r|| <= TU_SOLUTION_BOUND_FACTOR ||q|| / lambda_min(W), the bound every genuine
 *    solution meets (tu_problem_solution_bound; checked on small problems with W positive
 *    definite): a false SOLVED reached by impulses that ran off has a small relative
 *    measure (its denominators grow with ||r||, ||H r||, ||M v||) and a huge ||r||;
 *  - cadmm_problem_error of the answer is e: |e_lib - e| <= agree e + R + 1e-15 (with
 *    joints e_lib <= e (1 + agree) + R + 1e-15, its lambda being the least-squares one);
 *  - stats.error is e, with the same bound, or both are +inf (an answer too large for the
 *    measure's norms).
 * Returns the number of failed checks. */
static inline int tu_check_outcome(const char *label, const tu_problem *p, const tu_outcome *o,
                                   double tol, double slack, double agree)
{
    int before = *tu_failures();
    size_t m = 3 * p->nc, np = tu_problem_joints(p);
    double *u_ref, R;
    if (!o->solved_call) {
        TU_FAIL("%s: no solve (code %d: %s)", label, (int)o->rc, o->message);
        return *tu_failures() - before;
    }
    CHECK_MSG(o->stats.status == o->status, "%s: stats.status %d, solve returned %d", label,
              (int)o->stats.status, (int)o->status);
    CHECK_MSG(o->status >= CADMM_STATUS_SOLVED && o->status <= CADMM_STATUS_INFEASIBLE,
              "%s: status %d is not a cadmm_status", label, (int)o->status);
    CHECK_MSG(tu_all_finite(o->r, m) && tu_all_finite(o->u, m), "%s: r or u is not finite (%s)",
              label, tu_status_name(o->status));
    CHECK_MSG(tu_all_finite(o->v, p->n), "%s: v is not finite (%s)", label,
              tu_status_name(o->status));
    CHECK_MSG(tu_all_finite(o->lambda, np), "%s: lambda is not finite (%s)", label,
              tu_status_name(o->status));
    u_ref = (double *)tu_calloc(m, sizeof(double));
    if (p->is_global) {
        if (m > 0) memcpy(u_ref, p->w, m * sizeof(double));
        tu_csc_mul_t(&p->H, o->v, 1, u_ref);
    } else {
        if (m > 0) memcpy(u_ref, p->q, m * sizeof(double));
        tu_csc_mul(&p->W, o->r, 1, u_ref);
    }
    CHECK_MSG(tu_diff_norm(o->u, u_ref, m) <= 1e-10 * tu_max(1.0, tu_norm(u_ref, m)),
              "%s: the returned u is not %s (difference %.3e)", label,
              p->is_global ? "H^T v + w" : "W r + q", tu_diff_norm(o->u, u_ref, m));
    free(u_ref);
    R = tu_problem_error_roundoff(p, o->r, o->v, o->lambda) + 1e-15;
    if (o->status == CADMM_STATUS_INFEASIBLE) {
        /* Farkas, checked here on the returned impulses: y = r / ||r|| in the friction cone,
           pushing nothing (H y or W y about 0), against approaching velocities
           (y . (u + mu ||u_T|| e_N) < 0). The error may be anything (it fades with r). */
        double rn = tu_norm(o->r, m), opn = 0, dot = 0, cone = 0, *img;
        size_t rows = p->is_global ? p->n : m;
        const tu_csc *op = p->is_global ? &p->H : &p->W;
        img = (double *)tu_calloc(rows ? rows : 1, sizeof(double));
        tu_csc_mul(op, o->r, 0, img);
        for (size_t k = 0; k < (size_t)op->colptr[op->ncols]; ++k) opn += op->values[k] * op->values[k];
        for (size_t i = 0; i < p->nc; ++i) {
            const double *ri = o->r + 3 * i, *ui = o->u + 3 * i;
            double ut = hypot(ui[1], ui[2]);
            dot += ri[0] * (ui[0] + p->mu[i] * ut) + ri[1] * ui[1] + ri[2] * ui[2];
            cone = tu_max(cone, hypot(ri[1], ri[2]) - p->mu[i] * ri[0]);
        }
        CHECK_MSG(rn > 0 && tu_norm(img, rows) <= 1e-5 * sqrt(opn) * rn && dot < 0 &&
                      cone <= 1e-6 * rn,
                  "%s: INFEASIBLE without a certificate (||r|| %.3e, ||op r|| / ||op|| ||r|| "
                  "%.3e, r . u~ %.3e, cone violation %.3e)", label, rn,
                  tu_norm(img, rows) / (sqrt(opn) * rn), dot, cone / rn);
        free(img);
    } else if (o->status == CADMM_STATUS_SOLVED) {
        /* the round-off allowance is capped: past TU_ROUNDOFF_CAP tol an answer the
           library calls solved must be checkably so, whatever |W| |r| is */
        double Rs = R < TU_ROUNDOFF_CAP * tol ? R : TU_ROUNDOFF_CAP * tol;
        double B = tu_problem_solution_bound(p), rn = tu_norm(o->r, m);
        CHECK_MSG(o->e_ind <= tol * (1.0 + slack) + Rs, "%s: SOLVED but the independent error "
                  "is %.6e > tol %.1e (round-off estimate %.1e, allowed %.1e)", label,
                  o->e_ind, tol, R, Rs);
        /* the measure is relative to the answer's own size, so impulses that ran off make it
           small: ||r|| must also stay within the problem's own bound (+inf: none given) */
        CHECK_MSG(!(rn > TU_SOLUTION_BOUND_FACTOR * B), "%s: SOLVED but ||r|| = %.6e exceeds "
                  "%g ||q|| / lambda_min(W) = %.6e, which bounds every genuine solution",
                  label, rn, TU_SOLUTION_BOUND_FACTOR, TU_SOLUTION_BOUND_FACTOR * B);
    } else
        CHECK_MSG(o->e_ind > tol - R, "%s: %s but the independent error is %.6e <= tol %.1e "
                  "(round-off estimate %.1e)", label, tu_status_name(o->status), o->e_ind, tol,
                  R);
    /* without joints cadmm_problem_error measures exactly what e does (with joints it
       recomputes lambda by least squares, docs/algorithms.md §3.2, and may be smaller) */
    if (np == 0)
        CHECK_MSG((isinf(o->e_lib) && isinf(o->e_ind)) ||
                      fabs(o->e_lib - o->e_ind) <= agree * o->e_ind + R,
                  "%s: cadmm_problem_error %.15e, independent error %.15e (round-off "
                  "estimate %.1e)", label, o->e_lib, o->e_ind, R);
    else
        CHECK_MSG(o->e_lib <= o->e_ind * (1.0 + agree) + R,
                  "%s: cadmm_problem_error %.15e (least-squares lambda) above the independent "
                  "error %.15e (solver's lambda)", label, o->e_lib, o->e_ind);
    CHECK_MSG((isinf(o->stats.error) && isinf(o->e_ind)) ||
                  fabs(o->stats.error - o->e_ind) <= agree * o->e_ind + R,
              "%s: stats.error %.15e, independent error of the returned answer %.15e "
              "(round-off estimate %.1e)", label, o->stats.error, o->e_ind, R);
    return *tu_failures() - before;
}

#endif /* CADMM_H */

#ifdef __cplusplus
}
#endif

#endif /* CADMM_TEST_UTIL_H */
