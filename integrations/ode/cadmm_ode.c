/* cadmm_ode: ODE world step with cadmm contact impulses (see cadmm_ode.h). */
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

struct cadmm_ode {
    cadmm_ode_options opt;
    cadmm_settings *settings;
    cadmm_solver *solver;
    cadmm_problem *problem; /* built from the assembled arrays only when needed */
    char message[512];

    /* The assembled step. */
    dWorldID world;
    bool assembled; /* the arrays below hold a complete assembly */
    double h;
    size_t n_bodies, n_slots, n_contacts;
    buffer bodies;    /* dBodyID per body */
    buffer keys;      /* body_key, sorted by id */
    buffer body_slot; /* long per body: its slot or -1 */
    buffer slot_body; /* size_t per slot: its body */
    buffer contacts;  /* contact */
    buffer m_colptr, m_rowind, m_values, h_colptr, h_rowind, h_values;
    buffer f, w, mu, r, v, r0;

    /* The pattern the solver was built for: slots, then (slot1, slot2) per contact. */
    buffer pattern, solver_pattern;
    size_t pattern_len, solver_pattern_len;

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
    buffer *all[] = {&ctx->bodies,   &ctx->keys,     &ctx->body_slot, &ctx->slot_body,
                     &ctx->contacts, &ctx->m_colptr, &ctx->m_rowind,  &ctx->m_values,
                     &ctx->h_colptr, &ctx->h_rowind, &ctx->h_values,  &ctx->f,
                     &ctx->w,        &ctx->mu,       &ctx->r,         &ctx->v,
                     &ctx->r0,       &ctx->pattern,  &ctx->solver_pattern,
                     &ctx->previous, &ctx->used,     &ctx->pair_keys};
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

static cadmm_result read_contacts(cadmm_ode *ctx, const dContactGeom *geoms, size_t nc) {
    contact *cs = ctx->contacts.data;
    long *body_slot = ctx->body_slot.data;
    for (size_t c = 0; c < nc; c++) {
        const dContactGeom *g = &geoms[c];
        contact *k = &cs[c];
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
            for (int side = 0; side < 2; side++) {
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

cadmm_result cadmm_ode_assemble(cadmm_ode *ctx, dWorldID world, const dBodyID *bodies,
                                size_t n_bodies, const dContactGeom *geoms, size_t nc,
                                double h) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
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
    cadmm_result rc = read_contacts(ctx, geoms, nc);
    if (rc != CADMM_OK) return rc;

    /* Slots in body order, so that the pattern is stable while the contacts are. */
    size_t *slot_body = ctx->slot_body.data, ns = 0;
    for (size_t i = 0; i < n_bodies; i++)
        if (body_slot[i] == 0) {
            body_slot[i] = (long)ns;
            slot_body[ns++] = i;
        }
    ctx->n_slots = ns;
    contact *cs = ctx->contacts.data;
    long *pattern = reserve(&ctx->pattern, 1 + 2 * nc + ns, sizeof *pattern);
    if (!pattern) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
    pattern[0] = (long)ns;
    for (size_t c = 0; c < nc; c++) {
        cs[c].slot1 = body_slot[cs[c].slot1];
        cs[c].slot2 = cs[c].slot2 >= 0 ? body_slot[cs[c].slot2] : -1;
        pattern[1 + 2 * c] = cs[c].slot1;
        pattern[2 + 2 * c] = cs[c].slot2;
    }
    for (size_t s = 0; s < ns; s++) pattern[1 + 2 * nc + s] = (long)slot_body[s];
    ctx->pattern_len = 1 + 2 * nc + ns;
    if (nc == 0) {
        ctx->world = world;
        ctx->assembled = true;
        return CADMM_OK;
    }

    size_t n = 6 * ns, h_nnz = 0;
    for (size_t c = 0; c < nc; c++) h_nnz += 3 * 6 * (cs[c].slot2 >= 0 ? 2 : 1);
    if (!reserve(&ctx->m_colptr, n + 1, sizeof(int64_t)) ||
        !reserve(&ctx->m_rowind, 12 * ns, sizeof(int64_t)) ||
        !reserve(&ctx->m_values, 12 * ns, sizeof(double)) ||
        !reserve(&ctx->h_colptr, 3 * nc + 1, sizeof(int64_t)) ||
        !reserve(&ctx->h_rowind, h_nnz, sizeof(int64_t)) ||
        !reserve(&ctx->h_values, h_nnz, sizeof(double)) || !reserve(&ctx->f, n, sizeof(double)) ||
        !reserve(&ctx->v, n, sizeof(double)) || !reserve(&ctx->w, 3 * nc, sizeof(double)) ||
        !reserve(&ctx->r, 3 * nc, sizeof(double)) || !reserve(&ctx->r0, 3 * nc, sizeof(double)) ||
        !reserve(&ctx->mu, nc, sizeof(double)))
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

    /* ODE's contact joint right-hand side: push out at ERP of the depth beyond the surface
     * layer per step, capped at the maximum correcting velocity. */
    double erp = dWorldGetERP(world), layer = dWorldGetContactSurfaceLayer(world);
    double max_vel = dWorldGetContactMaxCorrectingVel(world);
    double *w = ctx->w.data, *mu = ctx->mu.data;
    for (size_t c = 0; c < nc; c++) {
        double depth = geoms[c].depth - layer;
        double push = depth > 0 ? erp * depth / h : 0.0;
        w[3 * c] = -(push < max_vel ? push : max_vel);
        w[3 * c + 1] = w[3 * c + 2] = 0.0;
        mu[c] = ctx->opt.mu;
    }
    ctx->world = world;
    ctx->assembled = true;
    return CADMM_OK;
}

/* The cadmm problem of the assembled arrays, built on first use. */
static cadmm_result build_problem(cadmm_ode *ctx) {
    if (ctx->problem) return CADMM_OK;
    size_t n = 6 * ctx->n_slots, nc = ctx->n_contacts;
    cadmm_csc M = {n, n, ctx->m_colptr.data, ctx->m_rowind.data, ctx->m_values.data};
    cadmm_csc H = {n, 3 * nc, ctx->h_colptr.data, ctx->h_rowind.data, ctx->h_values.data};
    cadmm_result rc = cadmm_problem_new_global(n, nc, &M, &H, ctx->f.data, ctx->w.data,
                                               ctx->mu.data, &ctx->problem);
    return rc == CADMM_OK ? CADMM_OK : fail_cadmm(ctx, rc, "cadmm_problem_new_global");
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

static double seconds_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* With a time limit, gives the solve what building and updating left of it (a little at
 * least: cadmm then runs its few sweeps and hands back their best answer). */
static cadmm_result limit_solve(cadmm_ode *ctx, double start) {
    if (!(ctx->opt.time_limit > 0)) return CADMM_OK;
    double left = ctx->opt.time_limit - (seconds_now() - start);
    cadmm_result rc = cadmm_settings_set_time_limit(ctx->settings, left > 1e-6 ? left : 1e-6);
    if (rc == CADMM_OK) rc = cadmm_solver_update_settings(ctx->solver, ctx->settings);
    if (rc == CADMM_OK) rc = cadmm_settings_set_time_limit(ctx->settings, ctx->opt.time_limit);
    return rc == CADMM_OK ? rc : fail_cadmm(ctx, rc, "cadmm_solver_update_settings");
}

/* Builds a new solver or gives the current one the step's values (same pattern: same
 * order of the M and H values), warm starts it and solves, within the time limit. */
static cadmm_result solve_contacts(cadmm_ode *ctx, cadmm_ode_step_info *info) {
    const double start = seconds_now();
    cadmm_result rc;
    info->rebuilt = !same_pattern(ctx);
    if (info->rebuilt) {
        cadmm_solver_free(ctx->solver);
        ctx->solver = NULL;
        ctx->solver_pattern_len = 0;
        rc = build_problem(ctx);
        if (rc != CADMM_OK) return rc;
        rc = cadmm_solver_new(ctx->problem, ctx->settings, &ctx->solver);
        if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_new");
        if (!reserve(&ctx->solver_pattern, ctx->pattern_len, sizeof(long)))
            return fail(ctx, CADMM_ERR_PANIC, "out of memory");
        memcpy(ctx->solver_pattern.data, ctx->pattern.data, ctx->pattern_len * sizeof(long));
        ctx->solver_pattern_len = ctx->pattern_len;
    } else {
        rc = cadmm_solver_update_values(ctx->solver, ctx->m_values.data, ctx->h_values.data, NULL,
                                        ctx->f.data, ctx->w.data, NULL, ctx->mu.data);
        if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_update_values");
    }
    if (ctx->opt.warm_start && ctx->n_previous > 0) {
        if (!reserve(&ctx->used, ctx->n_previous, 1))
            return fail(ctx, CADMM_ERR_PANIC, "out of memory");
        long matched = match_previous(ctx, ctx->r0.data);
        if (matched < 0) return fail(ctx, CADMM_ERR_PANIC, "out of memory");
        info->warm_matched = (size_t)matched;
        if (info->warm_matched > 0) {
            rc = cadmm_solver_warm_start(ctx->solver, ctx->r0.data, ctx->v.data);
            if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_warm_start");
        }
    }
    rc = limit_solve(ctx, start);
    if (rc != CADMM_OK) return rc;
    rc = cadmm_solver_solve(ctx->solver, &info->status);
    if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_solve");
    cadmm_stats stats = {.struct_size = sizeof stats};
    rc = cadmm_solver_get_stats(ctx->solver, &stats);
    if (rc == CADMM_OK) rc = cadmm_solver_get_solution(ctx->solver, ctx->r.data, NULL, ctx->v.data);
    if (rc != CADMM_OK) return fail_cadmm(ctx, rc, "cadmm_solver_get_solution");
    info->solved = true;
    info->iterations = stats.iterations;
    info->error = stats.error;
    return CADMM_OK;
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
    *info = (cadmm_ode_step_info){.contacts = ctx->n_contacts, .bodies = ctx->n_slots};
    if (ctx->n_contacts > 0) {
        cadmm_result rc = solve_contacts(ctx, info);
        if (rc != CADMM_OK) return rc;
    }
    /* Bodies in the problem take cadmm's velocities, the others move freely: M v = f. */
    const dBodyID *bodies = ctx->bodies.data;
    const long *body_slot = ctx->body_slot.data;
    const double *v = ctx->v.data;
    for (size_t i = 0; i < ctx->n_bodies; i++) {
        double vb[6];
        if (body_slot[i] >= 0 && ctx->n_contacts > 0) {
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

cadmm_result cadmm_ode_error(cadmm_ode *ctx, const double *r, double *error) {
    if (!ctx) return CADMM_ERR_NULL_POINTER;
    if ((!r && ctx->n_contacts) || !error)
        return fail(ctx, CADMM_ERR_NULL_POINTER, "cadmm_ode_error: NULL %s", !error ? "error" : "r");
    if (ctx->n_contacts == 0 || !ctx->assembled) {
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
    rc = cadmm_problem_error(ctx->problem, r, NULL, v, error);
    return rc == CADMM_OK ? CADMM_OK : fail_cadmm(ctx, rc, "cadmm_problem_error");
}

cadmm_result cadmm_ode_last_problem(const cadmm_ode *ctx, cadmm_ode_problem *out) {
    if (!ctx || !out) return CADMM_ERR_NULL_POINTER;
    *out = (cadmm_ode_problem){0};
    if (!ctx->assembled || ctx->n_contacts == 0) return CADMM_OK;
    size_t n = 6 * ctx->n_slots, nc = ctx->n_contacts;
    out->n = n;
    out->n_contacts = nc;
    out->M = (cadmm_csc){n, n, ctx->m_colptr.data, ctx->m_rowind.data, ctx->m_values.data};
    out->H = (cadmm_csc){n, 3 * nc, ctx->h_colptr.data, ctx->h_rowind.data, ctx->h_values.data};
    out->f = ctx->f.data;
    out->w = ctx->w.data;
    out->mu = ctx->mu.data;
    out->body_index = ctx->slot_body.data;
    return CADMM_OK;
}
