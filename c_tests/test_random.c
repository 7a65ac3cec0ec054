/* Small randomized problems from a fixed-seed generator, solved through the C API with every
 * variant name and a modest iteration cap:
 *
 *   families  global (W = H^T M^-1 H positive definite), global with a singular W (3 nc > n,
 *             and two contacts with the same rows of H), global with one joint (G, b),
 *             local (W = A^T A + 0.1 I), local with a singular W (rank 3 nc - 2), and a
 *             global and a local problem without any contact;
 *   mu        0, 1e-4, 0.3, 1, 10, 1e8 (every contact of a problem gets the same mu);
 *   variants  "auto", the twelve named ADMM ones and "newton" (semismooth Newton alone).
 *
 * Every call must succeed (these problems are all valid: no other code is expected), and
 * every solve must pass tu_check_outcome (test_util.h): finite outputs, u consistent with
 * r or v, stats.error equal to the independent error e of the returned answer, and a status
 * consistent with e (SOLVED: e <= tol, re-measured independently, with a capped round-off
 * allowance, and ||r|| within the a priori bound of the problem when W is positive
 * definite; otherwise e > tol). Each non-SOLVED status needs its reason: TIME_LIMIT fails
 * (no limit is set); MAX_ITERATIONS must come with the iteration count at the cap;
 * NUMERICAL_ERROR is accepted only with mu = 1e8 (the iterates overflow there: the returned
 * answer is then the last finite iterate, with its error); INFEASIBLE only with a singular
 * W and when the returned impulses carry the certificate tu_check_outcome verifies;
 * STALLED only for "newton" alone. The problems without a contact must be SOLVED
 * (v = M^-1 f, nothing to iterate on).
 *
 * "auto" must solve at least MIN_AUTO_SOLVED of the problems of each family, so a solver
 * that reaches SOLVED on no contact problem fails. At the end a table counts the statuses;
 * a run where no problem with contacts reached SOLVED, or none stopped at the cap, fails
 * (the test would then not exercise both sides of the consistency check; the problems
 * without a contact are left out of this count, being SOLVED by construction).
 *
 * Usage: test_random [FCLIB_DATA_DIR] (the directory is not used). Runs under valgrind too. */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-8
#define CAP 300u
#define SLACK 1e-12 /* relative, on TOL, for SOLVED: round-off of two summation orders */
#define AGREE 1e-9  /* stats.error against the independent error, relative */
#define SEED 0xC0FFEE2026ull
#define NB 3        /* bodies of the global problems: n = 9 */

static const char *const VARIANTS[] = {
    "auto",          "cp-N",          "cp-R",          "cp-RR",          "vp-N-He",
    "vp-R-He",       "vp-RR-He",      "vp-N-Wohlberg", "vp-R-Wohlberg",  "vp-RR-Wohlberg",
    "vp-N-Spectral", "vp-R-Spectral", "vp-RR-Spectral", "newton",
};
#define N_VARIANTS (sizeof VARIANTS / sizeof VARIANTS[0])

#define MU_OVERFLOW 1e8 /* the friction coefficient with which the iterates may overflow */
static const double MUS[] = {0.0, 1e-4, 0.3, 1.0, 10.0, MU_OVERFLOW};
#define N_MUS (sizeof MUS / sizeof MUS[0])

enum family { GLOBAL, GLOBAL_SINGULAR, GLOBAL_JOINT, LOCAL, LOCAL_SINGULAR, N_FAMILIES };
static const char *const FAMILY[] = {"global", "global, singular W", "global, one joint",
                                     "local", "local, singular W"};
/* Least number of the N_MUS problems of each family that "auto" must solve within CAP
 * iterations. Measured (seed SEED, CAP 300): 6 of 6 in each family but "local, singular W",
 * 5 of 6 (with mu = 1 it proves the problem infeasible); one problem of margin each. */
static const unsigned MIN_AUTO_SOLVED[N_FAMILIES] = {5, 5, 5, 5, 4};

/* ---- generator ------------------------------------------------------------------------------ */

static double *dense(size_t rows, size_t cols) { return (double *)tu_calloc(rows * cols,
                     sizeof(double)); }

/* A random SPD block-diagonal mass matrix (NB bodies of 3 velocities), row-major. */
static double *random_mass(tu_rng *g, size_t n)
{
    double *M = dense(n, n);
    for (size_t b = 0; b < n / 3; ++b) {
        double mass = tu_rng_range(g, 0.5, 3.0), c = tu_rng_range(g, -0.3, 0.3);
        for (size_t i = 0; i < 3; ++i) M[(3 * b + i) * n + 3 * b + i] = mass * tu_rng_range(g, 0.8,
             1.2);
        M[(3 * b) * n + 3 * b + 2] = M[(3 * b + 2) * n + 3 * b] = c * mass;
    }
    return M;
}

/* Fills columns 3k..3k+2 of H (n x m, row-major) for a contact of body b1 against body b2
 * (or the ground when b2 >= NB): a perturbed identity frame. */
static void contact_columns(tu_rng *g, double *H, size_t n, size_t m, size_t k, size_t b1,
                            size_t b2)
{
    (void)n;
    for (size_t i = 0; i < 3; ++i)
        for (size_t j = 0; j < 3; ++j) {
            double h = (i == j ? 1.0 : 0.0) + tu_rng_range(g, -0.4, 0.4);
            H[(3 * b1 + i) * m + 3 * k + j] += h;
            if (b2 < NB && b2 != b1) H[(3 * b2 + i) * m + 3 * k + j] -= h;
        }
}

static tu_problem random_global(tu_rng *g, enum family fam, double mu)
{
    tu_problem p;
    size_t n = 3 * NB, nc, m;
    double *M = random_mass(g, n), *H;
    memset(&p, 0, sizeof p);
    p.is_global = 1;
    p.n = n;
    /* singular W: 4 contacts on 9 velocities (rank <= 9 < 12), the last repeating the
       first's rows of H; otherwise 1 to 3 contacts on distinct bodies (W positive
       definite for a generic H) */
    nc = fam == GLOBAL_SINGULAR ? 4 : 1 + tu_rng_index(g, 3);
    m = 3 * nc;
    H = dense(n, m);
    for (size_t k = 0; k < nc; ++k) {
        if (fam == GLOBAL_SINGULAR && k == nc - 1) {
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j < 3; ++j) H[i * m + 3 * k + j] = H[i * m + j];
        } else {
            contact_columns(g, H, n, m, k, k % NB, NB); /* against the ground */
        }
    }
    p.nc = nc;
    p.M = tu_csc_from_dense(n, n, M);
    p.H = tu_csc_from_dense(n, m, H);
    p.f = (double *)tu_calloc(n, sizeof(double));
    p.w = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    /* gravity-like push along each contact's normal, plus a random tangential part */
    for (size_t i = 0; i < n; ++i) p.f[i] = tu_rng_range(g, -1.0, 1.0) - (i % 3 == 0 ? 1.5 : 0.0);
    for (size_t i = 0; i < m; ++i) p.w[i] = tu_rng_range(g, -0.05, 0.05);
    for (size_t k = 0; k < nc; ++k) p.mu[k] = mu;
    if (fam == GLOBAL_JOINT) {
        /* one bilateral constraint on a random combination of the last body's velocities */
        double Gd[3 * NB];
        memset(Gd, 0, sizeof Gd);
        for (size_t i = 3 * (NB - 1); i < 3 * NB; ++i) Gd[i] = tu_rng_range(g, -1.0, 1.0);
        Gd[3 * (NB - 1) + 1] += 1.5;
        p.G = tu_csc_from_dense(n, 1, Gd);
        p.b = (double *)tu_calloc(1, sizeof(double));
        p.b[0] = tu_rng_range(g, -0.2, 0.2);
    }
    free(M);
    free(H);
    return p;
}

static tu_problem random_local(tu_rng *g, enum family fam, double mu)
{
    tu_problem p;
    size_t nc = 1 + tu_rng_index(g, 3), m = 3 * nc;
    /* W = A^T A (+ 0.1 I): A is k x m with k = m (regular) or m - 2 (singular W) */
    size_t k = fam == LOCAL_SINGULAR ? m - 2 : m;
    double *A = dense(k, m), *W = dense(m, m);
    memset(&p, 0, sizeof p);
    p.nc = nc;
    for (size_t i = 0; i < k * m; ++i) A[i] = tu_rng_range(g, -1.0, 1.0);
    for (size_t i = 0; i < m; ++i)
        for (size_t j = 0; j < m; ++j) {
            double s = (fam == LOCAL && i == j) ? 0.1 : 0.0;
            for (size_t r = 0; r < k; ++r) s += A[r * m + i] * A[r * m + j];
            W[i * m + j] = s;
        }
    /* exactly symmetric: the library picks Cholesky for a symmetric W */
    for (size_t i = 0; i < m; ++i)
        for (size_t j = 0; j < i; ++j) W[i * m + j] = W[j * m + i];
    p.W = tu_csc_from_dense(m, m, W);
    p.q = (double *)tu_calloc(m, sizeof(double));
    p.mu = (double *)tu_calloc(nc, sizeof(double));
    for (size_t i = 0; i < m; ++i) p.q[i] = tu_rng_range(g, -1.0, 1.0) - (i % 3 == 0 ? 0.5 : 0.0);
    for (size_t c = 0; c < nc; ++c) p.mu[c] = mu;
    free(A);
    free(W);
    return p;
}

/* A problem without contacts: global (M v = f) or local (nothing at all). */
static tu_problem no_contact(tu_rng *g, int global)
{
    tu_problem p;
    memset(&p, 0, sizeof p);
    p.is_global = global;
    if (global) {
        double *M = random_mass(g, 3 * NB);
        p.n = 3 * NB;
        p.M = tu_csc_from_dense(p.n, p.n, M);
        p.H = tu_csc_from_dense(p.n, 0, M); /* n x 0 */
        p.f = (double *)tu_calloc(p.n, sizeof(double));
        for (size_t i = 0; i < p.n; ++i) p.f[i] = tu_rng_range(g, -1.0, 1.0);
        free(M);
    } else {
        p.W = tu_csc_from_dense(0, 0, NULL);
    }
    return p;
}

/* ---- solving ------------------------------------------------------------------------------ */

static unsigned counts[6];         /* per status, all solves */
static unsigned contact_counts[6]; /* per status, solves of problems with contacts */
static unsigned n_solves;
static unsigned auto_solved[N_FAMILIES]; /* "auto" solves that reached SOLVED, per family */
static double max_roundoff;              /* largest R / TOL over SOLVED answers */
static double max_bound_ratio;           /* largest ||r|| / bound over SOLVED answers */
static unsigned n_bounded;               /* SOLVED answers with a finite bound on ||r|| */

/* Solves `p` (of family `fam` and friction `mu`; fam < 0: no contact, must_solve) with every
 * variant and checks each outcome and the reason of each non-SOLVED status. */
static void solve_all_variants(const char *name, const tu_problem *p, int fam, double mu,
                               int must_solve)
{
    cadmm_problem *lib = NULL;
    cadmm_result rc = tu_problem_to_cadmm(p, &lib);
    unsigned solved = 0, capped = 0;
    if (rc != CADMM_OK) {
        TU_FAIL("%s: building the problem returned %d: %s", name, (int)rc, cadmm_last_error());
        return;
    }
    for (size_t vi = 0; vi < N_VARIANTS; ++vi) {
        char label[200];
        cadmm_settings *s = NULL;
        tu_outcome o;
        snprintf(label, sizeof label, "%s / %s", name, VARIANTS[vi]);
        REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
        REQUIRE(cadmm_settings_set_variant(s, VARIANTS[vi]) == CADMM_OK);
        REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
        REQUIRE(cadmm_settings_set_max_iterations(s, CAP) == CADMM_OK);
        tu_solve(p, lib, s, &o);
        ++n_solves;
        if (tu_check_outcome(label, p, &o, TOL, SLACK, AGREE) == 0 && o.solved_call) {
            /* no time limit is set */
            CHECK_MSG(o.status != CADMM_STATUS_TIME_LIMIT, "%s: status time_limit without a "
                      "time limit", label);
            /* Only Newton alone, with no ADMM to fall back on, may stop by stalling. */
            if (o.status == CADMM_STATUS_STALLED)
                CHECK_MSG(strcmp(VARIANTS[vi], "newton") == 0, "%s: status stalled", label);
            if (o.status == CADMM_STATUS_MAX_ITERATIONS)
                CHECK_MSG(o.stats.iterations == CAP, "%s: MAX_ITERATIONS after %llu iterations",
                          label, (unsigned long long)o.stats.iterations);
            /* The iterates overflow only with mu = 1e8 (Phi(u) = mu ||u_T|| dominates u); the
               returned answer is then finite (tu_check_outcome checked r, u, v, lambda). */
            if (o.status == CADMM_STATUS_NUMERICAL_ERROR)
                CHECK_MSG(mu == MU_OVERFLOW, "%s: numerical_error where the iterates cannot "
                          "overflow", label);
            /* INFEASIBLE: tu_check_outcome verified the certificate on the returned r; and
               only a singular W allows one (with W positive definite a solution exists, and
               tu_problem_solution_bound then gives a finite bound). */
            if (o.status == CADMM_STATUS_INFEASIBLE)
                CHECK_MSG(!isfinite(tu_problem_solution_bound(p)), "%s: infeasible, but W is "
                          "positive definite", label);
            if (o.status == CADMM_STATUS_SOLVED) {
                double B = tu_problem_solution_bound(p);
                double R = tu_problem_error_roundoff(p, o.r, o.v, o.lambda);
                max_roundoff = tu_max(max_roundoff, R / TOL);
                if (isfinite(B) && B > 0.0) {
                    max_bound_ratio = tu_max(max_bound_ratio, tu_norm(o.r, 3 * p->nc) / B);
                    ++n_bounded;
                }
            }
            if (must_solve)
                CHECK_MSG(o.status == CADMM_STATUS_SOLVED, "%s: not solved (%s)", label,
                          tu_status_name(o.status));
        }
        if (o.solved_call && o.status >= 0 && o.status <= CADMM_STATUS_INFEASIBLE) {
            ++counts[o.status];
            if (p->nc > 0) ++contact_counts[o.status];
            if (fam >= 0 && vi == 0 && o.status == CADMM_STATUS_SOLVED) ++auto_solved[fam];
            solved += o.status == CADMM_STATUS_SOLVED;
            capped += o.status == CADMM_STATUS_MAX_ITERATIONS;
        }
        tu_outcome_free(&o);
        cadmm_settings_free(s);
    }
    printf("  %-40s nc %zu: %2u solved, %2u at the cap\n", name, p->nc, solved, capped);
    cadmm_problem_free(lib);
}

int main(void)
{
    tu_rng g = tu_rng_new(SEED);
    printf("cadmm %s: randomized problems (seed %#llx, tol %.0e, cap %u iterations)\n",
           cadmm_version(), (unsigned long long)SEED, TOL, CAP);
    for (int fam = 0; fam < N_FAMILIES; ++fam)
        for (size_t mi = 0; mi < N_MUS; ++mi) {
            char name[128];
            tu_problem p = fam <= GLOBAL_JOINT ? random_global(&g, (enum family)fam, MUS[mi])
                                               : random_local(&g, (enum family)fam, MUS[mi]);
            snprintf(name, sizeof name, "%s, mu = %g", FAMILY[fam], MUS[mi]);
            solve_all_variants(name, &p, fam, MUS[mi], 0);
            tu_problem_free(&p);
        }
    for (int global = 1; global >= 0; --global) {
        tu_problem p = no_contact(&g, global);
        solve_all_variants(global ? "global, no contact" : "local, no contact", &p, -1, 0.0, 1);
        tu_problem_free(&p);
    }
    printf("%u solves: %u solved, %u max_iterations, %u time_limit, %u numerical_error, "
           "%u stalled, %u infeasible\n", n_solves, counts[0], counts[1], counts[2], counts[3],
           counts[4], counts[5]);
    printf("problems with contacts: %u solved, %u max_iterations, %u numerical_error, %u "
           "stalled, %u infeasible\n", contact_counts[0], contact_counts[1], contact_counts[3],
           contact_counts[4], contact_counts[5]);
    printf("\"auto\" solved per family (of %zu):", N_MUS);
    for (int fam = 0; fam < N_FAMILIES; ++fam)
        printf(" %s %u (at least %u)%s", FAMILY[fam], auto_solved[fam], MIN_AUTO_SOLVED[fam],
               fam + 1 < N_FAMILIES ? ";" : "\n");
    printf("SOLVED answers: largest round-off estimate %.1e tol; ||r|| at most %.3f of the "
           "a priori bound (%u answers with one)\n", max_roundoff, max_bound_ratio, n_bounded);
    for (int fam = 0; fam < N_FAMILIES; ++fam)
        CHECK_MSG(auto_solved[fam] >= MIN_AUTO_SOLVED[fam], "\"auto\" solved %u of the %zu "
                  "problems of family \"%s\", expected at least %u", auto_solved[fam], N_MUS,
                  FAMILY[fam], MIN_AUTO_SOLVED[fam]);
    /* counted on the problems with contacts only: the no-contact ones are always SOLVED */
    CHECK_MSG(contact_counts[CADMM_STATUS_SOLVED] > 0 &&
                  contact_counts[CADMM_STATUS_MAX_ITERATIONS] > 0,
              "the problems with contacts did not exercise both SOLVED (%u) and "
              "MAX_ITERATIONS (%u)", contact_counts[CADMM_STATUS_SOLVED],
              contact_counts[CADMM_STATUS_MAX_ITERATIONS]);
    return tu_finish("test_random");
}
