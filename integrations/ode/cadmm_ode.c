/* cadmm_ode: ODE world step with cadmm contact and joint impulses (see cadmm_ode.h). */
#include "cadmm_ode.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A growable allocation: arrays keep their memory from step to step. */
typedef struct buffer {
    void *data;
    size_t bytes;
} buffer;

/* One contact point of a step, and what the warm start of the next step needs. */
typedef struct contact {
    dGeomID g1, g2;
    long slot1, slot2; /* bodies' places in the problem, -1 for a fixed geom */
    double pos[3], n[3], t1[3], t2[3];
    double impulse[3]; /* on g1's body, world frame, after the solve */
} contact;

/* A body's share of the problem: mass, world inertia and f = M v + h (forces). */
typedef struct body_state {
    double mass, inertia[9], f[6], v[6];
} body_state;

typedef struct body_key {
    uintptr_t id;
    size_t index;
} body_key;

/* One joint row: its column of G on the joint's two bodies (a, ODE's first body, and b,
 * the second; world frame, linear then angular) and its b, bounds and compliance. A
 * contact's rolling or spinning friction row (after the joints' rows) is on the contact's
 * bodies (a g1's, b g2's); with `contact` >= 0 its bounds are -+ e times that contact's
 * normal impulse. */
typedef struct joint_row {
    double ga[6], gb[6];
    double b, lo, hi, c;
    long contact;   /* a rolling row's contact, -1 for a joint's row */
    bool by_normal; /* a rolling row bounded by e times its contact's normal impulse */
    double e;
} joint_row;

/* A joint of the step and where its rows are. */
typedef struct joint {
    dJointID id;
    long slot_a, slot_b; /* bodies' indices in the list, then their slots; -1 for the world */
    size_t first_row, n_rows;
} joint;

/* The part of a joint's reference pose ODE keeps without a public getter, recorded from the
 * bodies' poses the first time the host sees the joint (cadmm_ode.h). */
typedef struct joint_record {
    dJointID id;
    int type;
    dBodyID a, b;
    double axis_a[3]; /* hinge, slider, hinge-2: the axis in a's frame, to notice a new one */
    double axis_b[3]; /* hinge: its axis in b's frame (the world's for the world); hinge-2:
                       * axis 2 in b's frame, to notice a new one */
    double q[4];      /* slider, fixed: ODE's qrel, a's orientation relative to b's */
    double offset[3]; /* slider: a's center in b's frame; fixed: b's center seen from a's
                       * (the world's frame for the world) */
    double s0, c0;    /* hinge-2: sine and cosine of the angle between its axes */
} joint_record;

struct cadmm_ode {
    cadmm_ode_options opt;
    cadmm_settings *settings;
    cadmm_solver *solver;
    cadmm_problem *problem; /* built from the assembled arrays only when needed */
    char message[512];

    /* The assembled step. */
    double assembly_start; /* when its assembly began (seconds_now) */
    double after_solve;    /* seconds the last step took after cadmm's solve returned */
    dWorldID world;
    bool assembled; /* the arrays below hold a complete assembly */
    double h;
    size_t n_bodies, n_slots, n_contacts, n_joints, n_rows;
    size_t n_rolling; /* the last n_rolling of the n_rows rows: contacts' rolling friction */
    buffer bodies;    /* dBodyID per body */
    buffer keys;      /* body_key, sorted by id */
    buffer body_slot; /* long per body: its slot or -1 */
    buffer slot_body; /* size_t per slot: its body */
    buffer contacts;  /* contact */
    buffer joints;    /* joint */
    buffer rows;      /* joint_row */
    buffer m_colptr, m_rowind, m_values, h_colptr, h_rowind, h_values;
    buffer g_colptr, g_rowind, g_values;
    buffer f, w, mu, r, v, r0;
    buffer jb, jlo, jhi, jc, lambda; /* per joint row */
    buffer jfc, jfe;                 /* per joint row: bounding contact (int64_t), its e */
    bool any_bounded, any_compliance, any_contact_bounds;

    /* The pattern the solver was built for (see assemble), and the bounds and compliance
     * it holds, which cadmm_solver_update_values does not take. */
    buffer pattern, solver_pattern;
    size_t pattern_len, solver_pattern_len;
    buffer solver_lo, solver_hi, solver_c, solver_e;

    /* Joint reference poses, sorted by joint. */
    buffer records;
    size_t n_records;

    /* The previous solve's contacts, for the warm start. */
    buffer previous, used;
    buffer pair_keys; /* pair_key per previous contact, sorted */
    size_t n_previous;
};

static const char *null_ctx_message = "cadmm_ode: NULL context";

static cadmm_result fail(cadmm_ode *ctx, cadmm_result code, const char *fmt, ...) {
    va_list args;
    va_start(args, fmt);
    vsnprintf(ctx->message, sizeof ctx->message, fmt, args);
    va_end(args);
    return code;
}

/* cadmm's own detailed message for a failed cadmm call. */
static cadmm_result fail_cadmm(cadmm_ode *ctx, cadmm_result code, const char *call) {
    return fail(ctx, code, "%s: %s (%s)", call, cadmm_result_message(code), cadmm_last_error());
}

static void *reserve(buffer *b, size_t count, size_t size) {
    size_t bytes = count * size;
    if (bytes == 0) bytes = size; /* never NULL: an empty array is still a valid pointer */
    if (bytes > b->bytes) {
        size_t grown = b->bytes * 2 > bytes ? b->bytes * 2 : bytes;
        void *p = realloc(b->data, grown);
        if (!p) return NULL;
        b->data = p;
        b->bytes = grown;
    }
    return b->data;
}

cadmm_ode_options cadmm_ode_default_options(void) {
    cadmm_ode_options o = {.mu = 0.5, .tolerance = 1e-8, .warm_start = true, .match_radius = 0.01};
    return o;
}

cadmm_ode *cadmm_ode_new(const cadmm_ode_options *options) {
    if (!options || !(options->mu >= 0.0) || !isfinite(options->mu) ||
        !(options->match_radius >= 0.0) || !isfinite(options->match_radius) ||
        !(options->time_limit >= 0.0) || !isfinite(options->time_limit))
        return NULL;
    cadmm_ode *ctx = calloc(1, sizeof *ctx);
    if (!ctx) return NULL;
    ctx->opt = *options;
    if (cadmm_settings_new(&ctx->settings) != CADMM_OK ||
        cadmm_settings_set_tolerance(ctx->settings, options->tolerance) != CADMM_OK ||
        (options->max_iterations &&
         cadmm_settings_set_max_iterations(ctx->settings, options->max_iterations) != CADMM_OK) ||
        (options->time_limit > 0 &&
         cadmm_settings_set_time_limit(ctx->settings, options->time_limit) != CADMM_OK)) {
        cadmm_ode_free(ctx);
        return NULL;
    }
    return ctx;
}

void cadmm_ode_free(cadmm_ode *ctx) {
    if (!ctx) return;
    cadmm_solver_free(ctx->solver);
    cadmm_problem_free(ctx->problem);
    cadmm_settings_free(ctx->settings);
    buffer *all[] = {&ctx->bodies,    &ctx->keys,      &ctx->body_slot, &ctx->slot_body,
                     &ctx->contacts,  &ctx->joints,    &ctx->rows,      &ctx->m_colptr,
                     &ctx->m_rowind,  &ctx->m_values,  &ctx->h_colptr,  &ctx->h_rowind,
                     &ctx->h_values,  &ctx->g_colptr,  &ctx->g_rowind,  &ctx->g_values,
                     &ctx->f,         &ctx->w,         &ctx->mu,        &ctx->r,
                     &ctx->v,         &ctx->r0,        &ctx->jb,        &ctx->jlo,
                     &ctx->jhi,       &ctx->jc,        &ctx->jfc,       &ctx->jfe,
                     &ctx->lambda,    &ctx->pattern,   &ctx->solver_pattern,
                     &ctx->solver_lo, &ctx->solver_hi, &ctx->solver_c,  &ctx->solver_e,
                     &ctx->records,   &ctx->previous,  &ctx->used,      &ctx->pair_keys};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) free(all[i]->data);
    free(ctx);
}

const char *cadmm_ode_last_error(const cadmm_ode *ctx) {
    return ctx ? ctx->message : null_ctx_message;
}

void cadmm_ode_frame(const dReal normal[3], dReal t1[3], dReal t2[3]) {
    dVector3 n = {normal[0], normal[1], normal[2], 0}, p, q;
    dPlaneSpace(n, p, q);
    for (int k = 0; k < 3; k++) {
        t1[k] = p[k];
        t2[k] = q[k];
    }
}

/* ---- small 3D helpers ------------------------------------------------------------------ */

static void cross(const double a[3], const double b[3], double out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void copy3(const dReal *a, double out[3]) {
    for (int k = 0; k < 3; k++) out[k] = a[k];
}

/* R v and R^T v for ODE's 3x4 row-major rotations. */
static void rotate(const dReal *R, const double v[3], double out[3]) {
    for (int i = 0; i < 3; i++)
        out[i] = R[4 * i] * v[0] + R[4 * i + 1] * v[1] + R[4 * i + 2] * v[2];
}

static void unrotate(const dReal *R, const double v[3], double out[3]) {
    for (int i = 0; i < 3; i++) out[i] = R[i] * v[0] + R[4 + i] * v[1] + R[8 + i] * v[2];
}

/* Quaternions as ODE's (w, x, y, z): a b, and a's conjugate. */
static void qmul(const double a[4], const double b[4], double out[4]) {
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

static void qconj(const double a[4], double out[4]) {
    out[0] = a[0];
    out[1] = -a[1];
    out[2] = -a[2];
    out[3] = -a[3];
}

/* x = A^-1 b for a symmetric positive definite 3x3 A (row-major), by cofactors. */
static void solve3(const double a[9], const double b[3], double x[3]) {
    double c0 = a[4] * a[8] - a[5] * a[7], c1 = a[5] * a[6] - a[3] * a[8],
           c2 = a[3] * a[7] - a[4] * a[6];
    double det = a[0] * c0 + a[1] * c1 + a[2] * c2;
    double inv[9] = {c0, a[2] * a[7] - a[1] * a[8], a[1] * a[5] - a[2] * a[4],
                     c1, a[0] * a[8] - a[2] * a[6], a[2] * a[3] - a[0] * a[5],
                     c2, a[1] * a[6] - a[0] * a[7], a[0] * a[4] - a[1] * a[3]};
    for (int i = 0; i < 3; i++)
        x[i] = (inv[3 * i] * b[0] + inv[3 * i + 1] * b[1] + inv[3 * i + 2] * b[2]) / det;
}

/* Mass, world inertia R I R^T, velocity and f = M v + h (m g + F, T - omega x I omega):
 * the body's row of the problem. The gyroscopic term follows the body's ODE flag. */
static void body_state_of(dWorldID world, dBodyID b, double h, body_state *s) {
    dMass m;
    dBodyGetMass(b, &m);
    const dReal *R = dBodyGetRotation(b); /* 3x4, row-major */
    double RI[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            RI[3 * i + j] = R[4 * i] * m.I[j] + R[4 * i + 1] * m.I[4 + j] + R[4 * i + 2] * m.I[8 + j];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            s->inertia[3 * i + j] =
                RI[3 * i] * R[4 * j] + RI[3 * i + 1] * R[4 * j + 1] + RI[3 * i + 2] * R[4 * j + 2];
    s->mass = m.mass;

    const dReal *lv = dBodyGetLinearVel(b), *av = dBodyGetAngularVel(b);
    const dReal *force = dBodyGetForce(b), *torque = dBodyGetTorque(b);
    dVector3 g = {0, 0, 0, 0};
    if (dBodyGetGravityMode(b)) dWorldGetGravity(world, g);
    double omega[3] = {av[0], av[1], av[2]}, Iw[3], gyro[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++) Iw[i] = dot(&s->inertia[3 * i], omega);
    if (dBodyGetGyroscopicMode(b)) cross(omega, Iw, gyro);
    for (int i = 0; i < 3; i++) {
        s->v[i] = lv[i];
        s->v[3 + i] = av[i];
        s->f[i] = s->mass * lv[i] + h * (s->mass * g[i] + force[i]);
        s->f[3 + i] = Iw[i] + h * (torque[i] - gyro[i]);
    }
}

static int compare_keys(const void *a, const void *b) {
    uintptr_t x = ((const body_key *)a)->id, y = ((const body_key *)b)->id;
    return x < y ? -1 : x > y;
}

/* The index of a body in the list, -1 when absent. */
static long find_body(const cadmm_ode *ctx, dBodyID b) {
    body_key key = {(uintptr_t)b, 0};
    const body_key *hit = bsearch(&key, ctx->keys.data, ctx->n_bodies, sizeof key, compare_keys);
    return hit ? (long)hit->index : -1;
}

/* ---- assembly ------------------------------------------------------------------------ */

/* The surface modes of a dContact the problem cannot express, and why. */
static const struct {
    int flag;
    const char *why;
} unsupported_modes[] = {
    {dContactFDir1, "dContactFDir1: a given friction direction is not supported"},
    {dContactBounce, "dContactBounce: restitution is not supported"},
    {dContactSoftERP, "dContactSoftERP: a contact's own ERP is not supported"},
    {dContactSoftCFM, "dContactSoftCFM: a soft contact is not supported"},
    {dContactMotion1, "dContactMotion1: a surface velocity is not supported"},
    {dContactMotion2, "dContactMotion2: a surface velocity is not supported"},
    {dContactMotionN, "dContactMotionN: a surface velocity is not supported"},
    {dContactSlip1, "dContactSlip1: force-dependent slip is not supported"},
    {dContactSlip2, "dContactSlip2: force-dependent slip is not supported"},
};

/* The contacts, geom c at geoms + c stride bytes (a dContactGeom array, or the geoms of a
 * dContact array, whose surfaces are then checked). */
static cadmm_result read_contacts(cadmm_ode *ctx, const dContactGeom *geoms, size_t stride,
                                  const dContact *surfaces, size_t nc) {
    contact *cs = ctx->contacts.data;
    long *body_slot = ctx->body_slot.data;
    for (size_t c = 0; c < nc; c++) {
        const dContactGeom *g = (const dContactGeom *)((const char *)geoms + c * stride);
        contact *k = &cs[c];
        if (surfaces) {
            const dSurfaceParameters *sp = &surfaces[c].surface;
            for (size_t m = 0; m < sizeof unsupported_modes / sizeof unsupported_modes[0]; m++)
                if (sp->mode & unsupported_modes[m].flag)
                    return fail(ctx, CADMM_ERR_UNSUPPORTED, "contact %zu: surface mode %s", c,
                                unsupported_modes[m].why);
            if (!(sp->mu >= 0.0) || !isfinite(sp->mu))
                return fail(ctx, CADMM_ERR_INVALID_VALUE,
                            "contact %zu: surface.mu = %g must be finite and not negative", c,
                            sp->mu);
            /* dContactMu2 is dContactAxisDep: rho2 and rhoN for rolling friction, and mu2
             * for sliding, which cadmm's isotropic cone takes only equal to mu. */
            if ((sp->mode & dContactMu2) && sp->mu2 != sp->mu)
                return fail(ctx, CADMM_ERR_UNSUPPORTED,
                            "contact %zu: surface mode dContactMu2/dContactAxisDep with mu2 = %g "
                            "!= mu = %g: anisotropic friction is not supported", c, sp->mu2,
                            sp->mu);
            if ((sp->mode & dContactRolling) &&
                (isnan(sp->rho) || isnan(sp->rho2) || isnan(sp->rhoN)))
                return fail(ctx, CADMM_ERR_INVALID_VALUE,
                            "contact %zu: a rolling friction coefficient (rho, rho2, rhoN) is NaN",
                            c);
        }
        dBodyID b1 = g->g1 ? dGeomGetBody(g->g1) : NULL;
        dBodyID b2 = g->g2 ? dGeomGetBody(g->g2) : NULL;
        if (!b1)
            return fail(ctx, CADMM_ERR_INVALID_VALUE,
                        "contact %zu: g1 has no body (put the moving geom first: swap g1 and "
                        "g2 and negate the normal)", c);
        if (b1 == b2)
            return fail(ctx, CADMM_ERR_INVALID_VALUE, "contact %zu: g1 and g2 share a body", c);
        double len = sqrt(g->normal[0] * g->normal[0] + g->normal[1] * g->normal[1] +
                          g->normal[2] * g->normal[2]);
        if (!isfinite(g->depth) || !(fabs(len - 1.0) < 1e-6) || !isfinite(g->pos[0]) ||
            !isfinite(g->pos[1]) || !isfinite(g->pos[2]))
            return fail(ctx, CADMM_ERR_INVALID_VALUE,
                        "contact %zu: non-finite position or depth, or a normal of length %g "
                        "(must be a unit vector)", c, len);
        long i1 = find_body(ctx, b1), i2 = b2 ? find_body(ctx, b2) : -1;
        if (i1 < 0 || (b2 && i2 < 0))
            return fail(ctx, CADMM_ERR_INVALID_VALUE,
                        "contact %zu: the body of g%d is not in the bodies list", c, i1 < 0 ? 1 : 2);
        if (dBodyIsKinematic(b1) || (b2 && dBodyIsKinematic(b2)))
            return fail(ctx, CADMM_ERR_UNSUPPORTED,
                        "contact %zu touches a kinematic body: not supported", c);
        body_slot[i1] = 0;
        if (b2) body_slot[i2] = 0;
        k->g1 = g->g1;
        k->g2 = g->g2;
        k->slot1 = i1; /* body indices for now, slots once they are numbered */
        k->slot2 = i2;
        for (int d = 0; d < 3; d++) {
            k->pos[d] = g->pos[d];
            k->n[d] = g->normal[d];
        }
        dReal t1[3], t2[3];
        cadmm_ode_frame(g->normal, t1, t2);
        for (int d = 0; d < 3; d++) {
            k->t1[d] = t1[d];
            k->t2[d] = t2[d];
        }
    }
    return CADMM_OK;
}

/* ---- joints ---------------------------------------------------------------------------- */

/*
 * ODE's rows and cadmm's. ODE writes row k of a joint as its Jacobian J_k (J1 on the first
 * body, J2 on the second), a right-hand side rhs_k, a CFM_k and bounds on its force F_k.
 * Its step (step.cpp; quickstep.cpp solves the same system) scales rhs and CFM by 1/h and
 * solves the LCP
 *
 *     (J M^-1 J^T + CFM / h) F = rhs / h - J (v / h + M^-1 f_ext) + w,
 *
 * w_k = 0 inside the bounds, >= 0 at the low bound, <= 0 at the high one; then
 * v' = v + h M^-1 (f_ext + J^T F). Multiplied by h, with J v' = J v + h J M^-1 (f_ext
 * + J^T F), the row reads
 *
 *     J_k v' - rhs_k + CFM_k F_k = h w_k.
 *
 * cadmm's row is y_k = G_k^T v' + b_k + c_k lambda_k with the impulse lambda = F h, y_k = 0
 * inside the bounds, >= 0 at lo, <= 0 at hi, and M v' = M v + h f_ext + G lambda. So
 * G_k = J_k^T, lambda_k = h F_k, lo/hi = h times ODE's force bounds, and, comparing
 * J v' - rhs + CFM F with G^T v' + b + c h F:
 *
 *     b_k = -rhs_k,   c_k = CFM_k / h.
 *
 * ODE's rhs for an equality is ERP / h times the position error of body 2 from body 1
 * (the ball's anchor2 - anchor1), J v' being body 1's velocity relative to body 2's (its
 * anchor's): so b = -ERP (error) / h, and the row closes the ERP fraction of the error a
 * step. A limit's rhs is -StopERP (angle - stop) / h, so b = StopERP (angle - stop) / h,
 * negative past the stop, where y = J v' + b >= 0 turns the joint back; a motor's rhs is
 * Vel, so b = -Vel. The functions below build each row as ODE's getInfo2 does (joint.cpp,
 * hinge.cpp, ...), with ODE's rhs and CFM handed to row().
 */

#define PI 3.14159265358979323846

/* A joint being read: its bodies' poses and where its rows go. b is ODE's second body,
 * NULL for the world, whose pose is the identity and velocity zero. */
typedef struct joint_env {
    cadmm_ode *ctx;
    dJointID id;
    int type;
    dBodyID a, b;  /* ODE's first and second body (dJointGetBody swaps them back for a
                    * joint attached as (0, body), which ODE holds "reversed") */
    bool reversed;
    double h, erp, cfm; /* the world's ERP and CFM */
    double xa[3], xb[3], qa[4], qb[4], va[6], vb[6];
    const dReal *Ra, *Rb; /* NULL for the world */
    joint_row *rows;
    size_t n;
} joint_env;

static const char *joint_type_name(int type) {
    static const char *const names[] = {
        "unknown",   "ball",  "hinge", "slider", "contact", "universal", "hinge-2", "fixed",
        "null",      "AMotor", "LMotor", "Plane2D", "PR", "PU", "Piston", "DBall", "DHinge",
        "Transmission"};
    return type >= 0 && type < (int)(sizeof names / sizeof names[0]) ? names[type] : "unknown";
}

/* A new row with ODE's right-hand side and CFM (see above), an equality until bounded. */
static joint_row *row(joint_env *e, double rhs, double cfm) {
    joint_row *r = &e->rows[e->n++];
    memset(r, 0, sizeof *r);
    r->b = -rhs;
    r->c = cfm / e->h;
    r->lo = -INFINITY;
    r->hi = INFINITY;
    r->contact = -1;
    return r;
}

/* d . (velocity of a's point at arm a1 - velocity of b's at arm a2), arms from the centers. */
static void point_row(joint_row *r, const double d[3], const double a1[3], const double a2[3]) {
    double m1[3], m2[3];
    cross(a1, d, m1);
    cross(a2, d, m2);
    for (int k = 0; k < 3; k++) {
        r->ga[k] = d[k];
        r->ga[3 + k] = m1[k];
        r->gb[k] = -d[k];
        r->gb[3 + k] = -m2[k];
    }
}

/* d . (omega_a - omega_b). */
static void angular_row(joint_env *e, const double d[3], double rhs, double cfm) {
    joint_row *r = row(e, rhs, cfm);
    for (int k = 0; k < 3; k++) {
        r->ga[3 + k] = d[k];
        r->gb[3 + k] = -d[k];
    }
}

/* ODE's setBall: anchor pa (on a) held on pb (on b, or a world point), along the world
 * axes. */
static void ball_rows(joint_env *e, const double pa[3], const double pb[3], double erp,
                      double cfm) {
    double a1[3], a2[3];
    for (int k = 0; k < 3; k++) {
        a1[k] = pa[k] - e->xa[k];
        a2[k] = pb[k] - e->xb[k];
    }
    for (int k = 0; k < 3; k++) {
        double d[3] = {k == 0, k == 1, k == 2};
        point_row(row(e, erp / e->h * (pb[k] - pa[k]), cfm), d, a1, a2);
    }
}

/* ODE's setBall2 (hinge-2): the same along axis (its own ERP and CFM) and its plane space. */
static void ball2_rows(joint_env *e, const double pa[3], const double pb[3], const double axis[3],
                       double erp_axis, double cfm_axis) {
    double a1[3], a2[3], gap[3];
    for (int k = 0; k < 3; k++) {
        a1[k] = pa[k] - e->xa[k];
        a2[k] = pb[k] - e->xb[k];
        gap[k] = pb[k] - pa[k];
    }
    dVector3 n = {axis[0], axis[1], axis[2], 0}, p, q;
    dPlaneSpace(n, p, q);
    double dp[3] = {p[0], p[1], p[2]}, dq[3] = {q[0], q[1], q[2]};
    point_row(row(e, erp_axis / e->h * dot(axis, gap), cfm_axis), axis, a1, a2);
    point_row(row(e, e->erp / e->h * dot(dp, gap), e->cfm), dp, a1, a2);
    point_row(row(e, e->erp / e->h * dot(dq, gap), e->cfm), dq, a1, a2);
}

/* ODE's setFixedOrientation: omega_a = omega_b, turning b back to a qrel when it is off by
 * the rotation qerr = qa^* qb qrel^* (by 2 vec(qerr) in a's frame at small angles). */
static void orientation_rows(joint_env *e, const double qrel[4], double erp, double cfm) {
    double ca[4], cr[4], t[4], qerr[4], err[3];
    qconj(e->qa, ca);
    qconj(qrel, cr);
    qmul(ca, e->qb, t);
    qmul(t, cr, qerr);
    double sign = qerr[0] < 0 ? -1.0 : 1.0; /* the short way round */
    double v[3] = {sign * qerr[1], sign * qerr[2], sign * qerr[3]};
    rotate(e->Ra, v, err);
    for (int k = 0; k < 3; k++) {
        double d[3] = {k == 0, k == 1, k == 2};
        angular_row(e, d, 2.0 * erp / e->h * err[k], cfm);
    }
}

/* A limit and motor (ODE's dxJointLimitMotor), read through the joint's getter. */
typedef struct limot {
    double lo, hi, vel, fmax, bounce, cfm, stop_erp, stop_cfm;
} limot;

static limot read_limot(dReal (*get)(dJointID, int), dJointID j, int group) {
    return (limot){get(j, dParamLoStop + group), get(j, dParamHiStop + group),
                   get(j, dParamVel + group),    get(j, dParamFMax + group),
                   get(j, dParamBounce + group), get(j, dParamCFM + group),
                   get(j, dParamStopERP + group), get(j, dParamStopCFM + group)};
}

/* ODE's rotational limits are looked at only with a stop within [-pi, pi]. */
static bool rotational_stops(const limot *m) {
    return (m->lo >= -PI || m->hi <= PI) && m->lo <= m->hi;
}

/* ODE's addLimot: along ax (angular, or linear with the two bodies' torques balanced about
 * their midpoint), a limit row when `value` (the joint's angle or position) is at or past
 * a stop and `limited`, then a motor row when FMax > 0 (ODE drops the motor of a joint held
 * at lo == hi, an equality then). */
static void limot_rows(joint_env *e, const limot *m, const double ax[3], bool rotational,
                       double value, bool limited) {
    int limit = 0;
    double err = 0.0;
    if (limited && value <= m->lo) {
        limit = 1;
        err = value - m->lo;
    } else if (limited && value >= m->hi) {
        limit = 2;
        err = value - m->hi;
    }
    bool powered = m->fmax > 0 && !(limit && m->lo == m->hi);
    double ja[6] = {0}, jb[6] = {0};
    int at = rotational ? 3 : 0;
    for (int k = 0; k < 3; k++) {
        ja[at + k] = ax[k];
        jb[at + k] = -ax[k];
    }
    if (!rotational && e->b) {
        double c[3] = {0.5 * (e->xb[0] - e->xa[0]), 0.5 * (e->xb[1] - e->xa[1]),
                       0.5 * (e->xb[2] - e->xa[2])},
               ltd[3];
        cross(c, ax, ltd);
        for (int k = 0; k < 3; k++) ja[3 + k] = jb[3 + k] = ltd[k];
    }
    if (limit) {
        double rhs = -m->stop_erp / e->h * err;
        if (m->lo != m->hi && m->bounce > 0) {
            /* Bounce: at least -bounce times the incoming joint velocity. */
            double vel = dot(ax, &e->va[at]) - dot(ax, &e->vb[at]);
            if (limit == 1 && vel < 0 && -m->bounce * vel > rhs) rhs = -m->bounce * vel;
            if (limit == 2 && vel > 0 && -m->bounce * vel < rhs) rhs = -m->bounce * vel;
        }
        joint_row *r = row(e, rhs, m->stop_cfm);
        memcpy(r->ga, ja, sizeof ja);
        memcpy(r->gb, jb, sizeof jb);
        if (m->lo != m->hi) {
            r->lo = limit == 1 ? 0.0 : -INFINITY;
            r->hi = limit == 1 ? INFINITY : 0.0;
        }
    }
    if (powered) {
        joint_row *r = row(e, m->vel, m->cfm);
        memcpy(r->ga, ja, sizeof ja);
        memcpy(r->gb, jb, sizeof jb);
        r->lo = -m->fmax * e->h;
        r->hi = m->fmax * e->h;
    }
}

/* The anchors of a and b from a pair of getters: ODE's "1" is on a, "2" on b, swapped for
 * a reversed joint. */
static void anchors(const joint_env *e, void (*get1)(dJointID, dVector3),
                    void (*get2)(dJointID, dVector3), double pa[3], double pb[3]) {
    dVector3 p1, p2;
    get1(e->id, p1);
    get2(e->id, p2);
    copy3(e->reversed ? p2 : p1, pa);
    copy3(e->reversed ? p1 : p2, pb);
}

/* The joint's record, made or made again when the joint is new to the host or its type,
 * bodies or (hinge, slider, hinge-2) axes changed. NULL when out of memory. */
static joint_record *record_of(joint_env *e) {
    cadmm_ode *ctx = e->ctx;
    joint_record *recs = ctx->records.data;
    size_t lo = 0, hi = ctx->n_records;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if ((uintptr_t)recs[mid].id < (uintptr_t)e->id) lo = mid + 1;
        else hi = mid;
    }
    dVector3 axa = {0, 0, 0, 0}, axb = {0, 0, 0, 0};
    if (e->type == dJointTypeHinge) dJointGetHingeAxis(e->id, axa);
    if (e->type == dJointTypeSlider) dJointGetSliderAxis(e->id, axa);
    if (e->type == dJointTypeHinge2) {
        dJointGetHinge2Axis1(e->id, axa);
        dJointGetHinge2Axis2(e->id, axb);
    }
    double wa[3] = {axa[0], axa[1], axa[2]}, wb[3] = {axb[0], axb[1], axb[2]}, la[3], lb[3];
    unrotate(e->Ra, wa, la);
    if (e->Rb) unrotate(e->Rb, wb, lb);
    else copy3(axb, lb);
    joint_record *r = lo < ctx->n_records && recs[lo].id == e->id ? &recs[lo] : NULL;
    if (r && r->type == e->type && r->a == e->a && r->b == e->b) {
        double drift = 0.0;
        for (int k = 0; k < 3; k++) {
            drift = fmax(drift, fabs(la[k] - r->axis_a[k]));
            if (e->type == dJointTypeHinge2) drift = fmax(drift, fabs(lb[k] - r->axis_b[k]));
        }
        if (drift <= 1e-9) return r; /* only round-off: the axis ODE holds is the same */
    }
    if (!r) {
        recs = reserve(&ctx->records, ctx->n_records + 1, sizeof *recs);
        if (!recs) return NULL;
        memmove(&recs[lo + 1], &recs[lo], (ctx->n_records - lo) * sizeof *recs);
        ctx->n_records++;
        r = &recs[lo];
    }
    /* As ODE's setters record them (computeInitialRelativeRotation, computeOffset, ...). */
    memset(r, 0, sizeof *r);
    r->id = e->id;
    r->type = e->type;
    r->a = e->a;
    r->b = e->b;
    memcpy(r->axis_a, la, sizeof la);
    if (e->type == dJointTypeHinge) {
        if (e->Rb) unrotate(e->Rb, wa, r->axis_b);
        else memcpy(r->axis_b, wa, sizeof wa);
    }
    if (e->type == dJointTypeHinge2) {
        double c[3];
        memcpy(r->axis_b, lb, sizeof lb);
        cross(wa, wb, c);
        r->s0 = sqrt(dot(c, c));
        r->c0 = dot(wa, wb);
    }
    if (e->type == dJointTypeSlider || e->type == dJointTypeFixed) {
        double ca[4], d[3];
        qconj(e->qa, ca);
        qmul(ca, e->qb, r->q);
        for (int k = 0; k < 3; k++) d[k] = e->xa[k] - e->xb[k];
        if (!e->b) memcpy(r->offset, e->xa, sizeof r->offset);
        else if (e->type == dJointTypeSlider) unrotate(e->Rb, d, r->offset);
        else unrotate(e->Ra, d, r->offset);
    }
    return r;
}

static void ball_joint(joint_env *e) {
    double pa[3], pb[3];
    anchors(e, dJointGetBallAnchor, dJointGetBallAnchor2, pa, pb);
    ball_rows(e, pa, pb, dJointGetBallParam(e->id, dParamERP),
              dJointGetBallParam(e->id, dParamCFM));
}

static void hinge_joint(joint_env *e, const joint_record *rec) {
    double pa[3], pb[3], ax1[3], ax2[3], u[3];
    anchors(e, dJointGetHingeAnchor, dJointGetHingeAnchor2, pa, pb);
    ball_rows(e, pa, pb, e->erp, e->cfm);
    dVector3 axis, p, q;
    dJointGetHingeAxis(e->id, axis); /* on a */
    copy3(axis, ax1);
    if (e->Rb) rotate(e->Rb, rec->axis_b, ax2);
    else memcpy(ax2, rec->axis_b, sizeof ax2);
    /* Turn a's axis onto b's: (ax1 x ax2) . p at small angles. */
    cross(ax1, ax2, u);
    dPlaneSpace(axis, p, q);
    double dp[3] = {p[0], p[1], p[2]}, dq[3] = {q[0], q[1], q[2]};
    angular_row(e, dp, e->erp / e->h * dot(u, dp), e->cfm);
    angular_row(e, dq, e->erp / e->h * dot(u, dq), e->cfm);
    /* ODE's stops act on its own angle, which dJointGetHingeAngle negates when reversed. */
    limot m = read_limot(dJointGetHingeParam, e->id, 0);
    double angle = dJointGetHingeAngle(e->id);
    limot_rows(e, &m, ax1, true, e->reversed ? -angle : angle, rotational_stops(&m));
}

static void slider_joint(joint_env *e, const joint_record *rec) {
    orientation_rows(e, rec->q, e->erp, e->cfm);
    dVector3 axis, p, q;
    dJointGetSliderAxis(e->id, axis); /* on a */
    dPlaneSpace(axis, p, q);
    const double *dirs[2] = {(double[3]){p[0], p[1], p[2]}, (double[3]){q[0], q[1], q[2]}};
    /* a's center on the line through b's recorded point, ODE's two off-axis rows; the
     * angular terms use (omega_a + omega_b) / 2 for omega_b, as ODE does. */
    double c[3], gap[3];
    for (int k = 0; k < 3; k++) c[k] = e->xb[k] - e->xa[k];
    if (e->b) {
        double ofs[3];
        rotate(e->Rb, rec->offset, ofs);
        for (int k = 0; k < 3; k++) gap[k] = c[k] + ofs[k];
    } else {
        for (int k = 0; k < 3; k++) gap[k] = rec->offset[k] - e->xa[k];
    }
    for (int d = 0; d < 2; d++) {
        joint_row *r = row(e, e->erp / e->h * dot(dirs[d], gap), e->cfm);
        double half[3];
        cross(c, dirs[d], half);
        for (int k = 0; k < 3; k++) {
            r->ga[k] = dirs[d][k];
            r->gb[k] = -dirs[d][k];
            r->ga[3 + k] = r->gb[3 + k] = e->b ? 0.5 * half[k] : 0.0;
        }
    }
    /* dJointGetSliderPosition is along -axis for a reversed joint: so is its row. */
    limot m = read_limot(dJointGetSliderParam, e->id, 0);
    double ax[3] = {axis[0], axis[1], axis[2]};
    if (e->reversed)
        for (int k = 0; k < 3; k++) ax[k] = -ax[k];
    limot_rows(e, &m, ax, false, dJointGetSliderPosition(e->id),
               (m.lo > -INFINITY || m.hi < INFINITY) && m.lo <= m.hi);
}

static void fixed_joint(joint_env *e, const joint_record *rec) {
    double erp = dJointGetFixedParam(e->id, dParamERP), cfm = dJointGetFixedParam(e->id, dParamCFM);
    double ofs[3];
    rotate(e->Ra, rec->offset, ofs);
    /* b's center where a's frame puts it: x_a - x_b = R_a offset (the world: x_a = offset). */
    for (int k = 0; k < 3; k++) {
        double d[3] = {k == 0, k == 1, k == 2}, m[3];
        joint_row *r = row(e, erp / e->h * (e->b ? e->xb[k] - e->xa[k] + ofs[k]
                                                   : rec->offset[k] - e->xa[k]),
                           cfm);
        cross(d, ofs, m);
        for (int i = 0; i < 3; i++) {
            r->ga[i] = d[i];
            r->ga[3 + i] = e->b ? m[i] : 0.0;
            r->gb[i] = -d[i];
        }
    }
    orientation_rows(e, rec->q, e->erp, e->cfm);
}

static void universal_joint(joint_env *e) {
    double pa[3], pb[3], ax1[3], ax2[3], t[3], p[3];
    anchors(e, dJointGetUniversalAnchor, dJointGetUniversalAnchor2, pa, pb);
    ball_rows(e, pa, pb, e->erp, e->cfm);
    /* ODE's axis 1 is on a, axis 2 on b; its getters swap them for a reversed joint. */
    dVector3 g1, g2;
    dJointGetUniversalAxis1(e->id, g1);
    dJointGetUniversalAxis2(e->id, g2);
    copy3(e->reversed ? g2 : g1, ax1);
    copy3(e->reversed ? g1 : g2, ax2);
    double k = dot(ax1, ax2);
    for (int i = 0; i < 3; i++) t[i] = ax2[i] - k * ax1[i];
    cross(ax1, t, p);
    double len = sqrt(dot(p, p));
    for (int i = 0; i < 3; i++) p[i] /= len;
    angular_row(e, p, -e->erp / e->h * k, e->cfm); /* keeps the axes perpendicular */
    limot m1 = read_limot(dJointGetUniversalParam, e->id, 0);
    limot m2 = read_limot(dJointGetUniversalParam, e->id, dParamGroup);
    double a1 = dJointGetUniversalAngle1(e->id), a2 = dJointGetUniversalAngle2(e->id);
    limot_rows(e, &m1, ax1, true, e->reversed ? -a2 : a1, rotational_stops(&m1));
    limot_rows(e, &m2, ax2, true, e->reversed ? a1 : a2, rotational_stops(&m2));
}

static void hinge2_joint(joint_env *e, const joint_record *rec) {
    double pa[3], pb[3], ax1[3], ax2[3], u[3];
    anchors(e, dJointGetHinge2Anchor, dJointGetHinge2Anchor2, pa, pb);
    dVector3 g1, g2;
    dJointGetHinge2Axis1(e->id, g1);
    dJointGetHinge2Axis2(e->id, g2);
    copy3(g1, ax1);
    copy3(g2, ax2);
    cross(ax1, ax2, u);
    double s = sqrt(dot(u, u)), c = dot(ax1, ax2);
    for (int k = 0; k < 3; k++) u[k] /= s;
    ball2_rows(e, pa, pb, ax1, dJointGetHinge2Param(e->id, dParamSuspensionERP),
               dJointGetHinge2Param(e->id, dParamSuspensionCFM));
    /* Keeps the axes at their recorded angle: theta0 - theta ~ c s0 ... as ODE writes it. */
    angular_row(e, u, e->erp / e->h * (rec->c0 * s - rec->s0 * c), e->cfm);
    limot m1 = read_limot(dJointGetHinge2Param, e->id, 0);
    limot m2 = read_limot(dJointGetHinge2Param, e->id, dParamGroup);
    limot_rows(e, &m1, ax1, true, dJointGetHinge2Angle1(e->id), rotational_stops(&m1));
    limot_rows(e, &m2, ax2, true, 0.0, false); /* ODE never limits axis 2 */
}

static void pose_of(dBodyID body, double x[3], double q[4], double v[6]) {
    const dReal *p = dBodyGetPosition(body), *r = dBodyGetQuaternion(body);
    const dReal *lv = dBodyGetLinearVel(body), *av = dBodyGetAngularVel(body);
    for (int k = 0; k < 3; k++) {
        x[k] = p[k];
        v[k] = lv[k];
        v[3 + k] = av[k];
    }
    for (int k = 0; k < 4; k++) q[k] = r[k];
}

/* Joint j, seen from body `index` of the list: checked, and its rows added when `index`
 * is its first body (a joint of two listed bodies is met twice). */
static cadmm_result read_joint(cadmm_ode *ctx, dWorldID world, dJointID j, size_t index) {
    const dBodyID *bodies = ctx->bodies.data;
    long *body_slot = ctx->body_slot.data;
    if (!dJointIsEnabled(j)) return CADMM_OK;
    joint_env e = {.ctx = ctx, .id = j, .type = (int)dJointGetType(j), .h = ctx->h};
    dBodyID b0 = dJointGetBody(j, 0), b1 = dJointGetBody(j, 1);
    e.reversed = !b0;
    e.a = b0 ? b0 : b1;
    e.b = b0 ? b1 : NULL;
    long ia = find_body(ctx, e.a), ib = e.b ? find_body(ctx, e.b) : -1;
    const char *name = joint_type_name(e.type);
    if (dBodyIsKinematic(e.a) || (e.b && dBodyIsKinematic(e.b)))
        return fail(ctx, CADMM_ERR_UNSUPPORTED,
                    "%s joint on bodies[%zu] touches a kinematic body: not supported", name,
                    index);
    if (ia < 0 || (e.b && ib < 0))
        return fail(ctx, CADMM_ERR_INVALID_VALUE,
                    "%s joint on bodies[%zu]: its other body is not in the bodies list", name,
                    index);
    if (e.a != bodies[index]) return CADMM_OK; /* read from its first body */
    switch (e.type) {
    case dJointTypeBall: case dJointTypeHinge: case dJointTypeSlider: case dJointTypeFixed:
    case dJointTypeUniversal: case dJointTypeHinge2:
        break;
    case dJointTypeNull:
        return CADMM_OK; /* no rows */
    case dJointTypeContact:
        return fail(ctx, CADMM_ERR_UNSUPPORTED,
                    "contact joint (dJointTypeContact) on bodies[%zu]: contact joints made by "
                    "the user are not supported; hand its contact to cadmm_ode_assemble "
                    "(dContactGeom) or cadmm_ode_assemble_contacts (dContact)", index);
    default:
        return fail(ctx, CADMM_ERR_UNSUPPORTED,
                    "%s joint (dJointType%s) on bodies[%zu]: not supported by cadmm_ode "
                    "(ball, hinge, slider, fixed, universal, hinge-2 and null joints are)",
                    name, e.type == dJointTypeNone ? "None" : name, index);
    }
    if (e.type == dJointTypeHinge2 && !e.b)
        return fail(ctx, CADMM_ERR_INVALID_VALUE,
                    "hinge-2 joint on bodies[%zu] is attached to one body: it needs two, as in "
                    "ODE", index);
    e.erp = dWorldGetERP(world);
    e.cfm = dWorldGetCFM(world);
    pose_of(e.a, e.xa, e.qa, e.va);
    e.Ra = dBodyGetRotation(e.a);
    memset(e.xb, 0, sizeof e.xb);
    memset(e.vb, 0, sizeof e.vb);
    e.qb[0] = 1.0;
    e.qb[1] = e.qb[2] = e.qb[3] = 0.0;
    if (e.b) {
        pose_of(e.b, e.xb, e.qb, e.vb);
        e.Rb = dBodyGetRotation(e.b);
    }
    if (e.type == dJointTypeHinge2) {
        dVector3 g1, g2;
        dJointGetHinge2Axis1(j, g1);
        dJointGetHinge2Axis2(j, g2);
        double c[3], a1[3], a2[3];
        copy3(g1, a1);
        copy3(g2, a2);
        cross(a1, a2, c);
        if (!(dot(c, c) > 0))
            return fail(ctx, CADMM_ERR_INVALID_VALUE,
                        "hinge-2 joint on bodies[%zu]: its two axes are parallel", index);
    }

    /* At most 8 rows a joint (a universal joint with both limits and motors). */
    joint *js = reserve(&ctx->joints, ctx->n_joints + 1, sizeof *js);
    joint_row *rows = reserve(&ctx->rows, ctx->n_rows + 8, sizeof *rows);
    bool recorded = e.type != dJointTypeBall && e.type != dJointTypeUniversal;
    const joint_record *rec = recorded ? record_of(&e) : NULL;
    if (!js || !rows || (recorded && !rec)) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    e.rows = &rows[ctx->n_rows];
    switch (e.type) {
    case dJointTypeBall: ball_joint(&e); break;
    case dJointTypeHinge: hinge_joint(&e, rec); break;
    case dJointTypeSlider: slider_joint(&e, rec); break;
    case dJointTypeFixed: fixed_joint(&e, rec); break;
    case dJointTypeUniversal: universal_joint(&e); break;
    default: hinge2_joint(&e, rec); break;
    }
    for (size_t k = 0; k < e.n; k++) {
        const joint_row *r = &e.rows[k];
        bool finite = isfinite(r->b) && isfinite(r->c) && !isnan(r->lo) && !isnan(r->hi);
        for (int i = 0; i < 6; i++) finite = finite && isfinite(r->ga[i]) && isfinite(r->gb[i]);
        if (!finite || r->c < 0 || r->lo > r->hi)
            return fail(ctx, CADMM_ERR_INVALID_VALUE,
                        "%s joint on bodies[%zu], row %zu: %s (its ERP, CFM, stops, Vel and "
                        "FMax must be finite, its CFMs not negative)", name, index, k,
                        r->c < 0 ? "negative CFM" : "a non-finite value");
    }
    js[ctx->n_joints++] = (joint){j, ia, ib, ctx->n_rows, e.n};
    ctx->n_rows += e.n;
    body_slot[ia] = 0;
    if (ib >= 0) body_slot[ib] = 0;
    return CADMM_OK;
}

/* Every enabled joint of the listed bodies, body after body in list order. */
static cadmm_result read_joints(cadmm_ode *ctx, dWorldID world) {
    const dBodyID *bodies = ctx->bodies.data;
    ctx->n_joints = ctx->n_rows = 0;
    for (size_t i = 0; i < ctx->n_bodies; i++) {
        int count = dBodyGetNumJoints(bodies[i]);
        for (int k = 0; k < count; k++) {
            cadmm_result rc = read_joint(ctx, world, dBodyGetJoint(bodies[i], k), i);
            if (rc != CADMM_OK) return rc;
        }
    }
    return CADMM_OK;
}

/* Rolling and spinning friction, as ODE's contact joint writes it (a contact with
 * dContactRolling and friction, mu > 0): rows on g1's angular velocity minus g2's about t1,
 * t2 (rolling) and n (spinning), with the coefficients rho, rho2, rhoN (dContactAxisDep;
 * rho for all three otherwise), a row for each positive one. ODE bounds a row's force by
 * rho times the normal force with the axis's dContactApprox1 bit (_1, _2, _N: the contact's
 * e r_n bound here), by rho itself without it ([-rho h, rho h] on the impulse); an infinite
 * rho is an equality (no rolling). Every row has the world's CFM, as ODE's. */
static cadmm_result read_rolling(cadmm_ode *ctx, dWorldID world, const dContact *surfaces,
                                 size_t nc) {
    ctx->n_rolling = 0;
    if (!surfaces) return CADMM_OK;
    const contact *cs = ctx->contacts.data;
    const double cfm = dWorldGetCFM(world);
    for (size_t c = 0; c < nc; c++) {
        const dSurfaceParameters *sp = &surfaces[c].surface;
        if (!(sp->mode & dContactRolling) || !(sp->mu > 0)) continue;
        const bool axis_dep = (sp->mode & dContactAxisDep) != 0;
        const double rho[3] = {sp->rho, axis_dep ? sp->rho2 : sp->rho,
                               axis_dep ? sp->rhoN : sp->rho};
        const int approx[3] = {dContactApprox1_1, dContactApprox1_2, dContactApprox1_N};
        const double *axes[3] = {cs[c].t1, cs[c].t2, cs[c].n};
        joint_row *rows = reserve(&ctx->rows, ctx->n_rows + 3, sizeof *rows);
        if (!rows) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
        for (int i = 0; i < 3; i++) {
            if (!(rho[i] > 0)) continue;
            joint_row *r = &rows[ctx->n_rows++];
            memset(r, 0, sizeof *r);
            for (int k = 0; k < 3; k++) {
                r->ga[3 + k] = axes[i][k];
                r->gb[3 + k] = -axes[i][k];
            }
            r->c = cfm / ctx->h;
            r->lo = -INFINITY;
            r->hi = INFINITY;
            r->contact = (long)c;
            if (isinf(rho[i])) {
                /* no bound: the equality that holds the axis still */
            } else if (sp->mode & approx[i]) {
                r->by_normal = true;
                r->e = rho[i];
            } else {
                r->lo = -rho[i] * ctx->h;
                r->hi = rho[i] * ctx->h;
            }
            ctx->n_rolling++;
        }
    }
    return CADMM_OK;
}

void cadmm_ode_forget_joint(cadmm_ode *ctx, dJointID j) {
    if (!ctx) return;
    joint_record *recs = ctx->records.data;
    for (size_t k = 0; k < ctx->n_records; k++)
        if (recs[k].id == j) {
            memmove(&recs[k], &recs[k + 1], (ctx->n_records - k - 1) * sizeof *recs);
            ctx->n_records--;
            return;
        }
}

/* Column k of G, on the bodies in slots a and b (-1 for none), and row k's other arrays;
 * colptr[k] is where the column starts. */
static void g_column(cadmm_ode *ctx, size_t k, long a, long b) {
    const joint_row *r = &((const joint_row *)ctx->rows.data)[k];
    int64_t *colptr = ctx->g_colptr.data, *rowind = ctx->g_rowind.data, nnz = colptr[k];
    double *values = ctx->g_values.data;
    long slots[2] = {a, b};
    const double *g[2] = {r->ga, r->gb};
    /* The lower slot first: sorted row indices, which cadmm takes as they are. */
    const int swap = b >= 0 && b < a;
    for (int t = 0; t < 2; t++) {
        const int side = swap ? 1 - t : t;
        if (slots[side] < 0) continue;
        for (int i = 0; i < 6; i++) {
            rowind[nnz] = 6 * slots[side] + i;
            values[nnz++] = g[side][i];
        }
    }
    colptr[k + 1] = nnz;
    ((double *)ctx->jb.data)[k] = r->b;
    ((double *)ctx->jlo.data)[k] = r->lo;
    ((double *)ctx->jhi.data)[k] = r->hi;
    ((double *)ctx->jc.data)[k] = r->c;
    ((int64_t *)ctx->jfc.data)[k] = r->by_normal ? r->contact : -1;
    ((double *)ctx->jfe.data)[k] = r->e;
    ctx->any_bounded = ctx->any_bounded || r->lo > -INFINITY || r->hi < INFINITY;
    ctx->any_compliance = ctx->any_compliance || r->c != 0.0;
    ctx->any_contact_bounds = ctx->any_contact_bounds || r->by_normal;
}

/* G from the rows, the joints' then the contacts' rolling rows: each column has a's 6
 * entries, then b's; every entry is written, zero or not, so that the pattern depends only
 * on the joints' and contacts' bodies and row counts. Also b, the bounds, the compliance,
 * the bounding contacts, and whether cadmm needs to be handed the last three. */
static void assemble_g(cadmm_ode *ctx) {
    const joint *js = ctx->joints.data;
    const contact *cs = ctx->contacts.data;
    const joint_row *rows = ctx->rows.data;
    int64_t *colptr = ctx->g_colptr.data, *nnz = &colptr[0];
    *nnz = 0;
    ctx->any_bounded = ctx->any_compliance = ctx->any_contact_bounds = false;
    size_t k = 0;
    for (size_t j = 0; j < ctx->n_joints; j++)
        for (size_t end = js[j].first_row + js[j].n_rows; k < end; k++)
            g_column(ctx, k, js[j].slot_a, js[j].slot_b);
    for (; k < ctx->n_rows; k++)
        g_column(ctx, k, cs[rows[k].contact].slot1, cs[rows[k].contact].slot2);
}

/* H: column 3c+k holds direction d (n, t1, t2) and moment (p - x) x d on g1's body, their
 * negatives on g2's. Every entry is written, zero or not, so the pattern depends only on
 * which bodies each contact touches. */
static void assemble_h(cadmm_ode *ctx, const dBodyID *bodies) {
    const contact *cs = ctx->contacts.data;
    const size_t *slot_body = ctx->slot_body.data;
    int64_t *colptr = ctx->h_colptr.data, *rowind = ctx->h_rowind.data;
    double *values = ctx->h_values.data;
    int64_t nnz = 0;
    colptr[0] = 0;
    for (size_t c = 0; c < ctx->n_contacts; c++) {
        const contact *k = &cs[c];
        const double *dirs[3] = {k->n, k->t1, k->t2};
        for (int d = 0; d < 3; d++) {
            long slots[2] = {k->slot1, k->slot2};
            /* The lower slot first: sorted row indices, which cadmm takes as they are. */
            const int swap = k->slot2 >= 0 && k->slot2 < k->slot1;
            for (int t = 0; t < 2; t++) {
                const int side = swap ? 1 - t : t;
                if (slots[side] < 0) continue;
                const dReal *x = dBodyGetPosition(bodies[slot_body[slots[side]]]);
                double arm[3] = {k->pos[0] - x[0], k->pos[1] - x[1], k->pos[2] - x[2]}, mom[3];
                cross(arm, dirs[d], mom);
                double sign = side == 0 ? 1.0 : -1.0;
                for (int i = 0; i < 6; i++) {
                    rowind[nnz] = 6 * slots[side] + i;
                    values[nnz++] = sign * (i < 3 ? dirs[d][i] : mom[i - 3]);
                }
            }
            colptr[3 * c + d + 1] = nnz;
        }
    }
}

/* M: per slot, the mass on three diagonal entries and the 3x3 world inertia block. */
static void assemble_m(cadmm_ode *ctx, const body_state *s, size_t slot, int64_t *nnz) {
    int64_t *colptr = ctx->m_colptr.data, *rowind = ctx->m_rowind.data;
    double *values = ctx->m_values.data;
    for (size_t j = 0; j < 6; j++) {
        size_t col = 6 * slot + j;
        if (j < 3) {
            rowind[*nnz] = (int64_t)col;
            values[(*nnz)++] = s->mass;
        } else {
            for (size_t i = 0; i < 3; i++) {
                rowind[*nnz] = (int64_t)(6 * slot + 3 + i);
                values[(*nnz)++] = s->inertia[3 * i + (j - 3)];
            }
        }
        colptr[col + 1] = *nnz;
    }
}

/* The step's problem. Contact c's geom is at geoms + c stride bytes; with `surfaces` (a
 * dContact array) its mu is its surface's. The pattern the solver's reuse compares holds
 * the slots, the contacts' bodies, the joints' bodies and row counts and which rows are
 * bounded: everything the sparsity of M, H and G and cadmm's split of the joint rows
 * depend on. */
static double seconds_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static cadmm_result assemble(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                             size_t n_bodies, const dContactGeom *geoms, size_t stride,
                             const dContact *surfaces, size_t nc, double h) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    ctx->assembly_start = seconds_now();
    if (!world || (n_bodies && !bodies) || (nc && !geoms))
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_assemble: NULL %s",
                    !world ? "world" : (n_bodies && !bodies) ? "bodies" : "contacts");
    if (!(h > 0.0) || !isfinite(h))
        return fail(ctx, CADMM_ERR_INVALID_VALUE, "time step h = %g must be positive", h);
    cadmm_problem_free(ctx->problem);
    ctx->problem = NULL;
    ctx->world = NULL; /* set once the assembly succeeded */
    ctx->assembled = false;
    ctx->h = h;
    ctx->n_bodies = n_bodies;
    ctx->n_contacts = nc;
    ctx->n_joints = ctx->n_rows = 0;

    body_key *keys = reserve(&ctx->keys, n_bodies, sizeof *keys);
    long *body_slot = reserve(&ctx->body_slot, n_bodies, sizeof *body_slot);
    dBodyID *own = reserve(&ctx->bodies, n_bodies, sizeof *own);
    if (!keys || !body_slot || !own || !reserve(&ctx->slot_body, n_bodies, sizeof(size_t)) ||
        !reserve(&ctx->contacts, nc, sizeof(contact)))
        return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    for (size_t i = 0; i < n_bodies; i++) {
        if (!bodies[i]) return fail(ctx, CADMM_ERR_NULL_POINTER, "bodies[%zu] is NULL", i);
        own[i] = bodies[i];
        keys[i] = (body_key){(uintptr_t)bodies[i], i};
        body_slot[i] = -1;
    }
    qsort(keys, n_bodies, sizeof *keys, compare_keys);
    for (size_t i = 1; i < n_bodies; i++)
        if (keys[i].id == keys[i - 1].id)
            return fail(ctx, CADMM_ERR_INVALID_VALUE, "bodies[%zu] is listed twice", keys[i].index);
    cadmm_result rc = read_contacts(ctx, geoms, stride, surfaces, nc);
    if (rc == CADMM_OK) rc = read_joints(ctx, world);
    if (rc == CADMM_OK) rc = read_rolling(ctx, world, surfaces, nc);
    if (rc != CADMM_OK) return rc;

    /* Slots in body order, so that the pattern is stable while the contacts and joints
     * are. */
    size_t *slot_body = ctx->slot_body.data, ns = 0, nj = ctx->n_joints, nr = ctx->n_rows;
    for (size_t i = 0; i < n_bodies; i++)
        if (body_slot[i] == 0) {
            body_slot[i] = (long)ns;
            slot_body[ns++] = i;
        }
    ctx->n_slots = ns;
    contact *cs = ctx->contacts.data;
    joint *js = ctx->joints.data;
    const joint_row *rows = ctx->rows.data;
    size_t len = 3 + ns + 2 * nc + 3 * nj + 3 * nr;
    long *pattern = reserve(&ctx->pattern, len, sizeof *pattern), *at = pattern;
    if (!pattern) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    *at++ = (long)ns;
    *at++ = (long)nc;
    *at++ = (long)nj;
    for (size_t s = 0; s < ns; s++) *at++ = (long)slot_body[s];
    for (size_t c = 0; c < nc; c++) {
        cs[c].slot1 = body_slot[cs[c].slot1];
        cs[c].slot2 = cs[c].slot2 >= 0 ? body_slot[cs[c].slot2] : -1;
        *at++ = cs[c].slot1;
        *at++ = cs[c].slot2;
    }
    for (size_t j = 0; j < nj; j++) {
        js[j].slot_a = body_slot[js[j].slot_a];
        js[j].slot_b = js[j].slot_b >= 0 ? body_slot[js[j].slot_b] : -1;
        *at++ = js[j].slot_a;
        *at++ = js[j].slot_b;
        *at++ = (long)js[j].n_rows;
    }
    for (size_t k = 0; k < nr; k++) {
        *at++ = rows[k].lo > -INFINITY || rows[k].hi < INFINITY;
        *at++ = rows[k].contact;
        *at++ = rows[k].by_normal;
    }
    ctx->pattern_len = len;
    if (nc == 0 && nr == 0) {
        ctx->world = world;
        ctx->assembled = true;
        return CADMM_OK;
    }

    size_t n = 6 * ns, h_nnz = 0, g_nnz = 0;
    for (size_t c = 0; c < nc; c++) h_nnz += 3 * 6 * (cs[c].slot2 >= 0 ? 2 : 1);
    for (size_t j = 0; j < nj; j++) g_nnz += js[j].n_rows * 6 * (js[j].slot_b >= 0 ? 2 : 1);
    for (size_t k = nr - ctx->n_rolling; k < nr; k++)
        g_nnz += 6 * (cs[rows[k].contact].slot2 >= 0 ? 2 : 1);
    if (!reserve(&ctx->m_colptr, n + 1, sizeof(int64_t)) ||
        !reserve(&ctx->m_rowind, 12 * ns, sizeof(int64_t)) ||
        !reserve(&ctx->m_values, 12 * ns, sizeof(double)) ||
        !reserve(&ctx->h_colptr, 3 * nc + 1, sizeof(int64_t)) ||
        !reserve(&ctx->h_rowind, h_nnz, sizeof(int64_t)) ||
        !reserve(&ctx->h_values, h_nnz, sizeof(double)) ||
        !reserve(&ctx->g_colptr, nr + 1, sizeof(int64_t)) ||
        !reserve(&ctx->g_rowind, g_nnz, sizeof(int64_t)) ||
        !reserve(&ctx->g_values, g_nnz, sizeof(double)) || !reserve(&ctx->f, n, sizeof(double)) ||
        !reserve(&ctx->v, n, sizeof(double)) || !reserve(&ctx->w, 3 * nc, sizeof(double)) ||
        !reserve(&ctx->r, 3 * nc, sizeof(double)) || !reserve(&ctx->r0, 3 * nc, sizeof(double)) ||
        !reserve(&ctx->mu, nc, sizeof(double)) || !reserve(&ctx->jb, nr, sizeof(double)) ||
        !reserve(&ctx->jlo, nr, sizeof(double)) || !reserve(&ctx->jhi, nr, sizeof(double)) ||
        !reserve(&ctx->jc, nr, sizeof(double)) || !reserve(&ctx->lambda, nr, sizeof(double)) ||
        !reserve(&ctx->jfc, nr, sizeof(int64_t)) || !reserve(&ctx->jfe, nr, sizeof(double)))
        return fail(ctx, CADMM_ERR_PANIC, "out of memory");

    double *f = ctx->f.data, *v = ctx->v.data;
    int64_t m_nnz = 0;
    ((int64_t *)ctx->m_colptr.data)[0] = 0;
    for (size_t s = 0; s < ns; s++) {
        body_state st;
        body_state_of(world, own[slot_body[s]], h, &st);
        assemble_m(ctx, &st, s, &m_nnz);
        memcpy(&f[6 * s], st.f, sizeof st.f);
        memcpy(&v[6 * s], st.v, sizeof st.v);
    }
    assemble_h(ctx, own);
    assemble_g(ctx);

    /* ODE's contact joint right-hand side: push out at ERP of the depth beyond the surface
     * layer per step, capped at the maximum correcting velocity. */
    double erp = dWorldGetERP(world), layer = dWorldGetContactSurfaceLayer(world);
    double max_vel = dWorldGetContactMaxCorrectingVel(world);
    double *w = ctx->w.data, *mu = ctx->mu.data;
    for (size_t c = 0; c < nc; c++) {
        const dContactGeom *g = (const dContactGeom *)((const char *)geoms + c * stride);
        double depth = g->depth - layer;
        double push = depth > 0 ? erp * depth / h : 0.0;
        w[3 * c] = -(push < max_vel ? push : max_vel);
        w[3 * c + 1] = w[3 * c + 2] = 0.0;
        mu[c] = surfaces ? surfaces[c].surface.mu : ctx->opt.mu;
    }
    ctx->world = world;
    ctx->assembled = true;
    return CADMM_OK;
}

cadmm_result cadmm_ode_assemble(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                size_t n_bodies, const dContactGeom *contacts,
                                size_t n_contacts, double h) {
    return assemble(ctx, world, bodies, n_bodies, contacts, sizeof *contacts, NULL, n_contacts,
                    h);
}

cadmm_result cadmm_ode_assemble_contacts(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                         size_t n_bodies, const dContact *contacts,
                                         size_t n_contacts, double h) {
    return assemble(ctx, world, bodies, n_bodies, contacts ? &contacts->geom : NULL,
                    sizeof *contacts, contacts, n_contacts, h);
}

/* The cadmm problem of the assembled arrays, built on first use; bounds and compliance
 * are handed over only when some row has them. */
static cadmm_result build_problem(cadmm_ode *ctx) {
    if (ctx->problem) return CADMM_OK;
    size_t n = 6 * ctx->n_slots, nc = ctx->n_contacts, nr = ctx->n_rows;
    cadmm_csc M = {n, n, ctx->m_colptr.data, ctx->m_rowind.data, ctx->m_values.data};
    cadmm_csc H = {n, 3 * nc, ctx->h_colptr.data, ctx->h_rowind.data, ctx->h_values.data};
    cadmm_csc G = {n, nr, ctx->g_colptr.data, ctx->g_rowind.data, ctx->g_values.data};
    const char *call = "cadmm_problem_new_global";
    cadmm_result rc = cadmm_problem_new_global(n, nc, &M, &H, ctx->f.data, ctx->w.data,
                                               ctx->mu.data, &ctx->problem);
    if (rc == CADMM_OK && nr > 0) {
        call = "cadmm_problem_set_joints";
        rc = cadmm_problem_set_joints(ctx->problem, &G, ctx->jb.data);
    }
    if (rc == CADMM_OK && ctx->any_bounded) {
        call = "cadmm_problem_set_joint_bounds";
        rc = cadmm_problem_set_joint_bounds(ctx->problem, ctx->jlo.data, ctx->jhi.data);
    }
    if (rc == CADMM_OK && ctx->any_compliance) {
        call = "cadmm_problem_set_joint_compliance";
        rc = cadmm_problem_set_joint_compliance(ctx->problem, ctx->jc.data);
    }
    if (rc == CADMM_OK && ctx->any_contact_bounds) {
        call = "cadmm_problem_set_joint_friction";
        rc = cadmm_problem_set_joint_friction(ctx->problem, ctx->jfc.data, ctx->jfe.data);
    }
    if (rc == CADMM_OK) return CADMM_OK;
    cadmm_problem_free(ctx->problem);
    ctx->problem = NULL;
    return fail_cadmm(ctx, rc, call);
}

/* ---- solve and integrate ------------------------------------------------------------- */

/* A contact's geom pair, in either order, and where the contact sits. */
typedef struct pair_key {
    uintptr_t lo, hi;
    size_t index;
} pair_key;

static pair_key key_of(const contact *k, size_t index) {
    uintptr_t a = (uintptr_t)k->g1, b = (uintptr_t)k->g2;
    return (pair_key){a < b ? a : b, a < b ? b : a, index};
}

static int compare_pairs(const void *x, const void *y) {
    const pair_key *a = x, *b = y;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

/* Initial impulses from the previous step: same geom pair, nearest point within the match
 * radius, each previous point used once; the previous world impulse is expressed in the
 * new frame. The previous points are sorted by geom pair, so that each contact searches its
 * own pair's only. Returns how many contacts were matched, or -1 when out of memory. */
static long match_previous(cadmm_ode *ctx, double *r0) {
    const contact *cs = ctx->contacts.data, *prev = ctx->previous.data;
    unsigned char *used = ctx->used.data;
    pair_key *keys = reserve(&ctx->pair_keys, ctx->n_previous, sizeof *keys);
    if (!keys) return -1;
    for (size_t p = 0; p < ctx->n_previous; p++) keys[p] = key_of(&prev[p], p);
    qsort(keys, ctx->n_previous, sizeof *keys, compare_pairs);
    memset(used, 0, ctx->n_previous);
    long matched = 0;
    for (size_t c = 0; c < ctx->n_contacts; c++) {
        const contact *k = &cs[c];
        double best = ctx->opt.match_radius * ctx->opt.match_radius, sign = 1.0;
        long hit = -1;
        /* The first previous point of this pair: a lower bound on (lo, hi, index 0). */
        pair_key want = key_of(k, 0);
        size_t from = 0, to = ctx->n_previous;
        while (from < to) {
            size_t mid = from + (to - from) / 2;
            if (compare_pairs(&keys[mid], &want) < 0) from = mid + 1;
            else to = mid;
        }
        for (size_t j = from; j < ctx->n_previous && keys[j].lo == want.lo && keys[j].hi == want.hi;
             j++) {
            size_t p = keys[j].index;
            if (used[p]) continue;
            double d[3] = {prev[p].pos[0] - k->pos[0], prev[p].pos[1] - k->pos[1],
                           prev[p].pos[2] - k->pos[2]};
            if (dot(d, d) <= best) {
                best = dot(d, d);
                hit = (long)p;
                sign = prev[p].g1 == k->g1 ? 1.0 : -1.0;
            }
        }
        double *rc = &r0[3 * c];
        if (hit < 0) {
            rc[0] = rc[1] = rc[2] = 0.0;
            continue;
        }
        used[hit] = 1;
        matched++;
        const double *P = prev[hit].impulse;
        rc[0] = sign * dot(P, k->n);
        rc[1] = sign * dot(P, k->t1);
        rc[2] = sign * dot(P, k->t2);
    }
    return matched;
}

static bool same_pattern(const cadmm_ode *ctx) {
    return ctx->solver && ctx->pattern_len == ctx->solver_pattern_len &&
           memcmp(ctx->pattern.data, ctx->solver_pattern.data,
                  ctx->pattern_len * sizeof(long)) == 0;
}

/* With a time limit, gives the solve what assembling, building and updating left of it,
 * less what the last step took after its solve (reading back, integrating): a little at
 * least, cadmm then runs its few sweeps and hands back their best answer. */
static cadmm_result limit_solve(cadmm_ode *ctx) {
    if (!(ctx->opt.time_limit > 0)) return CADMM_OK;
    double left = ctx->opt.time_limit - (seconds_now() - ctx->assembly_start) - ctx->after_solve;
    cadmm_result rc = cadmm_settings_set_time_limit(ctx->settings, left > 1e-6 ? left : 1e-6);
    if (rc == CADMM_OK) rc = cadmm_solver_update_settings(ctx->solver, ctx->settings);
    if (rc == CADMM_OK) rc = cadmm_settings_set_time_limit(ctx->settings, ctx->opt.time_limit);
    return rc == CADMM_OK ? rc : fail_cadmm(ctx, rc, "cadmm_solver_update_settings");
}

/* The joint rows' bounds, compliance and rolling coefficients are those the solver holds. */
static bool same_limits(const cadmm_ode *ctx) {
    size_t bytes = ctx->n_rows * sizeof(double);
    return bytes == 0 || (memcmp(ctx->jlo.data, ctx->solver_lo.data, bytes) == 0 &&
                          memcmp(ctx->jhi.data, ctx->solver_hi.data, bytes) == 0 &&
                          memcmp(ctx->jc.data, ctx->solver_c.data, bytes) == 0 &&
                          memcmp(ctx->jfe.data, ctx->solver_e.data, bytes) == 0);
}

static cadmm_result keep_limits(cadmm_ode *ctx) {
    size_t nr = ctx->n_rows;
    if (!reserve(&ctx->solver_lo, nr, sizeof(double)) ||
        !reserve(&ctx->solver_hi, nr, sizeof(double)) ||
        !reserve(&ctx->solver_c, nr, sizeof(double)) ||
        !reserve(&ctx->solver_e, nr, sizeof(double)))
        return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    memcpy(ctx->solver_lo.data, ctx->jlo.data, nr * sizeof(double));
    memcpy(ctx->solver_hi.data, ctx->jhi.data, nr * sizeof(double));
    memcpy(ctx->solver_c.data, ctx->jc.data, nr * sizeof(double));
    memcpy(ctx->solver_e.data, ctx->jfe.data, nr * sizeof(double));
    return CADMM_OK;
}

/* The solver rebuilt for the assembled problem (in the memory it holds; a new one the first
 * time), its pattern and limits kept. A failure leaves no solver, so the next step builds
 * one. */
static cadmm_result rebuild(cadmm_ode *ctx) {
    ctx->solver_pattern_len = 0;
    cadmm_result rc = build_problem(ctx);
    if (rc == CADMM_OK && ctx->solver) {
        rc = cadmm_solver_rebuild(ctx->solver, ctx->problem);
        if (rc != CADMM_OK) rc = fail_cadmm(ctx, rc, "cadmm_solver_rebuild");
    } else if (rc == CADMM_OK) {
        rc = cadmm_solver_new(ctx->problem, ctx->settings, &ctx->solver);
        if (rc != CADMM_OK) rc = fail_cadmm(ctx, rc, "cadmm_solver_new");
    }
    if (rc != CADMM_OK) {
        cadmm_solver_free(ctx->solver);
        ctx->solver = NULL;
        return rc;
    }
    if (!reserve(&ctx->solver_pattern, ctx->pattern_len, sizeof(long)))
        return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    memcpy(ctx->solver_pattern.data, ctx->pattern.data, ctx->pattern_len * sizeof(long));
    ctx->solver_pattern_len = ctx->pattern_len;
    return keep_limits(ctx);
}

/* Builds a new solver or gives the current one the step's values (same pattern: same
 * order of the M, H and G values, same rows bounded) through cadmm_solver_update_values,
 * with cadmm_solver_update_joint_rows when a bound or a compliance changed: numeric
 * refactorization only. Then warm starts and solves, within the time limit. */
static cadmm_result solve_step(cadmm_ode *ctx, cadmm_ode_step_info *info) {
    cadmm_result rc;
    bool joints = ctx->n_rows > 0;
    info->rebuilt = !same_pattern(ctx);
    if (info->rebuilt) {
        rc = rebuild(ctx);
        if (rc != CADMM_OK) return rc;
    } else {
        rc = cadmm_solver_update_values(ctx->solver, ctx->m_values.data, ctx->h_values.data,
                                        joints ? ctx->g_values.data : NULL, ctx->f.data,
                                        ctx->w.data, joints ? ctx->jb.data : NULL, ctx->mu.data);
        if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_update_values");
        if (!same_limits(ctx)) {
            rc = cadmm_solver_update_joint_rows(ctx->solver, ctx->jlo.data, ctx->jhi.data,
                                                ctx->jc.data);
            if (rc == CADMM_OK && ctx->any_contact_bounds)
                rc = cadmm_solver_update_joint_friction(ctx->solver, ctx->jfe.data);
            if (rc == CADMM_ERR_PATTERN_CHANGED) { /* cadmm's own check of the bounded rows */
                info->rebuilt = true;
                rc = rebuild(ctx);
                if (rc != CADMM_OK) return rc;
            } else if (rc != CADMM_OK) {
                return fail_cadmm(ctx, rc, "cadmm_solver_update_joint_rows");
            }
            rc = keep_limits(ctx);
            if (rc != CADMM_OK) return rc;
        }
    }
    /* Warm start: the previous step's matched impulses (zero for new contacts), and the
     * bodies' velocities, which a joint's rows mostly keep from step to step (the joint
     * rows' multipliers start from zero). */
    if (ctx->opt.warm_start && (ctx->n_previous > 0 || joints)) {
        long matched = 0;
        if (ctx->n_previous > 0) {
            if (!reserve(&ctx->used, ctx->n_previous, 1))
                return fail(ctx, CADMM_ERR_PANIC, "out of memory");
            matched = match_previous(ctx, ctx->r0.data);
            if (matched < 0) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
        } else {
            memset(ctx->r0.data, 0, 3 * ctx->n_contacts * sizeof(double));
        }
        info->warm_matched = (size_t)matched;
        if (matched > 0 || joints) {
            rc = cadmm_solver_warm_start(ctx->solver, ctx->r0.data, ctx->v.data);
            if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_warm_start");
        }
    }
    rc = limit_solve(ctx);
    if (rc != CADMM_OK) return rc;
    rc = cadmm_solver_solve(ctx->solver, &info->status);
    if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_solve");
    cadmm_stats stats = {.struct_size = sizeof stats};
    rc = cadmm_solver_get_stats(ctx->solver, &stats);
    if (rc == CADMM_OK) rc = cadmm_solver_get_solution(ctx->solver, ctx->r.data, NULL, ctx->v.data);
    if (rc == CADMM_OK && joints)
        rc = cadmm_solver_get_joint_multipliers(ctx->solver, ctx->lambda.data, NULL);
    if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_get_solution");
    info->solved = true;
    info->iterations = stats.iterations;
    info->error = stats.error;
    return CADMM_OK;
}

/* The joints' dJointFeedback, where set: the force and torque G lambda / h of each row on
 * each body, f1/t1 on ODE's first body as ODE fills them (the world side of a joint
 * attached to it is left zero). */
static void fill_feedback(cadmm_ode *ctx) {
    const joint *js = ctx->joints.data;
    const joint_row *rows = ctx->rows.data;
    const double *lambda = ctx->lambda.data;
    for (size_t j = 0; j < ctx->n_joints; j++) {
        dJointFeedback *fb = dJointGetFeedback(js[j].id);
        if (!fb) continue;
        double sum[12] = {0};
        for (size_t k = js[j].first_row; k < js[j].first_row + js[j].n_rows; k++)
            for (int i = 0; i < 6; i++) {
                sum[i] += rows[k].ga[i] * lambda[k] / ctx->h;
                if (js[j].slot_b >= 0) sum[6 + i] += rows[k].gb[i] * lambda[k] / ctx->h;
            }
        for (int i = 0; i < 3; i++) {
            fb->f1[i] = sum[i];
            fb->t1[i] = sum[3 + i];
            fb->f2[i] = sum[6 + i];
            fb->t2[i] = sum[9 + i];
        }
    }
}

/* Semi-implicit Euler: x += h v, q += h/2 (0, omega) q then normalized, as ODE's own step
 * does without finite rotation. Force accumulators are cleared like after a world step. */
static void integrate(dBodyID b, const double v[6], double h) {
    const dReal *x = dBodyGetPosition(b), *q = dBodyGetQuaternion(b);
    const double *om = &v[3];
    dQuaternion nq = {q[0] - 0.5 * h * (om[0] * q[1] + om[1] * q[2] + om[2] * q[3]),
                      q[1] + 0.5 * h * (om[0] * q[0] + om[1] * q[3] - om[2] * q[2]),
                      q[2] + 0.5 * h * (om[1] * q[0] + om[2] * q[1] - om[0] * q[3]),
                      q[3] + 0.5 * h * (om[2] * q[0] + om[0] * q[2] - om[1] * q[1])};
    double len = sqrt(nq[0] * nq[0] + nq[1] * nq[1] + nq[2] * nq[2] + nq[3] * nq[3]);
    for (int i = 0; i < 4; i++) nq[i] /= len;
    dBodySetLinearVel(b, v[0], v[1], v[2]);
    dBodySetAngularVel(b, v[3], v[4], v[5]);
    dBodySetPosition(b, x[0] + h * v[0], x[1] + h * v[1], x[2] + h * v[2]);
    dBodySetQuaternion(b, nq);
    dBodySetForce(b, 0, 0, 0);
    dBodySetTorque(b, 0, 0, 0);
}

cadmm_result cadmm_ode_solve(cadmm_ode *ctx, cadmm_ode_step_info *info) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if (!info) return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_solve: NULL info");
    if (!ctx->world) return fail(ctx, CADMM_ERR_UNSUPPORTED, "cadmm_ode_solve: nothing assembled");
    *info = (cadmm_ode_step_info){.contacts = ctx->n_contacts, .joints = ctx->n_joints,
                                  .joint_rows = ctx->n_rows, .bodies = ctx->n_slots};
    bool solve = ctx->n_contacts > 0 || ctx->n_rows > 0;
    double solved_at = seconds_now();
    if (solve) {
        cadmm_result rc = solve_step(ctx, info);
        if (rc != CADMM_OK) return rc;
        solved_at = seconds_now();
        fill_feedback(ctx);
    }
    /* Bodies in the problem take cadmm's velocities, the others move freely: M v = f. */
    const dBodyID *bodies = ctx->bodies.data;
    const long *body_slot = ctx->body_slot.data;
    const double *v = ctx->v.data;
    for (size_t i = 0; i < ctx->n_bodies; i++) {
        double vb[6];
        if (body_slot[i] >= 0 && solve) {
            memcpy(vb, &v[6 * body_slot[i]], sizeof vb);
        } else {
            body_state st;
            body_state_of(ctx->world, bodies[i], ctx->h, &st);
            for (int k = 0; k < 3; k++) vb[k] = st.f[k] / st.mass;
            solve3(st.inertia, &st.f[3], &vb[3]);
        }
        integrate(bodies[i], vb, ctx->h);
    }
    /* Keep this step's impulses, in world coordinates, for the next warm start. */
    contact *cs = ctx->contacts.data;
    const double *r = ctx->r.data;
    for (size_t c = 0; c < ctx->n_contacts; c++)
        for (int d = 0; d < 3; d++)
            cs[c].impulse[d] = r[3 * c] * cs[c].n[d] + r[3 * c + 1] * cs[c].t1[d] +
                               r[3 * c + 2] * cs[c].t2[d];
    if (!reserve(&ctx->previous, ctx->n_contacts, sizeof(contact)))
        return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    if (ctx->n_contacts) memcpy(ctx->previous.data, cs, ctx->n_contacts * sizeof(contact));
    ctx->n_previous = ctx->n_contacts;
    ctx->world = NULL; /* a step consumes its assembly */
    ctx->after_solve = seconds_now() - solved_at;
    return CADMM_OK;
}

cadmm_result cadmm_ode_step(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                            size_t n_bodies, const dContactGeom *contacts, size_t n_contacts,
                            double h, cadmm_ode_step_info *info) {
    cadmm_result rc = cadmm_ode_assemble(ctx, world, bodies, n_bodies, contacts, n_contacts, h);
    return rc == CADMM_OK ? cadmm_ode_solve(ctx, info) : rc;
}

cadmm_result cadmm_ode_impulses(cadmm_ode *ctx, double *r) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if (!r && ctx->n_contacts)
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_impulses: NULL r");
    if (ctx->n_contacts) memcpy(r, ctx->r.data, 3 * ctx->n_contacts * sizeof *r);
    return CADMM_OK;
}

cadmm_result cadmm_ode_joint_multipliers(cadmm_ode *ctx, double *lambda) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if (!lambda && ctx->n_rows)
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_joint_multipliers: NULL lambda");
    if (ctx->n_rows) memcpy(lambda, ctx->lambda.data, ctx->n_rows * sizeof *lambda);
    return CADMM_OK;
}

cadmm_result cadmm_ode_joint_rows(const cadmm_ode *ctx, dJointID j, size_t *first,
                                  size_t *count) {
    if (!ctx || !first || !count) return CADMM_ERR_NULL_POINTER;
    *first = *count = 0;
    const joint *js = ctx->joints.data;
    for (size_t k = 0; k < ctx->n_joints; k++)
        if (js[k].id == j) {
            *first = js[k].first_row;
            *count = js[k].n_rows;
        }
    return CADMM_OK;
}

/* The measure on the last assembled problem of r, the bodies' current velocities and
 * lambda (NULL: cadmm's least-squares multipliers). */
static cadmm_result measure(cadmm_ode *ctx, const double *r, const double *lambda,
                            double *error) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if ((!r && ctx->n_contacts) || !error)
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_error: NULL %s", !error ? "error" : "r");
    if ((ctx->n_contacts == 0 && ctx->n_rows == 0) || !ctx->assembled) {
        *error = 0.0;
        return CADMM_OK;
    }
    cadmm_result rc = build_problem(ctx);
    if (rc != CADMM_OK) return rc;
    const dBodyID *bodies = ctx->bodies.data;
    const size_t *slot_body = ctx->slot_body.data;
    double *v = ctx->v.data;
    for (size_t s = 0; s < ctx->n_slots; s++) {
        const dReal *lv = dBodyGetLinearVel(bodies[slot_body[s]]);
        const dReal *av = dBodyGetAngularVel(bodies[slot_body[s]]);
        for (int k = 0; k < 3; k++) {
            v[6 * s + k] = lv[k];
            v[6 * s + 3 + k] = av[k];
        }
    }
    /* An empty array is a valid pointer for cadmm. */
    const double *rr = ctx->n_contacts ? r : ctx->r.data;
    if (lambda) {
        rc = cadmm_problem_error_with_multipliers(ctx->problem, rr, v, lambda, error);
        return rc == CADMM_OK ? CADMM_OK
                              : fail_cadmm(ctx, rc, "cadmm_problem_error_with_multipliers");
    }
    rc = cadmm_problem_error(ctx->problem, rr, NULL, v, error);
    return rc == CADMM_OK ? CADMM_OK : fail_cadmm(ctx, rc, "cadmm_problem_error");
}

cadmm_result cadmm_ode_error(cadmm_ode *ctx, const double *r, double *error) {
    return measure(ctx, r, NULL, error);
}

cadmm_result cadmm_ode_error_with_multipliers(cadmm_ode *ctx, const double *r,
                                              const double *lambda, double *error) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if (!lambda && ctx->n_rows)
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_error_with_multipliers: NULL lambda");
    return measure(ctx, r, ctx->n_rows ? lambda : ctx->lambda.data, error);
}

cadmm_result cadmm_ode_last_problem(const cadmm_ode *ctx, cadmm_ode_problem *out) {
    if (!ctx || !out) return CADMM_ERR_NULL_POINTER;
    *out = (cadmm_ode_problem){0};
    if (!ctx->assembled || (ctx->n_contacts == 0 && ctx->n_rows == 0)) return CADMM_OK;
    size_t n = 6 * ctx->n_slots, nc = ctx->n_contacts, nr = ctx->n_rows;
    out->n = n;
    out->n_contacts = nc;
    out->n_joint_rows = nr;
    out->M = (cadmm_csc){n, n, ctx->m_colptr.data, ctx->m_rowind.data, ctx->m_values.data};
    out->H = (cadmm_csc){n, 3 * nc, ctx->h_colptr.data, ctx->h_rowind.data, ctx->h_values.data};
    out->G = (cadmm_csc){n, nr, ctx->g_colptr.data, ctx->g_rowind.data, ctx->g_values.data};
    out->f = ctx->f.data;
    out->w = ctx->w.data;
    out->mu = ctx->mu.data;
    out->b = ctx->jb.data;
    out->lo = ctx->jlo.data;
    out->hi = ctx->jhi.data;
    out->c = ctx->jc.data;
    out->body_index = ctx->slot_body.data;
    out->friction_contact = ctx->jfc.data;
    out->friction = ctx->jfe.data;
    return CADMM_OK;
}
