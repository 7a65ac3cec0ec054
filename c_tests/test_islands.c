/* Contact islands through the C API, on a scene with known answers:
 *
 *   M = I (12 velocities: four unit point masses of 3 velocities each), H selects the
 *   velocities of the contact's mass (contact frame = world frame, normal first), w = 0:
 *   - mass 0 rests on the ground, pushed sideways: f = (-9.81, 0.5, 0), mu = 0.3, sticks:
 *     r = (9.81, -0.5, 0), v = 0;
 *   - mass 1 is pressed down, frictionless (mu = 0): r = (9.81, 0, 0), v = (0, 2, 0) for
 *     f = (-9.81, 2, 0);
 *   - mass 2 moves up, f = (1, 0, 0): its contact separates, r = 0, v = f;
 *   - mass 3 touches nothing: v = M^-1 f = f = (0, 0, -1).
 *
 * Checks: islands counted (3 contact islands), each island's statistics and status, the
 * rows in the systems (the frictionless island keeps 1 row), the answers, the same solution
 * bit for bit on 1 and 2 threads and with islands off (to 1e-7), bad settings and indices
 * refused by name, and a contact that touches no body and approaches reported
 * CADMM_STATUS_INFEASIBLE.
 *
 * Usage: test_islands [FCLIB_DATA_DIR] (the directory is not used). */
#include "cadmm.h"
#include "test_util.h"

#define TOL 1e-10
#define NV 12
#define NC 4

static const double F[NV] = {-9.81, 0.5, 0.0, -9.81, 2.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0};
static const double R_EXACT[3 * NC] = {9.81, -0.5, 0.0, 9.81, 0.0, 0.0, 0.0, 0.0, 0.0,
                                       0.0,  0.0,  0.0};
static const double V_EXACT[NV] = {0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0};

/* Solves the scene with the given islands and threads settings into r, v; returns the
 * status and fills st. Contact 3's columns of H are empty when `bodiless` (it then moves
 * with w = (-1, 0, 0), approaching), otherwise contact 3 is absent from the result check. */
static cadmm_status solve_scene(int islands, size_t threads, double w3, double r[3 * NC],
                                double v[NV], cadmm_stats *st, cadmm_solver **keep)
{
    static int64_t mcol[NV + 1], mrow[NV], hcol[3 * NC + 1], hrow[3 * NC];
    static double ones[NV];
    size_t k;
    for (k = 0; k < NV; ++k) {
        mcol[k] = (int64_t)k;
        mrow[k] = (int64_t)k;
        ones[k] = 1.0;
    }
    mcol[NV] = NV;
    /* Contacts 0, 1, 2 on masses 0, 1, 2; contact 3's columns are empty. */
    for (k = 0; k < 9; ++k) {
        hcol[k] = (int64_t)k;
        hrow[k] = (int64_t)k;
    }
    for (k = 9; k <= 3 * NC; ++k) hcol[k] = 9;
    cadmm_csc M = {NV, NV, mcol, mrow, ones};
    cadmm_csc H = {NV, 3 * NC, hcol, hrow, ones};
    double w[3 * NC] = {0};
    const double mu[NC] = {0.3, 0.0, 0.5, 0.5};
    w[9] = w3;
    cadmm_problem *p = NULL;
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    cadmm_status status = -1;
    REQUIRE(cadmm_problem_new_global(NV, NC, &M, &H, F, w, mu, &p) == CADMM_OK);
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_settings_set_islands(s, islands != 0) == CADMM_OK);
    REQUIRE(cadmm_settings_set_threads(s, threads) == CADMM_OK);
    REQUIRE(cadmm_solver_new(p, s, &sv) == CADMM_OK);
    REQUIRE(cadmm_solver_solve(sv, &status) == CADMM_OK);
    REQUIRE(cadmm_solver_get_solution(sv, r, NULL, v) == CADMM_OK);
    memset(st, 0, sizeof *st);
    st->struct_size = sizeof *st;
    REQUIRE(cadmm_solver_get_stats(sv, st) == CADMM_OK);
    cadmm_settings_free(s);
    cadmm_problem_free(p);
    if (keep)
        *keep = sv;
    else
        cadmm_solver_free(sv);
    return status;
}

int main(void)
{
    double r1[3 * NC], v1[NV], r2[3 * NC], v2[NV], r0[3 * NC], v0[NV];
    cadmm_stats st, isl;
    cadmm_solver *sv = NULL;
    cadmm_settings *s = NULL;
    size_t k;
    printf("cadmm %s: contact islands (exact answers known)\n", cadmm_version());

    /* w3 = +1: the bodiless contact separates, r = 0 solves it. */
    cadmm_status status = solve_scene(1, 1, 1.0, r1, v1, &st, &sv);
    CHECK_MSG(status == CADMM_STATUS_SOLVED, "status %d", status);
    CHECK_MSG(st.islands == 3, "islands %llu, expected 3", (unsigned long long)st.islands);
    CHECK_MSG(st.failed_island == -1, "failed_island %lld", (long long)st.failed_island);
    /* Rows: 3 (sticking) + 1 (frictionless island) + 3 (separating) = 7. */
    CHECK_MSG(st.rows == 7, "rows %llu, expected 7", (unsigned long long)st.rows);
    for (k = 0; k < 3; ++k) {
        memset(&isl, 0, sizeof isl);
        isl.struct_size = sizeof isl;
        CHECK(cadmm_solver_get_island_stats(sv, k, &isl) == CADMM_OK);
        CHECK_MSG(isl.status == CADMM_STATUS_SOLVED, "island %zu status %d", k, isl.status);
        CHECK_MSG(isl.error <= TOL, "island %zu error %.3e", k, isl.error);
    }
    /* Island 2 separates under the free motion: solved with no iteration. */
    CHECK(cadmm_solver_get_island_stats(sv, 2, &isl) == CADMM_OK);
    CHECK_MSG(isl.iterations == 0, "separating island: %llu iterations",
              (unsigned long long)isl.iterations);
    /* A bad index and a short struct are refused, *out untouched. */
    memset(&isl, 0x5a, sizeof isl);
    isl.struct_size = sizeof isl;
    CHECK(cadmm_solver_get_island_stats(sv, 3, &isl) == CADMM_ERR_INVALID_VALUE);
    CHECK(strstr(cadmm_last_error(), "island 3") != NULL);
    CHECK(isl.status == 0x5a5a5a5a);
    CHECK(cadmm_solver_get_island_stats(sv, 0, NULL) == CADMM_ERR_NULL_POINTER);
    cadmm_solver_free(sv);

    for (k = 0; k < 3 * NC; ++k)
        CHECK_MSG(fabs(r1[k] - R_EXACT[k]) <= 1e-7, "r[%zu] = %.10g, exact %.10g", k, r1[k],
                  R_EXACT[k]);
    for (k = 0; k < NV; ++k)
        CHECK_MSG(fabs(v1[k] - V_EXACT[k]) <= 1e-7, "v[%zu] = %.10g, exact %.10g", k, v1[k],
                  V_EXACT[k]);

    /* Two threads: the same bits. Islands off: the same answer. */
    status = solve_scene(1, 2, 1.0, r2, v2, &st, NULL);
    CHECK(status == CADMM_STATUS_SOLVED);
    CHECK(memcmp(r1, r2, sizeof r1) == 0 && memcmp(v1, v2, sizeof v1) == 0);
    status = solve_scene(0, 1, 1.0, r0, v0, &st, NULL);
    CHECK(status == CADMM_STATUS_SOLVED);
    CHECK_MSG(st.islands == 1, "islands off: islands %llu", (unsigned long long)st.islands);
    CHECK_MSG(st.rows == 3 * NC, "islands off: rows %llu", (unsigned long long)st.rows);
    for (k = 0; k < 3 * NC; ++k) CHECK(fabs(r0[k] - R_EXACT[k]) <= 1e-7);
    for (k = 0; k < NV; ++k) CHECK(fabs(v0[k] - V_EXACT[k]) <= 1e-7);

    /* w3 = -1: the bodiless contact approaches and nothing can stop it. */
    status = solve_scene(1, 1, -1.0, r2, v2, &st, NULL);
    CHECK_MSG(status == CADMM_STATUS_INFEASIBLE, "approaching bodiless contact: status %d",
              status);
    CHECK(r2[9] == 0.0 && r2[10] == 0.0 && r2[11] == 0.0);

    /* Settings refused by name, the settings unchanged. */
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    CHECK(cadmm_settings_set_threads(s, 0) == CADMM_ERR_INVALID_SETTING);
    CHECK(strstr(cadmm_last_error(), "threads") != NULL);
    CHECK(cadmm_settings_set_threads(s, 257) == CADMM_ERR_INVALID_SETTING);
    CHECK(cadmm_settings_set_threads(NULL, 2) == CADMM_ERR_NULL_POINTER);
    CHECK(cadmm_settings_set_islands(NULL, true) == CADMM_ERR_NULL_POINTER);
    cadmm_settings_free(s);
    return tu_finish("test_islands");
}
