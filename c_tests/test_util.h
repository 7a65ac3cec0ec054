/* Shared helpers of the cadmm C/C++ tests: checks, the FCLib data directory, a small owned
 * CSC type, and an independent implementation of the error measure of
 * docs/algorithms.md §3 (it does not call the library, so it can be compared with
 * cadmm_problem_error).
 *
 * Everything is `static inline` so each test program includes it without a separate
 * translation unit and without unused-function warnings. Valid C99 and C++17. */
#ifndef CADMM_TEST_UTIL_H
#define CADMM_TEST_UTIL_H

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

static inline double tu_norm(const double *x, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; ++i) s += x[i] * x[i];
    return sqrt(s);
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
    double s = 0.0;
    for (size_t c = 0; c < nc; ++c) {
        const double *ri = r + 3 * c, *ui = u + 3 * c;
        double ut = sqrt(ui[1] * ui[1] + ui[2] * ui[2]);
        double z[3], p[3];
        z[0] = ri[0] - (ui[0] + mu[c] * ut);
        z[1] = ri[1] - ui[1];
        z[2] = ri[2] - ui[2];
        tu_project_cone(z, mu[c], p);
        for (int k = 0; k < 3; ++k) s += (ri[k] - p[k]) * (ri[k] - p[k]);
    }
    return sqrt(s);
}

/* Denominators below this are skipped (docs/algorithms.md §3). */
#define TU_TINY 1.5e-8

static inline double tu_relative(double num, double den) { return den > TU_TINY ? num / den : num; }

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
    memcpy(u, q, m * sizeof(double));
    tu_csc_mul(W, r, 1, u);
    e = tu_relative(tu_natural_map(r, u, mu, nc), tu_norm(q, m));
    free(u);
    return e;
}

/* Global error: ||-M v + H r + f|| / max(||f||, ||M v||, ||H r||)
 *             + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),  u = H^T v + w. */
static inline double tu_global_error(const tu_csc *M, const tu_csc *H, const double *f,
                                     const double *w, const double *mu, size_t nc,
                                     const double *r, const double *v)
{
    size_t n = M->nrows, m = 3 * nc;
    double *mv = (double *)tu_calloc(n, sizeof(double));
    double *hr = (double *)tu_calloc(n, sizeof(double));
    double *eq = (double *)tu_calloc(n, sizeof(double));
    double *u = (double *)tu_calloc(m, sizeof(double));
    double e1, e2;
    if (!tu_all_finite(r, m) || !tu_all_finite(v, n)) {
        free(mv);
        free(hr);
        free(eq);
        free(u);
        return INFINITY;
    }
    tu_csc_mul(M, v, 0, mv);
    tu_csc_mul(H, r, 0, hr);
    for (size_t i = 0; i < n; ++i) eq[i] = -mv[i] + hr[i] + f[i];
    e1 = tu_relative(tu_norm(eq, n),
                     tu_max(tu_norm(f, n), tu_max(tu_norm(mv, n), tu_norm(hr, n))));
    memcpy(u, w, m * sizeof(double));
    tu_csc_mul_t(H, v, 1, u);
    e2 = tu_relative(tu_natural_map(r, u, mu, nc), tu_max(tu_norm(u, m), tu_norm(r, m)));
    free(mv);
    free(hr);
    free(eq);
    free(u);
    return e1 + e2;
}

#ifdef __cplusplus
}
#endif

#endif /* CADMM_TEST_UTIL_H */
