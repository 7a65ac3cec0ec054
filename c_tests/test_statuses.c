/* The statuses other than SOLVED, produced on purpose across the C boundary:
 *
 *   MAX_ITERATIONS  max_iterations = 1, 2, 3 on generated problems (global and local) and on
 *                   two FCLib files (Box_Stacks-i0122-82-5 global, Capsules-i100-889 local);
 *   TIME_LIMIT      a time limit of 1e-9 s with an iteration cap of 10^9 on a generated global
 *                   problem of 600 contacts and on the FCLib file Box_Stacks-i1000-557-13
 *                   (the limit is checked after each iteration, so the solve stops after the
 *                   first one, long before any cap);
 *   NUMERICAL_ERROR finite data whose first iterate overflows: M = 1e-160 I with f ~ 1e150
 *                   (global: v = (M + rho H H^T)^-1 f ~ 1e310) and W = 1e-160 I with q ~ 1e150
 *                   (local). Every datum and every norm of the data is representable
 *                   (||f||^2 ~ 1e300), so the independent measure is well defined; only the
 *                   iterates overflow.
 *
 * For each: the call succeeds, the status is the expected one, r, u, v are finite, the
 * returned u is consistent with r or v, stats.error equals the independent error of the
 * returned answer (test_util.h; relative 1e-9), and that error is above the tolerance
 * (tu_check_outcome). A limit reached is also checked for its own evidence: the iteration
 * count equals the cap, or the solve time exceeds the limit with fewer iterations than the
 * cap.
 *
 * Usage: test_statuses FCLIB_DATA_DIR. The generated cases always run; the FCLib cases need
 * the data directory, and the program exits 77 (CTest: skipped) when it is missing and
 * everything else passed. */
#include "cadmm.h"
#include "fclib_read.h"
#include "test_util.h"

#define TOL 1e-8
#define AGREE 1e-9 /* stats.error against the independent error, relative */

/* ---- generated problems ------------------------------------------------------------------- */

/* One contact whose first iterate overflows: diagonal M (or W) = 1e-160 I, H = I, and a
 * free velocity ~ 1e150 / 1e-160 = 1e310. */
static tu_problem gen_overflow(int global)
{
    static const double diag[9] = {1e-160, 0, 0, 0, 1e-160, 0, 0, 0, 1e-160};
    static const double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    tu_problem p;
    memset(&p, 0, sizeof p);
    p.is_global = global;
    p.nc = 1;
    p.mu = (double *)tu_calloc(1, sizeof(double));
    p.mu[0] = 0.3;
    if (global) {
        p.n = 3;
        p.M = tu_csc_from_dense(3, 3, diag);
        p.H = tu_csc_from_dense(3, 3, eye);
        p.f = (double *)tu_calloc(3, sizeof(double));
        p.w = (double *)tu_calloc(3, sizeof(double));
        p.f[0] = -1e150;
        p.f[1] = 1e149;
    } else {
        p.W = tu_csc_from_dense(3, 3, diag);
        p.q = (double *)tu_calloc(3, sizeof(double));
        p.q[0] = -1e150;
        p.q[1] = 1e149;
    }
    return p;
}

/* ---- one solve with an expected status ---------------------------------------------------- */

enum limit_kind { NO_LIMIT, ITERATION_CAP, TIME_CAP };

/* Solves `p` with variant "auto", tolerance TOL and the given limits; checks the expected
 * status and tu_check_outcome. For ITERATION_CAP the iteration count must be the cap; for
 * TIME_CAP the solve time must exceed the limit and the count stay below the cap. */
static void expect_status(const char *label, const tu_problem *p, cadmm_status expected,
                          uint32_t max_iterations, double time_limit, enum limit_kind limit)
{
    cadmm_problem *lib = NULL;
    cadmm_settings *s = NULL;
    tu_outcome o;
    cadmm_result rc = tu_problem_to_cadmm(p, &lib);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: building the problem failed (%d): %s", label, (int)rc, cadmm_last_error());
        return;
    }
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_variant(s, "auto") == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_settings_set_max_iterations(s, max_iterations) == CADMM_OK);
    if (time_limit > 0) REQUIRE(cadmm_settings_set_time_limit(s, time_limit) == CADMM_OK);
    tu_solve(p, lib, s, &o);
    printf("  %-44s %-15s after %6llu iterations (%.4f s), stats.error %.6e, independent %.6e\n",
           label, o.solved_call ? tu_status_name(o.status) : "(call failed)",
           (unsigned long long)o.stats.iterations, o.stats.solve_seconds, o.stats.error, o.e_ind);
    if (o.solved_call) {
        CHECK_MSG(o.status == expected, "%s: status %s, expected %s", label,
                  tu_status_name(o.status), tu_status_name(expected));
        if (limit == ITERATION_CAP)
            CHECK_MSG(o.stats.iterations == max_iterations, "%s: %llu iterations, cap %u", label,
                      (unsigned long long)o.stats.iterations, (unsigned)max_iterations);
        if (limit == TIME_CAP)
            CHECK_MSG(o.stats.solve_seconds >= time_limit && o.stats.iterations < max_iterations,
                      "%s: %llu iterations in %.3g s, limit %.3g s", label,
                      (unsigned long long)o.stats.iterations, o.stats.solve_seconds, time_limit);
    }
    /* a non-solved status must leave error > tol: the slack argument is unused here */
    tu_check_outcome(label, p, &o, TOL, 0.0, AGREE);
    tu_outcome_free(&o);
    cadmm_settings_free(s);
    cadmm_problem_free(lib);
}

static void max_iterations_cases(const char *name, const tu_problem *p)
{
    for (uint32_t k = 1; k <= 3; ++k) {
        char label[160];
        snprintf(label, sizeof label, "%s, max_iterations %u", name, (unsigned)k);
        expect_status(label, p, CADMM_STATUS_MAX_ITERATIONS, k, 0.0, ITERATION_CAP);
    }
}

static void time_limit_case(const char *name, const tu_problem *p)
{
    char label[160];
    snprintf(label, sizeof label, "%s, time limit 1e-9 s", name);
    expect_status(label, p, CADMM_STATUS_TIME_LIMIT, 1000000000u, 1e-9, TIME_CAP);
}

/* ---- FCLib files ---------------------------------------------------------------------------- */

static int read_file(const char *dir, const char *file, tu_problem *p)
{
    char path[4096], err[512];
    tu_join(path, sizeof path, dir, file);
    if (fcr_read(path, p, err, sizeof err) != 0) {
        TU_FAIL("reading %s: %s", path, err);
        return 0;
    }
    if (p->has_joints) {
        TU_FAIL("%s has joints, which the independent reader does not read", file);
        fcr_free(p);
        return 0;
    }
    return 1;
}

int main(int argc, char **argv)
{
    const char *dir = argc > 1 ? argv[1] : "../shared/data/fclib";
    tu_rng g = tu_rng_new(20261123u);
    int rc;
    printf("cadmm %s: non-solved statuses (tol %.0e)\n", cadmm_version(), TOL);

    printf("MAX_ITERATIONS\n");
    {
        tu_problem gp = tu_gen_global(&g, 8, 12, 0.4, 0), lp = tu_gen_local(&g, 5, 0.6);
        max_iterations_cases("generated global (24 velocities, 12 contacts)", &gp);
        max_iterations_cases("generated local (5 contacts)", &lp);
        tu_problem_free(&gp);
        tu_problem_free(&lp);
    }
    printf("TIME_LIMIT\n");
    {
        tu_problem gp = tu_gen_global(&g, 300, 600, 0.5, 0);
        time_limit_case("generated global (900 velocities, 600 contacts)", &gp);
        tu_problem_free(&gp);
    }
    printf("NUMERICAL_ERROR\n");
    for (int global = 1; global >= 0; --global) {
        tu_problem p = gen_overflow(global);
        expect_status(global ? "global, M = 1e-160 I, f ~ 1e150" : "local, W = 1e-160 I, q ~ 1e150",
                      &p, CADMM_STATUS_NUMERICAL_ERROR, 1000, 0.0, NO_LIMIT);
        tu_problem_free(&p);
    }

    if (!tu_is_dir(dir)) {
        printf("SKIP (FCLib part): data directory '%s' not found\n", dir);
        rc = tu_finish("test_statuses");
        return rc == 0 ? TU_SKIP : rc;
    }
    printf("FCLib files (%s)\n", dir);
    {
        tu_problem p;
        if (read_file(dir, "global/Box_Stacks-i0122-82-5.hdf5", &p)) {
            max_iterations_cases("Box_Stacks-i0122-82-5", &p);
            fcr_free(&p);
        }
        if (read_file(dir, "local/Capsules-i100-889.hdf5", &p)) {
            max_iterations_cases("Capsules-i100-889", &p);
            fcr_free(&p);
        }
        if (read_file(dir, "global/Box_Stacks-i1000-557-13.hdf5", &p)) {
            time_limit_case("Box_Stacks-i1000-557-13", &p);
            fcr_free(&p);
        }
        if (read_file(dir, "local/KaplasTower-i1061-4.hdf5", &p)) {
            time_limit_case("KaplasTower-i1061-4", &p);
            fcr_free(&p);
        }
    }
    return tu_finish("test_statuses");
}
