/* One problem shared out among MPI processes (cadmm_distributed_solver_*), run as
 *     mpirun -np K ./test_mpi [nx ny nz]          (CTest: K = 1, 2, 4, default 12 6 4)
 * (any other arguments, such as a data directory, are ignored).
 *
 * Scene, generated alike on every process: rigid spheres of radius 0.5 on an nx x ny x nz
 * lattice of spacing 1 (neighbours touch), the lowest layer on the floor z = 0; masses
 * jittered in [0.5, 1.5), inertia 0.1 m on the diagonal (a solid sphere of radius 0.5), 6
 * velocities per body (3 linear, then 3 angular). Contacts: each body of the lowest layer
 * with the floor and each body with its +x, +y and +z neighbours, mu = 0.5. The frame is
 * (n, t1, t2), n pointing from the second body (or the floor) toward the first. H's column
 * for a direction d holds (d, arm x d) on the first body, which reads the velocity of the
 * contact point v + omega x arm along d, and minus the same on the second body: u = H^T v is
 * the velocity of the first body relative to the second at the contact point, separating
 * when u_N > 0. f = M v0 + h m g (h = 0.01, g = -9.81 e_z, small random v0), w = 0.
 *
 * Split as a host engine would: body b goes to process floor((x_b - xmin) / width), width =
 * (xmax - xmin) / K, clamped to [0, K); each contact to its first body's process. Bodies are
 * named by ids 1000 + 7 b (ids need not be indices) and listed in descending order.
 *
 * Checks:
 *  - the distributed solve at tol 1e-6 ends SOLVED with the same status and iterations on
 *    every process; a warm start from its own answer solves again, alike everywhere;
 *  - the answers gathered on rank 0 (every contact and body exactly once) meet tol by the
 *    independent measure of test_util.h on the whole problem (up to its round-off
 *    allowance), the returned u is H^T v + w, and stats.error is that measure; the
 *    one-process solver on the whole problem passes tu_check_outcome at the same tol. How
 *    far apart the two answers are is printed only: a pile at rest is ill-conditioned, its
 *    impulses and velocities are not determined to the tolerance;
 *  - bad input is every process's error: a body id no process owns (999999, named by rank
 *    K-1) and a NaN in rank 0's f make cadmm_distributed_solver_new return
 *    CADMM_ERR_INVALID_VALUE on every process with *out untouched and cadmm_last_error
 *    naming the rank and the item; afterwards the good parts build again (a refused call
 *    leaves the processes in step).
 * Every process exits with the same code: the failures of all are summed. */
#include <mpi.h>

#ifndef CADMM_WITH_MPI
#error "test_mpi needs the distributed API: define CADMM_WITH_MPI (an MPI build's cadmm::cadmm does)"
#endif

#include "cadmm.h"
#include "test_util.h"

static int g_rank = 0, g_size = 1;

/* Failures name the process, each in one write so that processes do not interleave
 * within a line; a failed precondition stops every process. */
#undef TU_FAIL
#define TU_FAIL(...)                                                                      \
    do {                                                                                  \
        char tu_text_[1024];                                                              \
        snprintf(tu_text_, sizeof tu_text_, __VA_ARGS__);                                 \
        fprintf(stderr, "%s:%d: rank %d: FAILED: %s\n", __FILE__, __LINE__, g_rank,      \
                tu_text_);                                                                \
        ++*tu_failures();                                                                 \
    } while (0)

#undef REQUIRE
#define REQUIRE(cond)                                                                     \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "%s:%d: rank %d: REQUIRED condition failed: %s\n", __FILE__,  \
                    __LINE__, g_rank, #cond);                                             \
            MPI_Abort(MPI_COMM_WORLD, 1);                                                 \
        }                                                                                 \
    } while (0)

/* A call that must succeed; `message` is read after it (the library's detailed error). */
#define REQUIRE_CALL(expr, message)                                                       \
    do {                                                                                  \
        cadmm_result rc_ = (expr);                                                        \
        if (rc_ != CADMM_OK) {                                                            \
            fprintf(stderr, "%s:%d: rank %d: %s returned %s: %s\n", __FILE__, __LINE__,   \
                    g_rank, #expr, tu_result_name(rc_), (message));                       \
            MPI_Abort(MPI_COMM_WORLD, 1);                                                 \
        }                                                                                 \
    } while (0)

#define RADIUS 0.5
#define SPACING 1.0
#define MU 0.5
#define STEP 0.01
#define GRAVITY 9.81
#define DOFS 6
#define TOL 1e-6
#define SLACK 1e-12 /* relative, on TOL, for SOLVED: round-off of two summation orders */
#define AGREE 1e-9  /* stats.error against the independent error, relative */
#define BAD_ID 999999u
#define NO_BODY ((size_t)-1) /* the second "body" of a floor contact */
#define SEED 0x5EEDC0DEull

static uint64_t body_id(size_t b) { return 1000u + 7u * (uint64_t)b; }

static const char *solver_message(const cadmm_distributed_solver *sv)
{
    const char *m = cadmm_distributed_solver_last_error(sv);
    return m != NULL ? m : "(no solver)";
}

/* ---- the scene --------------------------------------------------------------------------- */

typedef struct scene {
    size_t nb, nc, ne;      /* bodies, contacts, entries of H */
    double *pos;            /* 3 nb: centres */
    double *mass;           /* nb */
    double *f;              /* DOFS nb: M v0 + h m g */
    size_t *first;          /* nc: the first body of each contact */
    size_t *colptr;         /* 3 nc + 1: each column's entries */
    size_t *ebody, *edof;   /* ne: each entry's body (index) and velocity in the body */
    double *eval;           /* ne */
    int *body_rank;         /* nb */
    int *contact_rank;      /* nc */
} scene;

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Tangents of a unit normal: t1 from the axis least aligned with n, t2 = n x t1. */
static void frame(const double n[3], double t1[3], double t2[3])
{
    double e[3] = {0.0, 0.0, 0.0}, d, len;
    size_t k = 0;
    for (size_t i = 1; i < 3; ++i)
        if (fabs(n[i]) < fabs(n[k])) k = i;
    e[k] = 1.0;
    d = n[k];
    for (size_t i = 0; i < 3; ++i) t1[i] = e[i] - d * n[i];
    len = tu_norm(t1, 3);
    for (size_t i = 0; i < 3; ++i) t1[i] /= len;
    cross(n, t1, t2);
}

/* Appends the entries of one body to the current column: sign (d, arm x d), zeros left out. */
static void add_entries(scene *sc, size_t b, const double arm[3], const double d[3],
                        double sign)
{
    double ang[3];
    cross(arm, d, ang);
    for (size_t k = 0; k < DOFS; ++k) {
        double value = sign * (k < 3 ? d[k] : ang[k - 3]);
        if (value == 0.0) continue;
        sc->ebody[sc->ne] = b;
        sc->edof[sc->ne] = k;
        sc->eval[sc->ne] = value;
        ++sc->ne;
    }
}

/* A contact between body b1 and body b2 below or beside it (NO_BODY: the floor), at b1's
 * surface point facing b2, normal toward b1. */
static void add_contact(scene *sc, size_t b1, size_t b2)
{
    const double *p1 = sc->pos + 3 * b1;
    double n[3] = {0.0, 0.0, 1.0}, t1[3], t2[3], a1[3], a2[3];
    const double *dir[3] = {n, t1, t2};
    size_t c = sc->nc;
    if (b2 != NO_BODY) {
        double len;
        for (size_t i = 0; i < 3; ++i) n[i] = p1[i] - sc->pos[3 * b2 + i];
        len = tu_norm(n, 3);
        for (size_t i = 0; i < 3; ++i) n[i] /= len;
    }
    frame(n, t1, t2);
    for (size_t i = 0; i < 3; ++i) {
        a1[i] = -RADIUS * n[i];
        a2[i] = b2 != NO_BODY ? p1[i] + a1[i] - sc->pos[3 * b2 + i] : 0.0;
    }
    for (size_t j = 0; j < 3; ++j) {
        add_entries(sc, b1, a1, dir[j], 1.0);
        if (b2 != NO_BODY) add_entries(sc, b2, a2, dir[j], -1.0);
        sc->colptr[3 * c + j + 1] = sc->ne;
    }
    sc->first[c] = b1;
    ++sc->nc;
}

static scene make_scene(size_t nx, size_t ny, size_t nz, int nranks)
{
    scene sc;
    tu_rng g = tu_rng_new(SEED);
    size_t nb = nx * ny * nz, max_nc = 4 * nb;
    double xmin = INFINITY, xmax = -INFINITY, width;
    memset(&sc, 0, sizeof sc);
    sc.nb = nb;
    sc.pos = (double *)tu_calloc(3 * nb, sizeof(double));
    sc.mass = (double *)tu_calloc(nb, sizeof(double));
    sc.f = (double *)tu_calloc(DOFS * nb, sizeof(double));
    sc.first = (size_t *)tu_calloc(max_nc, sizeof(size_t));
    sc.colptr = (size_t *)tu_calloc(3 * max_nc + 1, sizeof(size_t));
    sc.ebody = (size_t *)tu_calloc(3 * 2 * DOFS * max_nc, sizeof(size_t));
    sc.edof = (size_t *)tu_calloc(3 * 2 * DOFS * max_nc, sizeof(size_t));
    sc.eval = (double *)tu_calloc(3 * 2 * DOFS * max_nc, sizeof(double));
    sc.body_rank = (int *)tu_calloc(nb, sizeof(int));
    sc.contact_rank = (int *)tu_calloc(max_nc, sizeof(int));
    for (size_t b = 0; b < nb; ++b) {
        size_t i = b % nx, j = (b / nx) % ny, k = b / (nx * ny);
        double m = tu_rng_range(&g, 0.5, 1.5);
        sc.pos[3 * b] = SPACING * (double)i;
        sc.pos[3 * b + 1] = SPACING * (double)j;
        sc.pos[3 * b + 2] = RADIUS + SPACING * (double)k;
        sc.mass[b] = m;
        for (size_t d = 0; d < DOFS; ++d) /* f = M v0, v0 small */
            sc.f[DOFS * b + d] = (d < 3 ? m : 0.1 * m) * tu_rng_range(&g, -0.05, 0.05);
        sc.f[DOFS * b + 2] -= STEP * GRAVITY * m;
    }
    for (size_t b = 0; b < nb; ++b) {
        size_t i = b % nx, j = (b / nx) % ny, k = b / (nx * ny);
        if (k == 0) add_contact(&sc, b, NO_BODY);
        if (i + 1 < nx) add_contact(&sc, b, b + 1);
        if (j + 1 < ny) add_contact(&sc, b, b + nx);
        if (k + 1 < nz) add_contact(&sc, b, b + nx * ny);
    }
    /* the host's split by position along x */
    for (size_t b = 0; b < nb; ++b) {
        xmin = sc.pos[3 * b] < xmin ? sc.pos[3 * b] : xmin;
        xmax = sc.pos[3 * b] > xmax ? sc.pos[3 * b] : xmax;
    }
    width = (xmax - xmin) / (double)nranks;
    for (size_t b = 0; b < nb; ++b) {
        double slot = width > 0.0 ? floor((sc.pos[3 * b] - xmin) / width) : 0.0;
        sc.body_rank[b] = slot < 0.0 ? 0 : slot > nranks - 1 ? nranks - 1 : (int)slot;
    }
    for (size_t c = 0; c < sc.nc; ++c) sc.contact_rank[c] = sc.body_rank[sc.first[c]];
    return sc;
}

static void scene_free(scene *sc)
{
    free(sc->pos);
    free(sc->mass);
    free(sc->f);
    free(sc->first);
    free(sc->colptr);
    free(sc->ebody);
    free(sc->edof);
    free(sc->eval);
    free(sc->body_rank);
    free(sc->contact_rank);
    memset(sc, 0, sizeof *sc);
}

/* ---- one process's part ----------------------------------------------------------------- */

typedef struct part {
    cadmm_rank_part p;   /* views the arrays below */
    size_t *bodies;      /* n_bodies: global index of each owned body */
    size_t *contacts;    /* n_contacts: global index of each owned contact */
    uint64_t *ids, *h_body;
    size_t *dofs, *h_colptr, *h_dof;
    double *mass, *f, *h_values, *w, *mu;
} part;

static part make_part(const scene *sc, int rank)
{
    part pt;
    size_t nbo = 0, nco = 0, ne = 0;
    memset(&pt, 0, sizeof pt);
    for (size_t b = 0; b < sc->nb; ++b) nbo += sc->body_rank[b] == rank;
    for (size_t c = 0; c < sc->nc; ++c)
        if (sc->contact_rank[c] == rank) {
            ++nco;
            ne += sc->colptr[3 * c + 3] - sc->colptr[3 * c];
        }
    pt.bodies = (size_t *)tu_calloc(nbo, sizeof(size_t));
    pt.contacts = (size_t *)tu_calloc(nco, sizeof(size_t));
    pt.ids = (uint64_t *)tu_calloc(nbo, sizeof(uint64_t));
    pt.dofs = (size_t *)tu_calloc(nbo, sizeof(size_t));
    pt.mass = (double *)tu_calloc(DOFS * DOFS * nbo, sizeof(double));
    pt.f = (double *)tu_calloc(DOFS * nbo, sizeof(double));
    pt.h_colptr = (size_t *)tu_calloc(3 * nco + 1, sizeof(size_t));
    pt.h_body = (uint64_t *)tu_calloc(ne, sizeof(uint64_t));
    pt.h_dof = (size_t *)tu_calloc(ne, sizeof(size_t));
    pt.h_values = (double *)tu_calloc(ne, sizeof(double));
    pt.w = (double *)tu_calloc(3 * nco, sizeof(double));
    pt.mu = (double *)tu_calloc(nco, sizeof(double));
    /* descending: a host lists its bodies in its own order */
    nbo = 0;
    for (size_t b = sc->nb; b-- > 0;) {
        if (sc->body_rank[b] != rank) continue;
        pt.bodies[nbo] = b;
        pt.ids[nbo] = body_id(b);
        pt.dofs[nbo] = DOFS;
        for (size_t d = 0; d < DOFS; ++d) { /* column-major DOFS x DOFS block, diagonal */
            pt.mass[DOFS * DOFS * nbo + d * DOFS + d] = (d < 3 ? 1.0 : 0.1) * sc->mass[b];
            pt.f[DOFS * nbo + d] = sc->f[DOFS * b + d];
        }
        ++nbo;
    }
    nco = ne = 0;
    for (size_t c = 0; c < sc->nc; ++c) {
        if (sc->contact_rank[c] != rank) continue;
        for (size_t j = 3 * c; j < 3 * c + 3; ++j) {
            for (size_t e = sc->colptr[j]; e < sc->colptr[j + 1]; ++e, ++ne) {
                pt.h_body[ne] = body_id(sc->ebody[e]);
                pt.h_dof[ne] = sc->edof[e];
                pt.h_values[ne] = sc->eval[e];
            }
            pt.h_colptr[3 * nco + (j - 3 * c) + 1] = ne;
        }
        pt.mu[nco] = MU;
        pt.contacts[nco++] = c;
    }
    pt.p.n_bodies = nbo;
    pt.p.body_ids = pt.ids;
    pt.p.body_dofs = pt.dofs;
    pt.p.mass = pt.mass;
    pt.p.f = pt.f;
    pt.p.n_contacts = nco;
    pt.p.h_colptr = pt.h_colptr;
    pt.p.h_body = pt.h_body;
    pt.p.h_dof = pt.h_dof;
    pt.p.h_values = pt.h_values;
    pt.p.w = pt.w;
    pt.p.mu = pt.mu;
    return pt;
}

static void part_free(part *pt)
{
    free(pt->bodies);
    free(pt->contacts);
    free(pt->ids);
    free(pt->h_body);
    free(pt->dofs);
    free(pt->h_colptr);
    free(pt->h_dof);
    free(pt->mass);
    free(pt->f);
    free(pt->h_values);
    free(pt->w);
    free(pt->mu);
    memset(pt, 0, sizeof *pt);
}

/* ---- the whole problem, for rank 0 ------------------------------------------------------ */

static tu_problem whole_problem(const scene *sc)
{
    tu_problem p;
    size_t n = DOFS * sc->nb, m = 3 * sc->nc;
    memset(&p, 0, sizeof p);
    p.is_global = 1;
    p.n = n;
    p.nc = sc->nc;
    p.M.nrows = p.M.ncols = n;
    p.M.colptr = (int64_t *)tu_calloc(n + 1, sizeof(int64_t));
    p.M.rowind = (int64_t *)tu_calloc(n, sizeof(int64_t));
    p.M.values = (double *)tu_calloc(n, sizeof(double));
    for (size_t i = 0; i < n; ++i) {
        p.M.colptr[i + 1] = (int64_t)i + 1;
        p.M.rowind[i] = (int64_t)i;
        p.M.values[i] = (i % DOFS < 3 ? 1.0 : 0.1) * sc->mass[i / DOFS];
    }
    p.H.nrows = n;
    p.H.ncols = m;
    p.H.colptr = (int64_t *)tu_calloc(m + 1, sizeof(int64_t));
    p.H.rowind = (int64_t *)tu_calloc(sc->ne, sizeof(int64_t));
    p.H.values = (double *)tu_calloc(sc->ne, sizeof(double));
    for (size_t j = 0; j <= m; ++j) p.H.colptr[j] = (int64_t)sc->colptr[j];
    for (size_t e = 0; e < sc->ne; ++e) {
        p.H.rowind[e] = (int64_t)(DOFS * sc->ebody[e] + sc->edof[e]);
        p.H.values[e] = sc->eval[e];
    }
    p.f = (double *)tu_calloc(n, sizeof(double));
    memcpy(p.f, sc->f, n * sizeof(double));
    p.w = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(sc->nc, sizeof(double));
    for (size_t c = 0; c < sc->nc; ++c) p.mu[c] = MU;
    return p;
}

/* ---- collective helpers ----------------------------------------------------------------- */

/* Does every process hold the same value? */
static int same_everywhere(uint64_t x)
{
    uint64_t lo, hi;
    MPI_Allreduce(&x, &lo, 1, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
    MPI_Allreduce(&x, &hi, 1, MPI_UINT64_T, MPI_MAX, MPI_COMM_WORLD);
    return lo == hi;
}

/* Gathers each process's (index, `width` values) rows on rank 0 into `all` (rows by global
 * index, `total` of them); on rank 0 checks that each index arrives exactly once. */
static void gather_rows(const size_t *index, const double *values, size_t rows, size_t width,
                        size_t total, double *all, const char *what)
{
    int count = (int)rows, *counts = NULL, *displs = NULL, *vcounts = NULL, *vdispls = NULL;
    int64_t *idx = (int64_t *)tu_calloc(rows, sizeof(int64_t)), *all_idx = NULL;
    double *all_values = NULL;
    for (size_t i = 0; i < rows; ++i) idx[i] = (int64_t)index[i];
    if (g_rank == 0) {
        counts = (int *)tu_calloc((size_t)g_size, sizeof(int));
        displs = (int *)tu_calloc((size_t)g_size, sizeof(int));
        vcounts = (int *)tu_calloc((size_t)g_size, sizeof(int));
        vdispls = (int *)tu_calloc((size_t)g_size, sizeof(int));
    }
    MPI_Gather(&count, 1, MPI_INT, counts, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (g_rank == 0) {
        int sum = 0;
        for (int k = 0; k < g_size; ++k) {
            displs[k] = sum;
            vcounts[k] = counts[k] * (int)width;
            vdispls[k] = sum * (int)width;
            sum += counts[k];
        }
        CHECK_MSG((size_t)sum == total, "%s: %d rows gathered, the problem has %zu", what, sum,
                  total);
        all_idx = (int64_t *)tu_calloc((size_t)sum, sizeof(int64_t));
        all_values = (double *)tu_calloc((size_t)sum * width, sizeof(double));
    }
    MPI_Gatherv(idx, count, MPI_INT64_T, all_idx, counts, displs, MPI_INT64_T, 0,
                MPI_COMM_WORLD);
    MPI_Gatherv(values, count * (int)width, MPI_DOUBLE, all_values, vcounts, vdispls,
                MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (g_rank == 0) {
        int sum = displs[g_size - 1] + counts[g_size - 1];
        char *seen = (char *)tu_calloc(total, 1);
        for (int i = 0; i < sum; ++i) {
            int64_t g = all_idx[i];
            if (g < 0 || (size_t)g >= total || seen[g]) {
                TU_FAIL("%s: index %lld out of range or sent twice", what, (long long)g);
                continue;
            }
            seen[g] = 1;
            memcpy(all + (size_t)g * width, all_values + (size_t)i * width,
                   width * sizeof(double));
        }
        for (size_t g = 0; g < total; ++g)
            CHECK_MSG(seen[g], "%s: no process returned index %zu", what, g);
        free(seen);
    }
    free(idx);
    free(all_idx);
    free(all_values);
    free(counts);
    free(displs);
    free(vcounts);
    free(vdispls);
}

/* ---- the checks ------------------------------------------------------------------------- */

/* Solves the pile across the processes and checks the answer on rank 0 against the whole
 * problem and the one-process solver. */
static void check_solve(const scene *sc, const part *pt)
{
    size_t nco = pt->p.n_contacts, nbo = pt->p.n_bodies, n = DOFS * sc->nb, m = 3 * sc->nc;
    cadmm_settings *s = NULL;
    cadmm_distributed_solver *sv = NULL;
    cadmm_status status = -1, status2 = -1;
    cadmm_stats st, st2;
    double *r = (double *)tu_calloc(3 * nco, sizeof(double));
    double *u = (double *)tu_calloc(3 * nco, sizeof(double));
    double *v = (double *)tu_calloc(DOFS * nbo, sizeof(double));
    double *ru = (double *)tu_calloc(6 * nco, sizeof(double));
    double *all_ru = NULL, *all_v = NULL;
    double t0, t_solve;

    REQUIRE_CALL(cadmm_settings_new(&s), cadmm_last_error());
    REQUIRE_CALL(cadmm_settings_set_tolerance(s, TOL), cadmm_last_error());
    REQUIRE_CALL(cadmm_distributed_solver_new(MPI_Comm_c2f(MPI_COMM_WORLD), &pt->p, s, &sv),
                 cadmm_last_error());
    REQUIRE(sv != NULL);
    t0 = MPI_Wtime();
    REQUIRE_CALL(cadmm_distributed_solver_solve(sv, &status), solver_message(sv));
    t_solve = MPI_Wtime() - t0;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    REQUIRE_CALL(cadmm_distributed_solver_get_stats(sv, &st), solver_message(sv));
    REQUIRE_CALL(cadmm_distributed_solver_get_solution(sv, r, u, v), solver_message(sv));
    CHECK_MSG(status == CADMM_STATUS_SOLVED, "distributed solve: status %s, error %.3e after "
              "%llu iterations", tu_status_name(status), st.error,
              (unsigned long long)st.iterations);
    CHECK_MSG(st.status == status, "stats.status %d, the solve returned %d", (int)st.status,
              (int)status);
    /* the processes take every decision together: same status, same iteration count */
    CHECK_MSG(same_everywhere((uint64_t)(uint32_t)status), "the processes disagree on the status");
    CHECK_MSG(same_everywhere(st.iterations), "the processes disagree on the iterations (%llu "
              "here)", (unsigned long long)st.iterations);
    CHECK_MSG(tu_all_finite(r, 3 * nco) && tu_all_finite(u, 3 * nco) &&
                  tu_all_finite(v, DOFS * nbo), "the answer is not finite");

    /* gather (r, u) by contact and v by body on rank 0 */
    for (size_t i = 0; i < nco; ++i) {
        memcpy(ru + 6 * i, r + 3 * i, 3 * sizeof(double));
        memcpy(ru + 6 * i + 3, u + 3 * i, 3 * sizeof(double));
    }
    if (g_rank == 0) {
        all_ru = (double *)tu_calloc(6 * sc->nc, sizeof(double));
        all_v = (double *)tu_calloc(n, sizeof(double));
    }
    gather_rows(pt->contacts, ru, nco, 6, sc->nc, all_ru, "contacts");
    gather_rows(pt->bodies, v, nbo, DOFS, sc->nb, all_v, "bodies");

    if (g_rank == 0) {
        tu_problem P = whole_problem(sc);
        cadmm_problem *lib = tu_require_problem(&P);
        double *rd = (double *)tu_calloc(m, sizeof(double));
        double *ud = (double *)tu_calloc(m, sizeof(double));
        double *u_ref = (double *)tu_calloc(m, sizeof(double));
        double *v_free = (double *)tu_calloc(n, sizeof(double));
        double e_dist, R, Rs, e_lib = NAN;
        tu_outcome o;
        for (size_t c = 0; c < sc->nc; ++c) {
            memcpy(rd + 3 * c, all_ru + 6 * c, 3 * sizeof(double));
            memcpy(ud + 3 * c, all_ru + 6 * c + 3, 3 * sizeof(double));
        }
        /* the distributed answer, by the independent measure on the whole problem */
        e_dist = tu_problem_error(&P, rd, all_v, NULL);
        R = tu_problem_error_roundoff(&P, rd, all_v, NULL) + 1e-15;
        Rs = R < TU_ROUNDOFF_CAP * TOL ? R : TU_ROUNDOFF_CAP * TOL;
        CHECK_MSG(e_dist <= TOL * (1.0 + SLACK) + Rs, "distributed answer: independent error "
                  "%.6e > tol %.1e (round-off estimate %.1e)", e_dist, TOL, R);
        CHECK_MSG(fabs(st.error - e_dist) <= AGREE * e_dist + R, "distributed stats.error "
                  "%.15e, independent error of the gathered answer %.15e", st.error, e_dist);
        REQUIRE_CALL(cadmm_problem_error(lib, rd, ud, all_v, &e_lib), cadmm_last_error());
        CHECK_MSG(fabs(e_lib - e_dist) <= AGREE * e_dist + R, "cadmm_problem_error %.15e, "
                  "independent error %.15e", e_lib, e_dist);
        memcpy(u_ref, P.w, m * sizeof(double));
        tu_csc_mul_t(&P.H, all_v, 1, u_ref);
        CHECK_MSG(tu_diff_norm(ud, u_ref, m) <= 1e-10 * tu_max(1.0, tu_norm(u_ref, m)),
                  "distributed u is not H^T v + w (difference %.3e)",
                  tu_diff_norm(ud, u_ref, m));

        /* the one-process solver on the same whole problem */
        cadmm_settings *s1 = NULL;
        REQUIRE_CALL(cadmm_settings_new(&s1), cadmm_last_error());
        REQUIRE_CALL(cadmm_settings_set_tolerance(s1, TOL), cadmm_last_error());
        tu_solve(&P, lib, s1, &o);
        tu_check_outcome("one-process solve of the whole pile", &P, &o, TOL, SLACK, AGREE);
        CHECK_MSG(o.status == CADMM_STATUS_SOLVED, "one-process solve: status %s",
                  tu_status_name(o.status));
        for (size_t i = 0; i < n; ++i) v_free[i] = P.f[i] / P.M.values[i]; /* M diagonal */
        printf("pile %zu bodies, %zu contacts on %d process(es): distributed %s in %llu "
               "iterations (%.2f s), one process %s in %llu iterations\n",
               sc->nb, sc->nc, g_size, tu_status_name(status),
               (unsigned long long)st.iterations, t_solve, tu_status_name(o.status),
               (unsigned long long)o.stats.iterations);
        printf("  independent error: distributed %.3e (stats %.3e), one process %.3e\n",
               e_dist, st.error, o.e_ind);
        printf("  ||v_dist - v_one|| / ||M^-1 f|| = %.3e, ||r_dist - r_one|| / ||r_one|| = "
               "%.3e (printed only: a pile at rest is ill-conditioned)\n",
               tu_diff_norm(all_v, o.v, n) / tu_norm(v_free, n),
               tu_diff_norm(rd, o.r, m) / tu_max(1e-300, tu_norm(o.r, m)));
        tu_outcome_free(&o);
        cadmm_settings_free(s1);
        cadmm_problem_free(lib);
        tu_problem_free(&P);
        free(rd);
        free(ud);
        free(u_ref);
        free(v_free);
    }

    /* warm start from the answer: solved again, alike everywhere */
    REQUIRE_CALL(cadmm_distributed_solver_warm_start(sv, r, v), solver_message(sv));
    REQUIRE_CALL(cadmm_distributed_solver_solve(sv, &status2), solver_message(sv));
    memset(&st2, 0, sizeof st2);
    st2.struct_size = sizeof st2;
    REQUIRE_CALL(cadmm_distributed_solver_get_stats(sv, &st2), solver_message(sv));
    CHECK_MSG(status2 == CADMM_STATUS_SOLVED, "warm-started solve: status %s, error %.3e",
              tu_status_name(status2), st2.error);
    CHECK_MSG(same_everywhere(st2.iterations), "warm start: the processes disagree on the "
              "iterations (%llu here)", (unsigned long long)st2.iterations);
    if (g_rank == 0)
        printf("  warm start from the answer: %s in %llu iterations\n", tu_status_name(status2),
               (unsigned long long)st2.iterations);

    cadmm_distributed_solver_free(sv);
    cadmm_settings_free(s);
    free(r);
    free(u);
    free(v);
    free(ru);
    free(all_ru);
    free(all_v);
}

/* cadmm_distributed_solver_new must refuse `p` on every process: CADMM_ERR_INVALID_VALUE,
 * *out untouched, the message naming `rank` and containing each of `needles`. */
static void expect_refused(const char *label, const cadmm_rank_part *p, int rank,
                           const char *const *needles, size_t n_needles)
{
    static int sentinel;
    cadmm_distributed_solver *const untouched = (cadmm_distributed_solver *)(void *)&sentinel;
    cadmm_distributed_solver *out = untouched;
    cadmm_settings *s = NULL;
    cadmm_result rc;
    const char *msg;
    char word[32];
    REQUIRE_CALL(cadmm_settings_new(&s), cadmm_last_error());
    REQUIRE_CALL(cadmm_settings_set_tolerance(s, TOL), cadmm_last_error());
    rc = cadmm_distributed_solver_new(MPI_Comm_c2f(MPI_COMM_WORLD), p, s, &out);
    msg = cadmm_last_error();
    CHECK_MSG(rc == CADMM_ERR_INVALID_VALUE, "%s: returned %s, expected CADMM_ERR_INVALID_VALUE "
              "(message \"%s\")", label, tu_result_name(rc), msg);
    CHECK_MSG(out == untouched, "%s: *out was written on failure", label);
    snprintf(word, sizeof word, "rank %d", rank);
    CHECK_MSG(tu_has_word(msg, word), "%s: the message \"%s\" does not name \"%s\"", label, msg,
              word);
    for (size_t k = 0; k < n_needles; ++k)
        CHECK_MSG(strstr(msg, needles[k]) != NULL, "%s: the message \"%s\" does not contain "
                  "\"%s\"", label, msg, needles[k]);
    /* a solver built all the same is freed (collectively: the library promises one result on
       every process) */
    if (rc == CADMM_OK && out != untouched) cadmm_distributed_solver_free(out);
    if (g_rank == 0) printf("  %s: refused everywhere: \"%s\"\n", label, msg);
    cadmm_settings_free(s);
}

static void check_bad_input(part *pt)
{
    int last = g_size - 1;
    char entry[64], f_item[64];
    size_t bad = 0, ne = pt->p.h_colptr[3 * pt->p.n_contacts];
    uint64_t saved_id = 0;
    double saved_f = 0.0;

    /* rank K-1 names a body no process owns, in an entry of the middle of its H */
    if (g_rank == last) {
        REQUIRE(ne > 0);
        bad = ne / 2;
        saved_id = pt->h_body[bad];
        pt->h_body[bad] = BAD_ID;
    }
    {
        uint64_t b = bad;
        MPI_Bcast(&b, 1, MPI_UINT64_T, last, MPI_COMM_WORLD);
        snprintf(entry, sizeof entry, "h_body[%llu]", (unsigned long long)b);
    }
    {
        const char *needles[] = {"999999", entry};
        expect_refused("unknown body id", &pt->p, last, needles, 2);
    }
    if (g_rank == last) pt->h_body[bad] = saved_id;

    /* rank 0 hands a NaN in f */
    bad = (DOFS * pt->p.n_bodies) / 2;
    if (g_rank == 0) {
        REQUIRE(pt->p.n_bodies > 0);
        saved_f = pt->f[bad];
        pt->f[bad] = NAN;
    }
    {
        uint64_t b = bad;
        MPI_Bcast(&b, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
        snprintf(f_item, sizeof f_item, " f[%llu]", (unsigned long long)b);
    }
    {
        const char *needles[] = {f_item};
        expect_refused("NaN in f", &pt->p, 0, needles, 1);
    }
    if (g_rank == 0) pt->f[bad] = saved_f;

    /* after the refusals the processes are still in step: the good parts build again */
    {
        cadmm_settings *s = NULL;
        cadmm_distributed_solver *sv = NULL;
        REQUIRE_CALL(cadmm_settings_new(&s), cadmm_last_error());
        REQUIRE_CALL(cadmm_settings_set_tolerance(s, TOL), cadmm_last_error());
        REQUIRE_CALL(cadmm_distributed_solver_new(MPI_Comm_c2f(MPI_COMM_WORLD), &pt->p, s, &sv),
                     cadmm_last_error());
        CHECK(sv != NULL);
        cadmm_distributed_solver_free(sv);
        cadmm_settings_free(s);
    }
}

int main(int argc, char **argv)
{
    size_t dims[3] = {12, 6, 4};
    int failures, total;
    scene sc;
    part pt;

    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    if (argc == 4)
        for (int k = 0; k < 3; ++k) {
            long d = strtol(argv[k + 1], NULL, 10);
            REQUIRE(d >= 1 && d <= 1000);
            dims[k] = (size_t)d;
        }
    if (g_rank == 0)
        printf("cadmm %s: one pile across %d MPI process(es)\n", cadmm_version(), g_size);

    sc = make_scene(dims[0], dims[1], dims[2], g_size);
    pt = make_part(&sc, g_rank);
    check_solve(&sc, &pt);
    check_bad_input(&pt);
    part_free(&pt);
    scene_free(&sc);

    /* every process exits alike: the failures of all */
    failures = *tu_failures();
    MPI_Allreduce(&failures, &total, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    if (failures > 0) fprintf(stderr, "test_mpi: rank %d: %d check(s) FAILED\n", g_rank, failures);
    if (g_rank == 0) {
        if (total == 0)
            printf("test_mpi (%d processes): all checks passed\n", g_size);
        else
            fprintf(stderr, "test_mpi (%d processes): %d check(s) FAILED\n", g_size, total);
    }
    MPI_Finalize();
    return total == 0 ? 0 : 1;
}
