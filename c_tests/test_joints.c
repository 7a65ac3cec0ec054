/* A global problem with one joint (bilateral constraint G^T v + b = 0), solved through the
 * C API and checked against its exact answer and against the joint-aware error measure of
 * test_util.h (docs/algorithms.md §3.1), which is independent of the library.
 *
 * The problem: one unit point mass on the ground, M = I3, H = I3 (contact frame = world
 * frame, normal first), f = (-9.81, 1.0, 0), w = 0, mu = 0.5, and one joint G = e_1 (the
 * T1 velocity), b = -0.1: G^T v + b = 0 forces v_1 = 0.1.
 *
 * Exact answer (M v = H r + G lambda + f, u = H^T v + w = v):
 *   - the mass is pressed into the ground (f_N < 0) and cannot take off, so u_N = v_0 = 0
 *     and r_N = -f_N = 9.81;
 *   - the joint makes it slide along T1 at u_T = (0.1, 0): Coulomb's law puts r_T on the
 *     cone's boundary, opposite the sliding velocity: r_T = -mu r_N u_T / ||u_T||
 *     = (-4.905, 0);
 *   - the T2 row: v_2 = r_2 + f_2 = 0;
 *   - the T1 row gives the multiplier: v_1 = r_1 + lambda + f_1, 0.1 = -4.905 + lambda + 1,
 *     lambda = 4.005.
 *   So v = (0, 0.1, 0), r = (9.81, -4.905, 0), lambda = 4.005: every term of the measure is
 *   zero. De Saxce check: u~ = u + (mu ||u_T||, 0, 0) = (0.05, 0.1, 0) is on the boundary
 *   of K*_mu (||u~_T|| mu = 0.05 = u~_N) and r . u~ = 9.81 * 0.05 - 4.905 * 0.1 = 0.
 *
 * Usage: test_joints [FCLIB_DATA_DIR] (the directory is not used). */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-10   /* solver tolerance */
#define ACC 1e-7    /* accuracy required on r, v, lambda (absolute; all are O(1..10)) */

static const int64_t DIAG_COLPTR[4] = {0, 1, 2, 3};
static const int64_t DIAG_ROWIND[3] = {0, 1, 2};
static const double ONES[3] = {1.0, 1.0, 1.0};
static const double F[3] = {-9.81, 1.0, 0.0};
static const double W0[3] = {0.0, 0.0, 0.0};
static const double MU[1] = {0.5};
static const int64_t G_COLPTR[2] = {0, 1};
static const int64_t G_ROWIND[1] = {1};
static const double G_VALUES[1] = {1.0};
static const double B[1] = {-0.1};

static const double R_EXACT[3] = {9.81, -4.905, 0.0};
static const double V_EXACT[3] = {0.0, 0.1, 0.0};
static const double LAMBDA_EXACT = 4.005;

/* The least-squares multiplier of docs/algorithms.md §3.2 for the single column G = e_1:
 * lambda = argmin ||G l - (M v - H r - f)|| = (M v - H r - f)_1 (M = H = I). */
static double lambda_ls(const double r[3], const double v[3]) { return v[1] - r[1] - F[1]; }

int main(void)
{
    cadmm_csc I3 = {3, 3, DIAG_COLPTR, DIAG_ROWIND, ONES};
    cadmm_csc G = {3, 1, G_COLPTR, G_ROWIND, G_VALUES};
    tu_csc Mo = tu_csc_copy(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONES);
    tu_csc Ho = tu_csc_copy(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONES);
    tu_csc Go = tu_csc_copy(3, 1, G_COLPTR, G_ROWIND, G_VALUES);
    cadmm_problem *p = NULL;
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    cadmm_status status = -1;
    cadmm_stats st;
    double r[3], u[3], v[3], lambda[1] = {-1.0}, e_lib = -1.0, e_ind;
    size_t n_joints = 99;

    printf("cadmm %s: one contact with one joint (exact answer known)\n", cadmm_version());

    /* The independent measure itself: zero at the exact answer, and it sees each term. */
    {
        double l = LAMBDA_EXACT, lbad = -LAMBDA_EXACT, vbad[3] = {0.0, 0.2, 0.0};
        double e0 = tu_global_error_joints(&Mo, &Ho, &Go, F, W0, B, MU, 1, R_EXACT, V_EXACT, &l);
        double e_lam = tu_global_error_joints(&Mo, &Ho, &Go, F, W0, B, MU, 1, R_EXACT, V_EXACT,
                                              &lbad);
        double e_joint;
        l = lambda_ls(R_EXACT, vbad);
        e_joint = tu_global_error_joints(&Mo, &Ho, &Go, F, W0, B, MU, 1, R_EXACT, vbad, &l);
        printf("  independent measure: exact %.3e, lambda negated %.3e, v_1 = 0.2 %.3e\n", e0,
               e_lam, e_joint);
        CHECK_MSG(e0 <= 1e-15, "independent measure of the exact answer: %.3e", e0);
        /* equation term: ||2 lambda e_1|| / max(||f||, ||M v||, ||H r + G lambda||) */
        CHECK_MSG(e_lam > 0.5, "independent measure with lambda negated: %.3e", e_lam);
        /* joint term |0.2 - 0.1| / max(|G^T v| = 0.2, |b| = 0.1, |G|^T |f / M_11| = 1) = 0.1
           (the free motion's joint velocity, docs/algorithms.md §3.1) */
        CHECK_MSG(fabs(e_joint - 0.1) <= 0.01, "independent measure at v_1 = 0.2: %.3e (~0.1)",
                  e_joint);
    }

    REQUIRE(cadmm_problem_new_global(3, 1, &I3, &I3, F, W0, MU, &p) == CADMM_OK);
    REQUIRE(cadmm_problem_set_joints(p, &G, B) == CADMM_OK);
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_variant(s, "auto") == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_solver_new(p, s, &sv) == CADMM_OK);

    /* The number of joints is known before any solve. */
    CHECK(cadmm_solver_get_joint_multipliers(sv, NULL, &n_joints) == CADMM_OK);
    CHECK_MSG(n_joints == 1, "n_joints = %zu, expected 1", n_joints);

    REQUIRE(cadmm_solver_solve(sv, &status) == CADMM_OK);
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    REQUIRE(cadmm_solver_get_stats(sv, &st) == CADMM_OK);
    REQUIRE(cadmm_solver_get_solution(sv, r, u, v) == CADMM_OK);
    n_joints = 99;
    REQUIRE(cadmm_solver_get_joint_multipliers(sv, lambda, &n_joints) == CADMM_OK);
    printf("  status %s after %llu iterations, stats.error %.3e\n", tu_status_name(status),
           (unsigned long long)st.iterations, st.error);
    printf("  r = (%.12g, %.12g, %.12g), v = (%.12g, %.12g, %.12g), lambda = %.12g\n", r[0],
           r[1], r[2], v[0], v[1], v[2], lambda[0]);

    CHECK_MSG(status == CADMM_STATUS_SOLVED, "status %s, expected solved", tu_status_name(status));
    CHECK_MSG(n_joints == 1, "n_joints = %zu after the solve", n_joints);
    CHECK_MSG(tu_diff_norm(r, R_EXACT, 3) <= ACC,
              "r = (%.12g, %.12g, %.12g), exact (9.81, -4.905, 0)",
              r[0], r[1], r[2]);
    CHECK_MSG(tu_diff_norm(v, V_EXACT, 3) <= ACC, "v = (%.12g, %.12g, %.12g), exact (0, 0.1, 0)",
              v[0], v[1], v[2]);
    CHECK_MSG(tu_diff_norm(u, V_EXACT, 3) <= ACC, "u = (%.12g, %.12g, %.12g), exact (0, 0.1, 0)",
              u[0], u[1], u[2]);
    CHECK_MSG(fabs(lambda[0] - LAMBDA_EXACT) <= ACC, "lambda = %.12g, exact 4.005", lambda[0]);

    /* The library's measure (lambda recomputed by least squares) and the independent one
     * with the solver's own lambda: both at or below the tolerance, and they agree. */
    REQUIRE(cadmm_problem_error(p, r, u, v, &e_lib) == CADMM_OK);
    e_ind = tu_global_error_joints(&Mo, &Ho, &Go, F, W0, B, MU, 1, r, v, lambda);
    printf("  error of the answer: cadmm_problem_error %.3e, independent (solver's lambda) "
           "%.3e, stats %.3e\n", e_lib, e_ind, st.error);
    CHECK_MSG(e_lib <= 1e-8, "cadmm_problem_error of the solver's answer: %.3e > 1e-8", e_lib);
    CHECK_MSG(e_ind <= 1e-8, "independent error of the solver's answer: %.3e > 1e-8", e_ind);
    CHECK_MSG(st.error <= TOL, "stats.error %.3e > tol %.0e for a solved problem", st.error, TOL);
    /* The least-squares lambda makes the library's value the smaller one (§3.2); both
     * measure the same point, which is within ~1e-10 of the exact answer. */
    CHECK_MSG(e_lib <= e_ind + 1e-15, "least-squares lambda gave a larger error %.3e than the "
              "solver's lambda %.3e", e_lib, e_ind);
    CHECK_MSG(fabs(e_lib - e_ind) <= 1e-9, "library %.3e and independent %.3e disagree", e_lib,
              e_ind);
    /* The exact answer. */
    REQUIRE(cadmm_problem_error(p, R_EXACT, NULL, V_EXACT, &e_lib) == CADMM_OK);
    CHECK_MSG(e_lib <= 1e-15, "cadmm_problem_error of the exact answer: %.3e", e_lib);

    /* Perturbed answers: the joint term (v_1 = 0.2) and the cone term (r_T1 = -4.0, inside
     * the cone while the contact slides; the least-squares lambda absorbs the equation
     * residual of row 1, so only the complementarity term sees it). The independent
     * measure, with the least-squares lambda, must give the same value. */
    {
        struct {
            const char *what;
            double r[3], v[3];
        } cases[2] = {
            {"v_1 = 0.2", {9.81, -4.905, 0.0}, {0.0, 0.2, 0.0}},
            {"r_T1 = -4.0", {9.81, -4.0, 0.0}, {0.0, 0.1, 0.0}},
        };
        for (int i = 0; i < 2; ++i) {
            double l = lambda_ls(cases[i].r, cases[i].v), e_c;
            REQUIRE(cadmm_problem_error(p, cases[i].r, NULL, cases[i].v, &e_lib) == CADMM_OK);
            e_c = tu_global_error_joints(&Mo, &Ho, &Go, F, W0, B, MU, 1, cases[i].r, cases[i].v,
                                         &l);
            printf("  perturbed (%s): cadmm_problem_error %.6e, independent %.6e\n",
                   cases[i].what, e_lib, e_c);
            CHECK_MSG(e_lib > 1e-3, "perturbed answer (%s): error %.3e <= 1e-3", cases[i].what,
                      e_lib);
            CHECK_MSG(fabs(e_lib - e_c) <= 1e-12 * e_c, "perturbed answer (%s): library %.15e, "
                      "independent %.15e", cases[i].what, e_lib, e_c);
        }
    }

    /* Without joints the multiplier array is empty (and left untouched). */
    {
        cadmm_problem *q = NULL;
        cadmm_solver *s0 = NULL;
        double untouched[1] = {-7.0};
        size_t k = 99;
        REQUIRE(cadmm_problem_new_global(3, 1, &I3, &I3, F, W0, MU, &q) == CADMM_OK);
        REQUIRE(cadmm_solver_new(q, s, &s0) == CADMM_OK);
        CHECK(cadmm_solver_get_joint_multipliers(s0, untouched, &k) == CADMM_OK);
        CHECK_MSG(k == 0 && untouched[0] == -7.0, "no joints: n_joints %zu, lambda[0] %g", k,
                  untouched[0]);
        CHECK(cadmm_solver_get_joint_multipliers(NULL, untouched, &k) == CADMM_ERR_NULL_POINTER);
        cadmm_solver_free(s0);
        cadmm_problem_free(q);
    }

    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(p);
    tu_csc_free(&Mo);
    tu_csc_free(&Ho);
    tu_csc_free(&Go);
    return tu_finish("test_joints");
}
