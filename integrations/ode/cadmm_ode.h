/*
 * cadmm_ode: ODE bodies, joints and collision detection, cadmm for the impulses.
 *
 * Replaces dWorldStep/dWorldQuickStep for a world whose constraints are contacts and ODE's
 * ball, hinge, slider, fixed, universal and hinge-2 joints. Each step builds the global
 * problem of the bodies the contacts and joints touch
 *
 *     M v = H r + G lambda + f,   u = H^T v + w,   r in the Coulomb cones (mu),
 *     y = G^T v + b + c lambda,   lo <= lambda <= hi  (y = 0 inside the bounds),
 *
 * with M block diagonal (mass, world inertia), H one column per contact component
 * (normal first, then the two tangents of dPlaneSpace), f = M v + h (gravity + forces
 * - omega x I omega), w_N = -min(ERP depth' / h, max correcting velocity) with
 * depth' = max(depth - surface layer, 0): ODE's own contact joint right-hand side, read
 * from the world. cadmm solves it; the new velocities are set on the bodies and positions
 * and orientations are integrated here (semi-implicit Euler, normalized quaternions).
 *
 * Joints: G has one column per row of ODE's own joint Jacobian (6 entries per dynamic body:
 * linear then angular, world frame), read through ODE's public getters and written as
 * ODE's getInfo2 writes it. A row of ODE reads J v' = rhs - CFM F (F its force, v' the
 * velocity after the step); with the impulse lambda = F h that is the cadmm row with
 * b = -rhs and c = CFM / h (derivation in cadmm_ode.c). So an equality row has
 * b = -ERP e / h, e ODE's position error (e.g. the ball's second anchor minus its first),
 * which it closes by the ERP fraction a step, and c = CFM / h, with the world's ERP and CFM
 * (dWorldGetERP/CFM) or the joint's own (ball and fixed dParamERP/CFM, hinge-2
 * suspension, stop ERP/CFM); a limit (dParamLoStop/HiStop) is a row bounded [0, inf) at
 * the low stop or (-inf, 0] at the high one, present only while the joint is at or past
 * the stop (as ODE activates it), b = StopERP (overshoot) / h, c = StopCFM / h, raised by
 * dParamBounce as ODE does; a motor (dParamFMax > 0) is a row bounded [-FMax h, FMax h]
 * with b = -Vel and c = CFM / h. A powered joint at its stop gets both rows (ODE fakes the
 * pair with one row and dParamFudgeFactor, which is ignored here). A joint attached to the
 * world (one body 0) has columns for its one body only; one attached as (0, body) is held
 * "reversed" by ODE, and cadmm_ode follows it (such a hinge's stops and motor act on minus
 * dJointGetHingeAngle, as in dWorldStep). Rows per joint, in this order:
 *  - ball: 3 (anchor, world axes);
 *  - hinge: 3 (anchor) + 2 (axis alignment) [+ limit] [+ motor];
 *  - slider: 3 (orientation) + 2 (off-axis position) [+ limit] [+ motor];
 *  - fixed: 3 (position, the joint's ERP/CFM) + 3 (orientation, the world's);
 *  - universal: 3 (anchor) + 1 (axes perpendicular) [+ limit 1] [+ motor 1] [+ limit 2]
 *    [+ motor 2];
 *  - hinge-2 (two bodies): 3 (anchor, along axis 1 with the suspension ERP/CFM first)
 *    + 1 (axes' angle) [+ limit 1] [+ motor 1] [+ motor 2];
 *  - null: none.
 * ODE keeps some of a joint's reference pose without a public getter: the slider's and
 * the fixed joint's relative orientation and offset, the hinge's axis in its second
 * body's frame, the hinge-2's angle between its axes. cadmm_ode records them from the
 * bodies' poses the first time it sees the joint (and again when the joint's type, bodies
 * or axis change), as ODE's setters (dJointSetFixed, dJointSetSliderAxis, ...) record them
 * from the poses when they are called: step the joint first in the pose it was set in, and
 * call cadmm_ode_forget_joint after setting it again in another pose (dJointSetFixed) or
 * destroying it. A joint's dJointFeedback, when set, receives its force and torque on each
 * body (G lambda / h, f1/t1 on ODE's first body, as ODE fills it). Disabled joints are
 * skipped. Refused with a message naming the joint: AMotor, LMotor, Plane2D, PR, PU,
 * Piston, DBall, DHinge, Transmission and contact joints made by the user (contacts are
 * handed over as dContactGeom or dContact), a joint touching a kinematic body or a body
 * not in the list, a negative CFM.
 *
 * One cadmm solver lives across steps: a step with the same sparsity pattern as the last
 * (the same bodies, contacts, joints and joint rows, the same rows bounded) hands it the
 * new values (cadmm_solver_update_values, or cadmm_solver_update when a bound or a
 * compliance changed: numeric refactorization only), otherwise a new one is built.
 * Impulses are warm started from the previous step's, matched by geom pair and nearest
 * point.
 */
#ifndef CADMM_ODE_H
#define CADMM_ODE_H

#include <cadmm.h>
#include <ode/ode.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct cadmm_ode cadmm_ode;

typedef struct cadmm_ode_options {
    double mu;           /* friction coefficient of every contact handed over as dContactGeom
                          * (cadmm_ode_assemble_contacts takes each dContact's surface.mu) */
    double tolerance;    /* cadmm's error measure target */
    bool warm_start;     /* start from the previous step's matched impulses and the bodies'
                          * velocities (the joint rows' multipliers start from zero) */
    double match_radius; /* a previous contact point farther than this is not matched (m) */
    uint32_t max_iterations; /* cadmm's iteration limit; 0 for cadmm's default */
    double time_limit;   /* seconds per step, from cadmm_ode_assemble to the end of
                          * cadmm_ode_solve (building the solver, and the last step's time
                          * after its solve, counted in); 0 for none. With one, cadmm starts
                          * with Gauss-Seidel sweeps that need no factorization and hands back
                          * its best answer measured in time. */
} cadmm_ode_options;

/* What one step did. */
typedef struct cadmm_ode_step_info {
    size_t contacts;      /* contact points solved */
    size_t joints;        /* joints in the problem (enabled, not null) */
    size_t joint_rows;    /* their rows and the contacts' rolling rows (columns of G) */
    size_t bodies;        /* bodies in the problem (touched by a contact or a joint) */
    size_t warm_matched;  /* contacts warm started from a previous impulse */
    bool solved;          /* a solve ran (false when there was no contact and no joint row) */
    bool rebuilt;         /* a new cadmm solver was built (new pattern) */
    cadmm_status status;  /* how cadmm's solve ended */
    uint64_t iterations;  /* ADMM + Newton iterations */
    double error;         /* cadmm's error measure of the solution */
} cadmm_ode_step_info;

/* Defaults: mu 0.5, tolerance 1e-8, warm start on, match radius 1 cm, cadmm's iteration
 * limit, no time limit. */
cadmm_ode_options cadmm_ode_default_options(void);

/* A new integration context; NULL when out of memory or the options are invalid (mu,
 * match radius or time limit negative or not finite, a tolerance cadmm refuses). */
cadmm_ode *cadmm_ode_new(const cadmm_ode_options *options);
void cadmm_ode_free(cadmm_ode *ctx);

/* The reason of the last failed call on ctx (a static message for a NULL ctx). */
const char *cadmm_ode_last_error(const cadmm_ode *ctx);

/* The tangents of a contact frame (n, t1, t2), as ODE's contact joints use them. */
void cadmm_ode_frame(const dReal normal[3], dReal t1[3], dReal t2[3]);

/* Builds the step's problem from the bodies' current state and the joints attached to
 * them. `bodies` lists every dynamic body of the world (its order fixes the order of the
 * unknowns, and of the joints: body after body, each body's joints in ODE's order);
 * every contact must have a body on g1 (swap g1/g2 and negate the normal otherwise); a
 * geom without body is fixed. Every contact has the options' mu. Returns CADMM_OK or an
 * error code (then see cadmm_ode_last_error). */
cadmm_result cadmm_ode_assemble(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                size_t n_bodies, const dContactGeom *contacts,
                                size_t n_contacts, double h);

/* cadmm_ode_assemble with ODE's full contacts, as a near callback fills them for
 * dJointCreateContact: each contact's friction coefficient is its surface.mu (finite, not
 * negative). Surface modes the problem cannot express are refused with a message naming
 * the flag (CADMM_ERR_UNSUPPORTED): dContactMu2/AxisDep with mu2 != mu (anisotropic
 * sliding friction), dContactFDir1, dContactBounce, dContactSoftERP, dContactSoftCFM,
 * dContactMotion1/2/N, dContactSlip1/2. The dContactApprox1 flags are accepted: cadmm's
 * cone is the exact one they approximate for sliding friction.
 *
 * dContactRolling (with mu > 0, as ODE) adds the contact's rolling and spinning friction
 * rows after the joints' rows, as ODE's contact joint writes them: g1's angular velocity
 * minus g2's about t1 and t2 (rho; rho2 with dContactAxisDep) and about the normal (rho;
 * rhoN with dContactAxisDep), a row for each positive coefficient. With the axis's
 * dContactApprox1 bit (_1, _2, _N) the row's torque is bounded by the coefficient times
 * the contact's normal force (a row bounded by a contact, cadmm_problem_set_joint_friction),
 * without it by the coefficient itself; an infinite coefficient holds the axis still. The
 * rows have the world's CFM, as ODE's, and their multipliers follow the joints' in
 * cadmm_ode_joint_multipliers. cadmm solves a problem with rows bounded by a contact by
 * ADMM alone (its Newton phase has no term for such bounds). */
cadmm_result cadmm_ode_assemble_contacts(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                         size_t n_bodies, const dContact *contacts,
                                         size_t n_contacts, double h);

/* Drops what cadmm_ode recorded of joint j's reference pose (see above): the next step
 * records it again from the bodies' poses. Call it after setting a joint again in another
 * pose (dJointSetFixed, dJointSetSliderAxis, ...) or after dJointDestroy (a new joint may
 * take the same address). */
void cadmm_ode_forget_joint(cadmm_ode *ctx, dJointID j);

/* Solves the assembled problem, sets every body's velocity, integrates positions and
 * orientations over h and clears the force accumulators, as a world step does. */
cadmm_result cadmm_ode_solve(cadmm_ode *ctx, cadmm_ode_step_info *info);

/* cadmm_ode_assemble then cadmm_ode_solve. */
cadmm_result cadmm_ode_step(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                            size_t n_bodies, const dContactGeom *contacts, size_t n_contacts,
                            double h, cadmm_ode_step_info *info);

/* The impulses of the last step (3 per contact, normal first, frames of cadmm_ode_frame),
 * e.g. for contact sounds or breakage. */
cadmm_result cadmm_ode_impulses(cadmm_ode *ctx, double *r);

/* The joint multipliers of the last step (one impulse per joint row, force x h, along the
 * row's column of G): M v = H r + G lambda + f. */
cadmm_result cadmm_ode_joint_multipliers(cadmm_ode *ctx, double *lambda);

/* Where joint j's rows sit among the last assembled problem's: rows *first to
 * *first + *count - 1, in the order listed above (*count 0 when j took no part: disabled,
 * null, or not attached to a listed body). */
cadmm_result cadmm_ode_joint_rows(const cadmm_ode *ctx, dJointID j, size_t *first,
                                  size_t *count);

/* cadmm's error measure of impulses `r` (3 per contact, frames of cadmm_ode_frame) with the
 * bodies' current velocities, on the last assembled problem: measures another solver's step
 * (e.g. ODE's, its contact forces times h) by the same yardstick. With joints, their
 * multipliers are cadmm's least-squares ones (cadmm_problem_error), which know nothing of
 * the bounds: use cadmm_ode_error_with_multipliers for limits and motors. */
cadmm_result cadmm_ode_error(cadmm_ode *ctx, const double *r, double *error);

/* cadmm_ode_error with the joint multipliers given (one per joint row, e.g. those of
 * cadmm_ode_joint_multipliers; NULL when the problem has no joint row). */
cadmm_result cadmm_ode_error_with_multipliers(cadmm_ode *ctx, const double *r,
                                              const double *lambda, double *error);

/* The last assembled problem, as handed to cadmm (valid until the next assemble or free):
 * M v = H r + G lambda + f, u = H^T v + w, r in the cones of mu, y = G^T v + b + c lambda
 * with lo <= lambda <= hi. Unknowns: 6 per body touched by a contact or a joint (linear
 * then angular velocity, world frame); body k of the problem is bodies[body_index[k]] of
 * the list given to cadmm_ode_assemble. Lets a caller check an answer on its own. n,
 * n_contacts and n_joint_rows are 0 (and the pointers NULL) when the last step had no
 * contact and no joint row; lo, hi and c are given even where cadmm was not handed them
 * (all rows equalities, or no compliance). */
typedef struct cadmm_ode_problem {
    size_t n, n_contacts, n_joint_rows;
    cadmm_csc M, H, G; /* n x n, n x 3 n_contacts, n x n_joint_rows */
    const double *f, *w, *mu;
    const double *b, *lo, *hi, *c; /* n_joint_rows each */
    const size_t *body_index;
    /* n_joint_rows each: the contact whose normal impulse also bounds the row, -1 for none,
     * and the coefficient e of that bound (-+ e r_n): rolling friction rows with ODE's
     * dContactApprox1 bits (cadmm_problem_set_joint_friction). */
    const int64_t *friction_contact;
    const double *friction;
} cadmm_ode_problem;

cadmm_result cadmm_ode_last_problem(const cadmm_ode *ctx, cadmm_ode_problem *out);

#endif /* CADMM_ODE_H */
