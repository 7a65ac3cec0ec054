/* Dry joint friction and a soft constraint through the C API, against closed forms, each
 * step's answer checked by the independent measure of test_util.h (tu_global_error_rows).
 *
 * One body of mass m moving along one axis (n = 1, no contact), pushed by a force F_ext:
 *
 *   - Dry joint friction: the row G = 1, b = 0 (velocity 0), its multiplier in [-F h, F h].
 *     Below its limit (F >= F_ext) it holds: v = 0 and lambda = -F_ext h every step. Above
 *     (F < F_ext) it slips: each step v grows by h (F_ext - F) / m, lambda = -F h.
 *   - A spring of stiffness k: the compliant equality row v + y / h + c lambda = 0 with
 *     c = 1 / (h^2 k) (implicit Euler: lambda = -h k y_next), released at y = 0.1 without
 *     an external force: the periods between upward crossings of y = 0 within 0.2% of
 *     2 pi sqrt(m / k).
 *
 * Negative controls: the holding law on a slipping run, the slipping law on a holding run,
 * and the period of a quarter of the stiffness must all fail.
 *
 * Usage: test_joint_laws [FCLIB_DATA_DIR] (the directory is not used). */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-10
#define PI 3.14159265358979323846

static const int64_t ONE_COLPTR[2] = {0, 1};
static const int64_t ONE_ROWIND[1] = {0};
static const int64_t NONE_COLPTR[1] = {0};
static const int64_t NO_ROWS[1] = {0}; /* arrays of no entry (never read) */
static const double NO_VALUES[1] = {0.0};

/* One step of the body: M v = m v_prev + h F_ext + lambda, the row's b, bounds and
 * compliance as given; v and lambda out. 0 when a call failed or the step was not solved
 * to TOL by the independent measure. */
static int step(double m, double v_prev, double h, double force, double b, double lo, double hi,
                double c, double *v, double *lambda)
{
    double mass[1] = {m}, g[1] = {1.0}, f[1] = {m * v_prev + h * force}, bb[1] = {b};
    double lov[1] = {lo}, hiv[1] = {hi}, cv[1] = {c}, r[1] = {0.0};
    cadmm_csc M = {1, 1, ONE_COLPTR, ONE_ROWIND, mass};
    cadmm_csc H = {1, 0, NONE_COLPTR, NO_ROWS, NO_VALUES};
    cadmm_csc G = {1, 1, ONE_COLPTR, ONE_ROWIND, g};
    cadmm_problem *p = NULL;
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    cadmm_status status = CADMM_STATUS_UNSOLVED;
    int ok = cadmm_problem_new_global(1, 0, &M, &H, f, NO_VALUES, NO_VALUES, &p) == CADMM_OK &&
             cadmm_problem_set_joints(p, &G, bb) == CADMM_OK &&
             cadmm_problem_set_joint_bounds(p, lov, hiv) == CADMM_OK &&
             cadmm_problem_set_joint_compliance(p, cv) == CADMM_OK &&
             cadmm_settings_new(&s) == CADMM_OK &&
             cadmm_settings_set_tolerance(s, TOL) == CADMM_OK &&
             cadmm_solver_new(p, s, &sv) == CADMM_OK &&
             cadmm_solver_solve(sv, &status) == CADMM_OK &&
             cadmm_solver_get_solution(sv, r, NULL, v) == CADMM_OK &&
             cadmm_solver_get_joint_multipliers(sv, lambda, NULL) == CADMM_OK;
    if (!ok) printf("step failed: %s\n", cadmm_last_error());
    if (ok) {
        tu_csc Mo = tu_csc_copy(1, 1, ONE_COLPTR, ONE_ROWIND, mass);
        tu_csc Ho = tu_csc_copy(1, 0, NONE_COLPTR, NO_ROWS, NO_VALUES);
        tu_csc Go = tu_csc_copy(1, 1, ONE_COLPTR, ONE_ROWIND, g);
        tu_rows rows = {lov, hiv, cv, NULL, NULL};
        double e =
            tu_global_error_rows(&Mo, &Ho, &Go, f, NO_VALUES, bb, rows, NO_VALUES, 0, r, v, lambda);
        tu_csc_free(&Mo);
        tu_csc_free(&Ho);
        tu_csc_free(&Go);
        if (status != CADMM_STATUS_SOLVED || !(e <= TOL * (1 + 1e-3))) {
            printf("step not solved: status %d, independent error %.3e\n", (int)status, e);
            ok = 0;
        }
    }
    cadmm_solver_free(sv);
    cadmm_settings_free(s);
    cadmm_problem_free(p);
    return ok;
}

#define FRICTION_STEPS 20
#define MASS 2.0
#define PUSH 5.0 /* N */
#define H_FRICTION 0.01

/* The body pushed by PUSH against dry friction of limit `limit` (N) for FRICTION_STEPS
 * steps from rest: velocities and multipliers. */
static int dry_friction(double limit, double *v, double *lambda)
{
    double last = 0.0;
    for (int k = 0; k < FRICTION_STEPS; k++) {
        double F = limit * H_FRICTION;
        if (!step(MASS, last, H_FRICTION, PUSH, 0.0, -F, F, 0.0, &v[k], &lambda[k])) return 0;
        last = v[k];
    }
    return 1;
}

/* Holding: no motion, the friction carrying the push. */
static int holds(const double *v, const double *lambda)
{
    for (int k = 0; k < FRICTION_STEPS; k++)
        if (fabs(v[k]) > 1e-9 || fabs(lambda[k] + PUSH * H_FRICTION) > 1e-9) {
            printf("  step %d: v = %.3e, lambda = %.9f (holding wants 0, %.9f)\n", k, v[k],
                   lambda[k], -PUSH * H_FRICTION);
            return 0;
        }
    return 1;
}

/* Slipping: v grows by h (PUSH - limit) / m a step, the friction at -limit h. */
static int slips(const double *v, const double *lambda, double limit)
{
    for (int k = 0; k < FRICTION_STEPS; k++) {
        double want = (k + 1) * H_FRICTION * (PUSH - limit) / MASS;
        if (fabs(v[k] - want) > 1e-9 || fabs(lambda[k] + limit * H_FRICTION) > 1e-9) {
            printf("  step %d: v = %.9f, lambda = %.9f (slipping wants %.9f, %.9f)\n", k, v[k],
                   lambda[k], want, -limit * H_FRICTION);
            return 0;
        }
    }
    return 1;
}

#define H_SPRING 1e-3
#define SPRING_STEPS 4500

/* The spring of stiffness k released at y = 0.1: the periods between upward crossings of
 * y = 0 into periods (at most SPRING_STEPS), their number into *count. */
static int spring(double k, double *periods, int *count)
{
    double y = 0.1, v = 0.0, last_crossing = -1.0, lambda;
    *count = 0;
    for (int s = 0; s < SPRING_STEPS; s++) {
        double c = 1.0 / (H_SPRING * H_SPRING * k);
        if (!step(1.0, v, H_SPRING, 0.0, y / H_SPRING, -INFINITY, INFINITY, c, &v, &lambda))
            return 0;
        double y_next = y + H_SPRING * v;
        if (y < 0.0 && y_next >= 0.0) {
            double t = (s + (0.0 - y) / (y_next - y)) * H_SPRING;
            if (last_crossing >= 0.0) periods[(*count)++] = t - last_crossing;
            last_crossing = t;
        }
        y = y_next;
    }
    return 1;
}

/* Every period within 0.2% of `expected`, and at least one. */
static int period_is(const double *periods, int count, double expected)
{
    if (count == 0) {
        printf("  no whole period seen\n");
        return 0;
    }
    for (int i = 0; i < count; i++)
        if (fabs(periods[i] - expected) > 2e-3 * expected) {
            printf("  period %d: %.6f s, expected %.6f s\n", i, periods[i], expected);
            return 0;
        }
    return 1;
}

int main(void)
{
    double hv[FRICTION_STEPS], hl[FRICTION_STEPS], sv_[FRICTION_STEPS], sl[FRICTION_STEPS];
    double periods[SPRING_STEPS];
    int count;
    printf("cadmm %s: dry joint friction and a spring\n", cadmm_version());
    REQUIRE(dry_friction(1.25 * PUSH, hv, hl));
    REQUIRE(dry_friction(0.75 * PUSH, sv_, sl));
    CHECK_MSG(holds(hv, hl), "friction above the push does not hold the body");
    CHECK_MSG(slips(sv_, sl, 0.75 * PUSH), "friction below the push does not let it slip");
    printf("dry friction: holds at 1.25 x the push (lambda %.6f), slips at 0.75 x (v after "
           "%d steps %.6f m/s)\n",
           hl[FRICTION_STEPS - 1], FRICTION_STEPS, sv_[FRICTION_STEPS - 1]);
    printf("negative controls, each law on the other run:\n");
    CHECK_MSG(!holds(sv_, sl), "the holding law passed a slipping run");
    CHECK_MSG(!slips(hv, hl, 1.25 * PUSH), "the slipping law passed a holding run");

    const double k = 4.0 * PI * PI; /* a period of 1 s for 1 kg */
    REQUIRE(spring(k, periods, &count));
    CHECK_MSG(period_is(periods, count, 1.0), "the spring's period is not 2 pi sqrt(m / k)");
    printf("spring: %d periods, the first %.6f s (2 pi sqrt(m / k) = 1 s)\n", count,
           count ? periods[0] : 0.0);
    REQUIRE(spring(k / 4.0, periods, &count));
    printf("negative control, a quarter of the stiffness:\n");
    CHECK_MSG(!period_is(periods, count, 1.0), "a quarter of the stiffness kept the period");
    return tu_finish("test_joint_laws");
}
