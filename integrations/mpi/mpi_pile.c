/*
 * mpi_pile: a sphere pile stepped by a host engine that runs on several MPI processes,
 * with every step's contact impulses from cadmm's distributed solver (cadmm.h, built with
 * CADMM_WITH_MPI).
 *
 * What it shows: each process keeps only its slab of the pile (the bodies whose x position
 * falls in its share of the x range, and the contacts whose first body it owns), names
 * bodies by global ids, and hands its part to cadmm_distributed_solver_new. Contacts that
 * cross a slab boundary name the neighbouring process's bodies by id; the host only
 * exchanges those bodies' positions (a halo) to compute the contacts' frames and gaps, and
 * cadmm does the rest of the communication. Bodies have ids 1000 + 7 * (lattice index);
 * slabs are fixed at the start (a pile at rest stays put; an engine whose bodies travel
 * would move them between processes). Each step every process fills its cadmm_rank_part
 * and makes the same collective calls: cadmm_distributed_solver_new, _warm_start from the
 * last step's impulses of its contacts, _solve; then it reads its bodies' velocities and
 * frees the solver.
 *
 *   mpirun -np 4 ./mpi_pile [--nx 16 --ny 8 --nz 4] [--steps 50] [--tolerance 1e-6]
 *                           [--every 10]
 *   mpirun --hostfile hosts -np 64 ./mpi_pile --nx 256 --ny 64 --nz 8 --steps 100
 *
 * The scene mirrors scenes::pile of examples/extreme/scenes.rs: an nx x ny x nz lattice of
 * spheres of radius 0.5 one apart, resting on the floor z = 0, masses 0.5 to 1.5 from the
 * same fixed xorshift sequence (but starting at rest: scenes::pile's small initial
 * velocities are left out), rigid bodies with 6 velocities each (v, omega; world frame,
 * M diagonal, inertia 0.1 m), gravity 9.81, friction 0.5, time step h = 0.01. The
 * contacts are fixed (each sphere with the one below or the floor, and with its -x and -y
 * neighbours); their normals, points and gaps are recomputed from the positions each step.
 * A contact of body a on body b (or the floor) has its normal from b to a, FCLib frame
 * (n, t1, t2), u = H^T v + w the velocity of a relative to b, w = (gap / h, 0, 0) so that
 * the gap may close within the step but not be crossed, and M v = f + H r with
 * f = M v_prev + h F. Semi-implicit Euler: positions move by h v with the new v
 * (orientations are not tracked: spheres).
 *
 * Rank 0 prints every --every steps (and any unsolved one) the status, iterations, error,
 * and the slowest process's seconds in setup (_new and _warm_start) and _solve, then a
 * summary. Exit code, the same on every process: 0 when every step solved and the pile
 * stayed at rest (sphere centres between radius - 0.01 and their resting top + 0.01, none
 * moved more than 0.05 from its start, everything finite), 1 when not, 2 for bad
 * arguments or a failed call.
 */
#include <cadmm.h>
#include <mpi.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RADIUS 0.5
#define GRAVITY 9.81
#define STEP 0.01
#define MU 0.5
#define DOFS 6
#define ID_BASE 1000u
#define ID_STRIDE 7u
#define NO_BODY SIZE_MAX
/* The pile check: how far below its resting height a sphere may sink, how far any sphere
 * may move from where it started. */
#define MAX_SINK 0.01
#define MAX_MOVE 0.05

typedef double v3[3];

/* ---------------------------------------------------------------- small vector helpers */

static void cross(const v3 p, const v3 d, v3 out) {
    out[0] = p[1] * d[2] - p[2] * d[1];
    out[1] = p[2] * d[0] - p[0] * d[2];
    out[2] = p[0] * d[1] - p[1] * d[0];
}

static double norm3(const v3 p) { return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); }

/* Orthonormal contact frame (n, t1, t2), t2 = n x t1, as scenes.rs's frame(). */
static void frame(const v3 normal, v3 out[3]) {
    double len = norm3(normal);
    v3 n = {normal[0] / len, normal[1] / len, normal[2] / len};
    v3 helper = {0.0, 0.0, 0.0};
    v3 t1;
    helper[fabs(n[0]) < 0.9 ? 0 : 1] = 1.0;
    cross(helper, n, t1);
    len = norm3(t1);
    for (int i = 0; i < 3; i++) {
        out[0][i] = n[i];
        out[1][i] = t1[i] / len;
    }
    cross(out[0], out[1], out[2]);
}

/* Deterministic uniform numbers in [0, 1): xorshift64, the sequence of scenes.rs. */
static double uniform(uint64_t *seed) {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    return (double)(*seed >> 11) / (double)(UINT64_C(1) << 53);
}

/* ------------------------------------------------------- body ids -> local slots (hash) */

/* Open addressing from a body's global id to its slot in this process's body arrays
 * (owned bodies first, then the neighbours' bodies its contacts reach). */
typedef struct id_map {
    uint64_t *keys;
    size_t *slots;
    size_t cap; /* a power of two, at least twice the entries */
} id_map;

static size_t id_hash(uint64_t id, size_t cap) {
    return (size_t)((id * UINT64_C(0x9E3779B97F4A7C15)) >> 17) & (cap - 1);
}

static int map_init(id_map *m, size_t entries) {
    m->cap = 16;
    while (m->cap < 2 * entries + 2) m->cap *= 2;
    m->keys = calloc(m->cap, sizeof *m->keys);
    m->slots = malloc(m->cap * sizeof *m->slots);
    if (!m->keys || !m->slots) return -1;
    for (size_t i = 0; i < m->cap; i++) m->slots[i] = NO_BODY;
    return 0;
}

static size_t map_get(const id_map *m, uint64_t id) {
    for (size_t h = id_hash(id, m->cap);; h = (h + 1) & (m->cap - 1)) {
        if (m->slots[h] == NO_BODY) return NO_BODY;
        if (m->keys[h] == id) return m->slots[h];
    }
}

/* Inserts id -> slot unless id is there; the map never fills (sized for every entry). */
static void map_put(id_map *m, uint64_t id, size_t slot) {
    size_t h = id_hash(id, m->cap);
    while (m->slots[h] != NO_BODY && m->keys[h] != id) h = (h + 1) & (m->cap - 1);
    if (m->slots[h] == NO_BODY) {
        m->keys[h] = id;
        m->slots[h] = slot;
    }
}

static void map_free(id_map *m) {
    free(m->keys);
    free(m->slots);
}

/* ---------------------------------------------------------------------------- the pile */

typedef struct options {
    long nx, ny, nz, steps, every;
    double tolerance;
} options;

/* A contact this process owns: body a (owned slot), body b (slot, owned or a
 * neighbour's; NO_BODY for the floor). */
typedef struct contact {
    size_t a, b;
} contact;

/* This process's share of the pile. Slots 0..n_owned-1 are its bodies, n_owned..n_known-1
 * the neighbours' bodies its contacts reach (ghosts: positions only). */
typedef struct slab {
    int rank, size;
    size_t n_owned, n_known, n_contacts;
    uint64_t *id;   /* n_known */
    v3 *x;          /* n_known positions */
    v3 *x0;         /* n_owned starting positions */
    double *mass;   /* n_owned */
    double *vel;    /* n_owned * DOFS: v, omega */
    contact *contacts;
    id_map map;
    /* The halo: the owned bodies whose positions go to each process (grouped by
     * destination), and the ghosts whose positions come from each (grouped by source). */
    int *send_counts, *send_displs, *recv_counts, *recv_displs; /* in doubles */
    size_t *send_slots, *recv_slots;
    double *send_buf, *recv_buf;
} slab;

/* Which slab a position belongs to: equal widths of the lattice's x range, clamped. */
static int slab_of(double x, const options *o, int size) {
    double lo = 0.0, hi = (double)(o->nx - 1);
    double width = (hi - lo > 1e-9 ? hi - lo : 1e-9) / size;
    long s = (long)((x - lo) / width);
    return (int)(s < 0 ? 0 : s >= size ? size - 1 : s);
}

static uint64_t lattice_id(const options *o, long i, long j, long k) {
    return ID_BASE + ID_STRIDE * (uint64_t)((k * o->ny + j) * o->nx + i);
}

static void lattice_x(long i, long j, long k, v3 x) {
    x[0] = (double)i;
    x[1] = (double)j;
    x[2] = RADIUS + (double)k;
}

static void slab_free(slab *s) {
    free(s->id);
    free(s->x);
    free(s->x0);
    free(s->mass);
    free(s->vel);
    free(s->contacts);
    map_free(&s->map);
    free(s->send_counts);
    free(s->send_displs);
    free(s->recv_counts);
    free(s->recv_displs);
    free(s->send_slots);
    free(s->recv_slots);
    free(s->send_buf);
    free(s->recv_buf);
}

/* Generates the whole pile, keeping this process's slab; sets up the halo. 0 or -1 (out
 * of memory or a halo request for a body this process does not own; collective: every
 * process gets the same answer). */
static int slab_build(slab *s, const options *o) {
    long n_total = o->nx * o->ny * o->nz;
    int failed = 0;
    memset(s, 0, sizeof *s);
    MPI_Comm_rank(MPI_COMM_WORLD, &s->rank);
    MPI_Comm_size(MPI_COMM_WORLD, &s->size);
    /* Owned bodies: count, then fill (the random sequence runs over every body). */
    for (long i = 0; i < o->nx; i++)
        if (slab_of((double)i, o, s->size) == s->rank) s->n_owned += (size_t)(o->ny * o->nz);
    size_t max_known = s->n_owned + (size_t)(o->ny * o->nz); /* ghosts: one column at most */
    size_t max_contacts = 3 * s->n_owned;
    s->id = malloc((max_known + 1) * sizeof *s->id);
    s->x = malloc((max_known + 1) * sizeof *s->x);
    s->x0 = malloc((s->n_owned + 1) * sizeof *s->x0);
    s->mass = malloc((s->n_owned + 1) * sizeof *s->mass);
    s->vel = malloc((s->n_owned * DOFS + 1) * sizeof *s->vel);
    s->contacts = malloc((max_contacts + 1) * sizeof *s->contacts);
    s->send_counts = calloc((size_t)s->size, sizeof(int));
    s->send_displs = calloc((size_t)s->size, sizeof(int));
    s->recv_counts = calloc((size_t)s->size, sizeof(int));
    s->recv_displs = calloc((size_t)s->size, sizeof(int));
    int *ghost_owner = malloc((max_known + 1) * sizeof *ghost_owner);
    failed = !s->id || !s->x || !s->x0 || !s->mass || !s->vel || !s->contacts ||
             !s->send_counts || !s->send_displs || !s->recv_counts || !s->recv_displs ||
             !ghost_owner || map_init(&s->map, max_known) != 0;
    if (!failed) {
        uint64_t seed = UINT64_C(0x2545F4914F6CDD1D);
        size_t slot = 0;
        for (long b = 0; b < n_total; b++) {
            long i = b % o->nx, j = (b / o->nx) % o->ny, k = b / (o->nx * o->ny);
            double m = 0.5 + uniform(&seed);
            /* scenes::pile draws small initial velocities here; this pile starts at rest. */
            for (int skip = 0; skip < 3; skip++) (void)uniform(&seed);
            v3 x;
            lattice_x(i, j, k, x);
            if (slab_of(x[0], o, s->size) != s->rank) continue;
            s->id[slot] = lattice_id(o, i, j, k);
            memcpy(s->x[slot], x, sizeof x);
            memcpy(s->x0[slot], x, sizeof x);
            s->mass[slot] = m;
            double *v = s->vel + DOFS * slot;
            for (int d = 0; d < DOFS; d++) v[d] = 0.0;
            map_put(&s->map, s->id[slot], slot);
            slot++;
        }
        /* Contacts of the owned bodies, in the lattice's order: below (or the floor), -x,
         * -y. A neighbour in another slab becomes a ghost, remembered with its owner. */
        s->n_known = s->n_owned;
        for (size_t a = 0; a < s->n_owned; a++) {
            long i = lround(s->x[a][0]), j = lround(s->x[a][1]), k = lround(s->x[a][2] - RADIUS);
            long nb[3][3] = {{i, j, k - 1}, {i - 1, j, k}, {i, j - 1, k}};
            for (int c = 0; c < 3; c++) {
                long bi = nb[c][0], bj = nb[c][1], bk = nb[c][2];
                if (bi < 0 || bj < 0) continue;
                size_t b = NO_BODY;
                if (bk >= 0) {
                    uint64_t bid = lattice_id(o, bi, bj, bk);
                    b = map_get(&s->map, bid);
                    if (b == NO_BODY) {
                        v3 xb;
                        lattice_x(bi, bj, bk, xb);
                        b = s->n_known++;
                        s->id[b] = bid;
                        memcpy(s->x[b], xb, sizeof xb);
                        ghost_owner[b] = slab_of(xb[0], o, s->size);
                        map_put(&s->map, bid, b);
                    }
                }
                s->contacts[s->n_contacts++] = (contact){a, b};
            }
        }
    }
    /* The halo: tell each owner which of its bodies' positions this process needs. */
    size_t n_ghosts = failed ? 0 : s->n_known - s->n_owned;
    int *need = calloc((size_t)s->size, sizeof(int));
    int *give = calloc((size_t)s->size, sizeof(int));
    int *need_displs = calloc((size_t)s->size, sizeof(int));
    int *give_displs = calloc((size_t)s->size, sizeof(int));
    failed = failed || !need || !give || !need_displs || !give_displs;
    for (size_t g = 0; !failed && g < n_ghosts; g++) need[ghost_owner[s->n_owned + g]]++;
    /* The ghosts ordered by owner (counting sort): the order of the requests and of the
     * positions received each step. */
    uint64_t *need_ids = malloc((n_ghosts + 1) * sizeof *need_ids);
    s->recv_slots = malloc((n_ghosts + 1) * sizeof *s->recv_slots);
    s->recv_buf = malloc((3 * n_ghosts + 1) * sizeof *s->recv_buf);
    failed = failed || !need_ids || !s->recv_slots || !s->recv_buf;
    for (int r = 0; !failed && r < s->size; r++)
        need_displs[r] = r ? need_displs[r - 1] + need[r - 1] : 0;
    for (size_t g = 0; !failed && g < n_ghosts; g++) {
        size_t slot = s->n_owned + g;
        int owner = ghost_owner[slot];
        size_t k = (size_t)need_displs[owner] + (size_t)give[owner]++; /* give: a cursor here */
        need_ids[k] = s->id[slot];
        s->recv_slots[k] = slot;
    }
    for (int r = 0; !failed && r < s->size; r++) give[r] = 0;
    MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (failed) {
        free(need), free(give), free(need_displs), free(give_displs), free(ghost_owner);
        free(need_ids);
        return -1;
    }
    MPI_Alltoall(need, 1, MPI_INT, give, 1, MPI_INT, MPI_COMM_WORLD);
    int n_give = 0;
    for (int r = 0; r < s->size; r++) {
        give_displs[r] = n_give;
        n_give += give[r];
    }
    uint64_t *give_ids = malloc(((size_t)n_give + 1) * sizeof *give_ids);
    s->send_slots = malloc(((size_t)n_give + 1) * sizeof *s->send_slots);
    s->send_buf = malloc((3 * (size_t)n_give + 1) * sizeof *s->send_buf);
    failed = !give_ids || !s->send_slots || !s->send_buf;
    MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (!failed) {
        MPI_Alltoallv(need_ids, need, need_displs, MPI_UINT64_T, give_ids, give,
                      give_displs, MPI_UINT64_T, MPI_COMM_WORLD);
        for (int g = 0; g < n_give; g++) {
            s->send_slots[g] = map_get(&s->map, give_ids[g]);
            if (s->send_slots[g] == NO_BODY || s->send_slots[g] >= s->n_owned) {
                fprintf(stderr, "[rank %d] halo: body %llu asked for is not mine\n", s->rank,
                        (unsigned long long)give_ids[g]);
                failed = 1;
            }
        }
        for (int r = 0; r < s->size; r++) {
            s->send_counts[r] = 3 * give[r], s->send_displs[r] = 3 * give_displs[r];
            s->recv_counts[r] = 3 * need[r], s->recv_displs[r] = 3 * need_displs[r];
        }
        MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    }
    free(need), free(give), free(need_displs), free(give_displs), free(ghost_owner);
    free(need_ids), free(give_ids);
    return failed ? -1 : 0;
}

/* Refreshes the ghosts' positions from their owners (collective). */
static void halo_exchange(slab *s) {
    int n_send = 0, n_recv = 0;
    for (int r = 0; r < s->size; r++) n_send += s->send_counts[r], n_recv += s->recv_counts[r];
    for (int g = 0; g < n_send / 3; g++)
        memcpy(s->send_buf + 3 * g, s->x[s->send_slots[g]], sizeof(v3));
    MPI_Alltoallv(s->send_buf, s->send_counts, s->send_displs, MPI_DOUBLE, s->recv_buf,
                  s->recv_counts, s->recv_displs, MPI_DOUBLE, MPI_COMM_WORLD);
    for (int g = 0; g < n_recv / 3; g++)
        memcpy(s->x[s->recv_slots[g]], s->recv_buf + 3 * g, sizeof(v3));
}

/* ------------------------------------------------------------------- the rank's part */

/* Arrays of this process's cadmm_rank_part, allocated once for the fixed contact set. */
typedef struct part_arrays {
    size_t *dofs, *colptr, *h_dof;
    uint64_t *h_body;
    double *mass, *f, *h_values, *w, *mu;
} part_arrays;

static int part_alloc(part_arrays *p, const slab *s) {
    size_t nb = s->n_owned + 1, nc = s->n_contacts + 1;
    size_t entries = 3 * nc * 2 * DOFS; /* two bodies of 6 velocities per column at most */
    p->dofs = malloc(nb * sizeof *p->dofs);
    p->mass = calloc(nb * DOFS * DOFS, sizeof *p->mass);
    p->f = malloc(nb * DOFS * sizeof *p->f);
    p->colptr = malloc((3 * nc + 1) * sizeof *p->colptr);
    p->h_body = malloc(entries * sizeof *p->h_body);
    p->h_dof = malloc(entries * sizeof *p->h_dof);
    p->h_values = malloc(entries * sizeof *p->h_values);
    p->w = malloc(3 * nc * sizeof *p->w);
    p->mu = malloc(nc * sizeof *p->mu);
    return p->dofs && p->mass && p->f && p->colptr && p->h_body && p->h_dof && p->h_values &&
                   p->w && p->mu
               ? 0
               : -1;
}

static void part_free(part_arrays *p) {
    free(p->dofs), free(p->mass), free(p->f), free(p->colptr), free(p->h_body);
    free(p->h_dof), free(p->h_values), free(p->w), free(p->mu);
}

/* Fills the part for the current positions and velocities: M, f = M v + h F, H, w, mu. */
static cadmm_rank_part part_fill(part_arrays *p, const slab *s) {
    for (size_t b = 0; b < s->n_owned; b++) {
        double m = s->mass[b], inertia = 0.1 * m; /* 2/5 m r^2 at r = 0.5 */
        double diag[DOFS] = {m, m, m, inertia, inertia, inertia};
        double load[DOFS] = {0.0, 0.0, -m * GRAVITY, 0.0, 0.0, 0.0};
        p->dofs[b] = DOFS;
        for (int i = 0; i < DOFS; i++) {
            p->mass[DOFS * DOFS * b + (size_t)(DOFS * i + i)] = diag[i]; /* column-major */
            p->f[DOFS * b + (size_t)i] = diag[i] * s->vel[DOFS * b + (size_t)i] + STEP * load[i];
        }
    }
    size_t e = 0;
    for (size_t c = 0; c < s->n_contacts; c++) {
        size_t a = s->contacts[c].a, b = s->contacts[c].b;
        const double *xa = s->x[a];
        v3 normal = {0.0, 0.0, 1.0}, point;
        double gap;
        if (b == NO_BODY) { /* the floor: normal up, point midway across the gap */
            gap = xa[2] - RADIUS;
            point[0] = xa[0], point[1] = xa[1], point[2] = 0.5 * gap;
        } else { /* sphere on sphere: normal from b to a, point midway across the gap */
            const double *xb = s->x[b];
            v3 d = {xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]};
            double dist = norm3(d);
            gap = dist - 2.0 * RADIUS;
            for (int i = 0; i < 3; i++) {
                normal[i] = d[i] / dist;
                point[i] = xb[i] + (RADIUS + 0.5 * gap) * normal[i];
            }
        }
        v3 dirs[3];
        frame(normal, dirs);
        for (int j = 0; j < 3; j++) {
            p->colptr[3 * c + (size_t)j] = e;
            for (int side = 0; side < (b == NO_BODY ? 1 : 2); side++) {
                size_t body = side ? b : a;
                double sign = side ? -1.0 : 1.0;
                v3 arm, lever = {point[0] - s->x[body][0], point[1] - s->x[body][1],
                                 point[2] - s->x[body][2]};
                cross(lever, dirs[j], arm);
                for (int i = 0; i < 3; i++) {
                    if (dirs[j][i] != 0.0) {
                        p->h_body[e] = s->id[body], p->h_dof[e] = (size_t)i;
                        p->h_values[e++] = sign * dirs[j][i];
                    }
                    if (arm[i] != 0.0) {
                        p->h_body[e] = s->id[body], p->h_dof[e] = (size_t)(3 + i);
                        p->h_values[e++] = sign * arm[i];
                    }
                }
            }
            p->w[3 * c + (size_t)j] = j == 0 ? gap / STEP : 0.0;
        }
        p->mu[c] = MU;
    }
    p->colptr[3 * s->n_contacts] = e;
    return (cadmm_rank_part){
        .n_bodies = s->n_owned,
        .body_ids = s->id,
        .body_dofs = p->dofs,
        .mass = p->mass,
        .f = p->f,
        .n_contacts = s->n_contacts,
        .h_colptr = p->colptr,
        .h_body = p->h_body,
        .h_dof = p->h_dof,
        .h_values = p->h_values,
        .w = p->w,
        .mu = p->mu,
    };
}

/* ------------------------------------------------------------------------------ driver */

static const char *status_name(cadmm_status st) {
    switch (st) {
    case CADMM_STATUS_SOLVED: return "solved";
    case CADMM_STATUS_MAX_ITERATIONS: return "max-iterations";
    case CADMM_STATUS_TIME_LIMIT: return "time-limit";
    case CADMM_STATUS_NUMERICAL_ERROR: return "numerical-error";
    case CADMM_STATUS_STALLED: return "stalled";
    case CADMM_STATUS_INFEASIBLE: return "infeasible";
    case CADMM_STATUS_UNSOLVED: return "unsolved";
    default: return "unknown";
    }
}

static int parse_long(const char *text, long lo, long *out) {
    char *end;
    long v = strtol(text, &end, 10);
    if (*text == '\0' || *end != '\0' || v < lo) return -1;
    *out = v;
    return 0;
}

static int parse_options(int argc, char **argv, options *o) {
    *o = (options){.nx = 16, .ny = 8, .nz = 4, .steps = 50, .every = 10, .tolerance = 1e-6};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int bad = v == NULL;
        if (!bad && strcmp(a, "--nx") == 0) bad = parse_long(v, 1, &o->nx);
        else if (!bad && strcmp(a, "--ny") == 0) bad = parse_long(v, 1, &o->ny);
        else if (!bad && strcmp(a, "--nz") == 0) bad = parse_long(v, 1, &o->nz);
        else if (!bad && strcmp(a, "--steps") == 0) bad = parse_long(v, 1, &o->steps);
        else if (!bad && strcmp(a, "--every") == 0) bad = parse_long(v, 1, &o->every);
        else if (!bad && strcmp(a, "--tolerance") == 0) {
            char *end;
            o->tolerance = strtod(v, &end);
            bad = *end != '\0' || !(o->tolerance > 0.0) || !isfinite(o->tolerance);
        } else bad = 1;
        if (bad) return -1;
        i++;
    }
    /* Lattice indices and ids must fit comfortably. */
    if (o->nx > 1000000 || o->ny > 1000000 || o->nz > 1000000 ||
        (double)o->nx * (double)o->ny * (double)o->nz > 1e9)
        return -1;
    return 0;
}

static int compare_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Any process's flag, on every process. */
static int any(int flag) {
    MPI_Allreduce(MPI_IN_PLACE, &flag, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    return flag;
}

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    options o;
    if (parse_options(argc, argv, &o) != 0) { /* every process parses the same arguments */
        if (rank == 0)
            fprintf(stderr, "usage: mpirun -np K %s [--nx 16] [--ny 8] [--nz 4] [--steps 50] "
                            "[--tolerance 1e-6] [--every 10]\n",
                    argv[0]);
        MPI_Finalize();
        return 2;
    }

    int code = 0; /* 0 ok, 1 pile/solve check failed, 2 a call failed */
    slab s;
    part_arrays p = {0};
    cadmm_settings *settings = NULL;
    double *r = NULL, *v = NULL, *times = NULL;
    if (slab_build(&s, &o) != 0) {
        if (rank == 0) fprintf(stderr, "mpi_pile: building the slabs failed (out of memory?)\n");
        code = 2;
        goto done;
    }
    int setup_failed = part_alloc(&p, &s) != 0;
    r = calloc(3 * s.n_contacts + 1, sizeof *r); /* the impulses of the last step */
    v = malloc((DOFS * s.n_owned + 1) * sizeof *v);
    times = malloc((size_t)o.steps * sizeof *times);
    setup_failed = setup_failed || !r || !v || !times;
    if (!setup_failed) {
        cadmm_result rc = cadmm_settings_new(&settings);
        if (rc == CADMM_OK) rc = cadmm_settings_set_tolerance(settings, o.tolerance);
        if (rc != CADMM_OK) {
            fprintf(stderr, "[rank %d] settings: %s\n", rank, cadmm_last_error());
            setup_failed = 1;
        }
    }
    if (any(setup_failed)) {
        if (rank == 0) fprintf(stderr, "mpi_pile: setup failed\n");
        code = 2;
        goto done;
    }

    /* What each process holds, summed for rank 0. */
    unsigned long long mine[3] = {s.n_owned, s.n_contacts, 0}, total[3], most[3], least[3];
    for (size_t c = 0; c < s.n_contacts; c++) /* contacts whose second body is a ghost */
        mine[2] += s.contacts[c].b != NO_BODY && s.contacts[c].b >= s.n_owned;
    MPI_Reduce(mine, total, 3, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    MPI_Reduce(mine, most, 3, MPI_UNSIGNED_LONG_LONG, MPI_MAX, 0, MPI_COMM_WORLD);
    MPI_Reduce(mine, least, 3, MPI_UNSIGNED_LONG_LONG, MPI_MIN, 0, MPI_COMM_WORLD);
    if (rank == 0) {
        printf("mpi_pile: cadmm %s, %ldx%ldx%ld = %llu spheres, %llu contacts on %d process%s "
               "(%llu to %llu bodies each); %llu contacts reach a neighbour's body; "
               "tolerance %.0e, h %.2f, %ld steps\n",
               cadmm_version(), o.nx, o.ny, o.nz, total[0], total[1], size,
               size == 1 ? "" : "es", least[0], most[0], total[2], o.tolerance, STEP, o.steps);
        fflush(stdout);
    }

    long solved = 0, done_steps = 0;
    uint64_t total_iterations = 0;
    for (long step = 1; step <= o.steps && code != 2; step++) {
        halo_exchange(&s); /* the neighbours' positions, for the contacts across slabs */
        cadmm_rank_part part = part_fill(&p, &s);
        cadmm_distributed_solver *solver = NULL;
        cadmm_status status = CADMM_STATUS_UNSOLVED;
        double t0 = MPI_Wtime();
        /* Collective calls: each returns the same result code on every process. */
        cadmm_result rc = cadmm_distributed_solver_new(MPI_Comm_c2f(MPI_COMM_WORLD), &part,
                                                       settings, &solver);
        if (rc != CADMM_OK) {
            /* The same code and message on every process, naming the failing rank. */
            fprintf(stderr, "[rank %d] step %ld: cadmm_distributed_solver_new: %s: %s\n", rank,
                    step, cadmm_result_message(rc), cadmm_last_error());
            code = 2;
            break;
        }
        const char *call = "warm_start";
        if (step > 1) /* the previous step's impulses: the contact set is fixed */
            rc = cadmm_distributed_solver_warm_start(solver, r, NULL);
        double t2 = MPI_Wtime();
        if (rc == CADMM_OK) call = "solve", rc = cadmm_distributed_solver_solve(solver, &status);
        double t3 = MPI_Wtime();
        /* Not collective: agree on their outcome below. */
        cadmm_stats stats = {.struct_size = sizeof stats};
        if (rc == CADMM_OK)
            call = "get_solution", rc = cadmm_distributed_solver_get_solution(solver, r, NULL, v);
        if (rc == CADMM_OK)
            call = "get_stats", rc = cadmm_distributed_solver_get_stats(solver, &stats);
        if (rc != CADMM_OK)
            fprintf(stderr, "[rank %d] step %ld: cadmm_distributed_solver_%s: %s: %s\n", rank,
                    step, call, cadmm_result_message(rc),
                    cadmm_distributed_solver_last_error(solver));
        cadmm_distributed_solver_free(solver); /* on every process, before MPI_Finalize */
        if (any(rc != CADMM_OK)) {
            code = 2;
            break;
        }
        /* Semi-implicit Euler: the new velocities, then the positions they move to. */
        memcpy(s.vel, v, DOFS * s.n_owned * sizeof *v);
        for (size_t b = 0; b < s.n_owned; b++)
            for (int i = 0; i < 3; i++) s.x[b][i] += STEP * s.vel[DOFS * b + (size_t)i];

        double seconds[2] = {t2 - t0, t3 - t2}, slowest[2]; /* setup: new + warm start */
        MPI_Reduce(seconds, slowest, 2, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
        done_steps++;
        solved += status == CADMM_STATUS_SOLVED;
        total_iterations += stats.iterations;
        if (status != CADMM_STATUS_SOLVED && code == 0) code = 1;
        if (rank == 0) {
            times[step - 1] = slowest[1];
            if (step == 1 || step % o.every == 0 || step == o.steps ||
                status != CADMM_STATUS_SOLVED)
                printf("step %4ld  %-15s iterations %6llu  error %.2e  setup %.3f s  "
                       "solve %.3f s\n",
                       step, status_name(status), (unsigned long long)stats.iterations,
                       stats.error, slowest[0], slowest[1]);
            fflush(stdout);
        }
    }

    if (code == 2) {
        if (rank == 0) printf("FAIL: a cadmm call failed (see the messages above)\n");
    } else {
        /* The pile check, over every process's spheres: lowest and highest centre, largest
         * move from the start, everything finite. */
        double z_lo = INFINITY, highs[2] = {-INFINITY, 0.0}, lowest, highest[2];
        int finite = 1;
        for (size_t b = 0; b < s.n_owned; b++) {
            v3 d = {s.x[b][0] - s.x0[b][0], s.x[b][1] - s.x0[b][1], s.x[b][2] - s.x0[b][2]};
            double moved = norm3(d);
            finite = finite && isfinite(moved);
            z_lo = fmin(z_lo, s.x[b][2]);
            highs[0] = fmax(highs[0], s.x[b][2]);
            highs[1] = fmax(highs[1], moved);
        }
        MPI_Reduce(&z_lo, &lowest, 1, MPI_DOUBLE, MPI_MIN, 0, MPI_COMM_WORLD);
        MPI_Reduce(highs, highest, 2, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
        int all_finite = !any(!finite);
        if (rank == 0) {
            size_t n = (size_t)done_steps;
            qsort(times, n, sizeof *times, compare_double);
            double median = n ? 0.5 * (times[(n - 1) / 2] + times[n / 2]) : 0.0;
            double slowest = n ? times[n - 1] : 0.0;
            double z_top = (double)(o.nz - 1) + RADIUS;
            int pile_ok = all_finite && lowest >= RADIUS - MAX_SINK &&
                          highest[0] <= z_top + MAX_SINK && highest[1] <= MAX_MOVE;
            printf("summary: %ld/%ld steps solved, %.0f iterations per step on average; solve "
                   "time (slowest process) median %.3f s, max %.3f s; sphere z from %.4f to "
                   "%.4f (at rest: %.1f to %.1f), largest move %.2e\n",
                   solved, o.steps, n ? (double)total_iterations / (double)n : 0.0, median,
                   slowest, lowest, highest[0], RADIUS, z_top, highest[1]);
            if (solved != o.steps) printf("FAIL: %ld step(s) not solved\n", o.steps - solved);
            if (!pile_ok)
                printf("FAIL: the pile did not stay at rest (z from %.4f to %.4f, allowed %.2f "
                       "to %.2f; largest move %.3g, allowed %.2f)\n",
                       lowest, highest[0], RADIUS - MAX_SINK, z_top + MAX_SINK, highest[1],
                       MAX_MOVE);
            if (solved == o.steps && pile_ok) printf("PASS\n");
            if (!pile_ok && code == 0) code = 1;
        }
    }

done:
    /* Every process exits with the same code. */
    MPI_Allreduce(MPI_IN_PLACE, &code, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    cadmm_settings_free(settings);
    part_free(&p);
    slab_free(&s);
    free(r), free(v), free(times);
    MPI_Finalize();
    return code;
}
