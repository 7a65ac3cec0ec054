/* Install consumer: one contact, a unit mass pressed on the ground with a tangential push,
 * solved with every variant in the global and the local form.
 *
 * Global: M = m I, H = I, w = 0, so W = I/m and q = f/m. With f = m (-1, 0.2, -0.1) and
 * mu = 0.5 the contact sticks (||q_T|| = 0.22 <= mu |q_N| = 0.5): u = 0, r = -m q = -f,
 * v = 0. Local: the same problem with W = I/m, q = f/m. With mu = 0.1 it slides instead:
 * r_N = -q_N m = m, r_T = -mu r_N q_T/||q_T||. */
#include <cadmm.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *const VARIANTS[] = {
    "auto", "cp-N", "cp-R", "cp-RR", "vp-N-He", "vp-R-He", "vp-RR-He", "vp-N-Wohlberg",
    "vp-R-Wohlberg", "vp-RR-Wohlberg", "vp-N-Spectral", "vp-R-Spectral", "vp-RR-Spectral"};

static int failures = 0;

static void expect(int ok, const char *what, const char *variant, const char *form)
{
    if (!ok) {
        fprintf(stderr, "FAILED: %s (%s, %s)\n", what, variant, form);
        ++failures;
    }
}

static double dist(const double *a, const double *b)
{
    double s = 0.0;
    for (int i = 0; i < 3; ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(s);
}

static void solve(const cadmm_problem *p, const char *variant, const char *form,
                  const double r_exact[3], const double u_exact[3])
{
    cadmm_settings *s = NULL;
    cadmm_solver *sv = NULL;
    cadmm_status status = -1;
    double r[3] = {0}, u[3] = {0};
    expect(cadmm_settings_new(&s) == CADMM_OK, "settings_new", variant, form);
    expect(cadmm_settings_set_variant(s, variant) == CADMM_OK, "set_variant", variant, form);
    expect(cadmm_settings_set_tolerance(s, 1e-10) == CADMM_OK, "set_tolerance", variant, form);
    if (cadmm_solver_new(p, s, &sv) != CADMM_OK) {
        expect(0, "solver_new", variant, form);
        cadmm_settings_free(s);
        return;
    }
    expect(cadmm_solver_solve(sv, &status) == CADMM_OK, "solve", variant, form);
    expect(status == CADMM_STATUS_SOLVED, "status solved", variant, form);
    expect(cadmm_solver_get_solution(sv, r, u, NULL) == CADMM_OK, "get_solution", variant, form);
    expect(dist(r, r_exact) <= 1e-6 * fmax(1.0, sqrt(r_exact[0] * r_exact[0] + r_exact[1] * r_exact[1] + r_exact[2] * r_exact[2])),
           "r matches the closed form", variant, form);
    expect(dist(u, u_exact) <= 1e-6, "u matches the closed form", variant, form);
    cadmm_solver_free(sv);
    cadmm_settings_free(s);
}

int main(void)
{
    const double m = 2.0;
    const int64_t colptr[4] = {0, 1, 2, 3}, rowind[3] = {0, 1, 2};
    const double mvals[3] = {m, m, m}, ones[3] = {1.0, 1.0, 1.0}, wvals[3] = {1 / m, 1 / m, 1 / m};
    const cadmm_csc M = {3, 3, colptr, rowind, mvals};
    const cadmm_csc H = {3, 3, colptr, rowind, ones};
    const cadmm_csc W = {3, 3, colptr, rowind, wvals};
    const double f[3] = {-m, 0.2 * m, -0.1 * m}, w[3] = {0, 0, 0}, q[3] = {-1.0, 0.2, -0.1};
    const double mu_stick = 0.5, mu_slide = 0.1;
    const double r_stick[3] = {m, -0.2 * m, 0.1 * m}, zero[3] = {0, 0, 0};
    double qt = sqrt(0.2 * 0.2 + 0.1 * 0.1);
    /* sliding: r_N = m, r_T = -mu m q_T/|q_T|, u_T = q_T (1 - (1/m) mu m / |q_T|) */
    const double r_slide[3] = {m, -mu_slide * m * 0.2 / qt, mu_slide * m * 0.1 / qt};
    const double u_slide[3] = {0.0, 0.2 * (1 - mu_slide / qt), -0.1 * (1 - mu_slide / qt)};
    cadmm_problem *global = NULL, *local = NULL;
    size_t n = 0, nc = 0;
    bool is_global = false;

    printf("cadmm %s (%s)\n", cadmm_version(), cadmm_result_message(CADMM_OK));
    if (cadmm_problem_new_global(3, 1, &M, &H, f, w, &mu_stick, &global) != CADMM_OK ||
        cadmm_problem_new_local(1, &W, q, &mu_slide, &local) != CADMM_OK) {
        fprintf(stderr, "FAILED: building the problems\n");
        return 1;
    }
    expect(cadmm_problem_dims(global, &n, &nc, &is_global) == CADMM_OK && n == 3 && nc == 1 &&
               is_global,
           "problem_dims", "-", "global");
    for (size_t i = 0; i < sizeof VARIANTS / sizeof VARIANTS[0]; ++i) {
        solve(global, VARIANTS[i], "global", r_stick, zero);
        solve(local, VARIANTS[i], "local", r_slide, u_slide);
    }
    cadmm_problem_free(global);
    cadmm_problem_free(local);
    if (failures) {
        fprintf(stderr, "%d failure(s)\n", failures);
        return 1;
    }
    printf("install consumer: all variants solved both forms\n");
    return 0;
}
