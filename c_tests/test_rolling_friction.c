/* Rolling and spinning friction through the C API (cadmm_problem_set_joint_friction,
 * cadmm_solver_update_joint_friction): joint rows on a contact's relative angular velocity,
 * bounded by e r_n, on scenes with closed forms. Every step's answer is checked by the
 * independent measure of test_util.h (tu_global_error_rows).
 *
 * A ball (mass m, radius R, I = 2/5 m R^2) on a plane whose frame has x down the slope, y
 * along the normal, z across. Velocities (v, w); M = diag(m, m, m, I, I, I); each step
 * f = M v_prev + h m g. The contact at (0, -R, 0) has the velocity (v_y, v_x + R w_z,
 * v_z - R w_x), normal first; its rows are w_x and w_z (rolling, coefficient e_r) and w_y
 * (spinning, e_s).
 *
 *   - Rolling down a slope theta without slipping: a = 5/7 g (sin(theta) - e_r/R cos(theta)),
 *     each step exactly h a more. After an update of e_r the new rate holds.
 *   - Spinning at w0 on a level floor: w_y falls by h e_s m g / I a step and stops at
 *     T = I w0 / (e_s m g), never reversing.
 *
 * Negative controls: the same checks on runs without the rows must fail.
 *
 * Usage: test_rolling_friction [FCLIB_DATA_DIR] (the directory is not used). */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-10
#define H 0.01
#define G 9.81
#define STEPS 100
#define PI 3.14159265358979323846

static const int64_t M_COLPTR[7] = {0, 1, 2, 3, 4, 5, 6};
static const int64_t M_ROWIND[6] = {0, 1, 2, 3, 4, 5};
/* H's columns: normal (v_y), T1 (v_x + R w_z), T2 (v_z - R w_x). */
static const int64_t H_COLPTR[4] = {0, 1, 3, 5};
static const int64_t H_ROWIND[5] = {1, 0, 5, 2, 3};
/* G's columns: w_x, w_z, w_y. */
static const int64_t G_COLPTR[4] = {0, 1, 2, 3};
static const int64_t G_ROWIND[3] = {3, 5, 4};
static const double G_VALUES[3] = {1.0, 1.0, 1.0};
static const double ZERO3[3] = {0.0, 0.0, 0.0};
static const int64_t CONTACT[3] = {0, 0, 0};

typedef struct scene {
    double mass, radius, slope, mu;
    double e_roll, e_spin; /* 0 with `rows` off */
    int rows;              /* 1: the three rows, 0: none (the negative controls) */
    double spin0;          /* initial w_y */
    int switch_at;         /* from this step on, e_roll_late (0: never) */
    double e_roll_late;
} scene;

static double inertia(const scene *s) { return 0.4 * s->mass * s->radius * s->radius; }

/* Runs STEPS steps; v_x and w_y after each into vx and wy. 0 when a call failed or a step
 * was not solved to TOL by the independent measure. */
static int simulate(const scene *s, double *vx, double *wy)
{
    double m = s->mass, i = inertia(s), R = s->radius;
    double diag[6] = {m, m, m, i, i, i};
    double h_values[5] = {1.0, 1.0, R, 1.0, -R};
    double gravity[3] = {G * sin(s->slope), -G * cos(s->slope), 0.0};
    double v[6] = {0, 0, 0, 0, s->spin0, 0}, f[6], r[3], lambda[3] = {0, 0, 0};
    double e[3] = {s->e_roll, s->e_roll, s->e_spin}, mu[1] = {s->mu};
    cadmm_csc M = {6, 6, M_COLPTR, M_ROWIND, diag};
    cadmm_csc Hm = {6, 3, H_COLPTR, H_ROWIND, h_values};
    cadmm_csc Gm = {6, 3, G_COLPTR, G_ROWIND, G_VALUES};
    cadmm_problem *p = NULL;
    cadmm_settings *set = NULL;
    cadmm_solver *sv = NULL;
    tu_csc Mo = tu_csc_copy(6, 6, M_COLPTR, M_ROWIND, diag);
    tu_csc Ho = tu_csc_copy(6, 3, H_COLPTR, H_ROWIND, h_values);
    tu_csc Go = tu_csc_copy(6, 3, G_COLPTR, G_ROWIND, G_VALUES);
    int ok = 1;
    for (int k = 0; k < 6; ++k) f[k] = diag[k] * v[k] + (k < 3 ? H * m * gravity[k] : 0.0);
    ok = cadmm_problem_new_global(6, 1, &M, &Hm, f, ZERO3, mu, &p) == CADMM_OK;
    if (ok && s->rows)
        ok = cadmm_problem_set_joints(p, &Gm, ZERO3) == CADMM_OK &&
             cadmm_problem_set_joint_friction(p, CONTACT, e) == CADMM_OK;
    ok = ok && cadmm_settings_new(&set) == CADMM_OK &&
         cadmm_settings_set_tolerance(set, TOL) == CADMM_OK &&
         cadmm_solver_new(p, set, &sv) == CADMM_OK;
    for (int step = 0; ok && step < STEPS; ++step) {
        cadmm_status status = CADMM_STATUS_UNSOLVED;
        for (int k = 0; k < 6; ++k) f[k] = diag[k] * v[k] + (k < 3 ? H * m * gravity[k] : 0.0);
        if (s->switch_at > 0 && step == s->switch_at) {
            e[0] = e[1] = s->e_roll_late;
            ok = cadmm_solver_update_joint_friction(sv, e) == CADMM_OK;
        }
        ok = ok && cadmm_solver_update_values(sv, NULL, NULL, NULL, f, NULL, NULL, NULL) == CADMM_OK &&
             cadmm_solver_solve(sv, &status) == CADMM_OK &&
             cadmm_solver_get_solution(sv, r, NULL, v) == CADMM_OK &&
             cadmm_solver_get_joint_multipliers(sv, s->rows ? lambda : NULL, NULL) == CADMM_OK;
        if (!ok) break;
        double lo[3] = {-INFINITY, -INFINITY, -INFINITY}, hi[3] = {INFINITY, INFINITY, INFINITY};
        tu_rows rows = {lo, hi, NULL, CONTACT, e};
        double err = tu_global_error_rows(&Mo, &Ho, s->rows ? &Go : NULL, f, ZERO3, ZERO3, rows,
                                          mu, 1, r, v, lambda);
        if (status != CADMM_STATUS_SOLVED || err > TOL * (1 + 1e-3)) {
            printf("step %d: status %d, independent error %.3e\n", step, (int)status, err);
            ok = 0;
        }
        vx[step] = v[0];
        wy[step] = v[4];
    }
    if (!ok) printf("simulation failed: %s\n", cadmm_last_error());
    cadmm_solver_free(sv);
    cadmm_settings_free(set);
    cadmm_problem_free(p);
    tu_csc_free(&Mo);
    tu_csc_free(&Ho);
    tu_csc_free(&Go);
    return ok;
}

/* The rolling law of `s` on vx: v_x(k) = sum of h a over the steps, a from the coefficient
 * of each step. 1 when it holds. */
static int rolls_as_predicted(const scene *s, const double *vx)
{
    double expected = 0.0;
    for (int k = 0; k < STEPS; ++k) {
        double e = (s->switch_at > 0 && k >= s->switch_at) ? s->e_roll_late : s->e_roll;
        expected += H * 5.0 / 7.0 * G * (sin(s->slope) - e / s->radius * cos(s->slope));
        if (fabs(vx[k] - expected) > 1e-7 * fmax(1.0, fabs(expected))) {
            printf("  step %d: v_x %.9f, predicted %.9f\n", k, vx[k], expected);
            return 0;
        }
    }
    return 1;
}

/* The spinning law of `s` on wy: linear decay to zero, then still; the stop time into
 * *stop. 1 when it holds. */
static int spins_down_as_predicted(const scene *s, const double *wy, double *stop)
{
    double rate = s->e_spin * s->mass * G / inertia(s);
    *stop = -1.0;
    for (int k = 0; k < STEPS; ++k) {
        double expected = fmax(s->spin0 - (k + 1) * H * rate, 0.0);
        if (fabs(wy[k] - expected) > 1e-8 * s->spin0) {
            printf("  step %d: w_y %.9f, predicted %.9f\n", k, wy[k], expected);
            return 0;
        }
        if (*stop < 0.0 && fabs(wy[k]) <= 1e-8 * s->spin0) *stop = (k + 1) * H;
    }
    return *stop > 0.0;
}

int main(void)
{
    double vx[STEPS], wy[STEPS], stop;
    printf("cadmm %s: rolling and spinning friction\n", cadmm_version());
    {
        scene s = {2.0, 0.1, 20.0 * PI / 180.0, 1.0, 0.01, 0.005, 1, 0.0, 0, 0.0};
        REQUIRE(simulate(&s, vx, wy));
        printf("rolling down 20 degrees, e_r = 0.01 m: v_x = %.9f m/s after %d steps\n",
               vx[STEPS - 1], STEPS);
        CHECK_MSG(rolls_as_predicted(&s, vx), "the ball does not roll at the predicted rate");
        /* The coefficient changed by the solver's update at step 50. */
        scene late = s;
        late.switch_at = 50;
        late.e_roll_late = 0.02;
        REQUIRE(simulate(&late, vx, wy));
        CHECK_MSG(rolls_as_predicted(&late, vx), "the updated coefficient was not taken");
        /* Negative controls: without the rows, and the update's law on the first run. */
        scene none = s;
        none.rows = 0;
        REQUIRE(simulate(&none, vx, wy));
        printf("negative control, no rolling friction:\n");
        CHECK_MSG(!rolls_as_predicted(&s, vx), "a ball without rolling friction passed");
    }
    {
        scene s = {1.0, 0.1, 0.0, 0.5, 0.01, 0.005, 1, 10.0, 0, 0.0};
        double predicted = inertia(&s) * s.spin0 / (s.e_spin * s.mass * G);
        REQUIRE(simulate(&s, vx, wy));
        CHECK_MSG(spins_down_as_predicted(&s, wy, &stop), "the spin does not decay as predicted");
        printf("spinning at 10 rad/s: stops at %.2f s, predicted %.4f s\n", stop, predicted);
        CHECK_MSG(fabs(stop - predicted) <= H, "stop time %.3f s, predicted %.3f s", stop,
                  predicted);
        scene none = s;
        none.rows = 0;
        REQUIRE(simulate(&none, vx, wy));
        printf("negative control, no spinning friction:\n");
        CHECK_MSG(!spins_down_as_predicted(&s, wy, &stop), "a sphere without spinning friction passed");
    }
    /* Bad rows are named; nothing changes on failure. */
    {
        double diag[6] = {1, 1, 1, 1, 1, 1}, h_values[5] = {1, 1, 0.1, 1, -0.1}, mu[1] = {0.5};
        cadmm_csc M = {6, 6, M_COLPTR, M_ROWIND, diag};
        cadmm_csc Hm = {6, 3, H_COLPTR, H_ROWIND, h_values};
        cadmm_csc Gm = {6, 3, G_COLPTR, G_ROWIND, G_VALUES};
        double f[6] = {0, -0.1, 0, 0, 0, 0}, e[3] = {0.01, 0.01, 0.01}, neg[3] = {0.01, -1, 0};
        int64_t far[3] = {0, 1, -1}, bad[3] = {0, -2, 0}, none[3] = {-1, -1, -1};
        cadmm_problem *p = NULL;
        REQUIRE(cadmm_problem_new_global(6, 1, &M, &Hm, f, ZERO3, mu, &p) == CADMM_OK);
        REQUIRE(cadmm_problem_set_joints(p, &Gm, ZERO3) == CADMM_OK);
        CHECK(cadmm_problem_set_joint_friction(p, far, e) == CADMM_ERR_INVALID_VALUE);
        CHECK_MSG(strstr(cadmm_last_error(), "contact[1]") != NULL, "%s", cadmm_last_error());
        CHECK(cadmm_problem_set_joint_friction(p, bad, e) == CADMM_ERR_INVALID_VALUE);
        CHECK(cadmm_problem_set_joint_friction(p, none, e) == CADMM_ERR_INVALID_VALUE);
        CHECK_MSG(strstr(cadmm_last_error(), "without a contact") != NULL, "%s",
                  cadmm_last_error());
        CHECK(cadmm_problem_set_joint_friction(p, CONTACT, neg) == CADMM_ERR_INVALID_VALUE);
        CHECK(cadmm_problem_set_joint_friction(p, CONTACT, NULL) == CADMM_ERR_NULL_POINTER);
        CHECK(cadmm_problem_set_joint_friction(p, CONTACT, e) == CADMM_OK);
        CHECK(cadmm_problem_write_fclib(p, "rolling_friction.hdf5") != CADMM_OK);
        {
            cadmm_settings *set = NULL;
            cadmm_solver *sv = NULL;
            REQUIRE(cadmm_settings_new(&set) == CADMM_OK);
            REQUIRE(cadmm_solver_new(p, set, &sv) == CADMM_OK);
            CHECK(cadmm_solver_update_joint_friction(sv, neg) == CADMM_ERR_INVALID_VALUE);
            CHECK(cadmm_solver_update_joint_friction(sv, NULL) == CADMM_ERR_NULL_POINTER);
            cadmm_solver_free(sv);
            cadmm_settings_free(set);
        }
        cadmm_problem_free(p);
    }
    return tu_finish("test_rolling_friction");
}
