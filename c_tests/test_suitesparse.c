/* Reference checks of cadmm on real FCLib global problems with SuiteSparse CHOLMOD.
 *
 * For each file: read it with our own HDF5 reader (fclib_read.c, independent of the
 * library), build the problem through cadmm_problem_new_global, solve (tol 1e-8), then
 *  1. v against v_ref = M^-1 (H r + f), with a CHOLMOD factorization of M (UMFPACK LU
 *     when M is not symmetric: LMGC_GFC3D_CubeH8 stores only the upper triangle of M, and
 *     the library, like ../shared/tools/fc_error.py, takes M as stored);
 *  2. the error measure of docs/algorithms.md §3 computed here (test_util.h) against
 *     cadmm_problem_error, and against the solver's own statistics;
 *  3. the Delassus form W = H^T M^-1 H, q = H^T M^-1 f + w (same factorization), solved through
 *     cadmm_problem_new_local: each solution must solve the other formulation, and when
 *     W is positive definite (checked with CHOLMOD) the impulses must agree. When W is
 *     singular (redundant contacts, as in the box stacks: four corner contacts per face)
 *     r is not unique, so only u = H^T v + w and the error measures are compared;
 *  4. with the fclib feature: the library's own reader (cadmm_problem_read_fclib) gives the
 *     same problem as ours on every file of global/ and local/ (the 71 of the README):
 *     compressed column (nz = -1), compressed row (nz = -2: Capsules-i125-1213,
 *     LMGC_100_PR_PerioBox) and triplets. Equal error measures at two candidates, and the
 *     same data entry by entry (the library's problem written back with
 *     cadmm_problem_write_fclib and read by ours). Built without the feature, the
 *     comparison is skipped with a note (CI configures with -DCADMM_WITH_FCLIB=ON).
 *
 * Usage: test_suitesparse FCLIB_DATA_DIR (exit 77 = skipped, only when it does not exist). */
#include "cadmm.h"
#include "fclib_read.h"

#include <cholmod.h>
#include <dirent.h>
#include <umfpack.h>
#include <unistd.h>

#ifndef CADMM_TEST_HAVE_FCLIB
#define CADMM_TEST_HAVE_FCLIB 1
#endif

#define TOL 1e-8

/* The UMFPACK calls pass int64_t index arrays as SuiteSparse_long. */
_Static_assert(sizeof(SuiteSparse_long) == sizeof(int64_t), "SuiteSparse_long is 64-bit");

typedef struct file_case {
    const char *file;
    int must_solve; /* the solve must return CADMM_STATUS_SOLVED */
} file_case;

static const file_case FILES[] = {
    {"global/GFC3D_Example1.hdf5", 1},
    {"global/GFC3D_OneContact.hdf5", 1},
    {"global/Box_Stacks-i0122-82-5.hdf5", 1},
    {"global/LMGC_GFC3D_CubeH8.hdf5", 1},
};

static cholmod_common CM;

/* CHOLMOD copy of a CSC matrix (stype 1: symmetric, upper part used; 0: unsymmetric). */
static cholmod_sparse *to_cholmod(const tu_csc *a, int stype)
{
    size_t nnz = (size_t)a->colptr[a->ncols];
    cholmod_sparse *s = cholmod_l_allocate_sparse(a->nrows, a->ncols, nnz, 1, 1, stype,
                                                  CHOLMOD_REAL, &CM);
    REQUIRE(s != NULL);
    SuiteSparse_long *p = (SuiteSparse_long *)s->p, *i = (SuiteSparse_long *)s->i;
    double *x = (double *)s->x;
    for (size_t j = 0; j <= a->ncols; ++j) p[j] = (SuiteSparse_long)a->colptr[j];
    for (size_t k = 0; k < nnz; ++k) {
        i[k] = (SuiteSparse_long)a->rowind[k];
        x[k] = a->values[k];
    }
    return s;
}

/* max |A - A^T| <= rel * max |A| (the library's own criterion for a symmetric matrix). */
static int is_symmetric(const tu_csc *a, double rel)
{
    size_t n = a->nrows;
    double *d, worst = 0.0, scale = 0.0;
    if (a->nrows != a->ncols) return 0;
    d = (double *)tu_calloc(n * n, sizeof(double)); /* only used on small matrices */
    for (size_t j = 0; j < n; ++j)
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k) {
            d[(size_t)a->rowind[k] + j * n] += a->values[k];
            scale = tu_max(scale, fabs(a->values[k]));
        }
    for (size_t j = 0; j < n; ++j)
        for (size_t i = 0; i < j; ++i) worst = tu_max(worst, fabs(d[i + j * n] - d[j + i * n]));
    free(d);
    return worst <= rel * scale;
}

/* Dense column-major n x n array -> owned CSC (exact zeros dropped). */
static tu_csc dense_to_csc(size_t n, const double *d)
{
    tu_csc a;
    size_t nnz = 0, k = 0;
    for (size_t i = 0; i < n * n; ++i) nnz += d[i] != 0.0;
    a.nrows = a.ncols = n;
    a.colptr = (int64_t *)tu_calloc(n + 1, sizeof(int64_t));
    a.rowind = (int64_t *)tu_calloc(nnz, sizeof(int64_t));
    a.values = (double *)tu_calloc(nnz, sizeof(double));
    for (size_t j = 0; j < n; ++j) {
        a.colptr[j] = (int64_t)k;
        for (size_t i = 0; i < n; ++i)
            if (d[i + j * n] != 0.0) {
                a.rowind[k] = (int64_t)i;
                a.values[k++] = d[i + j * n];
            }
    }
    a.colptr[n] = (int64_t)k;
    return a;
}

/* M^-1 by CHOLMOD (symmetric M, upper triangle) or by UMFPACK (non-symmetric M: some FEM
 * files store only one triangle, and the library then takes M as stored, like
 * ../shared/tools/fc_error.py does). */
typedef struct msolver {
    int symmetric;
    size_t n;
    cholmod_sparse *A;
    cholmod_factor *L;
    const tu_csc *M;
    void *numeric;
} msolver;

static int msolver_init(msolver *s, const tu_csc *M)
{
    memset(s, 0, sizeof *s);
    s->n = M->nrows;
    s->M = M;
    s->symmetric = is_symmetric(M, 1e-12);
    if (s->symmetric) {
        s->A = to_cholmod(M, 1);
        s->L = cholmod_l_analyze(s->A, &CM);
        REQUIRE(s->L != NULL);
        return cholmod_l_factorize(s->A, s->L, &CM) && CM.status == CHOLMOD_OK;
    } else {
        void *symbolic = NULL;
        SuiteSparse_long st;
        st = umfpack_dl_symbolic((SuiteSparse_long)M->nrows, (SuiteSparse_long)M->ncols,
                                 (const SuiteSparse_long *)M->colptr,
                                 (const SuiteSparse_long *)M->rowind, M->values, &symbolic,
                                 NULL, NULL);
        if (st != UMFPACK_OK) return 0;
        st = umfpack_dl_numeric((const SuiteSparse_long *)M->colptr,
                                (const SuiteSparse_long *)M->rowind, M->values, symbolic,
                                &s->numeric, NULL, NULL);
        umfpack_dl_free_symbolic(&symbolic);
        return st == UMFPACK_OK;
    }
}

static void msolver_solve(const msolver *s, const double *b, double *x)
{
    if (s->symmetric) {
        cholmod_dense *B = cholmod_l_allocate_dense(s->n, 1, s->n, CHOLMOD_REAL, &CM), *X;
        REQUIRE(B != NULL);
        memcpy(B->x, b, s->n * sizeof(double));
        X = cholmod_l_solve(CHOLMOD_A, s->L, B, &CM);
        REQUIRE(X != NULL);
        memcpy(x, X->x, s->n * sizeof(double));
        cholmod_l_free_dense(&B, &CM);
        cholmod_l_free_dense(&X, &CM);
    } else {
        REQUIRE(umfpack_dl_solve(UMFPACK_A, (const SuiteSparse_long *)s->M->colptr,
                                 (const SuiteSparse_long *)s->M->rowind, s->M->values, x, b,
                                 s->numeric, NULL, NULL) == UMFPACK_OK);
    }
}

static void msolver_free(msolver *s)
{
    if (s->L) cholmod_l_free_factor(&s->L, &CM);
    if (s->A) cholmod_l_free_sparse(&s->A, &CM);
    if (s->numeric) umfpack_dl_free_numeric(&s->numeric);
}

/* Is the symmetric part of a dense column-major n x n matrix positive definite (CHOLMOD,
 * with a condition estimate above 1e-7)? */
static int sym_part_pd(size_t n, const double *W, double *rcond)
{
    double *S = (double *)tu_calloc(n * n, sizeof(double));
    tu_csc Sc;
    cholmod_sparse *A;
    cholmod_factor *L;
    int pd;
    for (size_t j = 0; j < n; ++j)
        for (size_t i = 0; i < n; ++i) S[i + j * n] = 0.5 * (W[i + j * n] + W[j + i * n]);
    Sc = dense_to_csc(n, S);
    A = to_cholmod(&Sc, 1);
    L = cholmod_l_analyze(A, &CM);
    REQUIRE(L != NULL);
    CM.quick_return_if_not_posdef = 1;
    cholmod_l_factorize(A, L, &CM);
    pd = CM.status == CHOLMOD_OK && L->minor == L->n;
    *rcond = pd ? cholmod_l_rcond(L, &CM) : 0.0;
    pd = pd && *rcond > 1e-7;
    CM.status = CHOLMOD_OK;
    cholmod_l_free_factor(&L, &CM);
    cholmod_l_free_sparse(&A, &CM);
    tu_csc_free(&Sc);
    free(S);
    return pd;
}

/* Solves a problem with cadmm; returns the status (or -1 when a call failed). */
static int solve(const cadmm_problem *p, const char *label, double *r, double *u, double *v,
                 cadmm_stats *st)
{
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    cadmm_status status = -1;
    cadmm_result rc;
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_settings_set_time_limit(s, 120.0) == CADMM_OK);
    rc = cadmm_solver_new(p, s, &sv);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: solver_new: %s", label, cadmm_result_message(rc));
        cadmm_settings_free(s);
        return -1;
    }
    rc = cadmm_solver_solve(sv, &status);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: solve: %s (%s)", label, cadmm_result_message(rc), cadmm_solver_last_error(sv));
        status = -1;
    } else {
        memset(st, 0, sizeof *st);
        st->struct_size = sizeof *st;
        REQUIRE(cadmm_solver_get_stats(sv, st) == CADMM_OK);
        REQUIRE(cadmm_solver_get_solution(sv, r, u, v) == CADMM_OK);
        printf("  %-7s status %d (%s) after %llu iterations, error %.3e, %.3f s, rho %.3g\n",
               label, status,
               status == CADMM_STATUS_SOLVED          ? "solved"
               : status == CADMM_STATUS_MAX_ITERATIONS ? "max iterations"
               : status == CADMM_STATUS_TIME_LIMIT     ? "time limit"
                                                       : "numerical error",
               (unsigned long long)st->iterations, st->error, st->solve_seconds, st->rho);
    }
    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    return status;
}

/* Deterministic pseudo-random vector in [-1, 1]. */
static void fill_random(double *x, size_t n, unsigned seed)
{
    unsigned long s = 2463534242UL + seed;
    for (size_t i = 0; i < n; ++i) {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s &= 0xffffffffUL;
        x[i] = (double)s / 2147483647.5 - 1.0;
    }
}

/* Largest |a - b| entry by entry (a missing entry is a zero), relative to the largest |a|,
 * |b|; 1 when the shapes differ. */
static double csc_difference(const tu_csc *a, const tu_csc *b)
{
    double worst = 0.0, scale = 0.0, *col;
    if (a->nrows != b->nrows || a->ncols != b->ncols) return 1.0;
    col = (double *)tu_calloc(a->nrows + 1, sizeof(double));
    for (size_t j = 0; j < a->ncols; ++j) {
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k) {
            col[a->rowind[k]] += a->values[k];
            scale = tu_max(scale, fabs(a->values[k]));
        }
        for (int64_t k = b->colptr[j]; k < b->colptr[j + 1]; ++k) {
            col[b->rowind[k]] -= b->values[k];
            scale = tu_max(scale, fabs(b->values[k]));
        }
        for (int64_t k = a->colptr[j]; k < a->colptr[j + 1]; ++k) {
            worst = tu_max(worst, fabs(col[a->rowind[k]]));
            col[a->rowind[k]] = 0.0;
        }
        for (int64_t k = b->colptr[j]; k < b->colptr[j + 1]; ++k) {
            worst = tu_max(worst, fabs(col[b->rowind[k]]));
            col[b->rowind[k]] = 0.0;
        }
    }
    free(col);
    return scale > 0.0 ? worst / scale : worst;
}

static double vec_difference(const double *a, const double *b, size_t n)
{
    double worst = 0.0, scale = 0.0;
    for (size_t i = 0; i < n; ++i) {
        worst = tu_max(worst, fabs(a[i] - b[i]));
        scale = tu_max(scale, tu_max(fabs(a[i]), fabs(b[i])));
    }
    return scale > 0.0 ? worst / scale : worst;
}

/* The library's reading of `path`, written back by the library (compressed column) and read
 * by ours, holds the same data entry by entry as our reading of `path` (P): the error
 * measure alone can miss an entry (a contact whose candidate lies in the polar cone does
 * not depend on W). A reader bug could hide here only behind an inverse bug of the writer. */
static void compare_data(const char *path, const fcr_problem *P, const cadmm_problem *lib)
{
    char copy[64], err[512];
    fcr_problem Q;
    size_t m = 3 * P->nc;
    double d = 0.0;
    cadmm_result rc;
    /* per process: CTest may run this program and its valgrind variant at once, here */
    snprintf(copy, sizeof copy, "test_suitesparse_copy_%ld.hdf5", (long)getpid());
    rc = cadmm_problem_write_fclib(lib, copy);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: cadmm_problem_write_fclib: %s", path, cadmm_last_error());
        return;
    }
    if (fcr_read(copy, &Q, err, sizeof err) != 0) {
        TU_FAIL("%s: reading the library's copy: %s", path, err);
        remove(copy);
        return;
    }
    remove(copy);
    if (Q.is_global != P->is_global || Q.n != P->n || Q.nc != P->nc) {
        TU_FAIL("%s: the library's copy has other dimensions", path);
    } else if (P->is_global) {
        d = tu_max(csc_difference(&P->M, &Q.M), csc_difference(&P->H, &Q.H));
        d = tu_max(d, tu_max(vec_difference(P->f, Q.f, P->n), vec_difference(P->w, Q.w, m)));
    } else {
        d = tu_max(csc_difference(&P->W, &Q.W), vec_difference(P->q, Q.q, m));
    }
    d = tu_max(d, vec_difference(P->mu, Q.mu, P->nc));
    CHECK_MSG(d <= 1e-15, "%s: the library's reader and ours differ: largest entry difference "
              "%.3e (relative to the largest entry)", path, d);
    fcr_free(&Q);
}

/* With the fclib feature: the library's reader and ours agree: same dims, same error at two
 * random candidates, and the same data entry by entry (compare_data). Returns 1 when the
 * readers were compared. */
static int compare_readers(const char *path, const fcr_problem *P, const cadmm_problem *ours)
{
    cadmm_problem *lib = NULL;
    size_t n = 0, nc = 0, m = 3 * P->nc;
    bool g = false;
    double *r, *v;
    if (!CADMM_TEST_HAVE_FCLIB) return 0;
    if (cadmm_problem_read_fclib(path, &lib) != CADMM_OK) {
        TU_FAIL("%s: cadmm_problem_read_fclib failed: %s", path, cadmm_last_error());
        return 0;
    }
    REQUIRE(cadmm_problem_dims(lib, &n, &nc, &g) == CADMM_OK);
    CHECK_MSG(n == P->n && nc == P->nc && (g ? 1 : 0) == P->is_global,
              "%s: library reader dims (%zu, %zu, %d), ours (%zu, %zu, %d)", path, n, nc,
              (int)g, P->n, P->nc, P->is_global);
    if (n != P->n || nc != P->nc) {
        cadmm_problem_free(lib);
        return 0;
    }
    r = (double *)tu_calloc(m + 1, sizeof(double));
    v = (double *)tu_calloc(P->n + 1, sizeof(double));
    for (unsigned seed = 1; seed <= 3; seed += 2) {
        double e1 = -1, e2 = -2;
        fill_random(r, m, seed);
        for (size_t k = 0; k < m; k += 3) r[k] = fabs(r[k]) + 0.5; /* in front of the cone */
        fill_random(v, P->n, seed + 1);
        REQUIRE(cadmm_problem_error(lib, r, NULL, v, &e1) == CADMM_OK);
        REQUIRE(cadmm_problem_error(ours, r, NULL, v, &e2) == CADMM_OK);
        CHECK_MSG(fabs(e1 - e2) <= 1e-12 * fabs(e2),
                  "%s: library reader and ours differ: error %.17g vs %.17g (candidate %u)",
                  path, e1, e2, seed);
    }
    free(r);
    free(v);
    compare_data(path, P, lib);
    cadmm_problem_free(lib);
    return 1;
}

static int by_name(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Every *.hdf5 of DIR/global and DIR/local read by both readers (see compare_readers). */
static void compare_readers_on_every_file(const char *dir)
{
    static const char *const subdirs[2] = {"global", "local"};
    size_t compared = 0, by_encoding[3] = {0, 0, 0}; /* nz = -1, -2, triplets */
    if (!CADMM_TEST_HAVE_FCLIB) {
        printf("NOTE: libcadmm built without the fclib feature: its FCLib reader is not "
               "compared with ours (configure with -DCADMM_WITH_FCLIB=ON)\n");
        return;
    }
    printf("both readers on every file:\n");
    for (int sd = 0; sd < 2; ++sd) {
        char sub[4096];
        char *names[512];
        size_t k = 0;
        DIR *d = opendir(tu_join(sub, sizeof sub, dir, subdirs[sd]));
        struct dirent *e;
        REQUIRE(d != NULL);
        while ((e = readdir(d)) != NULL) {
            size_t len = strlen(e->d_name);
            if (len > 5 && strcmp(e->d_name + len - 5, ".hdf5") == 0) {
                REQUIRE(k < sizeof names / sizeof names[0]);
                names[k] = (char *)tu_calloc(len + 1, 1);
                memcpy(names[k++], e->d_name, len + 1);
            }
        }
        closedir(d);
        qsort(names, k, sizeof names[0], by_name);
        for (size_t i = 0; i < k; ++i) {
            char path[4096], err[512];
            fcr_problem P;
            cadmm_problem *ours = NULL;
            tu_join(path, sizeof path, sub, names[i]);
            if (fcr_read(path, &P, err, sizeof err) != 0) {
                TU_FAIL("reading %s: %s", path, err);
            } else if (P.has_joints) {
                TU_FAIL("%s has joints, which our reader does not read", path);
                fcr_free(&P);
            } else if (tu_problem_to_cadmm(&P, &ours) != CADMM_OK) {
                TU_FAIL("%s: building the problem read by ours failed: %s", path,
                        cadmm_last_error());
                fcr_free(&P);
            } else {
                if (compare_readers(path, &P, ours)) {
                    ++compared;
                    ++by_encoding[P.encoding[0] == -1 ? 0 : P.encoding[0] == -2 ? 1 : 2];
                }
                cadmm_problem_free(ours);
                fcr_free(&P);
            }
            free(names[i]);
        }
    }
    printf("  readers agree on %zu files (first matrix: %zu compressed column, %zu compressed "
           "row, %zu triplets)\n", compared, by_encoding[0], by_encoding[1], by_encoding[2]);
    CHECK_MSG(compared == 71, "readers compared on %zu files, expected the 71 FCLib files",
              compared);
    CHECK_MSG(by_encoding[1] == 2, "%zu compressed-row files compared, expected 2",
              by_encoding[1]);
}

static void check_global_file(const char *dir, const file_case *fc)
{
    char path[4096], err[512];
    fcr_problem P;
    cadmm_problem *gp = NULL, *lp = NULL;
    cadmm_stats st_g, st_l;
    size_t n, m, nc;
    double *r, *u, *v, *r_loc, *u_loc, *hr_f, *v_ref, *v_free, *mv, *q, *tmp, *Wd, *hcol;
    msolver ms;
    tu_csc W;
    int sg, sl, w_pd;
    double rcond = 0.0;

    tu_join(path, sizeof path, dir, fc->file);
    printf("%s\n", fc->file);
    if (fcr_read(path, &P, err, sizeof err) != 0) {
        TU_FAIL("reading %s: %s", path, err);
        return;
    }
    REQUIRE(P.is_global && !P.has_joints);
    n = P.n, nc = P.nc, m = 3 * nc;
    printf("  n = %zu, %zu contacts, M nnz %lld, H nnz %lld (encodings %d/%d)\n", n, nc,
           (long long)P.M.colptr[n], (long long)P.H.colptr[m], P.encoding[0], P.encoding[1]);
    {
        cadmm_csc M = tu_csc_view(&P.M), H = tu_csc_view(&P.H);
        cadmm_result rc = cadmm_problem_new_global(n, nc, &M, &H, P.f, P.w, P.mu, &gp);
        if (rc != CADMM_OK) {
            TU_FAIL("%s: new_global: %s", fc->file, cadmm_result_message(rc));
            fcr_free(&P);
            return;
        }
    }
    compare_readers(path, &P, gp);

    r = (double *)tu_calloc(m, sizeof(double));
    u = (double *)tu_calloc(m, sizeof(double));
    r_loc = (double *)tu_calloc(m, sizeof(double));
    u_loc = (double *)tu_calloc(m, sizeof(double));
    q = (double *)tu_calloc(m, sizeof(double));
    v = (double *)tu_calloc(n, sizeof(double));
    hr_f = (double *)tu_calloc(n, sizeof(double));
    v_ref = (double *)tu_calloc(n, sizeof(double));
    v_free = (double *)tu_calloc(n, sizeof(double));
    mv = (double *)tu_calloc(n, sizeof(double));
    tmp = (double *)tu_calloc(n > m ? n : m, sizeof(double));
    hcol = (double *)tu_calloc(n, sizeof(double));
    Wd = (double *)tu_calloc(m * m, sizeof(double));
    memset(&W, 0, sizeof W);

    sg = solve(gp, "global", r, u, v, &st_g);
    if (sg != CADMM_STATUS_SOLVED) {
        if (fc->must_solve) TU_FAIL("%s: the global solve did not reach tol %g", fc->file, TOL);
        else printf("  NOTE: not solved (status %d): the reference checks are skipped\n", sg);
        goto cleanup;
    }

    /* ---- 1. v against M^-1 (H r + f) ---- */
    REQUIRE(msolver_init(&ms, &P.M));
    printf("  M is %s: reference solves with %s\n", ms.symmetric ? "symmetric" : "NOT symmetric",
           ms.symmetric ? "CHOLMOD (LL^T)" : "UMFPACK (LU), M taken as stored");
    memcpy(hr_f, P.f, n * sizeof(double));
    tu_csc_mul(&P.H, r, 1, hr_f);
    msolver_solve(&ms, hr_f, v_ref);
    msolver_solve(&ms, P.f, v_free);
    {
        double scale = tu_max(tu_norm(v_ref, n), tu_norm(v_free, n));
        double dv = tu_diff_norm(v, v_ref, n) / tu_max(scale, 1e-300);
        printf("  ||v - M^-1(H r + f)|| / max(||v_ref||, ||M^-1 f||) = %.3e\n", dv);
        CHECK_MSG(dv <= 1e-6, "%s: v differs from M^-1 (H r + f): %.3e", fc->file, dv);
    }

    /* ---- 2. error measure: ours, the library's, the solver's ---- */
    {
        double e_c = tu_global_error(&P.M, &P.H, P.f, P.w, P.mu, nc, r, v), e_lib = -1;
        REQUIRE(cadmm_problem_error(gp, r, u, v, &e_lib) == CADMM_OK);
        printf("  error measure: C %.6e, cadmm_problem_error %.6e, stats %.6e\n", e_c, e_lib,
               st_g.error);
        CHECK_MSG(fabs(e_c - e_lib) <= 1e-6 * e_lib + 1e-14,
                  "%s: error measure C %.10e vs library %.10e", fc->file, e_c, e_lib);
        CHECK_MSG(e_lib <= TOL, "%s: SOLVED but error %.3e > tol", fc->file, e_lib);
        /* the independent measure is the judge: at or below tol, with the slack of the
           agreement check above (the two sum in different orders) */
        CHECK_MSG(e_c <= TOL * (1.0 + 1e-6) + 1e-14, "%s: SOLVED but the independent error "
                  "%.6e > tol", fc->file, e_c);
        /* the solver's statistics describe the solution it returns */
        CHECK_MSG(st_g.error <= TOL, "%s: SOLVED but stats.error %.3e > tol", fc->file,
                  st_g.error);
        CHECK_MSG(fabs(st_g.error - e_lib) <= 1e-6 * e_lib + 1e-14,
                  "%s: stats.error %.10e vs error of the returned solution %.10e", fc->file,
                  st_g.error, e_lib);
        /* u returned = H^T v + w */
        memcpy(tmp, P.w, m * sizeof(double));
        tu_csc_mul_t(&P.H, v, 1, tmp);
        CHECK_MSG(tu_diff_norm(u, tmp, m) <= 1e-12 * tu_max(1.0, tu_norm(tmp, m)),
                  "%s: returned u is not H^T v + w", fc->file);
    }

    /* ---- 3. Delassus form W = H^T M^-1 H (column by column), q = H^T M^-1 f + w ---- */
    for (size_t j = 0; j < m; ++j) {
        memset(hcol, 0, n * sizeof(double));
        for (int64_t k = P.H.colptr[j]; k < P.H.colptr[j + 1]; ++k)
            hcol[P.H.rowind[k]] = P.H.values[k];
        msolver_solve(&ms, hcol, tmp);
        tu_csc_mul_t(&P.H, tmp, 0, Wd + j * m);
    }
    if (ms.symmetric) /* remove the round-off asymmetry */
        for (size_t j = 0; j < m; ++j)
            for (size_t i = 0; i < j; ++i) {
                double a = 0.5 * (Wd[i + j * m] + Wd[j + i * m]);
                Wd[i + j * m] = Wd[j + i * m] = a;
            }
    W = dense_to_csc(m, Wd);
    memcpy(q, P.w, m * sizeof(double));
    tu_csc_mul_t(&P.H, v_free, 1, q); /* q = H^T M^-1 f + w */
    w_pd = sym_part_pd(m, Wd, &rcond); /* r unique when W (its symmetric part) is PD */
    printf("  Delassus W: %zu x %zu, nnz %lld, %s (rcond estimate %.2e)\n", W.nrows, W.ncols,
           (long long)W.colptr[W.ncols],
           w_pd ? "positive definite" : "singular or ill-conditioned", rcond);
    {
        cadmm_csc Wv = tu_csc_view(&W);
        cadmm_result rc = cadmm_problem_new_local(nc, &Wv, q, P.mu, &lp);
        CHECK_MSG(rc == CADMM_OK, "%s: new_local: %s", fc->file, cadmm_result_message(rc));
    }
    if (lp != NULL) {
        sl = solve(lp, "local", r_loc, u_loc, NULL, &st_l);
        CHECK_MSG(sl == CADMM_STATUS_SOLVED, "%s: local (Delassus) solve status %d", fc->file, sl);
        if (sl == CADMM_STATUS_SOLVED) {
            double e;
            /* the global r solves the local problem ... */
            double e_gl_c = tu_local_error(&W, q, P.mu, nc, r), e_gl = -1;
            REQUIRE(cadmm_problem_error(lp, r, NULL, NULL, &e_gl) == CADMM_OK);
            printf("  global r in the local problem: error %.3e (C %.3e)\n", e_gl, e_gl_c);
            CHECK_MSG(e_gl <= 1e-6 && fabs(e_gl - e_gl_c) <= 1e-6 * e_gl + 1e-14,
                      "%s: global r has local error %.3e (C %.3e)", fc->file, e_gl, e_gl_c);
            /* ... and the local r, with v = M^-1 (H r + f), solves the global one */
            memcpy(hr_f, P.f, n * sizeof(double));
            tu_csc_mul(&P.H, r_loc, 1, hr_f);
            msolver_solve(&ms, hr_f, mv);
            REQUIRE(cadmm_problem_error(gp, r_loc, NULL, mv, &e) == CADMM_OK);
            printf("  local r in the global problem: error %.3e\n", e);
            CHECK_MSG(e <= 1e-6, "%s: local r has global error %.3e", fc->file, e);
            /* u from both formulations */
            {
                double du = tu_diff_norm(u_loc, u, m) /
                            tu_max(tu_norm(u, m), tu_max(tu_norm(q, m), 1e-300));
                printf("  ||u_local - u_global|| / max(||u||, ||q||) = %.3e\n", du);
                CHECK_MSG(du <= 1e-5, "%s: u differs between the forms: %.3e", fc->file, du);
            }
            if (w_pd) {
                double dr = tu_diff_norm(r_loc, r, m) / tu_max(tu_norm(r, m), 1e-300);
                printf("  W positive definite: ||r_local - r_global|| / ||r|| = %.3e\n", dr);
                CHECK_MSG(dr <= 1e-5, "%s: r differs between the forms: %.3e", fc->file, dr);
            } else {
                printf("  W singular: r is not unique, compared u and the error measures only\n");
            }
        }
        cadmm_problem_free(lp);
    }
    msolver_free(&ms);

cleanup:
    tu_csc_free(&W);
    free(r);
    free(u);
    free(r_loc);
    free(u_loc);
    free(q);
    free(v);
    free(hr_f);
    free(v_ref);
    free(v_free);
    free(mv);
    free(tmp);
    free(hcol);
    free(Wd);
    cadmm_problem_free(gp);
    fcr_free(&P);
}

/* Local files stored in compressed-row form (nz = -2): the two readers agree. */
static void check_local_reader(const char *dir, const char *file)
{
    char path[4096], err[512];
    fcr_problem P;
    cadmm_problem *lp = NULL;
    tu_join(path, sizeof path, dir, file);
    printf("%s\n", file);
    if (fcr_read(path, &P, err, sizeof err) != 0) {
        TU_FAIL("reading %s: %s", path, err);
        return;
    }
    CHECK_MSG(!P.is_global && P.encoding[0] == -2, "%s: expected a local nz = -2 file", file);
    {
        cadmm_csc W = tu_csc_view(&P.W);
        cadmm_result rc = cadmm_problem_new_local(P.nc, &W, P.q, P.mu, &lp);
        CHECK_MSG(rc == CADMM_OK, "%s: new_local: %s", file, cadmm_result_message(rc));
    }
    if (lp != NULL) {
        double *r = (double *)tu_calloc(3 * P.nc, sizeof(double)), e_c, e_lib = -1;
        fill_random(r, 3 * P.nc, 7);
        e_c = tu_local_error(&P.W, P.q, P.mu, P.nc, r);
        REQUIRE(cadmm_problem_error(lp, r, NULL, NULL, &e_lib) == CADMM_OK);
        CHECK_MSG(fabs(e_c - e_lib) <= 1e-10 * e_lib, "%s: local error C %.10e vs library %.10e",
                  file, e_c, e_lib);
        compare_readers(path, &P, lp);
        free(r);
        cadmm_problem_free(lp);
    }
    fcr_free(&P);
}

int main(int argc, char **argv)
{
    const char *dir;
    if (argc < 2) {
        fprintf(stderr, "usage: %s FCLIB_DATA_DIR\n", argv[0]);
        return 2;
    }
    dir = argv[1];
    if (!tu_is_dir(dir)) {
        printf("SKIP: FCLib data directory '%s' not found\n", dir);
        return TU_SKIP;
    }
    printf("cadmm %s: SuiteSparse CHOLMOD reference checks (tol %g)\n", cadmm_version(), TOL);
    cholmod_l_start(&CM);
    CM.print = 0;
    for (size_t i = 0; i < sizeof FILES / sizeof FILES[0]; ++i) check_global_file(dir, &FILES[i]);
    check_local_reader(dir, "local/LMGC_100_PR_PerioBox-i00361-60-03000.hdf5");
    check_local_reader(dir, "local/Capsules-i125-1213.hdf5");
    compare_readers_on_every_file(dir);
    cholmod_l_finish(&CM);
    return tu_finish("test_suitesparse");
}
