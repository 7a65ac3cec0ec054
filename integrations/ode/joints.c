/*
 * cadmm_ode_joints: ODE joints stepped by cadmm_ode, with closed-form checks.
 *
 *   cadmm_ode_joints --test limit|motor|all-types|match-ode|rolling [--seconds S]
 *                    [--no-stops] [--no-rolling]
 *
 * Every test steps its world at 60 Hz and checks every step: the solve ended solved, and
 * its answer re-measured on the problem cadmm_ode built (cadmm_ode_last_problem) is within
 * the tolerance (1e-8) twice, by cadmm_problem_error_with_multipliers on a problem rebuilt
 * from those arrays and by the driver's own copy of the measure (check.h), with the host's
 * impulses, joint multipliers and the velocities the bodies leave the step with. Then:
 *
 *  - limit: a 1 m, 1 kg rod on a hinge at its end to the world, released 10 degrees above
 *    horizontal onto its high stop at horizontal. ODE adds the limit row only once the
 *    angle is at or past the stop, so the step that reaches it passes it by up to one
 *    step of travel at the impact speed, h omega (omega from the energy of the fall, with
 *    5% for the step's discretization: 0.039 rad); from then on the row pulls the
 *    overshoot back by the stop ERP: each step's overshoot is at most (1 - StopERP) times
 *    the last's (+1e-9). At rest (the last half second) the limit row's multiplier is
 *    -h m g L / 2, the load torque's impulse, within 1e-6 relative. --no-stops removes the
 *    stop (the negative control: the rod swings through it and the checks fail).
 *  - motor: the same rod held horizontal by a hinge motor (Vel 0) of FMax half the load
 *    torque: its row saturates at exactly -FMax h (1e-9 relative) every step while the
 *    load exceeds FMax by 1%, and the first step's angular velocity is
 *    h (m g L / 2 - FMax) / I_anchor (1e-6 relative). And a flywheel (no load) driven by a
 *    motor of Vel 5 rad/s, FMax 0.2 N m then 0.3 from 0.5 s: omega grows by h FMax / I a
 *    step (the row at exactly +FMax h, 1e-9 relative) until it reaches Vel, then stays at
 *    Vel (1e-6 relative): the sign of b = -Vel; the new FMax goes to the solver without a
 *    new one being built (cadmm_solver_update).
 *  - all-types: ball, hinge (with stops), fixed, universal, hinge-2 (steering locked by
 *    lo = hi = 0, a soft suspension, a motor on the wheel), a slider to the world whose
 *    sphere comes down on the ground (contacts and joints in one problem), a powered
 *    slider between two bodies driven into its stop, and joints attached as (0, body),
 *    which ODE holds reversed: a hinge into its stop, a hinge motor, a slider onto its
 *    stop, a fixed joint; every joint's drift (its position and angle errors, measured
 *    from the poses the test set up) below DRIFT_M and DRIFT_RAD.
 *  - match-ode: the all-types world without the ground (the slider stops on its limit)
 *    and without the gyroscopic term (ODE 0.16 makes it implicit, the host explicit),
 *    stepped by cadmm_ode and by dWorldStep (ODE's exact LCP solve of the same rows): the
 *    bodies' positions agree within MATCH_M and the joints' feedback forces within
 *    MATCH_N: cadmm_ode writes ODE's rows.
 *  - rolling: balls with rolling and spinning friction (dContactRolling) against their
 *    closed forms and dWorldStep (see test_rolling); --no-rolling is its negative control.
 *
 * Exit code 0: every check passed; 1: a check failed (one "check failed: ..." line each on
 * stderr); 2: bad arguments or a failed call.
 */
#include "cadmm_ode.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define STEP (1.0 / 60.0)
#define GRAVITY 9.81
#define TOLERANCE 1e-8
#define PI 3.14159265358979323846

/* Joint drift: the errors ERP leaves. A joint turning at omega with arm L drifts by about
 * h^2 omega^2 L per step off its constraint (the semi-implicit step moves along the
 * tangent while the rows hold velocities only), which the rows take back by ERP a step:
 * h^2 omega^2 L / ERP at equilibrium, 1.7 cm at 5 rad/s and 0.5 m with ERP 0.2 and 60 Hz
 * (the falling double pendulum: measured at most 1.3 cm and 0.012 rad; ODE's own step
 * drifts the same, match-ode following it within 1.1e-7 m). The soft hinge-2 suspension's
 * travel along its axis is by design and not counted. */
#define DRIFT_M 0.02
#define DRIFT_RAD 0.03

/* cadmm_ode against dWorldStep: both solve the same rows, ODE exactly, cadmm to 1e-8 by
 * the relative measure; the swinging bodies carry the difference along (measured
 * 1.1e-7 m and 8e-6 N over 2 s, the most on the powered slider's block). */
#define MATCH_M 1e-6
#define MATCH_N 1e-4

static int failures = 0;

static void check_failed(const char *fmt, double a, double b) {
    fprintf(stderr, "cadmm_ode_joints: check failed: ");
    fprintf(stderr, fmt, a, b);
    fprintf(stderr, "\n");
    failures++;
}

static double norm3(const double a[3]) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

static void cross3(const double a[3], const double b[3], double out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* R v, R^T v (ODE's 3x4 rotations). */
static void rot(const dReal *R, const double v[3], double out[3]) {
    for (int i = 0; i < 3; i++)
        out[i] = R[4 * i] * v[0] + R[4 * i + 1] * v[1] + R[4 * i + 2] * v[2];
}

static void unrot(const dReal *R, const double v[3], double out[3]) {
    for (int i = 0; i < 3; i++) out[i] = R[i] * v[0] + R[4 + i] * v[1] + R[8 + i] * v[2];
}

/* Ra^T Rb (row-major; Rb NULL for the world's identity). */
static void relative_rotation(const dReal *Ra, const dReal *Rb, double rel[9]) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += Ra[4 * k + i] * (Rb ? Rb[4 * k + j] : (k == j));
            rel[3 * i + j] = s;
        }
}

/* The angle by which Ra^T Rb turned from rel0, its value at set-up. */
static double relative_angle(const dReal *Ra, const dReal *Rb, const double rel0[9]) {
    double rel[9], tr = 0.0;
    relative_rotation(Ra, Rb, rel);
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) tr += rel0[3 * k + i] * rel[3 * k + i]; /* tr(rel0^T rel) */
    double c = (tr - 1.0) / 2.0;
    return acos(c > 1.0 ? 1.0 : c < -1.0 ? -1.0 : c);
}

/* A box body of the given size and mass at p. */
static dBodyID box(dWorldID w, double mass, double lx, double ly, double lz, double x, double y,
                   double z) {
    dBodyID b = dBodyCreate(w);
    dMass m;
    dMassSetBoxTotal(&m, mass, lx, ly, lz);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, y, z);
    return b;
}

/* ---- stepping and the per-step checks ------------------------------------------------ */

typedef struct run {
    cadmm_ode *ctx;
    dWorldID world;
    dBodyID bodies[16];
    size_t n;
    double max_error, max_checked;
    size_t steps, unsolved, rebuilt, joint_rows_max;
    double *lambda; /* the last step's multipliers */
    size_t lambda_cap;
} run;

/* One host step and its checks, the contacts given as geoms or (full, not NULL) as
 * dContacts with their surfaces; 0, or 2 after a failed call. */
static int step_with(run *s, const dContactGeom *contacts, const dContact *full, size_t nc) {
    cadmm_ode_step_info info;
    cadmm_result rc =
        full ? cadmm_ode_assemble_contacts(s->ctx, s->world, s->bodies, s->n, full, nc, STEP)
             : cadmm_ode_assemble(s->ctx, s->world, s->bodies, s->n, contacts, nc, STEP);
    if (rc == CADMM_OK) rc = cadmm_ode_solve(s->ctx, &info);
    double r[3 * 8] = {0}; /* the worlds here have at most 4 contacts */
    cadmm_ode_problem p;
    if (rc == CADMM_OK) rc = cadmm_ode_impulses(s->ctx, r);
    if (rc == CADMM_OK) rc = cadmm_ode_last_problem(s->ctx, &p);
    if (rc == CADMM_OK && p.n_joint_rows > s->lambda_cap) {
        free(s->lambda);
        s->lambda_cap = 2 * p.n_joint_rows;
        s->lambda = malloc(s->lambda_cap * sizeof *s->lambda);
        if (!s->lambda) rc = CADMM_ERR_PANIC;
    }
    if (rc == CADMM_OK) rc = cadmm_ode_joint_multipliers(s->ctx, s->lambda);
    if (rc != CADMM_OK) {
        fprintf(stderr, "cadmm_ode_joints: step %zu: %s\n", s->steps,
                cadmm_ode_last_error(s->ctx));
        return 2;
    }
    s->steps++;
    if (p.n_joint_rows > s->joint_rows_max) s->joint_rows_max = p.n_joint_rows;
    if (!info.solved) return 0;
    s->unsolved += info.status != CADMM_STATUS_SOLVED;
    s->rebuilt += info.rebuilt;

    /* The answer re-measured on the problem as exported: the velocities the bodies leave
     * the step with, the host's impulses and multipliers. */
    double v[6 * 16];
    for (size_t k = 0; k < p.n / 6; k++) {
        dBodyID b = s->bodies[p.body_index[k]];
        const dReal *lv = dBodyGetLinearVel(b), *av = dBodyGetAngularVel(b);
        for (int d = 0; d < 3; d++) {
            v[6 * k + d] = lv[d];
            v[6 * k + 3 + d] = av[d];
        }
    }
    cadmm_problem *q = NULL;
    double e = INFINITY;
    rc = cadmm_problem_new_global(p.n, p.n_contacts, &p.M, &p.H, p.f, p.w, p.mu, &q);
    if (rc == CADMM_OK && p.n_joint_rows) rc = cadmm_problem_set_joints(q, &p.G, p.b);
    if (rc == CADMM_OK && p.n_joint_rows) rc = cadmm_problem_set_joint_bounds(q, p.lo, p.hi);
    if (rc == CADMM_OK && p.n_joint_rows) rc = cadmm_problem_set_joint_compliance(q, p.c);
    bool by_contact = false;
    for (size_t k = 0; k < p.n_joint_rows; k++) by_contact = by_contact || p.friction_contact[k] >= 0;
    if (rc == CADMM_OK && by_contact)
        rc = cadmm_problem_set_joint_friction(q, p.friction_contact, p.friction);
    if (rc == CADMM_OK) rc = cadmm_problem_error_with_multipliers(q, r, v, s->lambda, &e);
    cadmm_problem_free(q);
    if (rc != CADMM_OK) {
        fprintf(stderr, "cadmm_ode_joints: step %zu: re-measure: %s\n", s->steps,
                cadmm_last_error());
        return 2;
    }
    double checked = check_error(&p, r, v, s->lambda);
    if (!(e <= s->max_error)) s->max_error = e;
    if (!(checked <= s->max_checked)) s->max_checked = checked;
    return 0;
}

static int step(run *s, const dContactGeom *contacts, size_t nc) {
    return step_with(s, contacts, NULL, nc);
}

/* The per-step checks over the run. */
static void check_run(const run *s, const char *what) {
    char msg[160];
    snprintf(msg, sizeof msg, "%s: %%g of %%g steps ended above the tolerance", what);
    if (s->unsolved) check_failed(msg, (double)s->unsolved, (double)s->steps);
    snprintf(msg, sizeof msg, "%s: re-measured error %%.3g above the tolerance %%.3g", what);
    if (!(s->max_error <= TOLERANCE)) check_failed(msg, s->max_error, TOLERANCE);
    snprintf(msg, sizeof msg, "%s: check.c's re-measured error %%.3g above the tolerance %%.3g",
             what);
    if (!(s->max_checked <= TOLERANCE)) check_failed(msg, s->max_checked, TOLERANCE);
    printf("%s: %zu steps, %zu solver builds, at most %zu joint rows, worst re-measured error "
           "%.3g (check.c %.3g)\n",
           what, s->steps, s->rebuilt, s->joint_rows_max, s->max_error, s->max_checked);
}

static int start_run(run *s) {
    cadmm_ode_options o = cadmm_ode_default_options();
    o.tolerance = TOLERANCE;
    s->ctx = cadmm_ode_new(&o);
    s->world = dWorldCreate();
    dWorldSetGravity(s->world, 0, 0, -GRAVITY);
    dWorldSetContactSurfaceLayer(s->world, 0.001);
    return s->ctx ? 0 : 2;
}

static void end_run(run *s) {
    cadmm_ode_free(s->ctx);
    dWorldDestroy(s->world);
    free(s->lambda);
}

/* ---- limit ------------------------------------------------------------------------------ */

#define ROD_L 1.0
#define ROD_T 0.05
#define ROD_M 1.0

/* A rod of length ROD_L hinged at its end at the origin about +y, raised by `elevation`
 * above +x: the hinge angle grows as it falls (0 at set-up). */
static dJointID rod(run *s, double elevation) {
    dBodyID b = box(s->world, ROD_M, ROD_L, ROD_T, ROD_T, 0.5 * ROD_L * cos(elevation), 0,
                    0.5 * ROD_L * sin(elevation));
    dMatrix3 R;
    dRFromAxisAndAngle(R, 0, 1, 0, -elevation);
    dBodySetRotation(b, R);
    dJointID j = dJointCreateHinge(s->world, 0);
    dJointAttach(j, b, 0);
    dJointSetHingeAnchor(j, 0, 0, 0);
    dJointSetHingeAxis(j, 0, 1, 0);
    s->bodies[s->n++] = b;
    return j;
}

static double rod_inertia(void) { /* about the hinge */
    return ROD_M * (ROD_L * ROD_L + ROD_T * ROD_T) / 12.0 + ROD_M * 0.25 * ROD_L * ROD_L;
}

static int test_limit(double seconds, int no_stops) {
    run s = {0};
    if (start_run(&s)) return 2;
    const double elevation = 10 * PI / 180, stop = elevation, erp = 0.2;
    dJointID j = rod(&s, elevation);
    if (!no_stops) dJointSetHingeParam(j, dParamHiStop, stop);
    dJointSetHingeParam(j, dParamStopERP, erp);
    /* The impact speed from the fall's energy, and one step of travel at it. */
    double omega = sqrt(ROD_M * GRAVITY * ROD_L * sin(elevation) / rod_inertia());
    double bound = 1.05 * omega * STEP, load = STEP * ROD_M * GRAVITY * ROD_L / 2;
    double max_over = 0.0, last_over = 0.0, worst_ratio = 0.0, worst_rest = 0.0;
    size_t steps = (size_t)llround(seconds / STEP);
    size_t rest_from = steps - (size_t)llround(0.5 / STEP);
    int status = 0;
    for (size_t k = 0; k < steps && !status; k++) {
        if ((status = step(&s, NULL, 0))) break;
        double over = dJointGetHingeAngle(j) - stop;
        if (over > max_over) max_over = over;
        /* The ERP contraction while the rod stays past the stop. */
        if (last_over > 0 && over > 0 && over - (1 - erp) * last_over > worst_ratio)
            worst_ratio = over - (1 - erp) * last_over;
        last_over = over;
        if (k >= rest_from) {
            size_t first = 0, count = 0;
            cadmm_ode_joint_rows(s.ctx, j, &first, &count);
            /* 3 anchor rows, 2 axis rows, the limit. */
            double lambda = count == 6 ? s.lambda[first + 5] : 0.0;
            double rel = fabs(lambda + load) / load;
            if (!(rel <= worst_rest)) worst_rest = rel;
        }
    }
    if (!status) {
        check_run(&s, "limit");
        printf("limit: impact at %.4g rad/s, largest overshoot %.4g rad (bound h omega + 5%% = "
               "%.4g), ERP contraction slack %.2g, resting multiplier off -h m g L/2 = %.6g by "
               "%.3g relative\n",
               omega, max_over, bound, worst_ratio, -load, worst_rest);
        if (!(max_over <= bound))
            check_failed("the rod passed its stop by %.4g rad (bound %.4g rad)", max_over, bound);
        if (!(worst_ratio <= 1e-9))
            check_failed("an overshoot shrank by less than the stop ERP: %.3g rad more than "
                         "allowed (%g)", worst_ratio, 1e-9);
        if (!(worst_rest <= 1e-6))
            check_failed("the resting limit multiplier is %.3g off h m g L/2 relative (bound "
                         "%g)", worst_rest, 1e-6);
    }
    end_run(&s);
    return status;
}

/* ---- motor ------------------------------------------------------------------------------ */

static int test_motor(double seconds) {
    run s = {0};
    if (start_run(&s)) return 2;
    dJointID j = rod(&s, 0.0);
    const double load = ROD_M * GRAVITY * ROD_L / 2, fmax = 0.5 * load;
    dJointSetHingeParam(j, dParamVel, 0.0);
    dJointSetHingeParam(j, dParamFMax, fmax);
    /* A flywheel turning about z on a hinge at its center (no load), spun up by a motor
     * whose FMax goes from 0.2 to 0.3 N m at 0.5 s: a new bound on the same rows, which the
     * host hands to its solver without building a new one. */
    const double vel = 5.0;
    double wheel_fmax = 0.2, want = 0.0;
    dBodyID w = box(s.world, 2.0, 0.4, 0.4, 0.1, 3, 0, 0);
    s.bodies[s.n++] = w;
    dJointID jw = dJointCreateHinge(s.world, 0);
    dJointAttach(jw, w, 0);
    dJointSetHingeAnchor(jw, 3, 0, 0);
    dJointSetHingeAxis(jw, 0, 0, 1);
    dJointSetHingeParam(jw, dParamVel, vel);
    dJointSetHingeParam(jw, dParamFMax, wheel_fmax);
    dMass m;
    dBodyGetMass(w, &m);
    const double iw = m.I[10]; /* I_zz */

    double worst_sat = 0.0, worst_first = 0.0, worst_wheel = 0.0, worst_wheel_sat = 0.0;
    size_t saturated = 0, at_vel = 0, steps = (size_t)llround(seconds / STEP);
    size_t change = (size_t)llround(0.5 / STEP), builds_before = 0, builds_after = 0;
    int status = 0;
    for (size_t k = 0; k < steps && !status; k++) {
        if (k == change) {
            wheel_fmax = 0.3;
            dJointSetHingeParam(jw, dParamFMax, wheel_fmax);
            builds_before = s.rebuilt;
        }
        if ((status = step(&s, NULL, 0))) break;
        if (k == change) builds_after = s.rebuilt;
        size_t first = 0, count = 0;
        cadmm_ode_joint_rows(s.ctx, j, &first, &count);
        double angle = dJointGetHingeAngle(j);
        /* The rod's motor row (after 3 anchor and 2 axis rows) while the load exceeds it. */
        if (count == 6 && load * cos(angle) > 1.01 * fmax && angle < PI / 2) {
            double rel = fabs(s.lambda[first + 5] + fmax * STEP) / (fmax * STEP);
            if (!(rel <= worst_sat)) worst_sat = rel;
            saturated++;
        }
        if (k == 0) {
            double want = STEP * (load - fmax) / rod_inertia();
            worst_first = fabs(dJointGetHingeAngleRate(j) - want) / want;
        }
        /* The flywheel: omega grows by h FMax / I a step, saturated, until it reaches Vel. */
        cadmm_ode_joint_rows(s.ctx, jw, &first, &count);
        bool saturating = want + STEP * wheel_fmax / iw < vel;
        want = saturating ? want + STEP * wheel_fmax / iw : vel;
        at_vel += !saturating;
        double rate = dJointGetHingeAngleRate(jw), rel = fabs(rate - want) / want;
        if (!(rel <= worst_wheel)) worst_wheel = rel;
        if (count == 6 && saturating) {
            double sat = fabs(s.lambda[first + 5] - wheel_fmax * STEP) / (wheel_fmax * STEP);
            if (!(sat <= worst_wheel_sat)) worst_wheel_sat = sat;
        }
    }
    if (!status) {
        check_run(&s, "motor");
        printf("motor: rod motor saturated on %zu steps, its multiplier off -FMax h by %.3g "
               "relative; first step's rate off h (m g L/2 - FMax) / I by %.3g; flywheel rate "
               "off its closed form by %.3g (%zu steps at Vel), its multiplier off +FMax h by "
               "%.3g; solver builds %zu before and %zu after the new FMax\n",
               saturated, worst_sat, worst_first, worst_wheel, at_vel, worst_wheel_sat,
               builds_before, builds_after);
        if (builds_after != builds_before)
            check_failed("the new FMax built a new solver (%g builds, %g before)",
                         (double)builds_after, (double)builds_before);
        if (at_vel < 10)
            check_failed("the flywheel ran at its motor's Vel on %g steps only (want %g or more)",
                         (double)at_vel, 10.0);
        if (saturated < 5)
            check_failed("the rod's motor saturated on %g steps only (want %g or more)",
                         (double)saturated, 5.0);
        if (!(worst_sat <= 1e-9))
            check_failed("the saturated motor's multiplier is %.3g off -FMax h (bound %g)",
                         worst_sat, 1e-9);
        if (!(worst_first <= 1e-6))
            check_failed("the first step's rate is %.3g off h (m g L/2 - FMax) / I (bound %g)",
                         worst_first, 1e-6);
        if (!(worst_wheel <= 1e-6))
            check_failed("the flywheel's rate is %.3g off min(sum h FMax / I, Vel) (bound %g)",
                         worst_wheel, 1e-6);
        if (!(worst_wheel_sat <= 1e-9))
            check_failed("the flywheel motor's multiplier is %.3g off +FMax h (bound %g)",
                         worst_wheel_sat, 1e-9);
    }
    end_run(&s);
    return status;
}

/* ---- all-types and match-ode ------------------------------------------------------------ */

enum {
    BALL, HINGE, FIXED, UNIVERSAL, HINGE2, SLIDER_WORLD, SLIDER_PAIR, BALL2,
    HINGE_REV, MOTOR_REV, SLIDER_REV, FIXED_REV, N_JOINTS
};
static const char *const joint_names[N_JOINTS] = {
    "ball (0, body)",  "hinge",           "fixed",          "universal (0, body)",
    "hinge-2",         "slider (body, 0)", "slider (pair)", "ball (body, 0)",
    "hinge (0, body)", "motor (0, body)", "slider (0, body)", "fixed (0, body)"};

/* The world of every joint type and what the test recorded of each joint's set-up pose. */
typedef struct mechanisms {
    dJointID j[N_JOINTS];
    dJointFeedback fb[N_JOINTS];
    dBodyID sphere;
    dGeomID sphere_geom, ground;
    dSpaceID space;
    double hinge_axis_b[3];          /* the hinge's axis in its second body's frame */
    double fixed_rel[9], fixed_ofs[3]; /* the fixed joint: Ra^T Rb, b's center in a's frame */
    double slider_rel[9], slider_x0[3], slider_axis[3]; /* world slider */
    double pair_rel[9], pair_d0[3], pair_axis_b[3];     /* two-body slider, in b's frame */
    double hinge2_angle0;
    /* The joints attached as (0, body): their world axes and points. */
    double rev_hinge_axis[3], rev_motor_axis[3], rev_slider_x0[3], rev_slider_axis[3];
    double rev_fixed_x0[3], identity[9];
} mechanisms;

static void build_all(run *s, mechanisms *mc, int ground, int gyroscopic) {
    dWorldID w = s->world;
    memset(mc, 0, sizeof *mc);
    /* Ball (attached as (0, b1): ODE holds it reversed) and a hinge with stops between two
     * bars, a block glued to the second by a fixed joint: a double pendulum falling from
     * horizontal, turning out of its plane about the tilted hinge. */
    dBodyID b1 = box(w, 1.0, 0.6, 0.1, 0.1, 0.3, 0, 2);
    dBodyID b2 = box(w, 1.0, 0.6, 0.1, 0.1, 0.9, 0, 2);
    dBodyID b3 = box(w, 0.5, 0.2, 0.2, 0.2, 1.3, 0, 2);
    mc->j[BALL] = dJointCreateBall(w, 0);
    dJointAttach(mc->j[BALL], 0, b1);
    dJointSetBallAnchor(mc->j[BALL], 0, 0, 2);
    mc->j[HINGE] = dJointCreateHinge(w, 0);
    dJointAttach(mc->j[HINGE], b1, b2);
    dJointSetHingeAnchor(mc->j[HINGE], 0.6, 0, 2);
    dJointSetHingeAxis(mc->j[HINGE], 0, 1, 0.3);
    dJointSetHingeParam(mc->j[HINGE], dParamLoStop, -0.6);
    dJointSetHingeParam(mc->j[HINGE], dParamHiStop, 0.6);
    double axis[3] = {0, 1 / sqrt(1.09), 0.3 / sqrt(1.09)};
    unrot(dBodyGetRotation(b2), axis, mc->hinge_axis_b);
    mc->j[FIXED] = dJointCreateFixed(w, 0);
    dJointAttach(mc->j[FIXED], b2, b3);
    dJointSetFixed(mc->j[FIXED]);
    relative_rotation(dBodyGetRotation(b2), dBodyGetRotation(b3), mc->fixed_rel);
    double d23[3] = {1.3 - 0.9, 0, 0};
    unrot(dBodyGetRotation(b2), d23, mc->fixed_ofs);

    /* A universal joint to the world (attached as (0, b4)), its bar hanging off-centre so
     * that it swings about both axes, and a wheel on a hinge-2 at its end: steering locked
     * by lo = hi = 0, a soft suspension, a motor spinning the wheel. */
    dBodyID b4 = box(w, 1.0, 0.1, 0.1, 0.6, 0.1, 2.075, 1.85);
    dBodyID b5 = box(w, 0.8, 0.3, 0.1, 0.3, 0.2, 2.15, 1.7);
    mc->j[UNIVERSAL] = dJointCreateUniversal(w, 0);
    dJointAttach(mc->j[UNIVERSAL], 0, b4);
    dJointSetUniversalAnchor(mc->j[UNIVERSAL], 0, 2, 2);
    /* Axis 1 (on the world, this joint being reversed) first along y: ODE's default axes,
     * x on the body and y on the world, would meet the new one and make ODE's angle code
     * warn about parallel axes until the second is set. */
    dJointSetUniversalAxis1(mc->j[UNIVERSAL], 0, 1, 0);
    dJointSetUniversalAxis2(mc->j[UNIVERSAL], 1, 0, 0);
    mc->j[HINGE2] = dJointCreateHinge2(w, 0);
    dJointAttach(mc->j[HINGE2], b4, b5);
    dJointSetHinge2Anchor(mc->j[HINGE2], 0.2, 2.15, 1.7);
    const dReal a1[3] = {0, 0, 1}, a2[3] = {0, 1, 0};
    dJointSetHinge2Axes(mc->j[HINGE2], a1, a2);
    dJointSetHinge2Param(mc->j[HINGE2], dParamLoStop, 0);
    dJointSetHinge2Param(mc->j[HINGE2], dParamHiStop, 0);
    dJointSetHinge2Param(mc->j[HINGE2], dParamSuspensionERP, 0.4);
    dJointSetHinge2Param(mc->j[HINGE2], dParamSuspensionCFM, 0.01);
    dJointSetHinge2Param(mc->j[HINGE2], dParamVel2, 5.0);
    dJointSetHinge2Param(mc->j[HINGE2], dParamFMax2, 0.5);
    mc->hinge2_angle0 = PI / 2;

    /* A sphere on a slider to the world along a 45-degree line down to the ground: with the
     * ground it lands and rests there (contacts and joint rows in one problem), without it
     * it stops on the slider's high stop. */
    dBodyID b6 = dBodyCreate(w);
    dMass m;
    dMassSetSphereTotal(&m, 1.0, 0.1);
    dBodySetMass(b6, &m);
    dBodySetPosition(b6, 3, 0, 0.8);
    mc->sphere = b6;
    mc->j[SLIDER_WORLD] = dJointCreateSlider(w, 0);
    dJointAttach(mc->j[SLIDER_WORLD], b6, 0);
    dJointSetSliderAxis(mc->j[SLIDER_WORLD], 1, 0, -1);
    dJointSetSliderParam(mc->j[SLIDER_WORLD], dParamHiStop, ground ? 2.0 : 0.5);
    mc->slider_x0[0] = 3;
    mc->slider_x0[2] = 0.8;
    mc->slider_axis[0] = 1 / sqrt(2.0);
    mc->slider_axis[2] = -1 / sqrt(2.0);
    mc->slider_rel[0] = mc->slider_rel[4] = mc->slider_rel[8] = 1;
    if (ground) {
        mc->space = dSimpleSpaceCreate(0);
        mc->ground = dCreatePlane(mc->space, 0, 0, 1, 0);
        mc->sphere_geom = dCreateSphere(mc->space, 0.1);
        dGeomSetBody(mc->sphere_geom, b6);
    }

    /* A block hanging from a ball joint, a smaller one on a powered slider along x beside
     * it, driven into its high stop (powered and limited: both rows), unless matched with
     * ODE, which fakes that pair with one row and the motor's force applied outside its
     * feedback: then the stop is out of reach (the slider travels about 2 m in 2 s). */
    dBodyID b7 = box(w, 2.0, 0.3, 0.3, 0.3, 3, 2, 2);
    dBodyID b8 = box(w, 1.0, 0.2, 0.2, 0.2, 3.3, 2, 2);
    mc->j[BALL2] = dJointCreateBall(w, 0);
    dJointAttach(mc->j[BALL2], b7, 0);
    dJointSetBallAnchor(mc->j[BALL2], 3, 2, 2.3);
    mc->j[SLIDER_PAIR] = dJointCreateSlider(w, 0);
    dJointAttach(mc->j[SLIDER_PAIR], b8, b7);
    dJointSetSliderAxis(mc->j[SLIDER_PAIR], 1, 0, 0);
    dJointSetSliderParam(mc->j[SLIDER_PAIR], dParamVel, 0.3);
    dJointSetSliderParam(mc->j[SLIDER_PAIR], dParamFMax, 5.0);
    dJointSetSliderParam(mc->j[SLIDER_PAIR], dParamHiStop, ground ? 0.2 : 10.0);
    relative_rotation(dBodyGetRotation(b8), dBodyGetRotation(b7), mc->pair_rel);
    double d87[3] = {0.3, 0, 0}, ax[3] = {1, 0, 0};
    unrot(dBodyGetRotation(b7), d87, mc->pair_d0);
    unrot(dBodyGetRotation(b7), ax, mc->pair_axis_b);

    /* Joints attached as (0, body), which ODE holds reversed (its getters swap their 1 and
     * 2, and a hinge's stops and motor act on minus dJointGetHingeAngle): a bar on a hinge
     * about x swinging into a stop, a flywheel spun by a hinge motor, a block sliding down
     * a tilted line onto a stop, a block fixed to the world. */
    dBodyID b9 = box(w, 1.0, 0.1, 0.6, 0.1, 5, 0.3, 2);
    dBodyID b10 = box(w, 2.0, 0.4, 0.4, 0.1, 5, 2, 2);
    dBodyID b11 = box(w, 1.0, 0.2, 0.2, 0.2, 5, 4, 2);
    dBodyID b12 = box(w, 1.0, 0.2, 0.2, 0.2, 5, 6, 2);
    mc->j[HINGE_REV] = dJointCreateHinge(w, 0);
    dJointAttach(mc->j[HINGE_REV], 0, b9);
    dJointSetHingeAnchor(mc->j[HINGE_REV], 5, 0, 2);
    dJointSetHingeAxis(mc->j[HINGE_REV], 1, 0, 0);
    dJointSetHingeParam(mc->j[HINGE_REV], dParamLoStop, -0.5);
    dJointSetHingeParam(mc->j[HINGE_REV], dParamHiStop, 0.5);
    mc->rev_hinge_axis[0] = 1;
    mc->j[MOTOR_REV] = dJointCreateHinge(w, 0);
    dJointAttach(mc->j[MOTOR_REV], 0, b10);
    dJointSetHingeAnchor(mc->j[MOTOR_REV], 5, 2, 2);
    dJointSetHingeAxis(mc->j[MOTOR_REV], 0, 0, 1);
    dJointSetHingeParam(mc->j[MOTOR_REV], dParamVel, 3.0);
    dJointSetHingeParam(mc->j[MOTOR_REV], dParamFMax, 0.2);
    mc->rev_motor_axis[2] = 1;
    mc->j[SLIDER_REV] = dJointCreateSlider(w, 0);
    dJointAttach(mc->j[SLIDER_REV], 0, b11);
    dJointSetSliderAxis(mc->j[SLIDER_REV], 0, 1, -1);
    dJointSetSliderParam(mc->j[SLIDER_REV], dParamLoStop, -0.4);
    dJointSetSliderParam(mc->j[SLIDER_REV], dParamHiStop, 0.4);
    mc->rev_slider_x0[0] = 5;
    mc->rev_slider_x0[1] = 4;
    mc->rev_slider_x0[2] = 2;
    mc->rev_slider_axis[1] = 1 / sqrt(2.0);
    mc->rev_slider_axis[2] = -1 / sqrt(2.0);
    mc->j[FIXED_REV] = dJointCreateFixed(w, 0);
    dJointAttach(mc->j[FIXED_REV], 0, b12);
    dJointSetFixed(mc->j[FIXED_REV]);
    mc->rev_fixed_x0[0] = 5;
    mc->rev_fixed_x0[1] = 6;
    mc->rev_fixed_x0[2] = 2;
    mc->identity[0] = mc->identity[4] = mc->identity[8] = 1;

    dBodyID all[12] = {b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11, b12};
    for (int k = 0; k < 12; k++) {
        s->bodies[s->n++] = all[k];
        dBodySetGyroscopicMode(all[k], gyroscopic);
    }
    for (int k = 0; k < N_JOINTS; k++) dJointSetFeedback(mc->j[k], &mc->fb[k]);
}

/* Each joint's drift: position error (m) and angle error (rad). */
static void drifts(const mechanisms *mc, double pos[N_JOINTS], double ang[N_JOINTS]) {
    dVector3 p1, p2, g1, g2;
    double d[3], a[3], b[3];
    for (int k = 0; k < N_JOINTS; k++) pos[k] = ang[k] = 0.0;
    for (int k = BALL; k <= BALL2; k += BALL2 - BALL) {
        dJointGetBallAnchor(mc->j[k], p1);
        dJointGetBallAnchor2(mc->j[k], p2);
        for (int i = 0; i < 3; i++) d[i] = p1[i] - p2[i];
        pos[k] = norm3(d);
    }

    dJointGetHingeAnchor(mc->j[HINGE], p1);
    dJointGetHingeAnchor2(mc->j[HINGE], p2);
    for (int i = 0; i < 3; i++) d[i] = p1[i] - p2[i];
    pos[HINGE] = norm3(d);
    dJointGetHingeAxis(mc->j[HINGE], g1);
    dBodyID hb = dJointGetBody(mc->j[HINGE], 1);
    rot(dBodyGetRotation(hb), mc->hinge_axis_b, b);
    for (int i = 0; i < 3; i++) a[i] = g1[i];
    cross3(a, b, d);
    ang[HINGE] = atan2(norm3(d), dot3(a, b));

    dBodyID fa = dJointGetBody(mc->j[FIXED], 0), fb = dJointGetBody(mc->j[FIXED], 1);
    const dReal *xa = dBodyGetPosition(fa), *xb = dBodyGetPosition(fb);
    rot(dBodyGetRotation(fa), mc->fixed_ofs, a);
    for (int i = 0; i < 3; i++) d[i] = xb[i] - xa[i] - a[i];
    pos[FIXED] = norm3(d);
    ang[FIXED] = relative_angle(dBodyGetRotation(fa), dBodyGetRotation(fb), mc->fixed_rel);

    dJointGetUniversalAnchor(mc->j[UNIVERSAL], p1);
    dJointGetUniversalAnchor2(mc->j[UNIVERSAL], p2);
    for (int i = 0; i < 3; i++) d[i] = p1[i] - p2[i];
    pos[UNIVERSAL] = norm3(d);
    dJointGetUniversalAxis1(mc->j[UNIVERSAL], g1);
    dJointGetUniversalAxis2(mc->j[UNIVERSAL], g2);
    for (int i = 0; i < 3; i++) {
        a[i] = g1[i];
        b[i] = g2[i];
    }
    ang[UNIVERSAL] = fabs(asin(dot3(a, b)));

    /* Hinge-2: the anchor gap across axis 1 (along it is the suspension's travel). */
    dJointGetHinge2Anchor(mc->j[HINGE2], p1);
    dJointGetHinge2Anchor2(mc->j[HINGE2], p2);
    dJointGetHinge2Axis1(mc->j[HINGE2], g1);
    dJointGetHinge2Axis2(mc->j[HINGE2], g2);
    for (int i = 0; i < 3; i++) {
        a[i] = g1[i];
        b[i] = g2[i];
        d[i] = p1[i] - p2[i];
    }
    double along = dot3(d, a);
    for (int i = 0; i < 3; i++) d[i] -= along * a[i];
    pos[HINGE2] = norm3(d);
    cross3(a, b, d);
    ang[HINGE2] = fabs(atan2(norm3(d), dot3(a, b)) - mc->hinge2_angle0);

    /* World slider: the sphere's distance from its line, its rotation. */
    const dReal *x6 = dBodyGetPosition(mc->sphere);
    for (int i = 0; i < 3; i++) d[i] = x6[i] - mc->slider_x0[i];
    along = dot3(d, mc->slider_axis);
    for (int i = 0; i < 3; i++) d[i] -= along * mc->slider_axis[i];
    pos[SLIDER_WORLD] = norm3(d);
    ang[SLIDER_WORLD] = relative_angle(dBodyGetRotation(mc->sphere), NULL, mc->slider_rel);

    /* Two-body slider: a's center off its line in b's frame, the relative rotation. */
    dBodyID sa = dJointGetBody(mc->j[SLIDER_PAIR], 0), sb = dJointGetBody(mc->j[SLIDER_PAIR], 1);
    const dReal *x8 = dBodyGetPosition(sa), *x7 = dBodyGetPosition(sb);
    for (int i = 0; i < 3; i++) a[i] = x8[i] - x7[i];
    unrot(dBodyGetRotation(sb), a, d);
    for (int i = 0; i < 3; i++) d[i] -= mc->pair_d0[i];
    along = dot3(d, mc->pair_axis_b);
    for (int i = 0; i < 3; i++) d[i] -= along * mc->pair_axis_b[i];
    pos[SLIDER_PAIR] = norm3(d);
    ang[SLIDER_PAIR] = relative_angle(dBodyGetRotation(sa), dBodyGetRotation(sb), mc->pair_rel);

    /* The reversed hinges: anchor gap, the body's axis off the world's. */
    const double *world_axes[2] = {mc->rev_hinge_axis, mc->rev_motor_axis};
    for (int k = 0; k < 2; k++) {
        dJointID j = mc->j[HINGE_REV + k];
        dJointGetHingeAnchor(j, p1);
        dJointGetHingeAnchor2(j, p2);
        dJointGetHingeAxis(j, g1);
        for (int i = 0; i < 3; i++) {
            d[i] = p1[i] - p2[i];
            a[i] = g1[i];
        }
        pos[HINGE_REV + k] = norm3(d);
        cross3(a, world_axes[k], d);
        ang[HINGE_REV + k] = atan2(norm3(d), dot3(a, world_axes[k]));
    }
    dBodyID rb = dJointGetBody(mc->j[SLIDER_REV], 1);
    const dReal *x11 = dBodyGetPosition(rb);
    for (int i = 0; i < 3; i++) d[i] = x11[i] - mc->rev_slider_x0[i];
    along = dot3(d, mc->rev_slider_axis);
    for (int i = 0; i < 3; i++) d[i] -= along * mc->rev_slider_axis[i];
    pos[SLIDER_REV] = norm3(d);
    ang[SLIDER_REV] = relative_angle(dBodyGetRotation(rb), NULL, mc->identity);
    dBodyID fb2 = dJointGetBody(mc->j[FIXED_REV], 1);
    const dReal *x12 = dBodyGetPosition(fb2);
    for (int i = 0; i < 3; i++) d[i] = x12[i] - mc->rev_fixed_x0[i];
    pos[FIXED_REV] = norm3(d);
    ang[FIXED_REV] = relative_angle(dBodyGetRotation(fb2), NULL, mc->identity);
}

static int test_all_types(double seconds) {
    run s = {0};
    if (start_run(&s)) return 2;
    mechanisms mc;
    build_all(&s, &mc, 1, 1);
    double max_pos[N_JOINTS] = {0}, max_ang[N_JOINTS] = {0}, deepest = 0.0, resting = 0.0;
    size_t steps = (size_t)llround(seconds / STEP), contact_steps = 0;
    size_t rest_from = steps - (size_t)llround(0.5 / STEP);
    int status = 0;
    for (size_t k = 0; k < steps && !status; k++) {
        dContactGeom c[4];
        int nc = dCollide(mc.sphere_geom, mc.ground, 4, c, sizeof c[0]);
        for (int i = 0; i < nc; i++) {
            if (c[i].depth > deepest) deepest = c[i].depth;
            if (k >= rest_from && c[i].depth > resting) resting = c[i].depth;
        }
        contact_steps += nc > 0;
        if ((status = step(&s, c, (size_t)nc))) break;
        double pos[N_JOINTS], ang[N_JOINTS];
        drifts(&mc, pos, ang);
        for (int i = 0; i < N_JOINTS; i++) {
            if (!(pos[i] <= max_pos[i])) max_pos[i] = pos[i];
            if (!(ang[i] <= max_ang[i])) max_ang[i] = ang[i];
        }
    }
    if (!status) {
        check_run(&s, "all-types");
        printf("all-types: the sphere touched the ground on %zu steps (deepest %.3g m at the "
               "landing, %.3g m at rest); the pair slider ended at %.4g m (stop 0.2)\n",
               contact_steps, deepest, resting, dJointGetSliderPosition(mc.j[SLIDER_PAIR]));
        for (int i = 0; i < N_JOINTS; i++) {
            char msg[160];
            printf("  %-22s drift %.3g m, %.3g rad\n", joint_names[i], max_pos[i], max_ang[i]);
            snprintf(msg, sizeof msg, "the %s joint drifted %%.3g m (bound %%.3g m)",
                     joint_names[i]);
            if (!(max_pos[i] <= DRIFT_M)) check_failed(msg, max_pos[i], DRIFT_M);
            snprintf(msg, sizeof msg, "the %s joint turned %%.3g rad off (bound %%.3g rad)",
                     joint_names[i]);
            if (!(max_ang[i] <= DRIFT_RAD)) check_failed(msg, max_ang[i], DRIFT_RAD);
        }
        if (contact_steps < 10)
            check_failed("the sphere touched the ground on %g steps only (want %g or more)",
                         (double)contact_steps, 10.0);
        /* Landing at 3.7 m/s along its line (2.6 m/s down), it sinks up to one step's
         * travel (4.4 cm; 1.9 cm measured, as ODE's contacts would, pushed out at ERP a
         * step), then rests held by its contacts and slider, within the 1 mm surface layer
         * and 0.5 mm more. */
        if (!(resting <= 0.0015))
            check_failed("the sphere rests %.3g m deep (bound %.3g m)", resting, 0.0015);
        double slid = dJointGetSliderPosition(mc.j[SLIDER_PAIR]);
        if (!(fabs(slid - 0.2) <= 0.01))
            check_failed("the powered slider ended at %.4g m, not at its stop %.3g m", slid, 0.2);
    }
    if (mc.space) dSpaceDestroy(mc.space);
    end_run(&s);
    return status;
}

static int test_match_ode(double seconds) {
    run s = {0}, o = {0};
    if (start_run(&s) || start_run(&o)) return 2;
    mechanisms ms, mo;
    build_all(&s, &ms, 0, 0);
    build_all(&o, &mo, 0, 0);
    double worst_x = 0.0, worst_f = 0.0;
    size_t steps = (size_t)llround(seconds / STEP);
    int status = 0;
    for (size_t k = 0; k < steps && !status; k++) {
        if ((status = step(&s, NULL, 0))) break;
        dWorldStep(o.world, STEP);
        for (size_t i = 0; i < s.n; i++) {
            const dReal *a = dBodyGetPosition(s.bodies[i]), *b = dBodyGetPosition(o.bodies[i]);
            double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
            if (!(norm3(d) <= worst_x)) worst_x = norm3(d);
        }
        for (int j = 0; j < N_JOINTS; j++) {
            const dJointFeedback *a = &ms.fb[j], *b = &mo.fb[j];
            for (int i = 0; i < 3; i++) {
                double e = fmax(fmax(fabs(a->f1[i] - b->f1[i]), fabs(a->t1[i] - b->t1[i])),
                                fmax(fabs(a->f2[i] - b->f2[i]), fabs(a->t2[i] - b->t2[i])));
                if (!(e <= worst_f)) worst_f = e;
            }
        }
    }
    if (!status) {
        check_run(&s, "match-ode");
        printf("match-ode: bodies within %.3g m of dWorldStep's, joint feedback within %.3g N "
               "(N m)\n", worst_x, worst_f);
        if (!(worst_x <= MATCH_M))
            check_failed("a body is %.3g m from dWorldStep's (bound %.3g m)", worst_x, MATCH_M);
        if (!(worst_f <= MATCH_N))
            check_failed("a joint's feedback is %.3g off dWorldStep's (bound %.3g)", worst_f,
                         MATCH_N);
    }
    end_run(&s);
    end_run(&o);
    return status;
}

/* ---- rolling ------------------------------------------------------------------------------ */

/* Three 1 kg balls of radius 0.1 m on the ground plane (dContactRolling, mu 0.8):
 *  - A rolls along x at 2 m/s, rho = 0.01 with dContactApprox1 (the rolling torque bounded
 *    by rho times the normal force): a = -5/7 g rho / R;
 *  - B rolls the same way, rho = 0.05 N m without the approximation bits (a torque bound of
 *    its own): a = -5/7 rho / (m R);
 *  - C spins about the vertical at 10 rad/s, dContactAxisDep (mu2 = mu) with rhoN = 0.005
 *    and the approximation bits: w falls by h rhoN m g / I a step and stops at
 *    T = I w0 / (rhoN m g), then stays still.
 * Each step's v_x (A, B) and w_z (C) are checked against the closed forms within
 * ROLL_DRIFT of the initial speed (each step holds momentum to the tolerance relative to
 * the ball's, and the steps add up: 120 steps x 1e-8 = 1.2e-6, ten times that allowed;
 * measured 4.8e-7 and 2.3e-6), and the same world stepped by dWorldStep with ODE's own
 * contact joints must stay within ROLL_MATCH_M (measured 9.8e-7 m over 2 s; both worlds
 * without CFM: cadmm's contacts are rigid, and ODE's world CFM would let its balls sink
 * into the ground). --no-rolling drops dContactRolling (the negative control: the balls
 * keep rolling and spinning, and the checks fail). */
#define BALL_R 0.1
#define BALL_M 1.0
#define ROLL_DRIFT(seconds) (10.0 * (seconds) / STEP * TOLERANCE)
#define ROLL_MATCH_M 1e-5

typedef struct ball_world {
    dSpaceID space;
    dGeomID ground, geoms[3];
    dJointGroupID contacts; /* ODE's contact joints (the dWorldStep world) */
} ball_world;

static void build_balls(run *s, ball_world *bw) {
    bw->space = dSimpleSpaceCreate(0);
    bw->ground = dCreatePlane(bw->space, 0, 0, 1, 0);
    bw->contacts = dJointGroupCreate(0);
    dWorldSetCFM(s->world, 0.0);
    for (int i = 0; i < 3; i++) {
        dBodyID b = dBodyCreate(s->world);
        dMass m;
        dMassSetSphereTotal(&m, BALL_M, BALL_R);
        dBodySetMass(b, &m);
        /* 0.1 mm into the ground, inside the surface layer (no push-out): a ball that ends
         * a step rising by round-off keeps its contact. */
        dBodySetPosition(b, 0, 3.0 * i, BALL_R - 1e-4);
        bw->geoms[i] = dCreateSphere(bw->space, BALL_R);
        dGeomSetBody(bw->geoms[i], b);
        s->bodies[s->n++] = b;
    }
    dBodySetLinearVel(s->bodies[0], 2, 0, 0);
    dBodySetAngularVel(s->bodies[0], 0, 2 / BALL_R, 0);
    dBodySetLinearVel(s->bodies[1], 2, 0, 0);
    dBodySetAngularVel(s->bodies[1], 0, 2 / BALL_R, 0);
    dBodySetAngularVel(s->bodies[2], 0, 0, 10);
}

/* The balls' contacts with the ground, surfaces set (rolling unless `no_rolling`). */
static int ball_contacts(const ball_world *bw, int no_rolling, dContact out[3]) {
    int n = 0;
    for (int i = 0; i < 3; i++) {
        dContact *c = &out[n];
        memset(c, 0, sizeof *c);
        if (dCollide(bw->geoms[i], bw->ground, 1, &c->geom, sizeof *c) != 1) continue;
        c->surface.mu = 0.8;
        c->surface.mode = no_rolling ? 0 : dContactRolling;
        if (i == 0) c->surface.rho = 0.01, c->surface.mode |= dContactApprox1;
        if (i == 1) c->surface.rho = 0.05;
        if (i == 2) {
            c->surface.mode |= dContactAxisDep | dContactApprox1;
            c->surface.mu2 = c->surface.mu;
            c->surface.rho = c->surface.rho2 = 0.01;
            c->surface.rhoN = 0.005;
        }
        n++;
    }
    return n;
}

static int test_rolling(double seconds, int no_rolling) {
    run s = {0}, o = {0};
    if (start_run(&s) || start_run(&o)) return 2;
    ball_world bs, bo;
    build_balls(&s, &bs);
    build_balls(&o, &bo);
    const double I = 0.4 * BALL_M * BALL_R * BALL_R, w0 = 10.0;
    const double a[2] = {5.0 / 7.0 * GRAVITY * 0.01 / BALL_R, 5.0 / 7.0 * 0.05 / (BALL_M * BALL_R)};
    const double rate = 0.005 * BALL_M * GRAVITY / I, stop_at = I * w0 / (0.005 * BALL_M * GRAVITY);
    double off_v[2] = {0, 0}, off_w = 0.0, stopped = -1.0, worst_x = 0.0;
    size_t steps = (size_t)llround(seconds / STEP), rows = 0;
    int status = 0;
    for (size_t k = 0; k < steps && !status; k++) {
        dContact c[3];
        int nc = ball_contacts(&bs, no_rolling, c);
        if ((status = step_with(&s, NULL, c, (size_t)nc))) break;
        if (s.joint_rows_max > rows) rows = s.joint_rows_max;
        int no = ball_contacts(&bo, no_rolling, c);
        for (int i = 0; i < no; i++)
            dJointAttach(dJointCreateContact(o.world, bo.contacts, &c[i]), dGeomGetBody(c[i].geom.g1),
                         dGeomGetBody(c[i].geom.g2));
        dWorldStep(o.world, STEP);
        dJointGroupEmpty(bo.contacts);
        double t = (double)(k + 1) * STEP;
        for (int i = 0; i < 2; i++) {
            double v = dBodyGetLinearVel(s.bodies[i])[0], want = 2.0 - t * a[i];
            if (!(fabs(v - want) <= off_v[i])) off_v[i] = fabs(v - want);
        }
        double w = dBodyGetAngularVel(s.bodies[2])[2], want = fmax(w0 - t * rate, 0.0);
        if (!(fabs(w - want) <= off_w)) off_w = fabs(w - want);
        if (stopped < 0 && fabs(w) <= 1e-9) stopped = t;
        for (size_t i = 0; i < s.n; i++) {
            const dReal *x = dBodyGetPosition(s.bodies[i]), *y = dBodyGetPosition(o.bodies[i]);
            double d[3] = {x[0] - y[0], x[1] - y[1], x[2] - y[2]};
            if (!(norm3(d) <= worst_x)) worst_x = norm3(d);
        }
    }
    if (!status) {
        check_run(&s, "rolling");
        printf("rolling: %zu rows; A's speed off 2 - 5/7 g rho t / R by %.3g m/s, B's off "
               "2 - 5/7 rho t / (m R) by %.3g m/s; C's spin off its decay by %.3g rad/s, "
               "stopped at %.4g s (closed form %.4g s); bodies within %.3g m of dWorldStep's\n",
               rows, off_v[0], off_v[1], off_w, stopped, stop_at, worst_x);
        const double bound_v = 2.0 * ROLL_DRIFT(seconds), bound_w = w0 * ROLL_DRIFT(seconds);
        if (!(off_v[0] <= bound_v))
            check_failed("ball A's speed is %.3g m/s off its closed form (bound %.3g)", off_v[0],
                         bound_v);
        if (!(off_v[1] <= bound_v))
            check_failed("ball B's speed is %.3g m/s off its closed form (bound %.3g)", off_v[1],
                         bound_v);
        if (!(off_w <= bound_w && fabs(stopped - stop_at) <= STEP))
            check_failed("ball C's spin is %.3g rad/s off its decay, or it stopped at %.4g s",
                         off_w, stopped);
        if (!(worst_x <= ROLL_MATCH_M))
            check_failed("a ball is %.3g m from dWorldStep's (bound %.3g m)", worst_x,
                         ROLL_MATCH_M);
    }
    dJointGroupDestroy(bs.contacts);
    dJointGroupDestroy(bo.contacts);
    dSpaceDestroy(bs.space);
    dSpaceDestroy(bo.space);
    end_run(&s);
    end_run(&o);
    return status;
}

static int usage(const char *why) {
    fprintf(stderr,
            "cadmm_ode_joints: %s\n"
            "usage: cadmm_ode_joints --test limit|motor|all-types|match-ode|rolling "
            "[--seconds S] [--no-stops] [--no-rolling]\n",
            why);
    return 2;
}

int main(int argc, char **argv) {
    const char *test = NULL;
    double seconds = 2.0;
    int no_stops = 0, no_rolling = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--test") && i + 1 < argc) test = argv[++i];
        else if (!strcmp(argv[i], "--no-stops")) no_stops = 1;
        else if (!strcmp(argv[i], "--no-rolling")) no_rolling = 1;
        else if (!strcmp(argv[i], "--seconds") && i + 1 < argc) {
            char *end;
            seconds = strtod(argv[++i], &end);
            if (*end || !(seconds >= 2.0) || !(seconds <= 60.0))
                return usage("--seconds needs a number from 2 to 60 (the checks at rest look "
                             "at the last half second, after the landings)");
        } else {
            return usage("unknown argument or missing value");
        }
    }
    if (!test) return usage("--test is required");
    dInitODE2(0);
    int status;
    if (!strcmp(test, "limit")) status = test_limit(seconds, no_stops);
    else if (!strcmp(test, "motor")) status = test_motor(seconds);
    else if (!strcmp(test, "all-types")) status = test_all_types(seconds);
    else if (!strcmp(test, "match-ode")) status = test_match_ode(seconds);
    else if (!strcmp(test, "rolling")) status = test_rolling(seconds, no_rolling);
    else status = usage("--test must be limit, motor, all-types, match-ode or rolling");
    dCloseODE();
    if (status) return status;
    printf("%s\n", failures ? "FAILED" : "all checks passed");
    return failures ? 1 : 0;
}
