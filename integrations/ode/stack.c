/*
 * cadmm_ode_stack: box stacks and scenes in motion simulated by ODE at 60 Hz, with contact
 * impulses from cadmm (cadmm_ode.h) or from ODE's own solvers, printing one summary line.
 *
 *   cadmm_ode_stack --scene tower|mass-ratio-100|mass-ratio-1000|pyramid|slide|
 *                           big-pyramid|wall|bin|vehicle|chain
 *                   --solver cadmm|ode-quickstep|ode-step --seconds S
 *                   [--json] [--trace FILE.csv] [--cold] [--check] [--count N] [--seed N]
 *                   [--tolerance T] [--max-iterations N] [--check-tolerance T] [--mu M]
 *                   [--time-limit S] [--ode-iterations N] [--dump STEP,... --dump-dir DIR]
 *
 * --count and --seed size and vary big-pyramid, wall, bin and chain (scenes.h). --dump writes
 * the problem of each listed step (1-based) as an FCLib file, DIR/SCENE-stepN.hdf5, with
 * either solver (joints as equality rows; cadmm built with CADMM_WITH_FCLIB). --ode-iterations
 * sets dWorldQuickStep's iterations (dWorldSetQuickStepNumIterations; ODE's default 20).
 *
 * --check exits with 1 when the scene failed, after one "check failed: ..." line per failed
 * check on stderr:
 *  - stacks: a body fell, or the top body drifted 1 mm or more;
 *  - slide: the box did not stop, or stopped farther than SLIDE_SLACK from v0^2 / (2 mu g)
 *    (mu the scene's friction, 0.5);
 *  - vehicle: a wheel did not get over the bump, a hinge-2 opened across its suspension
 *    axis by VEHICLE_MAX_GAP or more, or turned its axes VEHICLE_MAX_ANGLE or more off
 *    (steering off its lock at 0, or axis 2 off square to axis 1);
 *  - a contact deeper than MAX_DEPTH (ODE's contact depths after every step; not for the
 *    scenes in motion, wall and bin, whose falling and tumbling bodies land up to a step's
 *    travel deep and whose bin starts with tilted neighbors overlapping by up to 12 cm:
 *    their at-rest checks do not apply either);
 *  - (cadmm) a step's solve ended above its tolerance, or its answer re-measured by the
 *    driver's own copy of the error measure (check.h) on the problem cadmm_ode built is above
 *    the check tolerance (--check-tolerance, default the solver's --tolerance, default 1e-8).
 * 2 means bad arguments or a failed call. --time-limit is cadmm's budget per step in
 * seconds (cadmm_ode_options.time_limit; 0, the default, for none).
 * --tolerance and --max-iterations set cadmm's, --mu
 * the friction coefficient handed to the solvers (default the scene's: 0.5, the vehicle's
 * 1); CTest uses them to show that the checks fire.
 *
 * ODE's solvers get contact joints with that mu and dContactApprox1 (friction pyramid whose
 * bound scales with the normal force), default ERP and CFM and iterations unless
 * --ode-iterations. Their impulses (contact joint feedback forces times h) are measured
 * with cadmm's error measure on the same problem cadmm solves, so max_error compares like
 * with like; the joint multipliers of the vehicle's hinge-2s and the chain's balls are
 * recovered from their feedback (ode_joint_multipliers), cadmm's are its own.
 */
#include "cadmm_ode.h"
#include "check.h"
#include "scenes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define STEP (1.0 / 60.0)
#define MAX_CONTACTS_PER_PAIR 8
#define GRAVITY 9.81

/* ODE pushes a contact out only beyond its surface layer (1 mm in these scenes), so a held
 * resting contact sits up to 1 mm deep by design; the scenes start 0.5 mm deep. 0.5 mm more
 * is a fifth of what one step of unopposed gravity sinks a resting box (g h^2 = 2.7 mm at
 * 60 Hz): a contact that is not held shows within a step. */
#define MAX_DEPTH 0.0015

/* Semi-implicit Euler takes each step's deceleration before its move, so a box launched at
 * v0 stops v0 h / 2 short of v0^2 / (2 mu g) (3.3 cm at 4 m/s and 60 Hz; 3.3 cm measured),
 * plus at most one step of travel at the last step's speed (mu g h^2 = 1.4 mm). The check
 * allows that bias plus 1 cm: 4.3 cm, 2.6% of the 1.63 m; a friction 5% off either way moves
 * the stop by 5 to 11 cm from Coulomb's. */
#define SLIDE_SLACK(v0) ((v0) * STEP / 2 + 0.01)

/* The vehicle's joints hold velocities (ERP 0.2 takes back a fifth of a position error a
 * step), so they open while the rear wheels come off the bump and the chassis pitches on
 * compressed springs: 3.15 mm at 1.67 s with cadmm at 1e-8 and with dWorldStep's exact
 * solve alike (the joint rows' drift, not a solver's; 3.3 mm with QuickStep; see
 * docs/perf/engine-vehicle-2026-11-27). The bound is 3 times that. The axes stay square
 * and the steering at its lock within 1e-15 rad under a converged solve (5e-4 rad with
 * QuickStep): 0.01 rad is a wheel visibly turned off. */
#define VEHICLE_MAX_GAP 0.01
#define VEHICLE_MAX_ANGLE 0.01

typedef enum { SOLVER_CADMM, SOLVER_QUICKSTEP, SOLVER_STEP } solver_kind;

typedef struct options {
    const char *scene, *trace;
    solver_kind solver;
    double seconds, tolerance, check_tolerance, mu, time_limit;
    long max_iterations, count, ode_iterations;
    unsigned long seed;
    int json, cold, check;
    /* --dump: steps (1-based) whose problem is written as an FCLib file into dump_dir. */
    const char *dump_dir;
    long dump[16];
    size_t n_dump;
} options;

/* The contacts of one step, g1 always carrying a body. */
typedef struct contact_list {
    dContactGeom *geoms;
    size_t n, cap;
    int failed;
} contact_list;

typedef struct summary {
    size_t steps, solved_steps, unsolved, builds, updates, contact_sum, max_contacts, warm_matched;
    size_t dumps_failed, dumps_differ; /* --dump: files not written or read, read back unlike */
    double iterations_sum, max_iterations, solve_ms_sum, max_solve_ms, cpu_ms_sum, max_cpu_ms;
    double max_penetration, max_drift, max_error, max_checked_error;
    int fell;
    /* The vehicle (observe_vehicle): its joints' largest gap across the suspension axis,
     * suspension travel along it, axes' error and steering angle; the chassis' lowest and
     * highest center, largest pitch (nose up or down) and roll, overall and while a wheel is
     * on the bump; the time at which the last wheel passed the bump (NAN: not yet). */
    double max_joint_gap, max_suspension_travel, max_axis_error, max_steer;
    double min_z, max_z, max_pitch, max_roll, bump_min_z, bump_max_z, bump_max_pitch, over_time;
} summary;

static double clock_ms(clockid_t clock) {
    struct timespec t;
    clock_gettime(clock, &t);
    return 1e3 * (double)t.tv_sec + 1e-6 * (double)t.tv_nsec;
}

/* Wall time, and this thread's CPU time: on a shared machine the CPU time is the steadier
 * figure (every solver here runs on the calling thread). */
typedef struct stamp {
    double wall, cpu;
} stamp;

static stamp now(void) {
    return (stamp){clock_ms(CLOCK_MONOTONIC), clock_ms(CLOCK_THREAD_CPUTIME_ID)};
}

static int usage(const char *why) {
    fprintf(stderr,
            "cadmm_ode_stack: %s\n"
            "usage: cadmm_ode_stack --scene %s --solver cadmm|ode-quickstep|ode-step\n"
            "                       --seconds S [--json] [--trace FILE.csv] [--cold] [--check]\n"
            "                       [--count N] [--seed N] [--tolerance T] [--max-iterations N]\n"
            "                       [--check-tolerance T] [--mu M] [--time-limit S]\n"
            "                       [--ode-iterations N] [--dump STEP,... --dump-dir DIR]\n",
            why, scene_names);
    return 2;
}

static int parse(int argc, char **argv, options *o) {
    /* mu -1: the scene's. */
    *o = (options){.solver = SOLVER_CADMM, .seconds = -1, .tolerance = 1e-8, .mu = -1, .seed = 1};
    const char *solver = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has_value = i + 1 < argc;
        if (!strcmp(a, "--json")) o->json = 1;
        else if (!strcmp(a, "--cold")) o->cold = 1;
        else if (!strcmp(a, "--check")) o->check = 1;
        else if (!strcmp(a, "--scene") && has_value) o->scene = argv[++i];
        else if (!strcmp(a, "--solver") && has_value) solver = argv[++i];
        else if (!strcmp(a, "--trace") && has_value) o->trace = argv[++i];
        else if (!strcmp(a, "--seconds") && has_value) {
            char *end;
            o->seconds = strtod(argv[++i], &end);
            if (*end || !(o->seconds > 0) || !isfinite(o->seconds))
                return usage("--seconds needs a positive number");
        } else if ((!strcmp(a, "--tolerance") || !strcmp(a, "--check-tolerance") ||
                    !strcmp(a, "--mu")) && has_value) {
            char *end;
            double x = strtod(argv[++i], &end);
            if (*end || !isfinite(x) || !(x > 0 || (x == 0 && !strcmp(a, "--mu"))))
                return usage("--tolerance and --check-tolerance need a positive number, --mu a "
                             "non-negative one");
            *(!strcmp(a, "--tolerance") ? &o->tolerance
              : !strcmp(a, "--mu")      ? &o->mu
                                        : &o->check_tolerance) = x;
        } else if (!strcmp(a, "--count") && has_value) {
            char *end;
            o->count = strtol(argv[++i], &end, 10);
            if (*end || o->count < 0 || o->count > SCENE_MAX_COUNT)
                return usage("--count needs an integer from 0 (the scene's default) to 100000");
        } else if (!strcmp(a, "--seed") && has_value) {
            char *end;
            const char *text = argv[++i];
            o->seed = strtoul(text, &end, 10);
            if (*end || !*text || *text == '-') return usage("--seed needs a non-negative integer");
        } else if (!strcmp(a, "--time-limit") && has_value) {
            char *end;
            o->time_limit = strtod(argv[++i], &end);
            if (*end || !(o->time_limit >= 0) || !isfinite(o->time_limit))
                return usage("--time-limit needs a non-negative number of seconds (0: none)");
        } else if (!strcmp(a, "--max-iterations") && has_value) {
            char *end;
            o->max_iterations = strtol(argv[++i], &end, 10);
            if (*end || o->max_iterations < 1 || o->max_iterations > 1000000000)
                return usage("--max-iterations needs a positive integer");
        } else if (!strcmp(a, "--dump-dir") && has_value) {
            o->dump_dir = argv[++i];
        } else if (!strcmp(a, "--dump") && has_value) {
            const char *at = argv[++i];
            for (;;) {
                char *end;
                long step = strtol(at, &end, 10);
                if (end == at || step < 1 || o->n_dump == sizeof o->dump / sizeof o->dump[0])
                    return usage("--dump takes up to 16 step numbers from 1, comma-separated");
                o->dump[o->n_dump++] = step;
                if (!*end) break;
                if (*end != ',') return usage("--dump takes step numbers separated by commas");
                at = end + 1;
            }
        } else if (!strcmp(a, "--ode-iterations") && has_value) {
            char *end;
            o->ode_iterations = strtol(argv[++i], &end, 10);
            if (*end || o->ode_iterations < 1 || o->ode_iterations > 1000000)
                return usage("--ode-iterations needs a positive integer");
        } else {
            char why[256];
            snprintf(why, sizeof why, "unknown argument or missing value: %s", a);
            return usage(why);
        }
    }
    if (!o->scene) return usage("--scene is required");
    if (o->n_dump && !o->dump_dir) return usage("--dump needs --dump-dir");
    if (o->seconds < 0) return usage("--seconds is required");
    if (o->check_tolerance == 0) o->check_tolerance = o->tolerance;
    if (!solver || !strcmp(solver, "cadmm")) o->solver = SOLVER_CADMM;
    else if (!strcmp(solver, "ode-quickstep")) o->solver = SOLVER_QUICKSTEP;
    else if (!strcmp(solver, "ode-step")) o->solver = SOLVER_STEP;
    else return usage("--solver must be cadmm, ode-quickstep or ode-step");
    return 0;
}

/* dSpaceCollide callback: every contact point of a pair, the moving geom first. Bodies
 * held together by a joint do not collide (the vehicle's wheels overlap its chassis). */
static void near_callback(void *data, dGeomID o1, dGeomID o2) {
    contact_list *list = data;
    dBodyID b1 = dGeomGetBody(o1), b2 = dGeomGetBody(o2);
    if (!b1 && !b2) return;
    if (b1 && b2 && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;
    if (list->n + MAX_CONTACTS_PER_PAIR > list->cap) {
        size_t cap = 2 * list->cap + MAX_CONTACTS_PER_PAIR;
        dContactGeom *g = realloc(list->geoms, cap * sizeof *g);
        if (!g) {
            list->failed = 1;
            return;
        }
        list->geoms = g;
        list->cap = cap;
    }
    dContactGeom *out = &list->geoms[list->n];
    int found = dCollide(o1, o2, MAX_CONTACTS_PER_PAIR, out, sizeof *out);
    for (int k = 0; k < found; k++) {
        dContactGeom *c = &out[k];
        if (!dGeomGetBody(c->g1)) {
            dGeomID g = c->g1;
            c->g1 = c->g2;
            c->g2 = g;
            int side = c->side1;
            c->side1 = c->side2;
            c->side2 = side;
            for (int d = 0; d < 3; d++) c->normal[d] = -c->normal[d];
        }
    }
    list->n += (size_t)found;
}

/* ODE's own step with contact joints; the impulses (feedback force times h) go to r in
 * the contact frames of cadmm_ode_frame. */
static void ode_step(const scene *s, const contact_list *cl, solver_kind kind, double mu,
                     dJointGroupID group, dJointFeedback *feedback, double *r) {
    for (size_t c = 0; c < cl->n; c++) {
        dContact ct;
        memset(&ct, 0, sizeof ct);
        ct.surface.mode = dContactApprox1;
        ct.surface.mu = mu;
        ct.geom = cl->geoms[c];
        dJointID j = dJointCreateContact(s->world, group, &ct);
        dJointAttach(j, dGeomGetBody(ct.geom.g1), dGeomGetBody(ct.geom.g2));
        dJointSetFeedback(j, &feedback[c]);
    }
    if (kind == SOLVER_QUICKSTEP) dWorldQuickStep(s->world, STEP);
    else dWorldStep(s->world, STEP);
    for (size_t c = 0; c < cl->n; c++) {
        dReal t1[3], t2[3];
        const dReal *n = cl->geoms[c].normal, *f = feedback[c].f1;
        cadmm_ode_frame(n, t1, t2);
        r[3 * c] = STEP * (f[0] * n[0] + f[1] * n[1] + f[2] * n[2]);
        r[3 * c + 1] = STEP * (f[0] * t1[0] + f[1] * t1[1] + f[2] * t1[2]);
        r[3 * c + 2] = STEP * (f[0] * t2[0] + f[1] * t2[1] + f[2] * t2[2]);
    }
    dJointGroupEmpty(group);
}

/* The problem's index (0-based, 6 unknowns each) of scene body b; p->n / 6 when absent. */
static size_t problem_body(const scene *s, const cadmm_ode_problem *p, dBodyID b) {
    for (size_t k = 0; k < p->n / 6; k++)
        if (s->bodies[p->body_index[k]] == b) return k;
    return p->n / 6;
}

/* ODE's multipliers of the scene's joints' rows (lambda, p->n_joint_rows of them), from
 * their feedback after ODE's step. ODE fills a joint's feedback with J^T F on each body (F
 * its rows' forces), and cadmm_ode writes the same rows J as G's columns, so
 * G_j lambda_j = h (f1, t1, f2, t2) holds with ODE's own lambda_j = F h: the normal
 * equations of those 12 equations (a joint has at most 6 rows, independent) give it back.
 * Rows of joints that are not the scene's stay 0. 0, or -1 if a joint has too many rows. */
static int ode_joint_multipliers(const scene *s, const cadmm_ode *ctx,
                                 const cadmm_ode_problem *p, double *lambda) {
    enum { MAX_ROWS = 8 };
    for (size_t k = 0; k < p->n_joint_rows; k++) lambda[k] = 0.0;
    for (size_t j = 0; j < s->n_joints; j++) {
        size_t first = 0, count = 0;
        if (cadmm_ode_joint_rows(ctx, s->joints[j], &first, &count) != CADMM_OK) return -1;
        if (count == 0) continue;
        if (count > MAX_ROWS) return -1;
        const dJointFeedback *fb = &s->joint_feedback[j];
        size_t k1 = problem_body(s, p, dJointGetBody(s->joints[j], 0)),
               k2 = problem_body(s, p, dJointGetBody(s->joints[j], 1));
        /* The target entry of unknown `row`: the force (or torque) times h on its body. */
        double a[MAX_ROWS][MAX_ROWS] = {{0}}, rhs[MAX_ROWS] = {0};
        for (size_t c = 0; c < count; c++) {
            const cadmm_csc *G = &p->G;
            for (int64_t i = G->colptr[first + c]; i < G->colptr[first + c + 1]; i++) {
                size_t row = (size_t)G->rowind[i], k = row / 6, d = row % 6;
                const dReal *f = k == k1 ? (d < 3 ? fb->f1 : fb->t1)
                                 : k == k2 ? (d < 3 ? fb->f2 : fb->t2)
                                           : NULL;
                if (f) rhs[c] += G->values[i] * STEP * f[d % 3];
                /* Column c against every column of the joint: G_j^T G_j. */
                for (size_t e = 0; e < count; e++)
                    for (int64_t l = G->colptr[first + e]; l < G->colptr[first + e + 1]; l++)
                        if ((size_t)G->rowind[l] == row) a[c][e] += G->values[i] * G->values[l];
            }
        }
        /* Gaussian elimination (the matrix is symmetric positive definite: no pivoting). */
        for (size_t c = 0; c < count; c++) {
            for (size_t r = c + 1; r < count; r++) {
                double q = a[r][c] / a[c][c];
                for (size_t e = c; e < count; e++) a[r][e] -= q * a[c][e];
                rhs[r] -= q * rhs[c];
            }
        }
        for (size_t c = count; c-- > 0;) {
            double x = rhs[c];
            for (size_t e = c + 1; e < count; e++) x -= a[c][e] * lambda[first + e];
            lambda[first + c] = x / a[c][c];
        }
    }
    return 0;
}

/* The vehicle after a step: each hinge-2's anchors (the one carried by the chassis, the
 * one by the wheel) apart across axis 1 (the joint's gap; along axis 1 is the suspension's
 * travel, by design), its axes off square, its steering angle (locked at 0); the chassis'
 * height, pitch and roll, also while a wheel is on the bump; when the last wheel passed
 * the bump's far foot. Returns the step's largest gap. */
static double observe_vehicle(const scene *s, summary *sum, double time) {
    double step_gap = 0.0;
    for (size_t j = 0; j < s->n_joints; j++) {
        dVector3 p1, p2, g1, g2;
        dJointGetHinge2Anchor(s->joints[j], p1);
        dJointGetHinge2Anchor2(s->joints[j], p2);
        dJointGetHinge2Axis1(s->joints[j], g1);
        dJointGetHinge2Axis2(s->joints[j], g2);
        double d[3], along = 0.0, gap2 = 0.0, c[3];
        for (int k = 0; k < 3; k++) d[k] = p1[k] - p2[k];
        for (int k = 0; k < 3; k++) along += d[k] * g1[k];
        for (int k = 0; k < 3; k++) gap2 += (d[k] - along * g1[k]) * (d[k] - along * g1[k]);
        c[0] = g1[1] * g2[2] - g1[2] * g2[1];
        c[1] = g1[2] * g2[0] - g1[0] * g2[2];
        c[2] = g1[0] * g2[1] - g1[1] * g2[0];
        double angle = atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                             g1[0] * g2[0] + g1[1] * g2[1] + g1[2] * g2[2]);
        double axis_error = fabs(angle - 1.5707963267948966),
               steer = fabs(dJointGetHinge2Angle1(s->joints[j]));
        if (!(sqrt(gap2) <= step_gap)) step_gap = sqrt(gap2);
        if (!(fabs(along) <= sum->max_suspension_travel)) sum->max_suspension_travel = fabs(along);
        if (!(axis_error <= sum->max_axis_error)) sum->max_axis_error = axis_error;
        if (!(steer <= sum->max_steer)) sum->max_steer = steer;
    }
    /* Pitch: the chassis' x axis (R's first column) above the horizontal; roll: its y axis. */
    const dReal *x = dBodyGetPosition(s->bodies[s->top]);
    const dReal *R = dBodyGetRotation(s->bodies[s->top]);
    double pitch = fabs(atan2(R[8], hypot(R[0], R[4])));
    double roll = fabs(atan2(R[9], hypot(R[1], R[5])));
    if (!(x[2] >= sum->min_z)) sum->min_z = x[2];
    if (!(x[2] <= sum->max_z)) sum->max_z = x[2];
    if (!(pitch <= sum->max_pitch)) sum->max_pitch = pitch;
    if (!(roll <= sum->max_roll)) sum->max_roll = roll;
    int on_bump = 0, all_over = 1;
    for (size_t i = 0; i < s->n; i++) {
        if (i == s->top) continue;
        double wx = dBodyGetPosition(s->bodies[i])[0];
        on_bump |= fabs(wx - s->bump_x) < s->wheel_radius + s->bump_radius;
        all_over &= wx > s->bump_x + s->bump_radius;
    }
    if (on_bump) {
        if (!(x[2] >= sum->bump_min_z)) sum->bump_min_z = x[2];
        if (!(x[2] <= sum->bump_max_z)) sum->bump_max_z = x[2];
        if (!(pitch <= sum->bump_max_pitch)) sum->bump_max_pitch = pitch;
    }
    if (all_over && isnan(sum->over_time)) sum->over_time = time;
    if (!(step_gap <= sum->max_joint_gap)) sum->max_joint_gap = step_gap;
    return step_gap;
}

/* The chain after a step: each ball joint's two anchors apart (the one its first body
 * carries, the one its second body or the world does); other joints are not read.
 * Returns the step's largest gap.
 * Reported, not checked: the joints hold velocities, and at the swing's bottom every solver
 * leaves them open by 13 to 14 cm (ODE's exact dWorldStep among them), closing again at
 * ERP's pace. */
static double observe_balls(const scene *s, summary *sum) {
    double step_gap = 0.0;
    for (size_t j = 0; j < s->n_joints; j++) {
        if (dJointGetType(s->joints[j]) != dJointTypeBall) continue;
        dVector3 p1, p2;
        dJointGetBallAnchor(s->joints[j], p1);
        dJointGetBallAnchor2(s->joints[j], p2);
        double d[3] = {p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]};
        double gap = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(gap <= step_gap)) step_gap = gap;
    }
    if (!(step_gap <= sum->max_joint_gap)) sum->max_joint_gap = step_gap;
    return step_gap;
}

/* Drift of the top body and whether any body left the stack (moved sideways by more than
 * its half width; not for the sliding box) or sank (by more than half its half height); a
 * scene in motion only reports its top body's height and drift. */
static void observe(const scene *s, summary *sum, double *top_z, double *drift) {
    for (size_t i = 0; i < s->n; i++) {
        if (s->in_motion && i != s->top) continue;
        const dReal *x = dBodyGetPosition(s->bodies[i]);
        double dx = x[0] - s->start[i][0], dy = x[1] - s->start[i][1];
        double side = sqrt(dx * dx + dy * dy);
        int sideways = side > s->half[i][0] && s->launch == 0;
        if (!s->in_motion &&
            (sideways || x[2] < s->start[i][2] - 0.5 * s->half[i][2] || !isfinite(side)))
            sum->fell = 1;
        if (i == s->top) {
            *top_z = x[2];
            *drift = side;
            if (side > sum->max_drift || !isfinite(side)) sum->max_drift = side;
        }
    }
}

/* The contacts of the bodies' current places (ODE's collision detection); the deepest
 * goes to max_penetration. Returns that depth, or -1 when out of memory. */
static double collide(const scene *s, contact_list *cl, summary *sum) {
    cl->n = 0;
    dSpaceCollide(s->space, cl, near_callback);
    if (cl->failed) return -1.0;
    double depth = 0.0;
    for (size_t c = 0; c < cl->n; c++)
        if (cl->geoms[c].depth > depth) depth = cl->geoms[c].depth;
    if (depth > sum->max_penetration) sum->max_penetration = depth;
    return depth;
}

/* --dump: the step's problem (1-based `step`) as DIR/SCENE-stepN.hdf5, joints as equality
 * rows; a problem FCLib cannot hold (rows bounded, compliant or bounded by a contact) is
 * reported, not written: every row property is handed over, so the writer refuses it.
 * The file is read back, and the step's answer (r, v, lambda) measured on both: 1 when the
 * two measures differ (the file does not hold the step's problem), -1 when it could not be
 * written or read, 0 otherwise (also for steps not listed). */
static int dump_problem(const options *o, const cadmm_ode_problem *p, size_t step,
                        const double *r, const double *v, const double *lambda) {
    int listed = 0;
    for (size_t k = 0; k < o->n_dump; k++) listed |= (size_t)o->dump[k] == step;
    if (!listed) return 0;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s-step%zu.hdf5", o->dump_dir, o->scene, step);
    cadmm_problem *made = NULL, *read = NULL;
    cadmm_result rc =
        cadmm_problem_new_global(p->n, p->n_contacts, &p->M, &p->H, p->f, p->w, p->mu, &made);
    if (rc == CADMM_OK && p->n_joint_rows) rc = cadmm_problem_set_joints(made, &p->G, p->b);
    if (rc == CADMM_OK && p->n_joint_rows) rc = cadmm_problem_set_joint_bounds(made, p->lo, p->hi);
    if (rc == CADMM_OK && p->n_joint_rows) rc = cadmm_problem_set_joint_compliance(made, p->c);
    if (rc == CADMM_OK && p->n_joint_rows)
        rc = cadmm_problem_set_joint_friction(made, p->friction_contact, p->friction);
    if (rc == CADMM_OK) rc = cadmm_problem_write_fclib(made, path);
    if (rc == CADMM_OK) rc = cadmm_problem_read_fclib(path, &read);
    double written = NAN, back = NAN;
    if (rc == CADMM_OK) rc = cadmm_problem_error_with_multipliers(made, r, v, lambda, &written);
    if (rc == CADMM_OK) rc = cadmm_problem_error_with_multipliers(read, r, v, lambda, &back);
    if (rc != CADMM_OK)
        fprintf(stderr, "cadmm_ode_stack: cannot dump %s: %s\n", path, cadmm_last_error());
    cadmm_problem_free(made);
    cadmm_problem_free(read);
    if (rc != CADMM_OK) return -1;
    /* The same doubles in the same order: the two measures agree to round-off. */
    return !(fabs(back - written) <= 1e-12 * fmax(1.0, fabs(written)));
}

static const char *solver_name(solver_kind k) {
    return k == SOLVER_CADMM ? "cadmm" : k == SOLVER_QUICKSTEP ? "ode-quickstep" : "ode-step";
}

static int compare_doubles(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The q-quantile of n values (nearest rank), sorting them; NAN for none. */
static double percentile(double *xs, size_t n, double q) {
    if (n == 0) return NAN;
    qsort(xs, n, sizeof *xs, compare_doubles);
    size_t rank = (size_t)ceil(q * (double)n);
    return xs[(rank < 1 ? 1 : rank > n ? n : rank) - 1];
}

static void print_number(const char *key, double x, int valid) {
    if (valid && isfinite(x)) printf(",\"%s\":%.6g", key, x);
    else printf(",\"%s\":null", key);
}

/* step_ms and step_cpu_ms (one per step) are sorted for their 99th percentiles. */
static void report(const options *o, const scene *s, const summary *sum, double *step_ms,
                   double *step_cpu_ms) {
    int is_cadmm = o->solver == SOLVER_CADMM;
    double solved = sum->solved_steps ? (double)sum->solved_steps : 1.0;
    double p99 = percentile(step_ms, sum->steps, 0.99),
           p99_cpu = percentile(step_cpu_ms, sum->steps, 0.99);
    if (o->json) {
        printf("{\"scene\":\"%s\",\"solver\":\"%s\",\"warm\":%s,\"count\":%ld,"
               "\"seed\":%lu,\"bodies\":%zu,\"steps\":%zu",
               o->scene, solver_name(o->solver), is_cadmm && !o->cold ? "true" : "false",
               o->count, o->seed, s->n, sum->steps);
        print_number("mean_iterations", sum->iterations_sum / solved, is_cadmm);
        print_number("max_iterations", sum->max_iterations, is_cadmm);
        print_number("mean_solve_ms", sum->solve_ms_sum / (double)sum->steps, 1);
        print_number("p99_solve_ms", p99, 1);
        print_number("max_solve_ms", sum->max_solve_ms, 1);
        print_number("mean_solve_cpu_ms", sum->cpu_ms_sum / (double)sum->steps, 1);
        print_number("p99_solve_cpu_ms", p99_cpu, 1);
        print_number("max_solve_cpu_ms", sum->max_cpu_ms, 1);
        print_number("max_penetration", sum->max_penetration, 1);
        /* The at-rest figures do not apply to a scene in motion. */
        print_number("max_drift", sum->max_drift, !s->in_motion);
        printf(",\"fell\":%s", s->in_motion ? "null" : sum->fell ? "true" : "false");
        print_number("max_error", sum->max_error, 1);
        print_number("max_checked_error", sum->max_checked_error, 1);
        print_number("mean_contacts", (double)sum->contact_sum / (double)sum->steps, 1);
        printf(",\"max_contacts\":%zu", sum->max_contacts);
        if (is_cadmm)
            printf(",\"unsolved_steps\":%zu,\"solver_builds\":%zu,\"solver_updates\":%zu,"
                   "\"warm_matched\":%zu",
                   sum->unsolved, sum->builds, sum->updates, sum->warm_matched);
        if (s->n_joints) {
            printf(",\"joints\":%zu", s->n_joints);
            print_number("ode_iterations", (double)o->ode_iterations,
                         o->solver == SOLVER_QUICKSTEP && o->ode_iterations > 0);
            print_number("max_joint_gap", sum->max_joint_gap, 1);
        }
        if (s->vehicle) {
            /* The vehicle (observe_vehicle; lengths in m, angles in rad, times in s). */
            const dReal *x = dBodyGetPosition(s->bodies[s->top]);
            print_number("max_axis_error", sum->max_axis_error, 1);
            print_number("max_steer", sum->max_steer, 1);
            print_number("max_suspension_travel", sum->max_suspension_travel, 1);
            print_number("distance", x[0] - s->start[s->top][0], 1);
            print_number("final_speed", dBodyGetLinearVel(s->bodies[s->top])[0], 1);
            print_number("over_bump_time", sum->over_time, 1);
            print_number("min_chassis_z", sum->min_z, 1);
            print_number("max_chassis_z", sum->max_z, 1);
            print_number("final_chassis_z", x[2], 1);
            print_number("max_pitch", sum->max_pitch, 1);
            print_number("max_roll", sum->max_roll, 1);
            print_number("bump_min_chassis_z", sum->bump_min_z, 1);
            print_number("bump_max_chassis_z", sum->bump_max_z, 1);
            print_number("bump_max_pitch", sum->bump_max_pitch, 1);
        }
        printf("}\n");
    } else {
        printf("%s with %s: %zu steps, %.3g ms per solve (p99 %.3g, max %.3g; CPU %.3g), "
               "%.1f contacts per step, max penetration %.3g m, max drift %.3g m, "
               "max error %.3g, %s\n",
               o->scene, solver_name(o->solver), sum->steps,
               sum->solve_ms_sum / (double)sum->steps, p99, sum->max_solve_ms,
               sum->cpu_ms_sum / (double)sum->steps, (double)sum->contact_sum / (double)sum->steps,
               sum->max_penetration, sum->max_drift, sum->max_error,
               s->in_motion ? "in motion" : sum->fell ? "FELL" : "stands");
        if (is_cadmm)
            printf("iterations: mean %.1f, max %.0f; %zu solver builds, %zu updates, "
                   "%zu steps above tolerance\n",
                   sum->iterations_sum / solved, sum->max_iterations, sum->builds, sum->updates,
                   sum->unsolved);
        if (s->n_joints && !s->vehicle)
            printf("joints: %zu, largest gap %.3g m\n", s->n_joints, sum->max_joint_gap);
        if (s->vehicle)
            printf("vehicle: drove %.3g m (%.3g m/s at the end), %s %.3g s; joint gap %.3g m, "
                   "axes %.3g rad off, steering %.3g rad, suspension travel %.3g m; chassis z "
                   "%.3g to %.3g m (on the bump %.3g to %.3g), pitch %.3g rad (on the bump "
                   "%.3g), roll %.3g rad\n",
                   dBodyGetPosition(s->bodies[s->top])[0] - s->start[s->top][0],
                   dBodyGetLinearVel(s->bodies[s->top])[0],
                   isnan(sum->over_time) ? "not over the bump after"
                                         : "all wheels over the bump at",
                   isnan(sum->over_time) ? (double)sum->steps * STEP : sum->over_time,
                   sum->max_joint_gap,
                   sum->max_axis_error, sum->max_steer, sum->max_suspension_travel, sum->min_z,
                   sum->max_z, sum->bump_min_z, sum->bump_max_z, sum->max_pitch,
                   sum->bump_max_pitch, sum->max_roll);
    }
}

int main(int argc, char **argv) {
    options o;
    int rc = parse(argc, argv, &o);
    if (rc) return rc;
    dInitODE2(0);
    scene s;
    int built = scene_build(&s, o.scene, o.count, o.seed);
    if (built != 0) {
        dCloseODE();
        if (built == -1) return usage("unknown --scene");
        fprintf(stderr, "cadmm_ode_stack: cannot build %s with --count %ld (out of memory, or "
                        "a base row above %d)\n", o.scene, o.count, SCENE_MAX_BASE);
        return 2;
    }
    if (o.mu < 0) o.mu = s.mu;
    if (o.ode_iterations > 0) dWorldSetQuickStepNumIterations(s.world, (int)o.ode_iterations);
    cadmm_ode_options copt = cadmm_ode_default_options();
    copt.mu = o.mu;
    copt.tolerance = o.tolerance;
    copt.max_iterations = (uint32_t)o.max_iterations;
    copt.time_limit = o.time_limit;
    copt.warm_start = !o.cold;
    cadmm_ode *ctx = cadmm_ode_new(&copt);
    FILE *trace = o.trace ? fopen(o.trace, "w") : NULL;
    dJointGroupID group = dJointGroupCreate(0);
    contact_list cl = {0};
    double *r = NULL, *v = NULL, *lambda = NULL, *step_ms = NULL, *step_cpu_ms = NULL;
    dJointFeedback *feedback = NULL;
    /* NAN: nothing seen yet (the comparisons in observe_vehicle take the first value). */
    summary sum = {.min_z = NAN, .max_z = NAN, .bump_min_z = NAN, .bump_max_z = NAN,
                   .bump_max_pitch = NAN, .over_time = NAN};
    int status = 0;
    if (!ctx || (o.trace && !trace)) {
        fprintf(stderr, "cadmm_ode_stack: %s\n",
                !ctx ? "cannot create the cadmm context" : "cannot open the trace file");
        status = 2;
        goto done;
    }
    if (trace)
        fprintf(trace, "step,time,solve_ms,solve_cpu_ms,iterations,error,contacts,rebuilt,warm_matched,"
                       "top_z,top_drift,max_depth,joint_gap\n");

    size_t steps = (size_t)llround(o.seconds / STEP);
    step_ms = malloc((steps + 1) * sizeof *step_ms);
    step_cpu_ms = malloc((steps + 1) * sizeof *step_cpu_ms);
    if (!step_ms || !step_cpu_ms) {
        fprintf(stderr, "cadmm_ode_stack: out of memory\n");
        status = 2;
        goto done;
    }
    for (size_t step = 0; step < steps; step++) {
        scene_before_step(&s, step);
        double depth = collide(&s, &cl, &sum); /* what the last step left */
        double *nr = depth < 0 ? NULL : realloc(r, (3 * cl.n + 1) * sizeof *r);
        double *nv = depth < 0 ? NULL : realloc(v, (6 * s.n + 1) * sizeof *v);
        dJointFeedback *nf = depth < 0 ? NULL : realloc(feedback, (cl.n + 1) * sizeof *nf);
        if (nr) r = nr;
        if (nv) v = nv;
        if (nf) feedback = nf;
        if (!nr || !nv || !nf) {
            fprintf(stderr, "cadmm_ode_stack: out of memory\n");
            status = 2;
            goto done;
        }

        /* Both paths assemble cadmm's problem from the state before the step: cadmm solves
         * it, ODE's solutions are measured on it. Only the solve is timed. */
        cadmm_ode_step_info info = {0};
        stamp t0 = now();
        cadmm_result cr = cadmm_ode_assemble(ctx, s.world, s.bodies, s.n, cl.geoms, cl.n, STEP);
        if (o.solver == SOLVER_CADMM) {
            if (cr == CADMM_OK) cr = cadmm_ode_solve(ctx, &info);
        } else if (cr == CADMM_OK) {
            t0 = now();
            ode_step(&s, &cl, o.solver, o.mu, group, feedback, r);
        }
        stamp t1 = now();
        double ms = t1.wall - t0.wall, cpu_ms = t1.cpu - t0.cpu;
        if (cr == CADMM_OK && o.solver == SOLVER_CADMM) cr = cadmm_ode_impulses(ctx, r);
        cadmm_ode_problem problem;
        if (cr == CADMM_OK) cr = cadmm_ode_last_problem(ctx, &problem);
        /* The joint multipliers: cadmm's own, or ODE's recovered from its joints' feedback. */
        size_t rows = cr == CADMM_OK ? problem.n_joint_rows : 0;
        if (rows) {
            double *nl = realloc(lambda, rows * sizeof *lambda);
            if (!nl) {
                fprintf(stderr, "cadmm_ode_stack: out of memory\n");
                status = 2;
                goto done;
            }
            lambda = nl;
            if (o.solver == SOLVER_CADMM) {
                cr = cadmm_ode_joint_multipliers(ctx, lambda);
            } else if (ode_joint_multipliers(&s, ctx, &problem, lambda)) {
                fprintf(stderr, "cadmm_ode_stack: step %zu: cannot recover ODE's joint "
                                "multipliers\n", step);
                status = 2;
                goto done;
            }
        }
        double error = 0.0;
        if (cr == CADMM_OK)
            cr = cadmm_ode_error_with_multipliers(ctx, r, rows ? lambda : NULL, &error);
        /* The same answer re-measured by check.c: the impulses, multipliers and the
         * velocities the bodies leave the step with, on the problem the integration built. */
        if (cr == CADMM_OK) {
            for (size_t k = 0; k < problem.n / 6; k++) {
                dBodyID b = s.bodies[problem.body_index[k]];
                const dReal *lv = dBodyGetLinearVel(b), *av = dBodyGetAngularVel(b);
                for (int d = 0; d < 3; d++) {
                    v[6 * k + d] = lv[d];
                    v[6 * k + 3 + d] = av[d];
                }
            }
            double checked = check_error(&problem, r, v, rows ? lambda : NULL);
            if (!(checked <= sum.max_checked_error)) sum.max_checked_error = checked;
        }
        if (cr == CADMM_OK && problem.n) {
            int dumped = dump_problem(&o, &problem, step + 1, r, v, rows ? lambda : NULL);
            sum.dumps_failed += dumped < 0;
            sum.dumps_differ += dumped > 0;
        }
        if (cr != CADMM_OK) {
            fprintf(stderr, "cadmm_ode_stack: step %zu: %s\n", step, cadmm_ode_last_error(ctx));
            status = 2;
            goto done;
        }
        sum.steps++;
        sum.contact_sum += cl.n;
        if (cl.n > sum.max_contacts) sum.max_contacts = cl.n;
        step_ms[sum.steps - 1] = ms;
        step_cpu_ms[sum.steps - 1] = cpu_ms;
        sum.solve_ms_sum += ms;
        if (ms > sum.max_solve_ms) sum.max_solve_ms = ms;
        sum.cpu_ms_sum += cpu_ms;
        if (cpu_ms > sum.max_cpu_ms) sum.max_cpu_ms = cpu_ms;
        if (error > sum.max_error || isnan(error)) sum.max_error = error;
        if (info.solved) {
            sum.solved_steps++;
            sum.iterations_sum += (double)info.iterations;
            if ((double)info.iterations > sum.max_iterations) sum.max_iterations = (double)info.iterations;
            sum.unsolved += info.status != CADMM_STATUS_SOLVED;
            sum.builds += info.rebuilt;
            sum.updates += !info.rebuilt;
            sum.warm_matched += info.warm_matched;
        }
        double top_z = 0.0, drift = 0.0;
        observe(&s, &sum, &top_z, &drift);
        double gap = s.vehicle     ? observe_vehicle(&s, &sum, (double)(step + 1) * STEP)
                     : s.n_joints ? observe_balls(&s, &sum)
                                  : 0.0;
        if (trace)
            fprintf(trace, "%zu,%.6f,%.6f,%.6f,%.0f,%.6e,%zu,%d,%zu,%.9f,%.9f,%.9f,%.9f\n", step,
                    (double)(step + 1) * STEP, ms, cpu_ms,
                    info.solved ? (double)info.iterations : NAN, error, cl.n, info.rebuilt,
                    info.warm_matched, top_z, drift, depth, gap);
    }
    if (collide(&s, &cl, &sum) < 0) { /* what the last step left */
        fprintf(stderr, "cadmm_ode_stack: out of memory\n");
        status = 2;
        goto done;
    }
    report(&o, &s, &sum, step_ms, step_cpu_ms);
    /* The sliding box against Coulomb's law: it stops after v0^2 / (2 mu g). */
    double slid = NAN, slide_expected = NAN, final_speed = NAN;
    if (s.launch > 0) {
        const dReal *x = dBodyGetPosition(s.bodies[0]), *lv = dBodyGetLinearVel(s.bodies[0]);
        slid = x[0] - s.start[0][0];
        slide_expected = s.launch * s.launch / (2.0 * s.mu * GRAVITY);
        final_speed = sqrt(lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]);
        printf("slide: stopped after %.4g m (Coulomb: %.4g m), final speed %.3g m/s\n", slid,
               slide_expected, final_speed);
    }
    if (o.check) {
        const char *failed[13];
        char buf[8][160];
        int nf = 0;
        if (sum.fell) failed[nf++] = "a body fell";
        if (s.launch == 0 && !s.in_motion && !(sum.max_drift < 1e-3))
            failed[nf++] = "the top body drifted 1 mm or more";
        if (s.launch > 0 && !(final_speed < 1e-3)) {
            snprintf(buf[0], sizeof buf[0], "the sliding box did not stop (%.3g m/s)", final_speed);
            failed[nf++] = buf[0];
        }
        if (s.launch > 0 && !(fabs(slid - slide_expected) <= SLIDE_SLACK(s.launch))) {
            snprintf(buf[1], sizeof buf[1],
                     "the box slid %.4g m, Coulomb's law says %.4g m (allowed %.3g m)", slid,
                     slide_expected, SLIDE_SLACK(s.launch));
            failed[nf++] = buf[1];
        }
        if (!s.in_motion && !(sum.max_penetration <= MAX_DEPTH)) {
            snprintf(buf[2], sizeof buf[2], "a contact penetrated %.3g m (bound %.3g m)",
                     sum.max_penetration, MAX_DEPTH);
            failed[nf++] = buf[2];
        }
        if (o.solver == SOLVER_CADMM && sum.unsolved) {
            snprintf(buf[3], sizeof buf[3], "%zu cadmm solves ended above their tolerance",
                     sum.unsolved);
            failed[nf++] = buf[3];
        }
        if (s.vehicle && isnan(sum.over_time)) {
            const dReal *x = dBodyGetPosition(s.bodies[s.top]);
            snprintf(buf[4], sizeof buf[4], "the vehicle did not get over the bump (drove %.3g m)",
                     x[0] - s.start[s.top][0]);
            failed[nf++] = buf[4];
        }
        if (s.vehicle && !(sum.max_joint_gap < VEHICLE_MAX_GAP)) {
            snprintf(buf[5], sizeof buf[5], "a wheel's joint opened %.3g m (bound %.3g m)",
                     sum.max_joint_gap, VEHICLE_MAX_GAP);
            failed[nf++] = buf[5];
        }
        if (s.vehicle && !(fmax(sum.max_axis_error, sum.max_steer) < VEHICLE_MAX_ANGLE)) {
            snprintf(buf[6], sizeof buf[6],
                     "a wheel's axes turned %.3g rad off (steering %.3g rad; bound %.3g rad)",
                     sum.max_axis_error, sum.max_steer, VEHICLE_MAX_ANGLE);
            failed[nf++] = buf[6];
        }
        if (sum.dumps_failed || sum.dumps_differ) {
            snprintf(buf[7], sizeof buf[7],
                     "%zu dumped steps not written or read, %zu read back as another problem",
                     sum.dumps_failed, sum.dumps_differ);
            failed[nf++] = buf[7];
        }
        char err[160];
        if (o.solver == SOLVER_CADMM && !(sum.max_checked_error <= o.check_tolerance)) {
            snprintf(err, sizeof err, "re-measured error %.3g above the check tolerance %.3g",
                     sum.max_checked_error, o.check_tolerance);
            failed[nf++] = err;
        }
        for (int k = 0; k < nf; k++)
            fprintf(stderr, "cadmm_ode_stack: check failed: %s (%s, %s)\n", failed[k], o.scene,
                    solver_name(o.solver));
        if (nf) status = 1;
    }
done:
    if (trace) fclose(trace);
    free(cl.geoms);
    free(r);
    free(v);
    free(lambda);
    free(feedback);
    free(step_ms);
    free(step_cpu_ms);
    dJointGroupDestroy(group);
    cadmm_ode_free(ctx);
    scene_free(&s);
    dCloseODE();
    return status;
}
