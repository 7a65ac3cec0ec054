/* A motor with a force limit pushing a block that rests on the ground by friction: a bounded
 * joint row beside a frictional contact, through the C API, against exact answers and the
 * independent measure of test_util.h (tu_global_error_rows).
 *
 * The block: unit mass, M = H = I3 (contact frame = world frame, normal first),
 * f = (-9.81, 0, 0) (gravity's impulse over the step pressing it down), w = 0, mu = 0.5:
 * friction holds up to mu r_N = 4.905. The motor is the row G = e_1 (the T1 velocity),
 * b = -0.3 (target velocity 0.3), its multiplier in [-F, F] (the motor's impulse limit).
 *
 *   - F = 6 (strong): the block slides at the target, u_T = (0.3, 0), friction on the cone's
 *     boundary against it, r = (9.81, -4.905, 0); the T1 row 0.3 = r_1 + lambda gives
 *     lambda = 5.205, inside [-6, 6].
 *   - F = 3 (weak): the motor cannot overcome static friction: v = 0, lambda = 3 at its
 *     bound (row velocity v_1 - 0.3 = -0.3 <= 0, as the upper bound asks), r_T = (-3, 0),
 *     inside the cone (3 <= 4.905).
 *
 * Negative controls: the strong motor's answer is not a solution of the weak motor's
 * problem (its multiplier 5.205 is beyond the bound 3): both the library's measure and the
 * independent one must say so. A compliance on the row is checked too: with c = 0.01 and
 * the strong motor the row reads v_1 - 0.3 + 0.01 lambda = 0 and, sliding, lambda = v_1 +
 * 4.905, so 1.01 v_1 = 0.3 - 0.04905: v_1 = 0.25095 / 1.01, lambda = v_1 + 4.905 (inside
 * [-6, 6]). (With c = 0.1 the same algebra gives v_1 < 0: the soft motor then cannot move
 * the block, which sticks with lambda = 3.)
 *
 * Usage: test_joint_rows [FCLIB_DATA_DIR] (the directory is not used). */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-10 /* solver tolerance */
#define ACC 1e-7  /* accuracy required on r, v, lambda (absolute; all are O(1..10)) */

static const int64_t DIAG_COLPTR[4] = {0, 1, 2, 3};
static const int64_t DIAG_ROWIND[3] = {0, 1, 2};
static const double ONES[3] = {1.0, 1.0, 1.0};
static const double F[3] = {-9.81, 0.0, 0.0};
static const double W0[3] = {0.0, 0.0, 0.0};
static const double MU[1] = {0.5};
static const int64_t G_COLPTR[2] = {0, 1};
static const int64_t G_ROWIND[1] = {1};
static const double G_VALUES[1] = {1.0};
static const double B[1] = {-0.3};

/* One solve's answer and its measures (library and independent). */
typedef struct answer {
    double r[3], v[3], lambda[1], e_lib, e_ind;
    cadmm_status status;
} answer;

/* The block's problem with motor limit `limit` and compliance `c` (NULL on failure). */
static cadmm_problem *block(double limit, double c)
{
    cadmm_csc I3 = {3, 3, DIAG_COLPTR, DIAG_ROWIND, ONES};
    cadmm_csc G = {3, 1, G_COLPTR, G_ROWIND, G_VALUES};
    double lo[1] = {-limit}, hi[1] = {limit}, comp[1] = {c};
    cadmm_problem *p = NULL;
    if (cadmm_problem_new_global(3, 1, &I3, &I3, F, W0, MU, &p) != CADMM_OK ||
        cadmm_problem_set_joints(p, &G, B) != CADMM_OK ||
        cadmm_problem_set_joint_bounds(p, lo, hi) != CADMM_OK ||
        cadmm_problem_set_joint_compliance(p, comp) != CADMM_OK) {
        printf("building the problem failed: %s\n", cadmm_last_error());
        cadmm_problem_free(p);
        return NULL;
    }
    return p;
}

/* The independent measure of (r, v, lambda) on the block with motor limit `limit`. */
static double independent(double limit, double c, const double *r, const double *v,
                          const double *lambda)
{
    tu_csc Mo = tu_csc_copy(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONES);
    tu_csc Go = tu_csc_copy(3, 1, G_COLPTR, G_ROWIND, G_VALUES);
    double lo[1] = {-limit}, hi[1] = {limit}, comp[1] = {c};
    tu_rows rows = {lo, hi, comp, NULL, NULL};
    double e = tu_global_error_rows(&Mo, &Mo, &Go, F, W0, B, rows, MU, 1, r, v, lambda);
    tu_csc_free(&Mo);
    tu_csc_free(&Go);
    return e;
}

/* Solves the block with motor limit `limit` and compliance `c` into `a`; 0 when a call
 * failed. */
static int solve(double limit, double c, answer *a)
{
    cadmm_problem *p = block(limit, c);
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    double u[3];
    int ok = p != NULL && cadmm_settings_new(&s) == CADMM_OK &&
             cadmm_settings_set_tolerance(s, TOL) == CADMM_OK &&
             cadmm_solver_new(p, s, &sv) == CADMM_OK &&
             cadmm_solver_solve(sv, &a->status) == CADMM_OK &&
             cadmm_solver_get_solution(sv, a->r, u, a->v) == CADMM_OK &&
             cadmm_solver_get_joint_multipliers(sv, a->lambda, NULL) == CADMM_OK &&
             cadmm_problem_error_with_multipliers(p, a->r, a->v, a->lambda, &a->e_lib) == CADMM_OK;
    if (!ok) printf("solve failed: %s\n", cadmm_last_error());
    else a->e_ind = independent(limit, c, a->r, a->v, a->lambda);
    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(p);
    return ok;
}

static void expect(const char *what, const answer *a, const double r[3], const double v[3],
                   double lambda)
{
    printf("%s: status %d, r = (%.9f, %.9f, %.9f), v = (%.9f, %.9f, %.9f), lambda = %.9f, "
           "error %.3e (independent %.3e)\n",
           what, (int)a->status, a->r[0], a->r[1], a->r[2], a->v[0], a->v[1], a->v[2],
           a->lambda[0], a->e_lib, a->e_ind);
    CHECK_MSG(a->status == CADMM_STATUS_SOLVED, "%s: not solved", what);
    CHECK_MSG(a->e_ind <= TOL * (1 + 1e-3), "%s: independent error %.3e", what, a->e_ind);
    CHECK_MSG(tu_diff_norm(a->r, r, 3) <= ACC, "%s: r off", what);
    CHECK_MSG(tu_diff_norm(a->v, v, 3) <= ACC, "%s: v off", what);
    CHECK_MSG(fabs(a->lambda[0] - lambda) <= ACC, "%s: lambda off", what);
}

int main(void)
{
    answer strong, weak, soft;
    printf("cadmm %s: a motor with a force limit against static friction\n", cadmm_version());
    REQUIRE(solve(6.0, 0.0, &strong));
    REQUIRE(solve(3.0, 0.0, &weak));
    REQUIRE(solve(6.0, 0.01, &soft));
    {
        const double r[3] = {9.81, -4.905, 0.0}, v[3] = {0.0, 0.3, 0.0};
        expect("strong motor slides the block", &strong, r, v, 5.205);
    }
    {
        const double r[3] = {9.81, -3.0, 0.0}, v[3] = {0.0, 0.0, 0.0};
        expect("weak motor saturates, friction holds", &weak, r, v, 3.0);
    }
    {
        const double v1 = 0.25095 / 1.01, lambda = v1 + 4.905;
        const double r[3] = {9.81, -4.905, 0.0}, v[3] = {0.0, v1, 0.0};
        expect("compliant motor", &soft, r, v, lambda);
    }
    /* Negative control: the strong motor's answer on the weak motor's problem. */
    {
        cadmm_problem *p = block(3.0, 0.0);
        double e_lib = -1.0;
        REQUIRE(p != NULL);
        CHECK(cadmm_problem_error_with_multipliers(p, strong.r, strong.v, strong.lambda, &e_lib) ==
              CADMM_OK);
        double e_ind = independent(3.0, 0.0, strong.r, strong.v, strong.lambda);
        printf("negative control: the strong answer on the weak problem measures %.3e "
               "(independent %.3e)\n",
               e_lib, e_ind);
        CHECK_MSG(e_lib > 1e-2 && e_ind > 1e-2, "a multiplier beyond its bound went unseen");
        CHECK_MSG(fabs(e_lib - e_ind) <= 1e-12 * e_ind, "the two measures disagree");
        cadmm_problem_free(p);
    }
    /* The strong motor's solver takes the weak motor's bounds for the next step. */
    {
        cadmm_problem *p = block(6.0, 0.0);
        cadmm_settings *s = NULL;
        cadmm_solver *sv = NULL;
        cadmm_status status = -1;
        double weak_lo[1] = {-3.0}, weak_hi[1] = {3.0}, none[1] = {-INFINITY};
        double r[3], v[3], lambda[1];
        REQUIRE(p != NULL && cadmm_settings_new(&s) == CADMM_OK);
        REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
        REQUIRE(cadmm_solver_new(p, s, &sv) == CADMM_OK);
        CHECK(cadmm_solver_update_joint_rows(sv, weak_lo, weak_hi, NULL) == CADMM_OK);
        CHECK(cadmm_solver_solve(sv, &status) == CADMM_OK && status == CADMM_STATUS_SOLVED);
        CHECK(cadmm_solver_get_solution(sv, r, NULL, v) == CADMM_OK);
        CHECK(cadmm_solver_get_joint_multipliers(sv, lambda, NULL) == CADMM_OK);
        printf("updated to the weak motor: lambda = %.9f, v_1 = %.3e\n", lambda[0], v[1]);
        CHECK_MSG(fabs(lambda[0] - 3.0) <= ACC && fabs(v[1]) <= ACC, "update not taken");
        /* Both bounds infinite would make the row an equality: a new pattern, refused. */
        double open_hi[1] = {INFINITY};
        CHECK(cadmm_solver_update_joint_rows(sv, none, open_hi, NULL) ==
              CADMM_ERR_PATTERN_CHANGED);
        CHECK(cadmm_solver_update_joint_rows(sv, NULL, NULL, NULL) == CADMM_OK);
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
    /* Bad bounds are named. */
    {
        cadmm_problem *p = block(6.0, 0.0);
        double lo[1] = {1.0}, hi[1] = {0.0}, c[1] = {-1.0};
        REQUIRE(p != NULL);
        CHECK(cadmm_problem_set_joint_bounds(p, lo, hi) == CADMM_ERR_INVALID_VALUE);
        CHECK_MSG(strstr(cadmm_last_error(), "lower bound above upper bound") != NULL, "%s",
                  cadmm_last_error());
        CHECK(cadmm_problem_set_joint_compliance(p, c) == CADMM_ERR_INVALID_VALUE);
        CHECK_MSG(strstr(cadmm_last_error(), "compliance") != NULL, "%s", cadmm_last_error());
        CHECK(cadmm_problem_write_fclib(p, "joint_rows.hdf5") != CADMM_OK);
        cadmm_problem_free(p);
    }
    return tu_finish("test_joint_rows");
}
