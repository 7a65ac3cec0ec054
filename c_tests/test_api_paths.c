/* API paths not covered elsewhere:
 *
 *   1. cadmm_solver_update_values refused: a NaN in M, H, f, w and mu, an infinite w, a
 *      negative mu, an indefinite M, and the forms the API lets a caller get wrong (the local
 *      values path on a global solver, G or b for a problem without joints). Each failure
 *      returns its documented code; then, as the header promises, cadmm_solver_solve and
 *      cadmm_solver_warm_start refuse with the same code, the last solve's solution and
 *      statistics stay readable, and a valid update (new f) repairs the solver: the next
 *      solve is SOLVED by the independent measure of the new values.
 *   2. cadmm_solver_update_local_values: new W values, q and mu, solved and compared with a
 *      fresh solver built from the same data (both checked independently); its refusals (a
 *      NaN in W, q and mu, a negative mu, an indefinite W, the global path on a local
 *      solver) with the same repair; a W made non-symmetric is accepted (non-symmetric W is
 *      supported: the header names CADMM_ERR_SINGULAR for it) and solved.
 *   3. cadmm_settings_set_anderson_interval: 1 and 5 on a named ADMM variant with Anderson
 *      memory 5 change the Anderson attempts (accepted + rejected; at most one attempt per
 *      `every` iterations); 0 is refused with CADMM_ERR_INVALID_SETTING and the settings
 *      keep the previous interval.
 *   4. cadmm_solver_get_trace_phase with "auto": CADMM_PHASE_ADMM (0) for ADMM points
 *      (finite residuals), CADMM_PHASE_NEWTON (1) for the point ending a Newton phase (NaN
 *      residuals), one such point per Newton phase; index out of range ->
 *      CADMM_ERR_INVALID_VALUE, NULL -> CADMM_ERR_NULL_POINTER, the out-parameter untouched
 *      on failure; an int32_t out-parameter (the type cadmm_phase names) still compiles.
 *   5. cadmm_last_error is per thread: two threads fail at once (a barrier before and after
 *      the failing calls), each with another error, many rounds; each reads its own message.
 *   6. A time limit of 0.05 s on a generated global problem of 600 contacts: TIME_LIMIT, and
 *      the wall time of cadmm_solver_solve stays within a stated bound of the limit.
 *   7. cadmm_settings_set_linear_solver: "direct", "iterative" and "auto" each solve a
 *      generated problem; the matrix-free backend counts conjugate-gradient iterations in the
 *      statistics and runs no Newton phase, the direct one counts none; a bad name ->
 *      CADMM_ERR_INVALID_SETTING, NULL settings or name -> CADMM_ERR_NULL_POINTER.
 *
 * Every solve is checked with tu_check_outcome (test_util.h's independent error measure).
 *
 * Usage: test_api_paths [FCLIB_DATA_DIR] (not used: the problems are generated). The
 * environment variable CADMM_UNDER_VALGRIND (set by CMake for the valgrind variant) widens
 * the time bound of case 6. */
/* clock_gettime and pthread barriers (the build systems define it too) */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif

#include "cadmm.h"
#include "test_util.h"

#include <pthread.h>
#include <stdbool.h>
#include <time.h>

#define TOL 1e-8
#define AGREE 1e-9 /* stats.error against the independent error, relative */

static double now_seconds(void)
{
    struct timespec ts;
    REQUIRE(clock_gettime(CLOCK_MONOTONIC, &ts) == 0);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- problems ----------------------------------------------------------------------------- */

/* Index of entry (row, col) in the values of `a`. */
static size_t csc_index(const tu_csc *a, size_t row, size_t col)
{
    for (int64_t k = a->colptr[col]; k < a->colptr[col + 1]; ++k)
        if ((size_t)a->rowind[k] == row) return (size_t)k;
    REQUIRE(!"entry not in the pattern");
    return 0;
}

static size_t nnz(const tu_csc *a) { return (size_t)a->colptr[a->ncols]; }

static double *dup(const double *x, size_t n)
{
    double *y = (double *)tu_calloc(n, sizeof(double));
    if (n > 0) memcpy(y, x, n * sizeof(double));
    return y;
}

static cadmm_settings *settings_tol(double tol)
{
    cadmm_settings *s = NULL;
    REQUIRE_OK(cadmm_settings_new(&s));
    REQUIRE_OK(cadmm_settings_set_tolerance(s, tol));
    return s;
}

/* ---- solving and checking ------------------------------------------------------------------ */

/* Solves with `sv`, whose problem must hold the values of `p`, reads everything back into `o`
 * (the caller frees it) and checks it with tu_check_outcome at `tol`; the status must be
 * `expected` (-1: any). */
static void solve_into(const char *label, cadmm_solver *sv, const tu_problem *p, double tol,
                       cadmm_status expected, tu_outcome *o)
{
    size_t m = 3 * p->nc;
    cadmm_problem *lib = tu_require_problem(p);
    memset(o, 0, sizeof *o);
    o->status = -1;
    o->r = (double *)tu_calloc(m, sizeof(double));
    o->u = (double *)tu_calloc(m, sizeof(double));
    o->v = (double *)tu_calloc(p->n, sizeof(double));
    o->lambda = (double *)tu_calloc(0, sizeof(double));
    o->rc = cadmm_solver_solve(sv, &o->status);
    if (o->rc != CADMM_OK) {
        TU_FAIL("%s: cadmm_solver_solve returned %s (%d): %s", label, tu_result_name(o->rc),
                (int)o->rc, cadmm_solver_last_error(sv));
        cadmm_problem_free(lib);
        return;
    }
    o->solved_call = 1;
    o->stats.struct_size = sizeof o->stats;
    REQUIRE_OK(cadmm_solver_get_stats(sv, &o->stats));
    REQUIRE_OK(cadmm_solver_get_solution(sv, o->r, o->u, p->is_global ? o->v : NULL));
    o->e_ind = tu_problem_error(p, o->r, o->v, o->lambda);
    REQUIRE_OK(cadmm_problem_error(lib, o->r, o->u, o->v, &o->e_lib));
    printf("  %-56s %-15s %6llu iterations, stats.error %.3e, independent %.3e\n", label,
           tu_status_name(o->status), (unsigned long long)o->stats.iterations, o->stats.error,
           o->e_ind);
    if (expected >= 0)
        CHECK_MSG(o->status == expected, "%s: status %s, expected %s", label,
                  tu_status_name(o->status), tu_status_name(expected));
    tu_check_outcome(label, p, o, tol, 0.0, AGREE);
    cadmm_problem_free(lib);
}

static cadmm_stats solve_check(const char *label, cadmm_solver *sv, const tu_problem *p,
                               double tol, cadmm_status expected)
{
    tu_outcome o;
    solve_into(label, sv, p, tol, expected, &o);
    tu_outcome_free(&o);
    return o.stats;
}

/* A refused update changes nothing (the header of cadmm_solver_update_values): stats and
   solution are those of the last solve, and a solve solves the problem the solver held,
   `p`, as the independent measure checks, with the answer it gave before. */
static void expect_unchanged(const char *label, cadmm_solver *sv, const tu_problem *p,
                             const double *last_r, cadmm_status last_status)
{
    size_t m = 3 * p->nc;
    char what[200];
    cadmm_stats st;
    tu_outcome o;
    double *r = (double *)tu_calloc(m, sizeof(double));
    cadmm_result rc;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    rc = cadmm_solver_get_stats(sv, &st);
    CHECK_MSG(rc == CADMM_OK && st.status == last_status,
              "%s: get_stats after the refused update: %s, status %s (last solve: %s)", label,
              tu_result_name(rc), tu_status_name(st.status), tu_status_name(last_status));
    rc = cadmm_solver_get_solution(sv, r, NULL, NULL);
    CHECK_MSG(rc == CADMM_OK && tu_diff_norm(r, last_r, m) == 0.0,
              "%s: get_solution after the refused update: %s, r moved by %.3e", label,
              tu_result_name(rc), tu_diff_norm(r, last_r, m));
    snprintf(what, sizeof what, "after %s refused, the problem held", label);
    solve_into(what, sv, p, TOL, CADMM_STATUS_SOLVED, &o);
    if (o.solved_call)
        CHECK_MSG(tu_rel_diff(o.r, last_r, m) <= 1e-6,
                  "%s: the problem held solves to another r (%.3e away)", label,
                  tu_rel_diff(o.r, last_r, m));
    tu_outcome_free(&o);
    free(r);
}

/* ---- case 1: update_values refused, then repaired ------------------------------------------ */

/* One refused global update: `rc` is what update_values returned, `code` the documented one. */
static void global_refusal(const char *label, cadmm_solver *sv, tu_problem *p, cadmm_result rc,
                           cadmm_result code, double *last_r, cadmm_status *last_status,
                           int *round)
{
    char what[200];
    tu_outcome o;
    CHECK_MSG(rc == code, "update_values with %s returned %s (%d), expected %s (\"%s\")", label,
              tu_result_name(rc), (int)rc, tu_result_name(code), cadmm_solver_last_error(sv));
    printf("  refused %-34s %-32s \"%s\"\n", label, tu_result_name(rc), cadmm_solver_last_error(sv));
    if (rc == CADMM_OK) return;
    CHECK_MSG(cadmm_solver_last_error(sv)[0] != '\0', "%s: no message", label);
    expect_unchanged(label, sv, p, last_r, *last_status);
    /* then new forces alone, every other value kept (NULL): taken, whatever was refused */
    ++*round;
    for (size_t i = 0; i < p->n; ++i) p->f[i] *= (*round % 2) ? 1.25 : 0.8;
    EXPECT_RC(cadmm_solver_update_values(sv, NULL, NULL, NULL, p->f, NULL, NULL, NULL),
              CADMM_OK);
    snprintf(what, sizeof what, "after %s, f alone (scaled)", label);
    solve_into(what, sv, p, TOL, CADMM_STATUS_SOLVED, &o);
    if (o.solved_call) {
        memcpy(last_r, o.r, 3 * p->nc * sizeof(double));
        *last_status = o.status;
    }
    tu_outcome_free(&o);
}

static void test_update_values_errors(void)
{
    tu_rng g = tu_rng_new(20261125u);
    tu_problem p = tu_gen_global(&g, 3, 5, 0.5, 1);
    cadmm_problem *lib = tu_require_problem(&p);
    cadmm_settings *s = settings_tol(TOL);
    cadmm_solver *sv = NULL;
    size_t m = 3 * p.nc, mnnz = nnz(&p.M), hnnz = nnz(&p.H);
    double *bad, *last_r = (double *)tu_calloc(m, sizeof(double));
    double dummy[1] = {0.0};
    cadmm_status last_status;
    tu_outcome o;
    int round = 0;

    printf("1. update_values refused (global, n = %zu, %zu contacts):\n", p.n, p.nc);
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    solve_into("first solve", sv, &p, TOL, CADMM_STATUS_SOLVED, &o);
    REQUIRE(o.solved_call);
    memcpy(last_r, o.r, m * sizeof(double));
    last_status = o.status;
    tu_outcome_free(&o);

#define REFUSE(label, call, code) \
    global_refusal(label, sv, &p, (call), code, last_r, &last_status, &round)

    bad = dup(p.M.values, mnnz);
    bad[csc_index(&p.M, 1, 1)] = NAN;
    REFUSE("NaN in M", cadmm_solver_update_values(sv, bad, NULL, NULL, NULL, NULL, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.H.values, hnnz);
    bad[hnnz / 2] = NAN;
    REFUSE("NaN in H", cadmm_solver_update_values(sv, NULL, bad, NULL, NULL, NULL, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.f, p.n);
    bad[p.n - 1] = NAN;
    REFUSE("NaN in f", cadmm_solver_update_values(sv, NULL, NULL, NULL, bad, NULL, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.w, m);
    bad[4] = NAN;
    REFUSE("NaN in w", cadmm_solver_update_values(sv, NULL, NULL, NULL, NULL, bad, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    bad[4] = -INFINITY;
    REFUSE("-inf in w", cadmm_solver_update_values(sv, NULL, NULL, NULL, NULL, bad, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.mu, p.nc);
    bad[2] = NAN;
    REFUSE("NaN in mu", cadmm_solver_update_values(sv, NULL, NULL, NULL, NULL, NULL, NULL, bad),
           CADMM_ERR_INVALID_VALUE);
    bad[2] = -0.1;
    REFUSE("mu -0.1", cadmm_solver_update_values(sv, NULL, NULL, NULL, NULL, NULL, NULL, bad),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    /* M indefinite: the diagonal of the second body's first velocity negated (M stays
       symmetric) */
    bad = dup(p.M.values, mnnz);
    bad[csc_index(&p.M, 3, 3)] = -bad[csc_index(&p.M, 3, 3)];
    REFUSE("M indefinite", cadmm_solver_update_values(sv, bad, NULL, NULL, NULL, NULL, NULL, NULL),
           CADMM_ERR_NOT_POSITIVE_DEFINITE);
    free(bad);

    /* the wrong form: the local path on a global solver, G and b without joints; refused,
       and, as every refusal, changing nothing */
    REFUSE("local values on a global solver",
           cadmm_solver_update_local_values(sv, p.M.values, NULL, NULL), CADMM_ERR_UNSUPPORTED);
    REFUSE("G values without joints",
           cadmm_solver_update_values(sv, NULL, NULL, dummy, NULL, NULL, NULL, NULL),
           CADMM_ERR_UNSUPPORTED);
    REFUSE("b without joints",
           cadmm_solver_update_values(sv, NULL, NULL, NULL, NULL, NULL, dummy, NULL),
           CADMM_ERR_UNSUPPORTED);
#undef REFUSE

    EXPECT_RC(cadmm_solver_update_values(NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL),
              CADMM_ERR_NULL_POINTER);

    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    free(last_r);
    tu_problem_free(&p);
}

/* ---- case 2: update_local_values ----------------------------------------------------------- */

static void local_refusal(const char *label, cadmm_solver *sv, tu_problem *p, cadmm_result rc,
                          cadmm_result code, double *last_r, cadmm_status *last_status)
{
    char what[200];
    tu_outcome o;
    CHECK_MSG(rc == code, "local update with %s returned %s (%d), expected %s (\"%s\")", label,
              tu_result_name(rc), (int)rc, tu_result_name(code), cadmm_solver_last_error(sv));
    printf("  refused %-34s %-32s \"%s\"\n", label, tu_result_name(rc), cadmm_solver_last_error(sv));
    if (rc == CADMM_OK) return;
    expect_unchanged(label, sv, p, last_r, *last_status);
    for (size_t i = 0; i < 3 * p->nc; ++i) p->q[i] *= 1.1;
    EXPECT_RC(cadmm_solver_update_local_values(sv, NULL, p->q, NULL), CADMM_OK);
    snprintf(what, sizeof what, "after %s, q alone (scaled)", label);
    solve_into(what, sv, p, TOL, CADMM_STATUS_SOLVED, &o);
    if (o.solved_call) {
        memcpy(last_r, o.r, 3 * p->nc * sizeof(double));
        *last_status = o.status;
    }
    tu_outcome_free(&o);
}

static void test_update_local_values(void)
{
    tu_rng g = tu_rng_new(777u);
    tu_problem p = tu_gen_local(&g, 4, 0.5), next = tu_gen_local(&g, 4, 0.3);
    cadmm_problem *lib = tu_require_problem(&p), *lib_next;
    cadmm_settings *s = settings_tol(TOL);
    cadmm_solver *sv = NULL;
    size_t m = 3 * p.nc, wnnz = nnz(&p.W);
    double *bad, *last_r = (double *)tu_calloc(m, sizeof(double)), dummy[1] = {0.0};
    cadmm_status last_status;
    tu_outcome o, fresh;

    printf("2. update_local_values (local, %zu contacts, W dense):\n", p.nc);
    REQUIRE(nnz(&next.W) == wnnz);
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    solve_check("first solve", sv, &p, TOL, CADMM_STATUS_SOLVED);

    /* new W, q and mu: the values of `next` */
    EXPECT_RC(cadmm_solver_update_local_values(sv, next.W.values, next.q, next.mu), CADMM_OK);
    tu_problem_free(&p);
    p = next;
    memset(&next, 0, sizeof next);
    solve_into("updated W, q, mu", sv, &p, TOL, CADMM_STATUS_SOLVED, &o);
    lib_next = tu_require_problem(&p);
    tu_solve(&p, lib_next, s, &fresh);
    printf("  %-56s %-15s %6llu iterations, stats.error %.3e, independent %.3e\n",
           "fresh solver on the same data", tu_status_name(fresh.status),
           (unsigned long long)fresh.stats.iterations, fresh.stats.error, fresh.e_ind);
    CHECK_MSG(fresh.status == CADMM_STATUS_SOLVED, "fresh solver: status %s",
              tu_status_name(fresh.status));
    tu_check_outcome("fresh solver on the updated data", &p, &fresh, TOL, 0.0, AGREE);
    REQUIRE(o.solved_call && fresh.solved_call);
    /* both answers are within TOL of a solution of the same (well-conditioned) problem */
    CHECK_MSG(tu_rel_diff(o.r, fresh.r, m) <= 1e-5,
              "updated and fresh solvers differ: ||r - r_fresh|| / max(1, ||r_fresh||) = %.3e",
              tu_rel_diff(o.r, fresh.r, m));
    printf("  updated vs fresh: relative difference of r %.3e\n", tu_rel_diff(o.r, fresh.r, m));
    memcpy(last_r, o.r, m * sizeof(double));
    last_status = o.status;
    tu_outcome_free(&o);
    tu_outcome_free(&fresh);
    cadmm_problem_free(lib_next);

#define REFUSE(label, call, code) local_refusal(label, sv, &p, (call), code, last_r, &last_status)
    bad = dup(p.W.values, wnnz);
    bad[csc_index(&p.W, 2, 5)] = NAN;
    REFUSE("NaN in W", cadmm_solver_update_local_values(sv, bad, NULL, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.q, m);
    bad[0] = NAN;
    REFUSE("NaN in q", cadmm_solver_update_local_values(sv, NULL, bad, NULL),
           CADMM_ERR_INVALID_VALUE);
    bad[0] = INFINITY;
    REFUSE("+inf in q", cadmm_solver_update_local_values(sv, NULL, bad, NULL),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    bad = dup(p.mu, p.nc);
    bad[1] = NAN;
    REFUSE("NaN in mu", cadmm_solver_update_local_values(sv, NULL, NULL, bad),
           CADMM_ERR_INVALID_VALUE);
    bad[1] = -0.5;
    REFUSE("mu -0.5", cadmm_solver_update_local_values(sv, NULL, NULL, bad),
           CADMM_ERR_INVALID_VALUE);
    free(bad);

    /* W[0][0] = -1e8 (W stays symmetric): e_0^T (W + rho I) e_0 = rho - 1e8 < 0, so W + rho I
       is indefinite for any rho below 1e8, far above the penalties of these solves */
    {
        cadmm_stats st;
        memset(&st, 0, sizeof st);
        st.struct_size = sizeof st;
        REQUIRE_OK(cadmm_solver_get_stats(sv, &st));
        REQUIRE(st.rho < 1e6);
    }
    bad = dup(p.W.values, wnnz);
    bad[csc_index(&p.W, 0, 0)] = -1e8;
    REFUSE("W indefinite", cadmm_solver_update_local_values(sv, bad, NULL, NULL),
           CADMM_ERR_NOT_POSITIVE_DEFINITE);
    free(bad);

    REFUSE("global values on a local solver",
           cadmm_solver_update_values(sv, p.W.values, dummy, NULL, NULL, NULL, NULL, NULL),
           CADMM_ERR_UNSUPPORTED);
#undef REFUSE
    EXPECT_RC(cadmm_solver_update_local_values(NULL, NULL, NULL, NULL), CADMM_ERR_NULL_POINTER);

    /* W made non-symmetric (one entry of the upper triangle moved): accepted and solved */
    p.W.values[csc_index(&p.W, 0, 1)] += 0.05;
    EXPECT_RC(cadmm_solver_update_local_values(sv, p.W.values, NULL, NULL), CADMM_OK);
    solve_check("W non-symmetric", sv, &p, TOL, CADMM_STATUS_SOLVED);

    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    free(last_r);
    tu_problem_free(&p);
}

/* ---- case 3: the Anderson interval -------------------------------------------------------- */

static cadmm_stats anderson_run(const char *label, const tu_problem *p, const cadmm_problem *lib,
                                const cadmm_settings *s)
{
    tu_outcome o;
    tu_solve(p, lib, s, &o);
    printf("  %-30s %-15s %6llu iterations, Anderson %llu accepted, %llu rejected, "
           "independent error %.3e\n",
           label, o.solved_call ? tu_status_name(o.status) : "(failed)",
           (unsigned long long)o.stats.iterations, (unsigned long long)o.stats.anderson_accepted,
           (unsigned long long)o.stats.anderson_rejected, o.e_ind);
    CHECK_MSG(o.status == CADMM_STATUS_SOLVED, "%s: status %s", label, tu_status_name(o.status));
    tu_check_outcome(label, p, &o, TOL, 0.0, AGREE);
    tu_outcome_free(&o);
    return o.stats;
}

static void test_anderson_interval(void)
{
    tu_rng g = tu_rng_new(4242u);
    tu_problem p = tu_gen_global(&g, 8, 12, 0.4, 0);
    cadmm_problem *lib = tu_require_problem(&p);
    cadmm_settings *s = settings_tol(TOL);
    cadmm_stats every1, every5, kept;
    uint64_t tries1, tries5, tries_kept;

    printf("3. Anderson interval (cp-R, memory 5, islands off; global, %zu contacts):\n", p.nc);
    REQUIRE_OK(cadmm_settings_set_variant(s, "cp-R"));
    /* one ADMM run over the whole problem: with islands each island counts its own
       iterations and the statistics add their Anderson steps */
    REQUIRE_OK(cadmm_settings_set_islands(s, false));
    REQUIRE_OK(cadmm_settings_set_anderson(s, 5));
    REQUIRE_OK(cadmm_settings_set_max_iterations(s, 50000));
    EXPECT_RC(cadmm_settings_set_anderson_interval(s, 1), CADMM_OK);
    every1 = anderson_run("interval 1", &p, lib, s);
    EXPECT_RC(cadmm_settings_set_anderson_interval(s, 5), CADMM_OK);
    every5 = anderson_run("interval 5", &p, lib, s);
    /* 0 is refused and the settings keep the interval 5 */
    EXPECT_RC(cadmm_settings_set_anderson_interval(s, 0), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_anderson_interval(NULL, 2), CADMM_ERR_NULL_POINTER);
    kept = anderson_run("interval 5, after 0 refused", &p, lib, s);

    tries1 = every1.anderson_accepted + every1.anderson_rejected;
    tries5 = every5.anderson_accepted + every5.anderson_rejected;
    tries_kept = kept.anderson_accepted + kept.anderson_rejected;
    CHECK_MSG(every1.iterations > 20 && tries1 > 10,
              "interval 1: %llu iterations, %llu Anderson attempts: the problem should iterate",
              (unsigned long long)every1.iterations, (unsigned long long)tries1);
    CHECK_MSG(tries5 <= every5.iterations / 5 + 1,
              "interval 5: %llu Anderson attempts in %llu iterations (at most one per 5)",
              (unsigned long long)tries5, (unsigned long long)every5.iterations);
    CHECK_MSG(every1.iterations != every5.iterations || tries1 != tries5,
              "intervals 1 and 5 ran the same: %llu iterations, %llu attempts",
              (unsigned long long)every1.iterations, (unsigned long long)tries1);
    CHECK_MSG(kept.iterations == every5.iterations && tries_kept == tries5 &&
                  kept.anderson_accepted == every5.anderson_accepted,
              "after the refused interval 0 the solve differs from interval 5: %llu iterations "
              "and %llu attempts, %llu and %llu before",
              (unsigned long long)kept.iterations, (unsigned long long)tries_kept,
              (unsigned long long)every5.iterations, (unsigned long long)tries5);

    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    tu_problem_free(&p);
}

/* ---- case 4: trace phases ---------------------------------------------------------------- */

static void test_trace_phase(void)
{
    tu_rng g = tu_rng_new(99u);
    /* a stack of 40 bodies, each on the one below (n = 120, 120 contact rows): above the
       size (48) up to which an island starts with Newton on its dense form, so ADMM runs
       first, then hands over (at 20 bodies ADMM finishes sooner than a Newton phase is
       predicted to, and keeps going) */
    tu_problem p = tu_gen_global(&g, 40, 40, 0.5, 1);
    cadmm_problem *lib = tu_require_problem(&p);
    cadmm_settings *s = settings_tol(1e-10);
    cadmm_solver *sv = NULL;
    cadmm_stats st;
    size_t len, admm_points = 0, newton_points = 0;
    cadmm_phase phase;

    printf("4. trace phases (auto, trace on, tolerance 1e-10; global, %zu contacts):\n", p.nc);
    REQUIRE_OK(cadmm_settings_set_variant(s, "auto"));
    REQUIRE_OK(cadmm_settings_set_trace(s, true));
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));

    /* before any solve the trace is empty: index 0 is out of range */
    phase = -7;
    EXPECT_RC(cadmm_solver_get_trace_phase(sv, 0, &phase), CADMM_ERR_INVALID_VALUE);
    CHECK_MSG(phase == -7, "a refused get_trace_phase wrote %d", (int)phase);

    st = solve_check("solve", sv, &p, 1e-10, CADMM_STATUS_SOLVED);
    len = cadmm_solver_trace_len(sv);
    CHECK_MSG(st.newton_phases >= 1 && st.newton_iterations < st.iterations,
              "the solve should run ADMM then Newton: %llu iterations, %llu Newton steps in %llu "
              "phases", (unsigned long long)st.iterations,
              (unsigned long long)st.newton_iterations, (unsigned long long)st.newton_phases);
    for (size_t i = 0; i < len; ++i) {
        cadmm_trace_point pt;
        int nan_res;
        phase = -7;
        REQUIRE_OK(cadmm_solver_get_trace(sv, i, &pt));
        EXPECT_RC(cadmm_solver_get_trace_phase(sv, i, &phase), CADMM_OK);
        nan_res = isnan(pt.primal_residual) && isnan(pt.dual_residual);
        CHECK_MSG(phase == CADMM_PHASE_ADMM || phase == CADMM_PHASE_NEWTON,
                  "point %zu: phase %d", i, (int)phase);
        CHECK_MSG((phase == CADMM_PHASE_NEWTON) == nan_res,
                  "point %zu (iteration %llu): phase %d but residuals %.3e, %.3e", i,
                  (unsigned long long)pt.iteration, (int)phase, pt.primal_residual,
                  pt.dual_residual);
        if (phase == CADMM_PHASE_ADMM) {
            CHECK_MSG(isfinite(pt.primal_residual) && isfinite(pt.dual_residual),
                      "ADMM point %zu: residuals %.3e, %.3e", i, pt.primal_residual,
                      pt.dual_residual);
            ++admm_points;
        } else if (phase == CADMM_PHASE_NEWTON) {
            ++newton_points;
        }
    }
    printf("  %zu trace points: %zu ADMM (phase 0), %zu Newton (phase 1); stats: %llu "
           "iterations, %llu Newton steps, %llu Newton phases\n",
           len, admm_points, newton_points, (unsigned long long)st.iterations,
           (unsigned long long)st.newton_iterations, (unsigned long long)st.newton_phases);
    CHECK_MSG(admm_points >= 1, "no ADMM point in the trace");
    CHECK_MSG(newton_points == st.newton_phases,
              "%zu Newton points in the trace, %llu Newton phases in the stats", newton_points,
              (unsigned long long)st.newton_phases);
    if (len > 0) {
        int32_t as_int = -7;
        EXPECT_RC(cadmm_solver_get_trace_phase(sv, 0, &phase), CADMM_OK);
        CHECK_MSG(phase == CADMM_PHASE_ADMM, "the first point has phase %d (ADMM comes first)",
                  (int)phase);
        /* cadmm_phase is int32_t: a program written before it had a name still compiles */
        EXPECT_RC(cadmm_solver_get_trace_phase(sv, 0, &as_int), CADMM_OK);
        CHECK_MSG(as_int == phase, "the phase read as int32_t is %d", (int)as_int);
        /* a solve whose Newton phases all met the tolerance ended with one */
        if (st.newton_fallbacks == 0) {
            EXPECT_RC(cadmm_solver_get_trace_phase(sv, len - 1, &phase), CADMM_OK);
            CHECK_MSG(phase == CADMM_PHASE_NEWTON,
                      "the last point has phase %d (the solve ends with Newton)", (int)phase);
        }
    }
    phase = -7;
    EXPECT_RC(cadmm_solver_get_trace_phase(sv, len, &phase), CADMM_ERR_INVALID_VALUE);
    EXPECT_RC(cadmm_solver_get_trace_phase(sv, (size_t)-1, &phase), CADMM_ERR_INVALID_VALUE);
    CHECK_MSG(phase == -7, "a refused get_trace_phase wrote %d", (int)phase);
    EXPECT_RC(cadmm_solver_get_trace_phase(sv, 0, NULL), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_solver_get_trace_phase(NULL, 0, &phase), CADMM_ERR_NULL_POINTER);
    CHECK_MSG(phase == -7, "a refused get_trace_phase wrote %d", (int)phase);

    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    tu_problem_free(&p);
}

/* ---- case 5: cadmm_last_error from two threads --------------------------------------------- */

#define ROUNDS 2000

typedef struct thread_arg {
    int which;               /* 0: a dimension error, 1: an invalid setting */
    pthread_barrier_t *barrier;
    const char *expected;    /* this thread's own message */
    int mismatches;
    char first_wrong[256];
} thread_arg;

/* The failing call of thread `which`: 0 builds a global problem whose M is 3 x 3 for n = 2
 * (CADMM_ERR_DIMENSION), 1 sets a negative tolerance (CADMM_ERR_INVALID_SETTING). */
static cadmm_result failing_call(int which, cadmm_settings *s)
{
    static const int64_t colptr[4] = {0, 1, 2, 3}, rowind[3] = {0, 1, 2};
    static const double one[3] = {1.0, 1.0, 1.0}, zero[3] = {0.0, 0.0, 0.0}, mu[1] = {0.5};
    if (which == 0) {
        cadmm_problem *p = NULL;
        cadmm_csc M = {3, 3, colptr, rowind, one}, H = {3, 3, colptr, rowind, one};
        return cadmm_problem_new_global(2, 1, &M, &H, zero, zero, mu, &p);
    }
    return cadmm_settings_set_tolerance(s, -1.0);
}

static void *thread_main(void *argp)
{
    thread_arg *a = (thread_arg *)argp;
    cadmm_settings *s = NULL; /* each thread its own object */
    REQUIRE_OK(cadmm_settings_new(&s));
    for (int k = 0; k < ROUNDS; ++k) {
        cadmm_result rc;
        const char *msg;
        pthread_barrier_wait(a->barrier); /* both fail at once */
        rc = failing_call(a->which, s);
        pthread_barrier_wait(a->barrier); /* both have failed before either reads */
        msg = cadmm_last_error();
        if (rc != (a->which == 0 ? CADMM_ERR_DIMENSION : CADMM_ERR_INVALID_SETTING) ||
            msg == NULL || strcmp(msg, a->expected) != 0) {
            if (a->mismatches++ == 0)
                snprintf(a->first_wrong, sizeof a->first_wrong, "round %d: %s, \"%s\"", k,
                         tu_result_name(rc), msg ? msg : "(NULL)");
        }
    }
    cadmm_settings_free(s);
    return NULL;
}

static void test_last_error_threads(void)
{
    char expected[2][256];
    pthread_barrier_t barrier;
    pthread_t th[2];
    thread_arg args[2];
    cadmm_settings *s = NULL;

    printf("5. cadmm_last_error from two threads failing at once (%d rounds):\n", ROUNDS);
    /* each failure's message, taken on this thread first */
    REQUIRE_OK(cadmm_settings_new(&s));
    for (int w = 0; w < 2; ++w) {
        REQUIRE(failing_call(w, s) == (w == 0 ? CADMM_ERR_DIMENSION : CADMM_ERR_INVALID_SETTING));
        snprintf(expected[w], sizeof expected[w], "%s", cadmm_last_error());
        printf("  thread %d's failure: \"%s\"\n", w, expected[w]);
    }
    cadmm_settings_free(s);
    REQUIRE(expected[0][0] != '\0' && strcmp(expected[0], expected[1]) != 0);
    REQUIRE(pthread_barrier_init(&barrier, NULL, 2) == 0);
    for (int w = 0; w < 2; ++w) {
        memset(&args[w], 0, sizeof args[w]);
        args[w].which = w;
        args[w].barrier = &barrier;
        args[w].expected = expected[w];
        REQUIRE(pthread_create(&th[w], NULL, thread_main, &args[w]) == 0);
    }
    for (int w = 0; w < 2; ++w) REQUIRE(pthread_join(th[w], NULL) == 0);
    pthread_barrier_destroy(&barrier);
    for (int w = 0; w < 2; ++w)
        CHECK_MSG(args[w].mismatches == 0,
                  "thread %d read another message than its own failure's in %d of %d rounds; "
                  "first: %s", w, args[w].mismatches, ROUNDS, args[w].first_wrong);
    /* this thread's message is still its own last failure (thread 1's kind) */
    CHECK_MSG(strcmp(cadmm_last_error(), expected[1]) == 0,
              "the main thread's message changed: \"%s\"", cadmm_last_error());
}

/* ---- case 6: how far a solve overruns its time limit --------------------------------------- */

static void test_time_limit_overrun(void)
{
    const double limit = 0.05;
    tu_rng g = tu_rng_new(20261123u);
    tu_problem p = tu_gen_global(&g, 300, 600, 0.5, 0);
    cadmm_problem *lib = tu_require_problem(&p);
    cadmm_settings *s = settings_tol(1e-14);
    cadmm_solver *sv = NULL;
    double one_iteration = INFINITY, wall, t0, scale, bound;
    const char *vg = getenv("CADMM_UNDER_VALGRIND");
    tu_outcome o;
    cadmm_stats st;

    printf("6. time limit %.2f s (global, n = %zu, %zu contacts):\n", limit, p.n, p.nc);
    /* one iteration's cost: the quickest of three solves limited to 1 iteration (wall time
       around cadmm_solver_solve, so it includes the fixed cost of a solve too) */
    REQUIRE_OK(cadmm_settings_set_max_iterations(s, 1));
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    for (int k = 0; k < 3; ++k) {
        char label[64];
        snprintf(label, sizeof label, "max_iterations 1 (run %d)", k + 1);
        t0 = now_seconds();
        solve_into(label, sv, &p, 1e-14, CADMM_STATUS_MAX_ITERATIONS, &o);
        wall = now_seconds() - t0;
        tu_outcome_free(&o);
        one_iteration = wall < one_iteration ? wall : one_iteration;
    }
    cadmm_solver_free(sv);
    CHECK_MSG(one_iteration < limit || vg != NULL,
              "one iteration takes %.4f s, not less than the limit %.2f s: a larger problem "
              "than needed, or a slow machine", one_iteration, limit);

    /* Built without a limit, which is then set: ADMM and Newton run into it. (A solver built
       with one starts with Gauss-Seidel sweeps, checked after.) */
    REQUIRE_OK(cadmm_settings_set_max_iterations(s, 1000000000u));
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    REQUIRE_OK(cadmm_settings_set_time_limit(s, limit));
    REQUIRE_OK(cadmm_solver_update_settings(sv, s));
    t0 = now_seconds();
    solve_into("time limit 0.05 s", sv, &p, 1e-14, CADMM_STATUS_TIME_LIMIT, &o);
    wall = now_seconds() - t0;
    st = o.stats;
    tu_outcome_free(&o);
    /* The limit is checked between iterations, so a solve may pass it by a Newton step in
       progress, the final measure and copying out: all within a few iterations' cost. The
       bound is the larger of 5 iterations (measured above, with whatever slows this run down
       included) and 0.25 s (scheduling noise on a loaded machine: other builds share the
       cores). Under valgrind (~50x slower) the fixed part scales by 50; the iteration part
       is measured under valgrind already. */
    scale = vg != NULL ? 50.0 : 1.0;
    bound = limit + tu_max(5.0 * one_iteration, 0.25 * scale);
    printf("  one iteration <= %.4f s; the limited solve: %llu iterations (%llu Newton), "
           "%.4f s wall, %.4f s by its stats; bound %.4f s%s\n",
           one_iteration, (unsigned long long)st.iterations,
           (unsigned long long)st.newton_iterations, wall, st.solve_seconds, bound,
           vg != NULL ? " (valgrind)" : "");
    CHECK_MSG(wall <= bound, "the solve took %.4f s with a limit of %.2f s: more than the bound "
              "%.4f s (one iteration %.4f s)", wall, limit, bound, one_iteration);
    /* ADMM does not start an iteration that, as long as its last one, would end past the
       limit: it may stop up to an iteration before the limit, not long before it. */
    CHECK_MSG(wall >= 0.5 * limit && st.solve_seconds >= 0.5 * limit,
              "TIME_LIMIT after %.4f s wall (%.4f s by the stats), long before the limit %.2f s",
              wall, st.solve_seconds, limit);
    CHECK_MSG(st.iterations >= 1 && st.iterations < 1000000000u, "%llu iterations",
              (unsigned long long)st.iterations);
    CHECK_MSG(st.gauss_seidel_sweeps == 0, "%llu sweeps without a limit at build",
              (unsigned long long)st.gauss_seidel_sweeps);
    cadmm_solver_free(sv);

    /* Built with the limit (M is made of the bodies' blocks): sweeps first, each started only
       when it and a measure fit in what is left; at 1e-14 they hand over to ADMM and Newton
       while enough time is left. Either way the solve ends within the same bound, and not
       long before the limit. */
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    t0 = now_seconds();
    solve_into("time limit 0.05 s, built with it", sv, &p, 1e-14, CADMM_STATUS_TIME_LIMIT, &o);
    wall = now_seconds() - t0;
    st = o.stats;
    tu_outcome_free(&o);
    printf("  built with the limit: %llu sweeps, %llu iterations, %.4f s wall\n",
           (unsigned long long)st.gauss_seidel_sweeps, (unsigned long long)st.iterations, wall);
    CHECK_MSG(st.gauss_seidel_sweeps >= 4, "%llu sweeps",
              (unsigned long long)st.gauss_seidel_sweeps);
    CHECK_MSG(wall <= bound && wall >= 0.5 * limit,
              "the swept solve took %.4f s with a limit of %.2f s (bound %.4f s)", wall, limit,
              bound);

    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    tu_problem_free(&p);
}

/* ---- case 7: the v-update backends ------------------------------------------------------ */

/* Each backend solves a generated problem to TOL by the independent measure; the matrix-free
 * one really runs conjugate gradients (and no Newton phase), the direct one none; a bad name
 * is refused and leaves the settings as they were. */
static void test_linear_solver(void)
{
    static const char *const names[] = {"direct", "iterative", "auto"};
    tu_rng g = tu_rng_new(2718u);
    tu_problem p = tu_gen_global(&g, 20, 30, 0.4, 0);
    cadmm_problem *lib = tu_require_problem(&p);
    cadmm_settings *s = settings_tol(TOL);

    printf("7. v-update backends (global, %zu bodies' velocities, %zu contacts):\n", p.n, p.nc);
    for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
        tu_outcome o;
        REQUIRE_OK(cadmm_settings_set_linear_solver(s, names[k]));
        tu_solve(&p, lib, s, &o);
        printf("  %-10s %-15s %6llu iterations, %llu conjugate-gradient iterations, "
               "independent error %.3e\n", names[k],
               o.solved_call ? tu_status_name(o.status) : "(failed)",
               (unsigned long long)o.stats.iterations,
               (unsigned long long)o.stats.linear_iterations, o.e_ind);
        CHECK_MSG(o.status == CADMM_STATUS_SOLVED, "%s: status %s", names[k],
                  tu_status_name(o.status));
        tu_check_outcome(names[k], &p, &o, TOL, 0.0, AGREE);
        if (k == 0)
            CHECK_MSG(o.stats.linear_iterations == 0, "direct: %llu CG iterations",
                      (unsigned long long)o.stats.linear_iterations);
        if (k == 1)
            CHECK_MSG(o.stats.linear_iterations > 0 && o.stats.newton_iterations == 0,
                      "iterative: %llu CG iterations, %llu Newton iterations",
                      (unsigned long long)o.stats.linear_iterations,
                      (unsigned long long)o.stats.newton_iterations);
        tu_outcome_free(&o);
    }
    EXPECT_RC(cadmm_settings_set_linear_solver(s, "cholesky"), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_linear_solver(s, NULL), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_settings_set_linear_solver(NULL, "auto"), CADMM_ERR_NULL_POINTER);

    cadmm_settings_free(s);
    cadmm_problem_free(lib);
    tu_problem_free(&p);
}

int main(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    printf("cadmm %s: update_values / update_local_values refusals, Anderson interval, trace "
           "phases, per-thread last error, time limit overrun, v-update backends\n", cadmm_version());
    test_update_values_errors();
    test_update_local_values();
    test_anderson_interval();
    test_trace_phase();
    test_last_error_threads();
    test_time_limit_overrun();
    test_linear_solver();
    return tu_finish("test_api_paths");
}
