/*
 * cadmm_ode: ODE bodies and collision detection, cadmm for the contact impulses.
 *
 * Replaces dWorldStep/dWorldQuickStep for a world whose only constraints are contacts.
 * Each step builds the global problem of the bodies the contacts touch
 *
 *     M v = H r + f,   u = H^T v + w,   r in the Coulomb cones (mu),
 *
 * with M block diagonal (mass, world inertia), H one column per contact component
 * (normal first, then the two tangents of dPlaneSpace), f = M v + h (gravity + forces
 * - omega x I omega), w_N = -min(ERP depth' / h, max correcting velocity) with
 * depth' = max(depth - surface layer, 0): ODE's own contact joint right-hand side, read
 * from the world. cadmm solves it; the new velocities are set on the bodies and positions
 * and orientations are integrated here (semi-implicit Euler, normalized quaternions).
 *
 * One cadmm solver lives across steps: a step with the same sparsity pattern as the last
 * hands it the new values (cadmm_solver_update_values: numeric refactorization only, no
 * cadmm problem built), otherwise a new one is built. Impulses are
 * warm started from the previous step's, matched by geom pair and nearest point.
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
    double mu;           /* friction coefficient of every contact */
    double tolerance;    /* cadmm's error measure target */
    bool warm_start;     /* start from the previous step's matched impulses */
    double match_radius; /* a previous contact point farther than this is not matched (m) */
    uint32_t max_iterations; /* cadmm's iteration limit; 0 for cadmm's default */
    double time_limit;   /* seconds per cadmm_ode_solve, building the solver included; 0 for
                          * none. With one, cadmm starts with Gauss-Seidel sweeps that need no
                          * factorization and hands back its best answer measured in time. */
} cadmm_ode_options;

/* What one step did. */
typedef struct cadmm_ode_step_info {
    size_t contacts;      /* contact points solved */
    size_t bodies;        /* bodies in the problem (touched by a contact) */
    size_t warm_matched;  /* contacts warm started from a previous impulse */
    bool solved;          /* a solve ran (false when there was no contact) */
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

/* Builds the step's problem from the bodies' current state. `bodies` lists every dynamic
 * body of the world (its order fixes the order of the unknowns); every contact must have a
 * body on g1 (swap g1/g2 and negate the normal otherwise); a geom without body is fixed.
 * Returns CADMM_OK or an error code (then see cadmm_ode_last_error). */
cadmm_result cadmm_ode_assemble(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                size_t n_bodies, const dContactGeom *contacts,
                                size_t n_contacts, double h);

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

/* cadmm's error measure of impulses `r` (3 per contact, frames of cadmm_ode_frame) with the
 * bodies' current velocities, on the last assembled problem: measures another solver's step
 * (e.g. ODE's, its contact forces times h) by the same yardstick. */
cadmm_result cadmm_ode_error(cadmm_ode *ctx, const double *r, double *error);

/* The last assembled problem, as handed to cadmm (valid until the next assemble or free):
 * M v = H r + f, u = H^T v + w, r in the cones of mu. Unknowns: 6 per body touched by a
 * contact (linear then angular velocity, world frame); body k of the problem is
 * bodies[body_index[k]] of the list given to cadmm_ode_assemble. Lets a caller check an
 * answer on its own. n and n_contacts are 0 (and the pointers NULL) when the last step had
 * no contact. */
typedef struct cadmm_ode_problem {
    size_t n, n_contacts;
    cadmm_csc M, H; /* n x n, n x 3 n_contacts */
    const double *f, *w, *mu;
    const size_t *body_index;
} cadmm_ode_problem;

cadmm_result cadmm_ode_last_problem(const cadmm_ode *ctx, cadmm_ode_problem *out);

#endif /* CADMM_ODE_H */
