/* Changing a built solver between solves, and the codes that came with it:
 *
 *   cadmm_solver_update_settings  the tolerance, the iteration and time limits, the trace and
 *                                 the threads are taken; a change of any other setting
 *                                 (variant, initial rho, s update, Anderson memory and
 *                                 interval, Newton phase, islands) is refused with
 *                                 CADMM_ERR_INVALID_SETTING, a message naming the setting,
 *                                 and no change at all (the next solve still runs with the
 *                                 previous settings);
 *   CADMM_STATUS_UNSOLVED         the status of a new solver's statistics;
 *   CADMM_ERR_PATTERN_CHANGED     cadmm_solver_update with the same sizes but another
 *                                 sparsity pattern of H (global) or W (local);
 *   cadmm_result_message          PATTERN_CHANGED and OUT_OF_MEMORY have their own messages.
 *
 * Every solve is checked against the independent error measure of test_util.h
 * (tu_check_outcome): a SOLVED answer is within the tolerance by that measure, a limit
 * reached is above it, and stats.error agrees with it.
 *
 * Usage: test_update_settings [FCLIB_DATA_DIR] (the directory is not used: the problems are
 * generated). */
#include "cadmm.h"
#include "test_util.h"

#include <stdbool.h>

#define AGREE 1e-9 /* stats.error against the independent error, relative */


/* ---- problems ----------------------------------------------------------------------------- */

enum pattern { ORIGINAL, EXTRA_NONZERO, MOVED_NONZERO };

/* A stack of three free bodies of 3 velocities each on the ground (n = 9, 3 contacts:
 * body 0 on the ground, body 1 on body 0, body 2 on body 1), every body pushed down and
 * sideways; the contact frames are the identity plus a fixed perturbation, mu = 0.5. One
 * island; H has full rank (W = H^T M^-1 H is definite).
 *
 * The block of contact 0 on body 0 has a hole: its entry (row 1, column 2) is zero. The
 * EXTRA_NONZERO pattern fills it (one more non-zero), MOVED_NONZERO fills it and empties
 * the entry (row 2, column 1) of the same block (as many non-zeros, one moved). Every
 * other value is the same in the three (fixed seed), and the coupling graph too. */
static tu_problem stack_problem(enum pattern pat)
{
    const size_t nb = 3, nc = 3, n = 9, m = 9;
    tu_rng g = tu_rng_new(20240611u);
    tu_problem p;
    double Md[81] = {0}, Hd[81] = {0};
    memset(&p, 0, sizeof p);
    p.is_global = 1;
    p.n = n;
    p.nc = nc;
    for (size_t b = 0; b < nb; ++b) {
        double mass = tu_rng_range(&g, 0.5, 4.0), c = tu_rng_range(&g, -0.2, 0.2);
        for (size_t i = 0; i < 3; ++i) Md[(3 * b + i) * n + 3 * b + i] = mass;
        Md[(3 * b) * n + 3 * b + 1] = Md[(3 * b + 1) * n + 3 * b] = c * mass;
    }
    for (size_t k = 0; k < nc; ++k) {
        size_t b1 = k; /* the upper body; k - 1 the lower one, the ground for k = 0 */
        for (size_t i = 0; i < 3; ++i)
            for (size_t j = 0; j < 3; ++j) {
                double h = (i == j ? 1.0 : 0.0) + tu_rng_range(&g, -0.3, 0.3);
                Hd[(3 * b1 + i) * m + 3 * k + j] = h;
                if (k > 0) Hd[(3 * (b1 - 1) + i) * m + 3 * k + j] = -h;
            }
    }
    Hd[1 * m + 2] = 0.0; /* the hole: body 0 row 1, contact 0 column 2 */
    if (pat == EXTRA_NONZERO || pat == MOVED_NONZERO) Hd[1 * m + 2] = 0.1;
    if (pat == MOVED_NONZERO) {
        REQUIRE(Hd[2 * m + 1] != 0.0);
        Hd[2 * m + 1] = 0.0;
    }
    p.M = tu_csc_from_dense(n, n, Md);
    p.H = tu_csc_from_dense(n, m, Hd);
    p.f = (double *)tu_calloc(n, sizeof(double));
    p.w = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    for (size_t i = 0; i < n; ++i) /* down (normal direction 0) and sideways */
        p.f[i] = i % 3 == 0 ? -2.0 - tu_rng_range(&g, 0.0, 1.0) : tu_rng_range(&g, -1.2, 1.2);
    for (size_t i = 0; i < m; ++i) p.w[i] = tu_rng_range(&g, -0.05, 0.05);
    for (size_t k = 0; k < nc; ++k) p.mu[k] = 0.5;
    return p;
}

/* A local problem of two coupled contacts: W = 2 I with the coupling W[0][3] = W[3][0] =
 * 0.2 and W[0][1] = W[1][0] = 0.3. EXTRA_NONZERO adds the symmetric pair W[1][4] = W[4][1]
 * = 0.1; MOVED_NONZERO moves the coupling pair from (0, 3) to (1, 4). W stays symmetric,
 * diagonally dominant, and one island (contacts 0 and 1 coupled) in all three. */
static tu_problem coupled_local_problem(enum pattern pat)
{
    const size_t nc = 2, m = 6;
    static const double q[6] = {-1.0, 0.3, -0.2, -0.5, -0.4, 0.1};
    tu_problem p;
    double Wd[36] = {0};
    memset(&p, 0, sizeof p);
    p.nc = nc;
    for (size_t i = 0; i < m; ++i) Wd[i * m + i] = 2.0;
    Wd[0 * m + 1] = Wd[1 * m + 0] = 0.3;
    if (pat != MOVED_NONZERO) Wd[0 * m + 3] = Wd[3 * m + 0] = 0.2;
    if (pat != ORIGINAL) Wd[1 * m + 4] = Wd[4 * m + 1] = pat == MOVED_NONZERO ? 0.2 : 0.1;
    p.W = tu_csc_from_dense(m, m, Wd);
    p.q = (double *)tu_calloc(m, sizeof(double));
    memcpy(p.q, q, sizeof q);
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    p.mu[0] = 0.5;
    p.mu[1] = 0.4;
    return p;
}

/* ---- settings ------------------------------------------------------------------------------ */

/* The settings update_settings may change; everything else keeps its default. */
typedef struct knobs {
    double tolerance;
    uint32_t max_iterations;
    double time_limit; /* INFINITY: none */
    bool trace;
    size_t threads;
} knobs;

static knobs default_knobs(double tolerance)
{
    knobs k;
    k.tolerance = tolerance;
    k.max_iterations = 100000;
    k.time_limit = INFINITY;
    k.trace = false;
    k.threads = 1;
    return k;
}

/* New settings: the defaults, with the values of `k`. */
static cadmm_settings *make_settings(const knobs *k)
{
    cadmm_settings *s = NULL;
    REQUIRE_OK(cadmm_settings_new(&s));
    REQUIRE_OK(cadmm_settings_set_tolerance(s, k->tolerance));
    REQUIRE_OK(cadmm_settings_set_max_iterations(s, k->max_iterations));
    REQUIRE_OK(cadmm_settings_set_time_limit(s, k->time_limit));
    REQUIRE_OK(cadmm_settings_set_trace(s, k->trace));
    REQUIRE_OK(cadmm_settings_set_threads(s, k->threads));
    return s;
}

/* update_settings with the defaults and `k`: must succeed. */
static void update_ok(const char *label, cadmm_solver *sv, const knobs *k)
{
    cadmm_settings *s = make_settings(k);
    cadmm_result rc = cadmm_solver_update_settings(sv, s);
    CHECK_MSG(rc == CADMM_OK, "%s: update_settings returned %s (%d), expected CADMM_OK (\"%s\")",
              label, tu_result_name(rc), (int)rc, cadmm_solver_last_error(sv));
    cadmm_settings_free(s);
}

/* ---- solving and checking ------------------------------------------------------------------ */

/* Solves (cold unless the caller warm-started), reads everything back into `o` and checks it
 * with tu_check_outcome at tolerance `tol`; the status must be `expected`. Returns the
 * statistics. */
static cadmm_stats solve_check(const char *label, cadmm_solver *sv, const tu_problem *p,
                               const cadmm_problem *lib, double tol, cadmm_status expected)
{
    tu_outcome o;
    size_t m = 3 * p->nc;
    memset(&o, 0, sizeof o);
    o.status = -1;
    o.rc = cadmm_solver_solve(sv, &o.status);
    if (o.rc != CADMM_OK) {
        TU_FAIL("%s: cadmm_solver_solve returned %s (%d): %s", label, tu_result_name(o.rc),
                (int)o.rc, cadmm_solver_last_error(sv));
        o.stats.status = -1;
        return o.stats;
    }
    o.solved_call = 1;
    o.r = (double *)tu_calloc(m, sizeof(double));
    o.u = (double *)tu_calloc(m, sizeof(double));
    o.v = (double *)tu_calloc(p->n, sizeof(double));
    o.lambda = (double *)tu_calloc(0, sizeof(double));
    o.stats.struct_size = sizeof o.stats;
    REQUIRE_OK(cadmm_solver_get_stats(sv, &o.stats));
    REQUIRE_OK(cadmm_solver_get_solution(sv, o.r, o.u, p->is_global ? o.v : NULL));
    o.e_ind = tu_problem_error(p, o.r, o.v, o.lambda);
    REQUIRE_OK(cadmm_problem_error(lib, o.r, o.u, o.v, &o.e_lib));
    printf("  %-52s %-15s %6llu iterations, stats.error %.3e, independent %.3e\n", label,
           tu_status_name(o.status), (unsigned long long)o.stats.iterations, o.stats.error,
           o.e_ind);
    CHECK_MSG(o.status == expected, "%s: status %s, expected %s", label, tu_status_name(o.status),
              tu_status_name(expected));
    tu_check_outcome(label, p, &o, tol, 0.0, AGREE);
    tu_outcome_free(&o);
    return o.stats;
}

/* The solver still runs with max_iterations = 1 and tolerance 1e-14 (case 3). */
static void expect_still_one_iteration(const char *label, cadmm_solver *sv, const tu_problem *p,
                                       const cadmm_problem *lib)
{
    char what[200];
    cadmm_stats st;
    snprintf(what, sizeof what, "after %s", label);
    st = solve_check(what, sv, p, lib, 1e-14, CADMM_STATUS_MAX_ITERATIONS);
    CHECK_MSG(st.iterations == 1,
              "%s: %llu iterations, the refused update_settings changed the limit of 1",
              what, (unsigned long long)st.iterations);
}

/* update_settings with `s` (valid settings) must be refused with CADMM_ERR_INVALID_SETTING,
 * the solver's message naming `name` (as a whole word); then the solver must still run as
 * before. */
static void expect_refused(const char *label, const char *name, cadmm_solver *sv,
                           cadmm_settings *s, const tu_problem *p, const cadmm_problem *lib)
{
    cadmm_result rc = cadmm_solver_update_settings(sv, s);
    const char *msg = cadmm_solver_last_error(sv);
    CHECK_MSG(rc == CADMM_ERR_INVALID_SETTING,
              "update_settings with %s returned %s (%d), expected CADMM_ERR_INVALID_SETTING",
              label, tu_result_name(rc), (int)rc);
    CHECK_MSG(msg != NULL && tu_has_word(msg, name),
              "update_settings with %s: the message \"%s\" does not name '%s'", label,
              msg ? msg : "(NULL)", name);
    printf("  refused %-40s \"%s\"\n", label, msg ? msg : "(NULL)");
    cadmm_settings_free(s);
    expect_still_one_iteration(label, sv, p, lib);
}

/* ---- cases 1 to 5: update_settings on one global solver ------------------------------------ */

static void test_update_settings(void)
{
    tu_problem p = stack_problem(ORIGINAL);
    cadmm_problem *lib = tu_require_problem(&p);
    knobs k = default_knobs(1e-3);
    cadmm_settings *s = make_settings(&k);
    cadmm_solver *sv = NULL;
    cadmm_stats st, loose, tight;
    size_t len;

    printf("update_settings (global stack, n = %zu, %zu contacts):\n", p.n, p.nc);
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    cadmm_settings_free(s);

    /* 1. a new solver has not solved: UNSOLVED; then a loose solve */
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    REQUIRE_OK(cadmm_solver_get_stats(sv, &st));
    CHECK_MSG(st.status == CADMM_STATUS_UNSOLVED,
              "stats of a new solver: status %s (%d), expected unsolved (%d)",
              tu_status_name(st.status), (int)st.status, (int)CADMM_STATUS_UNSOLVED);
    CHECK_MSG(st.iterations == 0, "stats of a new solver: %llu iterations",
              (unsigned long long)st.iterations);
    loose = solve_check("1. tolerance 1e-3", sv, &p, lib, 1e-3, CADMM_STATUS_SOLVED);
    CHECK_MSG(loose.error <= 1e-3, "1. tolerance 1e-3: stats.error %.3e", loose.error);
    /* otherwise case 2 could not tell whether the new tolerance was taken */
    CHECK_MSG(loose.error > 1e-10,
              "1. the loose solve already reached %.3e <= 1e-10: choose another problem",
              loose.error);

    /* 2. only the tolerance changes, to 1e-10 */
    k.tolerance = 1e-10;
    update_ok("2. tolerance 1e-10", sv, &k);
    tight = solve_check("2. tolerance 1e-10 (cold)", sv, &p, lib, 1e-10, CADMM_STATUS_SOLVED);
    CHECK_MSG(tight.error <= 1e-10, "2. tolerance 1e-10: stats.error %.3e", tight.error);
    CHECK_MSG(tight.iterations >= 1, "2. tolerance 1e-10: %llu iterations",
              (unsigned long long)tight.iterations);
    printf("  (tolerance 1e-3: %llu iterations, error %.3e; 1e-10: %llu iterations, error "
           "%.3e)\n",
           (unsigned long long)loose.iterations, loose.error,
           (unsigned long long)tight.iterations, tight.error);

    /* 3. an iteration limit of 1 with a tolerance the first iterate cannot meet */
    k.tolerance = 1e-14;
    k.max_iterations = 1;
    update_ok("3. max_iterations 1, tolerance 1e-14", sv, &k);
    st = solve_check("3. max_iterations 1, tolerance 1e-14", sv, &p, lib, 1e-14,
                     CADMM_STATUS_MAX_ITERATIONS);
    CHECK_MSG(st.iterations == 1, "3. max_iterations 1: %llu iterations",
              (unsigned long long)st.iterations);

    /* 4. refusals: each carries generous limits too, so that a partial update would show
       in the next solve (it would not stop after 1 iteration) */
    {
        knobs loose_k = default_knobs(1e-6);
        loose_k.max_iterations = 1000;
        loose_k.trace = true;
        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_variant(s, "cp-N"));
        expect_refused("variant cp-N", "variant", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_islands(s, false));
        expect_refused("islands off", "islands", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_anderson(s, 3));
        expect_refused("Anderson memory 3", "anderson", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_anderson_interval(s, 2));
        expect_refused("Anderson interval 2", "anderson_interval", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_initial_rho(s, "given", 2.0));
        expect_refused("initial rho given 2", "initial_rho", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_s_update(s, "external"));
        expect_refused("s update external", "s_update", sv, s, &p, lib);

        s = make_settings(&loose_k);
        REQUIRE_OK(cadmm_settings_set_newton(s, false));
        expect_refused("Newton phase off", "newton_polish", sv, s, &p, lib);

        /* invalid values: refused where they are set, with INVALID_SETTING, the settings
           unchanged; those settings (still case 3's values) are then accepted and change
           nothing */
        s = make_settings(&k);
        EXPECT_RC(cadmm_settings_set_tolerance(s, -1.0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_tolerance(s, 0.0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_tolerance(s, NAN), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_max_iterations(s, 0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_time_limit(s, -1.0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_threads(s, 0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_solver_update_settings(sv, s), CADMM_OK);
        expect_still_one_iteration("settings whose invalid values were refused", sv, &p, lib);

        /* NULL arguments */
        EXPECT_RC(cadmm_solver_update_settings(NULL, s), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_update_settings(sv, NULL), CADMM_ERR_NULL_POINTER);
        cadmm_settings_free(s);
        expect_still_one_iteration("update_settings with NULL settings", sv, &p, lib);
    }

    /* the time limit is taken: 1e-9 s stops the solve long before the iteration cap (the
       library may stop before the first iteration) */
    k = default_knobs(1e-14);
    k.max_iterations = 1000000000u;
    k.time_limit = 1e-9;
    update_ok("time limit 1e-9 s", sv, &k);
    st = solve_check("time limit 1e-9 s", sv, &p, lib, 1e-14, CADMM_STATUS_TIME_LIMIT);
    CHECK_MSG(st.iterations < k.max_iterations && st.solve_seconds >= k.time_limit,
              "time limit 1e-9 s: %llu iterations in %.3g s", (unsigned long long)st.iterations,
              st.solve_seconds);

    /* 5. the trace on (with 2 threads and a time limit of a minute: also accepted), then off */
    k = default_knobs(1e-8);
    k.trace = true;
    k.threads = 2;
    k.time_limit = 60.0;
    update_ok("5. trace on, 2 threads, time limit 60 s", sv, &k);
    st = solve_check("5. trace on", sv, &p, lib, 1e-8, CADMM_STATUS_SOLVED);
    CHECK_MSG(st.iterations > 1, "5. trace on: %llu iterations (the problem should need more)",
              (unsigned long long)st.iterations);
    len = cadmm_solver_trace_len(sv);
    CHECK_MSG(len > 0, "5. trace on: trace_len %zu after %llu iterations", len,
              (unsigned long long)st.iterations);
    if (len > 0) {
        cadmm_trace_point pt;
        EXPECT_RC(cadmm_solver_get_trace(sv, 0, &pt), CADMM_OK);
        CHECK_MSG(pt.iteration >= 1, "5. first trace point at iteration %llu",
                  (unsigned long long)pt.iteration);
    }
    printf("  trace on: %zu points (%llu iterations, %llu of them Newton steps in %llu "
           "phases)\n",
           len, (unsigned long long)st.iterations, (unsigned long long)st.newton_iterations,
           (unsigned long long)st.newton_phases);
    k.trace = false;
    update_ok("5. trace off", sv, &k);
    st = solve_check("5. trace off", sv, &p, lib, 1e-8, CADMM_STATUS_SOLVED);
    len = cadmm_solver_trace_len(sv);
    CHECK_MSG(len == 0, "5. trace off: trace_len %zu after %llu iterations", len,
              (unsigned long long)st.iterations);

    cadmm_solver_free(sv);
    cadmm_problem_free(lib);
    tu_problem_free(&p);
}

/* ---- case 6: cadmm_solver_update with another pattern --------------------------------------- */

/* Builds a solver on `orig`, then updates it with `extra` and `moved` (same sizes, other
 * pattern): CADMM_ERR_PATTERN_CHANGED each time, and the solve refuses with the same code;
 * an update with the original pattern and other values repairs it. */
static void pattern_case(const char *name, tu_problem *orig, tu_problem *extra,
                         tu_problem *moved)
{
    cadmm_problem *lib = tu_require_problem(orig), *lib_extra = tu_require_problem(extra),
                  *lib_moved = tu_require_problem(moved), *lib_vals;
    knobs k = default_knobs(1e-8);
    cadmm_settings *s = make_settings(&k);
    cadmm_solver *sv = NULL;
    cadmm_result rc;
    char label[160];

    printf("update with another pattern (%s):\n", name);
    REQUIRE(orig->is_global ? orig->H.colptr[orig->H.ncols] + 1 == extra->H.colptr[extra->H.ncols]
                            : orig->W.colptr[orig->W.ncols] + 2 == extra->W.colptr[extra->W.ncols]);
    REQUIRE(orig->is_global ? orig->H.colptr[orig->H.ncols] == moved->H.colptr[moved->H.ncols]
                            : orig->W.colptr[orig->W.ncols] == moved->W.colptr[moved->W.ncols]);
    REQUIRE_OK(cadmm_solver_new(lib, s, &sv));
    cadmm_settings_free(s);
    snprintf(label, sizeof label, "%s, first solve", name);
    solve_check(label, sv, orig, lib, 1e-8, CADMM_STATUS_SOLVED);

    rc = cadmm_solver_update(sv, lib_extra);
    CHECK_MSG(rc == CADMM_ERR_PATTERN_CHANGED,
              "%s: update with one more non-zero returned %s (%d), expected "
              "CADMM_ERR_PATTERN_CHANGED (\"%s\")",
              name, tu_result_name(rc), (int)rc, cadmm_solver_last_error(sv));
    printf("  one more non-zero:  %s \"%s\"\n", tu_result_name(rc), cadmm_solver_last_error(sv));
    CHECK_MSG(cadmm_solver_last_error(sv)[0] != '\0', "%s: no message after the refused update",
              name);
    /* a refused update changes nothing: the problem held still solves */
    snprintf(label, sizeof label, "%s, after the refused update", name);
    solve_check(label, sv, orig, lib, 1e-8, CADMM_STATUS_SOLVED);

    rc = cadmm_solver_update(sv, lib_moved);
    CHECK_MSG(rc == CADMM_ERR_PATTERN_CHANGED,
              "%s: update with one non-zero moved returned %s (%d), expected "
              "CADMM_ERR_PATTERN_CHANGED (\"%s\")",
              name, tu_result_name(rc), (int)rc, cadmm_solver_last_error(sv));
    printf("  one non-zero moved: %s \"%s\"\n", tu_result_name(rc), cadmm_solver_last_error(sv));

    /* the same pattern with other values is accepted and solved */
    if (orig->is_global)
        for (size_t i = 0; i < orig->n; ++i) orig->f[i] *= 1.5;
    else
        for (size_t i = 0; i < 3 * orig->nc; ++i) orig->q[i] *= 1.5;
    lib_vals = tu_require_problem(orig);
    EXPECT_RC(cadmm_solver_update(sv, lib_vals), CADMM_OK);
    snprintf(label, sizeof label, "%s, same pattern, other values", name);
    solve_check(label, sv, orig, lib_vals, 1e-8, CADMM_STATUS_SOLVED);

    cadmm_solver_free(sv);
    cadmm_problem_free(lib);
    cadmm_problem_free(lib_extra);
    cadmm_problem_free(lib_moved);
    cadmm_problem_free(lib_vals);
}

static void test_pattern_changed(void)
{
    tu_problem g = stack_problem(ORIGINAL), ge = stack_problem(EXTRA_NONZERO),
               gm = stack_problem(MOVED_NONZERO);
    tu_problem l = coupled_local_problem(ORIGINAL), le = coupled_local_problem(EXTRA_NONZERO),
               lm = coupled_local_problem(MOVED_NONZERO);
    pattern_case("global, H", &g, &ge, &gm);
    pattern_case("local, W", &l, &le, &lm);
    tu_problem_free(&g);
    tu_problem_free(&ge);
    tu_problem_free(&gm);
    tu_problem_free(&l);
    tu_problem_free(&le);
    tu_problem_free(&lm);
}

/* ---- result messages ----------------------------------------------------------------------- */

static void test_messages(void)
{
    const char *unknown = cadmm_result_message(9999);
    const char *pattern = cadmm_result_message(CADMM_ERR_PATTERN_CHANGED);
    const char *oom = cadmm_result_message(CADMM_ERR_OUT_OF_MEMORY);
    CHECK_MSG(CADMM_ERR_PATTERN_CHANGED == 11 && CADMM_ERR_OUT_OF_MEMORY == 12 &&
                  CADMM_STATUS_UNSOLVED == 6,
              "codes: PATTERN_CHANGED %d, OUT_OF_MEMORY %d, UNSOLVED %d",
              (int)CADMM_ERR_PATTERN_CHANGED, (int)CADMM_ERR_OUT_OF_MEMORY,
              (int)CADMM_STATUS_UNSOLVED);
    REQUIRE(unknown != NULL && pattern != NULL && oom != NULL);
    printf("result messages: 11 \"%s\", 12 \"%s\", 9999 \"%s\"\n", pattern, oom, unknown);
    CHECK_MSG(strcmp(unknown, "unknown result code") == 0, "message of 9999: \"%s\"", unknown);
    CHECK_MSG(pattern[0] != '\0' && strcmp(pattern, unknown) != 0,
              "CADMM_ERR_PATTERN_CHANGED has no message of its own: \"%s\"", pattern);
    CHECK_MSG(oom[0] != '\0' && strcmp(oom, unknown) != 0,
              "CADMM_ERR_OUT_OF_MEMORY has no message of its own: \"%s\"", oom);
    CHECK_MSG(strcmp(pattern, oom) != 0, "PATTERN_CHANGED and OUT_OF_MEMORY share \"%s\"", oom);
    CHECK_MSG(strcmp(pattern, cadmm_result_message(CADMM_ERR_INVALID_CSC)) != 0,
              "PATTERN_CHANGED has the message of INVALID_CSC: \"%s\"", pattern);
}

int main(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    printf("cadmm %s: update_settings, UNSOLVED, PATTERN_CHANGED\n", cadmm_version());
    test_messages();
    test_update_settings();
    test_pattern_changed();
    return tu_finish("test_update_settings");
}
