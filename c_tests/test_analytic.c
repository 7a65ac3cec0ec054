/* Single-contact problems with a closed-form Coulomb answer, solved through the C API in
 * the global and the local form with every variant name and "auto".
 *
 * Conventions (docs/algorithms.md §1): contact vectors are (N, T1, T2), normal first.
 * Local form u = W r + q; global form M v = H r + f, u = H^T v + w, so the global problem
 * is the local one with the Delassus W = H^T M^-1 H and q = H^T M^-1 f + w. Coulomb's law
 * in De Saxce's form: K*_mu contains u + (mu ||u_T||, 0, 0), r is in K_mu, and the two are
 * orthogonal.
 *
 * ---- Closed form for W = diag(aN, aT, aT) (aN, aT > 0) --------------------------------
 * Then u_N = aN r_N + q_N and u_T = aT r_T + q_T: normal and tangential parts decouple.
 *  (a) take-off / open, q_N >= 0: r = 0, u = q. Admissible: u~ = (q_N + mu|q_T|, q_T) lies
 *      in K*_mu iff mu |q_T| <= q_N + mu |q_T| iff q_N >= 0. Unique: r_N > 0 would need
 *      u_N = 0 (an active contact does not separate) but u_N = aN r_N + q_N > 0.
 *  (b) q_N < 0: the contact is active, u_N = 0, so r_N = -q_N / aN > 0.
 *      stick (u_T = 0): r_T = -q_T / aT, admissible iff ||r_T|| <= mu r_N, i.e.
 *          ||q_T|| <= mu (aT / aN) |q_N|.          r = -W^-1 q, u = 0.
 *      slide (otherwise): Coulomb gives r_T = -mu r_N u_T / ||u_T||, so
 *          u_T (1 + aT mu r_N / ||u_T||) = q_T: u_T is parallel to q_T with
 *          ||u_T|| = ||q_T|| - aT mu r_N > 0, and r_T = -mu r_N q_T / ||q_T||,
 *          u_T = q_T (1 - aT mu r_N / ||q_T||), u_N = 0. The impulse is on the boundary of
 *          K_mu, opposite the sliding velocity. De Saxce check: u~ = (mu ||u_T||, u_T) is on
 *          the boundary of K*_mu and r . u~ = mu r_N ||u_T|| - mu r_N ||u_T|| = 0.
 *      frictionless (mu = 0): the slide formula with mu = 0: r = (-q_N / aN, 0, 0),
 *          u = (0, q_T): K_0 is the normal ray, K*_0 the half-space u_N >= 0.
 *  Example: M = m I, H = I, w = 0 gives aN = aT = 1/m, q = f/m = v_free, and sticking
 *  r = -m v_free; a rotated frame H = R (R orthogonal) keeps W = R^T R / m = I/m.
 *
 * ---- Manufactured solutions for a coupled W (no closed form for sliding) ---------------
 * Choose (r*, u*) satisfying the cone conditions exactly (stick: u* = 0, r* inside K; slide:
 * u*_N = 0, r*_T = -mu r*_N u*_T / ||u*_T||; open: r* = 0, u*_N > 0; frictionless: mu = 0,
 * r*_T = 0, u*_N = 0) and set q = u* - W r* (local) or, in the global form,
 * v* = H (H^T H)^-1 (u* - w) and f = M v* - H r*. For the moderately coupled, well
 * conditioned W used below and mu <= 0.5 the solution is unique, so the solver must return
 * r* (its error measure at (r*, u*, v*) is checked to be ~0 with the library's
 * cadmm_problem_error and with the independent one of test_util.h). */
#include "cadmm.h"
#include "test_util.h"

/* Solver tolerance on the error measure. The measure is relative to max(||u||, ||r||): for
 * the heavy body (M = 1000 I, r ~ 1e3, u ~ 1) a measure of 1e-9 still allows a relative
 * error of ~1e-6 on r (an error du in u_N moves r_N by du / W_NN = 1e3 du), hence 1e-10. */
#define TOL 1e-10
#define ACC 1e-6     /* required accuracy, scaled: ||x - x_exact|| / max(1, ||x_exact||) */
#define NMAX 6
#define PI 3.14159265358979323846

static const char *const VARIANTS[] = {
    "auto",          "cp-N",           "cp-R",           "cp-RR",         "vp-N-He",
    "vp-R-He",       "vp-RR-He",       "vp-N-Wohlberg",  "vp-R-Wohlberg", "vp-RR-Wohlberg",
    "vp-N-Spectral", "vp-R-Spectral",  "vp-RR-Spectral",
};
#define N_VARIANTS (sizeof VARIANTS / sizeof VARIANTS[0])

/* ---- small dense linear algebra (row-major) ------------------------------------------- */

/* Solves A x = b (n <= NMAX) by Gaussian elimination with partial pivoting. */
static void dense_solve(size_t n, const double *A, const double *b, double *x)
{
    double a[NMAX * NMAX], y[NMAX];
    memcpy(a, A, n * n * sizeof(double));
    memcpy(y, b, n * sizeof(double));
    for (size_t k = 0; k < n; ++k) {
        size_t piv = k;
        for (size_t i = k + 1; i < n; ++i)
            if (fabs(a[i * n + k]) > fabs(a[piv * n + k])) piv = i;
        REQUIRE(fabs(a[piv * n + k]) > 1e-300);
        if (piv != k) {
            for (size_t j = 0; j < n; ++j) {
                double t = a[k * n + j];
                a[k * n + j] = a[piv * n + j];
                a[piv * n + j] = t;
            }
            double t = y[k];
            y[k] = y[piv];
            y[piv] = t;
        }
        for (size_t i = k + 1; i < n; ++i) {
            double l = a[i * n + k] / a[k * n + k];
            for (size_t j = k; j < n; ++j) a[i * n + j] -= l * a[k * n + j];
            y[i] -= l * y[k];
        }
    }
    for (size_t k = n; k-- > 0;) {
        double s = y[k];
        for (size_t j = k + 1; j < n; ++j) s -= a[k * n + j] * x[j];
        x[k] = s / a[k * n + k];
    }
}

/* y = A x, A is rows x cols row-major. */
static void dense_mul(size_t rows, size_t cols, const double *A, const double *x, double *y)
{
    for (size_t i = 0; i < rows; ++i) {
        double s = 0.0;
        for (size_t j = 0; j < cols; ++j) s += A[i * cols + j] * x[j];
        y[i] = s;
    }
}

/* y = A^T x, A is rows x cols row-major. */
static void dense_mul_t(size_t rows, size_t cols, const double *A, const double *x, double *y)
{
    for (size_t j = 0; j < cols; ++j) {
        double s = 0.0;
        for (size_t i = 0; i < rows; ++i) s += A[i * cols + j] * x[i];
        y[j] = s;
    }
}

/* ---- problem forms ----------------------------------------------------------------------- */

typedef struct form {
    const char *name;
    int global;
    size_t n;          /* velocities (global) */
    double M[NMAX * NMAX]; /* n x n */
    double H[NMAX * 3];    /* n x 3 */
    double w[3];
    double W[9];       /* local form: 3 x 3 */
    int closed_form;   /* effective W = diag(aN, aT, aT) (checked numerically) */
    double aN, aT;
} form;

enum { OPEN, STICK, SLIDE };
static const char *const CATEGORY[] = {"open", "stick", "slide"};

typedef struct contact_case {
    const char *name;
    double mu;
    int category;
    double q[3];          /* closed-form forms: the free local velocity */
    double r_star[3];     /* manufactured forms: the solution */
    double u_star[3];
} contact_case;

static const contact_case CASES[] = {
    /* stick: ||q_T|| = 0.224 <= mu (aT/aN) |q_N| for every closed-form W below */
    {"stick", 0.5, STICK, {-1.0, 0.2, -0.1}, {1.0, 0.2, -0.1}, {0.0, 0.0, 0.0}},
    /* slide: ||q_T|| = 1 > mu (aT/aN) |q_N| = 0.6 at most */
    {"slide", 0.3, SLIDE, {-1.0, 0.8, -0.6}, {1.0, -0.18, 0.24}, {0.0, 0.42, -0.56}},
    /* open / take-off: the normal free velocity is positive */
    {"open", 0.5, OPEN, {0.5, 0.3, -0.2}, {0.0, 0.0, 0.0}, {0.5, 0.3, -0.2}},
    /* frictionless: mu = 0, slides freely, only a normal impulse */
    {"frictionless", 0.0, SLIDE, {-1.0, 0.4, 0.2}, {1.2, 0.0, 0.0}, {0.0, 0.4, -0.3}},
    /* pressed straight down: stick with r_T = 0 */
    {"press", 0.5, STICK, {-2.0, 0.0, 0.0}, {2.0, 0.0, 0.0}, {0.0, 0.0, 0.0}},
};
#define N_CASES (sizeof CASES / sizeof CASES[0])

/* Closed-form Coulomb solution for W = diag(aN, aT, aT), see the header comment. */
static int coulomb_diag(double aN, double aT, const double q[3], double mu, double r[3],
                        double u[3])
{
    double qt = sqrt(q[1] * q[1] + q[2] * q[2]);
    if (q[0] >= 0.0) { /* (a) open */
        r[0] = r[1] = r[2] = 0.0;
        memcpy(u, q, 3 * sizeof(double));
        return OPEN;
    }
    r[0] = -q[0] / aN;
    u[0] = 0.0;
    if (qt <= mu * aT * r[0]) { /* (b) stick */
        r[1] = -q[1] / aT;
        r[2] = -q[2] / aT;
        u[1] = u[2] = 0.0;
        return STICK;
    }
    /* (b) slide (qt > 0 here, since qt > mu aT r_N >= 0) */
    r[1] = -mu * r[0] * q[1] / qt;
    r[2] = -mu * r[0] * q[2] / qt;
    u[1] = q[1] * (1.0 - aT * mu * r[0] / qt);
    u[2] = q[2] * (1.0 - aT * mu * r[0] / qt);
    return SLIDE;
}

/* Rotation Rz(30 deg) Rx(45 deg), row-major. */
static void rotation(double R[9])
{
    double c1 = cos(PI / 6.0), s1 = sin(PI / 6.0);
    double c2 = cos(PI / 4.0), s2 = sin(PI / 4.0);
    double Rz[9] = {c1, -s1, 0, s1, c1, 0, 0, 0, 1};
    double Rx[9] = {1, 0, 0, 0, c2, -s2, 0, s2, c2};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k) s += Rz[i * 3 + k] * Rx[k * 3 + j];
            R[i * 3 + j] = s;
        }
}

static form make_form(int id)
{
    form F;
    double R[9];
    /* moderately coupled SPD matrices */
    static const double Mc[9] = {4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0};
    static const double Wc[9] = {2.0, 0.3, -0.2, 0.3, 1.5, 0.1, -0.2, 0.1, 1.2};
    memset(&F, 0, sizeof F);
    rotation(R);
    switch (id) {
    case 0: /* local, W = diag(1, 2, 2): closed form */
        F.name = "local W=diag(1,2,2)";
        F.W[0] = 1.0, F.W[4] = 2.0, F.W[8] = 2.0;
        F.closed_form = 1, F.aN = 1.0, F.aT = 2.0;
        break;
    case 1: /* local, coupled SPD W: manufactured */
        F.name = "local W coupled SPD";
        memcpy(F.W, Wc, sizeof Wc);
        break;
    case 2: /* global, M = 2.5 I, H = I, w = 0: W = I / 2.5 */
        F.name = "global M=2.5I H=I";
        F.global = 1, F.n = 3;
        F.M[0] = F.M[4] = F.M[8] = 2.5;
        F.H[0] = F.H[4] = F.H[8] = 1.0;
        F.closed_form = 1, F.aN = F.aT = 0.4;
        break;
    case 3: /* global, rotated frame: H = R, W = R^T R / m = I / m */
        F.name = "global M=2.5I H=R w!=0";
        F.global = 1, F.n = 3;
        F.M[0] = F.M[4] = F.M[8] = 2.5;
        memcpy(F.H, R, sizeof R);
        F.w[0] = 0.1, F.w[1] = -0.2, F.w[2] = 0.05;
        F.closed_form = 1, F.aN = F.aT = 0.4;
        break;
    case 4: /* heavy body: impulses ~ 1e3 (scaled comparison) */
        F.name = "global M=1000I H=R";
        F.global = 1, F.n = 3;
        F.M[0] = F.M[4] = F.M[8] = 1000.0;
        memcpy(F.H, R, sizeof R);
        F.closed_form = 1, F.aN = F.aT = 1e-3;
        break;
    case 5: /* two bodies (masses 2 and 3) touching: u = R^T (v1 - v2), H = [R; -R],
               W = R^T (1/2 + 1/3) R = (5/6) I */
        F.name = "global two bodies H=[R;-R]";
        F.global = 1, F.n = 6;
        for (int i = 0; i < 3; ++i) {
            F.M[i * 6 + i] = 2.0;
            F.M[(i + 3) * 6 + i + 3] = 3.0;
            for (int j = 0; j < 3; ++j) {
                F.H[i * 3 + j] = R[i * 3 + j];
                F.H[(i + 3) * 3 + j] = -R[i * 3 + j];
            }
        }
        F.closed_form = 1, F.aN = F.aT = 5.0 / 6.0;
        break;
    case 6: /* global, coupled SPD M, H = I, w != 0: manufactured */
        F.name = "global M coupled H=I";
        F.global = 1, F.n = 3;
        memcpy(F.M, Mc, sizeof Mc);
        F.H[0] = F.H[4] = F.H[8] = 1.0;
        F.w[0] = 0.05;
        break;
    default: /* global, coupled SPD M = L L^T and H = L: W = L^T (L L^T)^-1 L = I */
    {
        double L[9] = {0};
        F.name = "global M coupled H=chol(M)";
        F.global = 1, F.n = 3;
        memcpy(F.M, Mc, sizeof Mc);
        for (int j = 0; j < 3; ++j) {
            double s = Mc[j * 3 + j];
            for (int k = 0; k < j; ++k) s -= L[j * 3 + k] * L[j * 3 + k];
            L[j * 3 + j] = sqrt(s);
            for (int i = j + 1; i < 3; ++i) {
                double t = Mc[i * 3 + j];
                for (int k = 0; k < j; ++k) t -= L[i * 3 + k] * L[j * 3 + k];
                L[i * 3 + j] = t / L[j * 3 + j];
            }
        }
        memcpy(F.H, L, sizeof L);
        F.closed_form = 1, F.aN = F.aT = 1.0;
        break;
    }
    }
    return F;
}
#define N_FORMS 8

/* Effective Delassus W = H^T M^-1 H (global) or W (local), row-major 3 x 3. */
static void effective_w(const form *F, double Weff[9])
{
    if (!F->global) {
        memcpy(Weff, F->W, 9 * sizeof(double));
        return;
    }
    for (int j = 0; j < 3; ++j) {
        double h[NMAX], x[NMAX], col[3];
        for (size_t i = 0; i < F->n; ++i) h[i] = F->H[i * 3 + j];
        dense_solve(F->n, F->M, h, x);
        dense_mul_t(F->n, 3, F->H, x, col);
        for (int i = 0; i < 3; ++i) Weff[i * 3 + j] = col[i];
    }
}

/* A fully specified single-contact instance with its exact answer. */
typedef struct instance {
    double f[NMAX], q[3], mu;
    double r[3], u[3], v[NMAX];
} instance;

/* y = (H^T H)^-1 z, then H y: a velocity v with H^T v = z. */
static void lift(const form *F, const double z[3], double *v)
{
    double HtH[9], y[3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (size_t k = 0; k < F->n; ++k) s += F->H[k * 3 + i] * F->H[k * 3 + j];
            HtH[i * 3 + j] = s;
        }
    dense_solve(3, HtH, z, y);
    dense_mul(F->n, 3, F->H, y, v);
}

static instance make_instance(const form *F, const contact_case *C)
{
    instance I;
    double Weff[9];
    memset(&I, 0, sizeof I);
    I.mu = C->mu;
    effective_w(F, Weff);
    if (F->closed_form) {
        /* the derivation above needs W = diag(aN, aT, aT): check it */
        double D[9] = {F->aN, 0, 0, 0, F->aT, 0, 0, 0, F->aT};
        REQUIRE(tu_diff_norm(Weff, D, 9) <= 1e-12 * tu_norm(D, 9));
        memcpy(I.q, C->q, sizeof I.q);
        int cat = coulomb_diag(F->aN, F->aT, I.q, I.mu, I.r, I.u);
        CHECK_MSG(cat == C->category, "%s/%s: closed form gives %s, the case says %s",
                  F->name, C->name, CATEGORY[cat], CATEGORY[C->category]);
        if (F->global) {
            /* f with H^T M^-1 f = q - w: f = M v0 where H^T v0 = q - w */
            double z[3], v0[NMAX], rhs[NMAX], hr[NMAX];
            for (int i = 0; i < 3; ++i) z[i] = I.q[i] - F->w[i];
            lift(F, z, v0);
            dense_mul(F->n, F->n, F->M, v0, I.f);
            dense_mul(F->n, 3, F->H, I.r, hr);
            for (size_t i = 0; i < F->n; ++i) rhs[i] = hr[i] + I.f[i];
            dense_solve(F->n, F->M, rhs, I.v);
        }
    } else {
        double wr[3];
        memcpy(I.r, C->r_star, sizeof I.r);
        memcpy(I.u, C->u_star, sizeof I.u);
        dense_mul(3, 3, Weff, I.r, wr);
        for (int i = 0; i < 3; ++i) I.q[i] = I.u[i] - wr[i];
        if (F->global) {
            double z[3], mv[NMAX], hr[NMAX];
            for (int i = 0; i < 3; ++i) z[i] = I.u[i] - F->w[i];
            lift(F, z, I.v); /* H^T v* + w = u* */
            dense_mul(F->n, F->n, F->M, I.v, mv);
            dense_mul(F->n, 3, F->H, I.r, hr);
            for (size_t i = 0; i < F->n; ++i) I.f[i] = mv[i] - hr[i]; /* M v* = H r* + f */
        }
    }
    return I;
}

/* Builds the cadmm problem of (F, I); also fills the CSC copies for the C error measure. */
static cadmm_problem *build(const form *F, const instance *I, tu_csc *A, tu_csc *B)
{
    cadmm_problem *p = NULL;
    cadmm_result rc;
    if (F->global) {
        *A = tu_csc_from_dense(F->n, F->n, F->M);
        *B = tu_csc_from_dense(F->n, 3, F->H);
        cadmm_csc M = tu_csc_view(A), H = tu_csc_view(B);
        rc = cadmm_problem_new_global(F->n, 1, &M, &H, I->f, F->w, &I->mu, &p);
    } else {
        *A = tu_csc_from_dense(3, 3, F->W);
        memset(B, 0, sizeof *B);
        cadmm_csc W = tu_csc_view(A);
        rc = cadmm_problem_new_local(1, &W, I->q, &I->mu, &p);
    }
    CHECK_MSG(rc == CADMM_OK, "%s: problem_new returned %d (%s)", F->name, rc,
              cadmm_result_message(rc));
    return rc == CADMM_OK ? p : NULL;
}

static double c_error(const form *F, const instance *I, const tu_csc *A, const tu_csc *B,
                      const double *r, const double *v)
{
    if (F->global) return tu_global_error(A, B, I->f, F->w, &I->mu, 1, r, v);
    return tu_local_error(A, I->q, &I->mu, 1, r);
}

/* Solves one instance with the given settings and checks everything against the exact
 * answer. Returns the number of iterations (0 on failure). */
static uint64_t solve_and_check(const form *F, const contact_case *C, const instance *I,
                                cadmm_problem *p, const tu_csc *A, const tu_csc *B,
                                const cadmm_settings *s, const char *label)
{
    cadmm_solver *sv = NULL;
    cadmm_status status = -1;
    cadmm_stats st;
    double r[3], u[3], v[NMAX], e_lib = -1.0, e_c;
    cadmm_result rc = cadmm_solver_new(p, s, &sv);
    if (rc != CADMM_OK) {
        TU_FAIL("%s / %s / %s: solver_new returned %d (%s)", F->name, C->name, label, rc,
                cadmm_result_message(rc));
        return 0;
    }
    rc = cadmm_solver_solve(sv, &status);
    if (rc != CADMM_OK) {
        TU_FAIL("%s / %s / %s: solve returned %d (%s): %s", F->name, C->name, label, rc,
                cadmm_result_message(rc), cadmm_solver_last_error(sv));
        cadmm_solver_free(sv);
        return 0;
    }
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    REQUIRE(cadmm_solver_get_stats(sv, &st) == CADMM_OK);
    REQUIRE(cadmm_solver_get_solution(sv, r, u, F->global ? v : NULL) == CADMM_OK);
    REQUIRE(cadmm_problem_error(p, r, u, F->global ? v : NULL, &e_lib) == CADMM_OK);
    e_c = c_error(F, I, A, B, r, v);

    double dr = tu_rel_diff(r, I->r, 3);
    double du = tu_diff_norm(u, I->u, 3) / tu_max(1.0, tu_max(tu_norm(I->u, 3), tu_norm(I->q, 3)));
    double dv = F->global ? tu_rel_diff(v, I->v, F->n) : 0.0;
    /* The independent error e_c judges the answer on its own: at or below the tolerance
     * (relative slack 1e-9: the library stopped on its own evaluation, which sums in another
     * order), and equal to the library's value for the same answer and to the one the
     * solver reports (relative 1e-9, with 1e-15 absolute for errors near round-off). */
    int ok = status == CADMM_STATUS_SOLVED && st.status == status && dr <= ACC && du <= ACC &&
             dv <= ACC && e_lib <= TOL && st.error <= TOL &&
             /* a contact that separates under the free motion is a short cut */
             (C->category == OPEN ? st.iterations == 0 : st.iterations >= 1) &&
             e_c <= TOL * (1.0 + 1e-9) && fabs(e_lib - e_c) <= 1e-9 * e_c + 1e-15 &&
             fabs(st.error - e_c) <= 1e-9 * e_c + 1e-15;
    if (!ok) {
        TU_FAIL("%s / %s / %s: status %d (stats %d) after %llu iterations, error %.3g "
                "(stats %.3g, C %.3g)\n    r = (%.10g, %.10g, %.10g) exact (%.10g, %.10g, "
                "%.10g) diff %.3g\n    u = (%.10g, %.10g, %.10g) exact (%.10g, %.10g, %.10g) "
                "diff %.3g, v diff %.3g",
                F->name, C->name, label, status, st.status, (unsigned long long)st.iterations,
                e_lib, st.error, e_c, r[0], r[1], r[2], I->r[0], I->r[1], I->r[2], dr, u[0],
                u[1], u[2], I->u[0], I->u[1], I->u[2], du, dv);
    }
    cadmm_solver_free(sv);
    return ok ? st.iterations : 0;
}

static cadmm_settings *settings_for(const char *variant)
{
    cadmm_settings *s = NULL;
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_variant(s, variant) == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_settings_set_max_iterations(s, 20000) == CADMM_OK);
    return s;
}

int main(void)
{
    unsigned solves = 0;
    printf("cadmm %s: analytic single-contact tests (tol %.0e, accuracy %.0e)\n",
           cadmm_version(), TOL, ACC);
    for (int fi = 0; fi < N_FORMS; ++fi) {
        form F = make_form(fi);
        for (size_t ci = 0; ci < N_CASES; ++ci) {
            const contact_case *C = &CASES[ci];
            instance I = make_instance(&F, C);
            tu_csc A, B;
            cadmm_problem *p = build(&F, &I, &A, &B);
            if (p == NULL) continue;

            /* The exact answer has (numerically) zero error with both measures. */
            {
                double e_lib = -1.0;
                REQUIRE(cadmm_problem_error(p, I.r, I.u, F.global ? I.v : NULL, &e_lib) ==
                        CADMM_OK);
                double e_c = c_error(&F, &I, &A, &B, I.r, I.v);
                CHECK_MSG(e_lib <= 1e-13 && e_c <= 1e-13,
                          "%s / %s: exact answer has error %.3g (library) %.3g (C)", F.name,
                          C->name, e_lib, e_c);
            }
            /* Every variant name and auto. */
            for (size_t vi = 0; vi < N_VARIANTS; ++vi) {
                cadmm_settings *s = settings_for(VARIANTS[vi]);
                solve_and_check(&F, C, &I, p, &A, &B, s, VARIANTS[vi]);
                cadmm_settings_free(s);
                ++solves;
            }
            /* Settings sweep on the stick and slide cases: initial rho rules, Anderson
             * on/off, s update internal/external. */
            if (C->category != OPEN && ci < 2) {
                static const char *const rules[] = {"normal", "acary", "ghadimi",
                                                    "dicairano", "given"};
                static const char *const smodes[] = {"internal", "external"};
                for (int ri = 0; ri < 5; ++ri)
                    for (uint32_t aa = 0; aa <= 5; aa += 5)
                        for (int si = 0; si < 2; ++si) {
                            char label[128];
                            cadmm_settings *s = settings_for(ri % 2 ? "vp-RR-He" : "auto");
                            REQUIRE(cadmm_settings_set_initial_rho(s, rules[ri], 10.0) ==
                                    CADMM_OK);
                            REQUIRE(cadmm_settings_set_anderson(s, aa) == CADMM_OK);
                            REQUIRE(cadmm_settings_set_s_update(s, smodes[si]) == CADMM_OK);
                            snprintf(label, sizeof label, "%s rho=%s anderson=%u s=%s",
                                     ri % 2 ? "vp-RR-He" : "auto", rules[ri], (unsigned)aa,
                                     smodes[si]);
                            solve_and_check(&F, C, &I, p, &A, &B, s, label);
                            cadmm_settings_free(s);
                            ++solves;
                        }
            }
            cadmm_problem_free(p);
            tu_csc_free(&A);
            tu_csc_free(&B);
        }
    }
    printf("%u solves on %d forms x %zu cases\n", solves, N_FORMS, N_CASES);
    return tu_finish("test_analytic");
}
