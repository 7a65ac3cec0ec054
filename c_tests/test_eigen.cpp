// Reference checks of cadmm on real FCLib global problems with Eigen, compiled as C++17
// (so it also checks that cadmm.h works from C++).
//
// Same checks as test_suitesparse.c with Eigen::SimplicialLDLT instead of CHOLMOD (SparseLU
// for a non-symmetric M), plus dense checks (Eigen::LDLT or PartialPivLU,
// SelfAdjointEigenSolver) on the small problems: v against
// M^-1 (H r + f), the error measure of docs/algorithms.md §3 re-implemented here with
// Eigen against cadmm_problem_error, and the Delassus form W = H^T M^-1 H,
// q = H^T M^-1 f + w solved through the local API. Matrices are handed to the library
// straight from Eigen's compressed storage (SparseMatrix<double, ColMajor, int64_t>).
//
// Usage: test_eigen FCLIB_DATA_DIR (exit 77 = skipped, only when it does not exist).
#include "cadmm.h"
#include "fclib_read.h"

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#ifndef CADMM_TEST_HAVE_FCLIB
#define CADMM_TEST_HAVE_FCLIB 1
#endif

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int64_t>;
using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;

constexpr double kTol = 1e-8;
constexpr Eigen::Index kDenseMax = 500; // dense checks up to this size

struct ProblemDeleter {
    void operator()(cadmm_problem *p) const { cadmm_problem_free(p); }
};
struct SettingsDeleter {
    void operator()(cadmm_settings *s) const { cadmm_settings_free(s); }
};
struct SolverDeleter {
    void operator()(cadmm_solver *s) const { cadmm_solver_free(s); }
};
using ProblemPtr = std::unique_ptr<cadmm_problem, ProblemDeleter>;
using SettingsPtr = std::unique_ptr<cadmm_settings, SettingsDeleter>;
using SolverPtr = std::unique_ptr<cadmm_solver, SolverDeleter>;

SpMat to_eigen(const tu_csc &a)
{
    std::vector<Eigen::Triplet<double, int64_t>> t;
    for (size_t j = 0; j < a.ncols; ++j)
        for (int64_t k = a.colptr[j]; k < a.colptr[j + 1]; ++k)
            t.emplace_back(a.rowind[k], static_cast<int64_t>(j), a.values[k]);
    SpMat m(static_cast<Eigen::Index>(a.nrows), static_cast<Eigen::Index>(a.ncols));
    m.setFromTriplets(t.begin(), t.end());
    m.makeCompressed();
    return m;
}

// A view of a compressed Eigen matrix as a cadmm_csc (no copy).
cadmm_csc view(const SpMat &m)
{
    cadmm_csc c{};
    c.nrows = static_cast<size_t>(m.rows());
    c.ncols = static_cast<size_t>(m.cols());
    c.colptr = m.outerIndexPtr();
    c.rowind = m.innerIndexPtr();
    c.values = m.valuePtr();
    return c;
}

Vec to_vec(const double *x, size_t n) { return Eigen::Map<const Vec>(x, static_cast<Eigen::Index>(n)); }

// Projection onto K_mu (docs/algorithms.md §2), written again here with Eigen types.
Eigen::Vector3d project_cone(const Eigen::Vector3d &z, double mu)
{
    const double t = z.tail<2>().norm();
    if (t <= mu * z(0)) return z;
    if (mu * t + z(0) <= 0.0) return Eigen::Vector3d::Zero();
    const double a = (z(0) + mu * t) / (1.0 + mu * mu);
    Eigen::Vector3d p(a, 0.0, 0.0);
    if (t > 0.0) p.tail<2>() = (mu * a / t) * z.tail<2>();
    return p;
}

// No floor (docs/algorithms.md §3): a zero denominator leaves the residual as it is.
double relative(double num, double den) { return den > 0.0 ? num / den : num; }

double natural_map(const Vec &r, const Vec &u, const Vec &mu)
{
    double s = 0.0;
    for (Eigen::Index c = 0; c < mu.size(); ++c) {
        Eigen::Vector3d ri = r.segment<3>(3 * c), ui = u.segment<3>(3 * c);
        Eigen::Vector3d ut = ui;
        ut(0) += mu(c) * ui.tail<2>().norm(); // De Saxce
        s += (ri - project_cone(ri - ut, mu(c))).squaredNorm();
    }
    return std::sqrt(s);
}

double global_error(const SpMat &M, const SpMat &H, const Vec &f, const Vec &w, const Vec &mu,
                    const Vec &r, const Vec &v)
{
    const Vec mv = M * v, hr = H * r;
    const Vec u = H.transpose() * v + w;
    const double e1 = relative((-mv + hr + f).norm(), std::max({f.norm(), mv.norm(), hr.norm()}));
    const double e2 = relative(natural_map(r, u, mu), std::max(u.norm(), r.norm()));
    return e1 + e2;
}

double local_error(const SpMat &W, const Vec &q, const Vec &mu, const Vec &r)
{
    const Vec u = W * r + q;
    return relative(natural_map(r, u, mu), q.norm());
}

struct Result {
    cadmm_status status = -1;
    Vec r, u, v;
    cadmm_stats stats{};
};

Result solve(const cadmm_problem *p, size_t n, size_t m, const char *label)
{
    Result res;
    cadmm_settings *s_raw = nullptr;
    REQUIRE(cadmm_settings_new(&s_raw) == CADMM_OK);
    SettingsPtr s(s_raw);
    REQUIRE(cadmm_settings_set_tolerance(s.get(), kTol) == CADMM_OK);
    REQUIRE(cadmm_settings_set_time_limit(s.get(), 120.0) == CADMM_OK);
    cadmm_solver *sv_raw = nullptr;
    cadmm_result rc = cadmm_solver_new(p, s.get(), &sv_raw);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: solver_new: %s", label, cadmm_result_message(rc));
        return res;
    }
    SolverPtr sv(sv_raw);
    rc = cadmm_solver_solve(sv.get(), &res.status);
    if (rc != CADMM_OK) {
        TU_FAIL("%s: solve: %s (%s)", label, cadmm_result_message(rc),
                cadmm_solver_last_error(sv.get()));
        res.status = -1;
        return res;
    }
    res.r.resize(static_cast<Eigen::Index>(m));
    res.u.resize(static_cast<Eigen::Index>(m));
    res.v.resize(static_cast<Eigen::Index>(n));
    REQUIRE(cadmm_solver_get_solution(sv.get(), res.r.data(), res.u.data(),
                                      n ? res.v.data() : nullptr) == CADMM_OK);
    res.stats.struct_size = sizeof res.stats;
    REQUIRE(cadmm_solver_get_stats(sv.get(), &res.stats) == CADMM_OK);
    std::printf("  %-7s status %d after %llu iterations, error %.3e, %.3f s\n", label,
                res.status, static_cast<unsigned long long>(res.stats.iterations),
                res.stats.error, res.stats.solve_seconds);
    return res;
}

void check_file(const std::string &dir, const char *file)
{
    std::printf("%s\n", file);
    char err[512];
    fcr_problem P;
    const std::string path = dir + "/" + file;
    if (fcr_read(path.c_str(), &P, err, sizeof err) != 0) {
        TU_FAIL("reading %s: %s", path.c_str(), err);
        return;
    }
    REQUIRE(P.is_global && !P.has_joints);
    const size_t n = P.n, nc = P.nc, m = 3 * nc;
    const SpMat M = to_eigen(P.M), H = to_eigen(P.H);
    const Vec f = to_vec(P.f, n), w = to_vec(P.w, m), mu = to_vec(P.mu, nc);
    fcr_free(&P);

    // Through the API, from Eigen's own compressed arrays.
    cadmm_problem *gp_raw = nullptr;
    {
        const cadmm_csc Mc = view(M), Hc = view(H);
        const cadmm_result rc = cadmm_problem_new_global(n, nc, &Mc, &Hc, f.data(), w.data(),
                                                         mu.data(), &gp_raw);
        if (rc != CADMM_OK) {
            TU_FAIL("%s: new_global: %s", file, cadmm_result_message(rc));
            return;
        }
    }
    ProblemPtr gp(gp_raw);
    const Result g = solve(gp.get(), n, m, "global");
    if (g.status != CADMM_STATUS_SOLVED) {
        TU_FAIL("%s: the global solve did not reach tol %g (status %d)", file, kTol, g.status);
        return;
    }

    // 1. v against M^-1 (H r + f): sparse LDL^T, or sparse LU when M is not symmetric
    // (LMGC_GFC3D_CubeH8 stores only the upper triangle of M; the library, like
    // ../shared/tools/fc_error.py, takes M as stored).
    const Mat Mdense(M);
    const bool m_sym = (Mdense - Mdense.transpose()).cwiseAbs().maxCoeff() <=
                       1e-12 * Mdense.cwiseAbs().maxCoeff();
    Eigen::SimplicialLDLT<SpMat> ldlt;
    Eigen::SparseLU<SpMat, Eigen::COLAMDOrdering<int64_t>> lu;
    if (m_sym) {
        ldlt.compute(M);
        REQUIRE(ldlt.info() == Eigen::Success);
    } else {
        lu.compute(M);
        REQUIRE(lu.info() == Eigen::Success);
    }
    std::printf("  M is %s: reference solves with %s\n", m_sym ? "symmetric" : "NOT symmetric",
                m_sym ? "Eigen::SimplicialLDLT" : "Eigen::SparseLU (M taken as stored)");
    auto msolve = [&](const auto &b) -> Mat {
        if (m_sym) return ldlt.solve(Mat(b));
        return lu.solve(Mat(b));
    };
    const Vec v_ref = msolve(H * g.r + f);
    const Vec v_free = msolve(f);
    const double scale = std::max(v_ref.norm(), v_free.norm());
    const double dv = (g.v - v_ref).norm() / scale;
    std::printf("  ||v - M^-1(H r + f)|| / max(||v_ref||, ||M^-1 f||) = %.3e\n", dv);
    CHECK_MSG(dv <= 1e-6, "%s: v differs from M^-1 (H r + f): %.3e", file, dv);

    // 2. error measure.
    double e_lib = -1.0;
    REQUIRE(cadmm_problem_error(gp.get(), g.r.data(), g.u.data(), g.v.data(), &e_lib) == CADMM_OK);
    const double e_eig = global_error(M, H, f, w, mu, g.r, g.v);
    std::printf("  error measure: Eigen %.6e, cadmm_problem_error %.6e\n", e_eig, e_lib);
    CHECK_MSG(std::fabs(e_eig - e_lib) <= 1e-6 * e_lib + 1e-14,
              "%s: error measure Eigen %.10e vs library %.10e", file, e_eig, e_lib);
    CHECK_MSG(e_lib <= kTol, "%s: SOLVED but error %.3e", file, e_lib);

    // 3. Delassus form: W = H^T M^-1 H (dense, symmetrized), q = H^T M^-1 f + w.
    const Mat MinvH = msolve(Mat(H));
    Mat Wd = Mat(H.transpose()) * MinvH;
    if (m_sym) Wd = 0.5 * (Wd + Wd.transpose()).eval(); // round-off asymmetry only
    const Vec q = H.transpose() * v_free + w;
    SpMat W = Wd.sparseView(0.0, 0.0);
    W.makeCompressed();
    // r is unique when W (its symmetric part) is positive definite
    const Mat Wsym = 0.5 * (Wd + Wd.transpose());
    const Eigen::SelfAdjointEigenSolver<Mat> eig(Wsym, Eigen::EigenvaluesOnly);
    const double lmin = eig.eigenvalues().minCoeff(), lmax = eig.eigenvalues().maxCoeff();
    const bool w_pd = lmin > 1e-7 * lmax;
    std::printf("  Delassus W %zu x %zu: eigenvalues in [%.3e, %.3e] -> %s\n", m, m, lmin, lmax,
                w_pd ? "positive definite" : "singular");

    // Dense checks on the small problems.
    if (Mdense.rows() <= kDenseMax) {
        Eigen::LDLT<Mat> dl;
        Eigen::PartialPivLU<Mat> dlu;
        if (m_sym) {
            dl.compute(Mdense);
            REQUIRE(dl.info() == Eigen::Success && dl.isPositive());
        } else {
            dlu.compute(Mdense);
        }
        auto dsolve = [&](const Mat &b) -> Mat { return m_sym ? Mat(dl.solve(b)) : Mat(dlu.solve(b)); };
        const Vec v_dense = dsolve(Mat(H * g.r + f));
        const double dd = (v_dense - v_ref).norm() / scale;
        const double dvd = (g.v - v_dense).norm() / scale;
        Mat Wdense = Mat(H.transpose()) * dsolve(Mat(H));
        if (m_sym) Wdense = 0.5 * (Wdense + Wdense.transpose()).eval();
        const double dw = (Wdense - Wd).norm() / Wd.norm();
        std::printf("  dense %s: |v_dense - v_sparse| %.2e, |v - v_dense| %.2e, |W_dense - W| %.2e\n",
                    m_sym ? "LDLT" : "LU", dd, dvd, dw);
        CHECK_MSG(dd <= 1e-10 && dvd <= 1e-6 && dw <= 1e-10,
                  "%s: dense check failed (%.3e, %.3e, %.3e)", file, dd, dvd, dw);
    }

    cadmm_problem *lp_raw = nullptr;
    {
        const cadmm_csc Wc = view(W);
        const cadmm_result rc = cadmm_problem_new_local(nc, &Wc, q.data(), mu.data(), &lp_raw);
        if (rc != CADMM_OK) {
            TU_FAIL("%s: new_local: %s", file, cadmm_result_message(rc));
            return;
        }
    }
    ProblemPtr lp(lp_raw);
    const Result l = solve(lp.get(), 0, m, "local");
    CHECK_MSG(l.status == CADMM_STATUS_SOLVED, "%s: local solve status %d", file, l.status);
    if (l.status != CADMM_STATUS_SOLVED) return;

    double e_gl = -1.0;
    REQUIRE(cadmm_problem_error(lp.get(), g.r.data(), nullptr, nullptr, &e_gl) == CADMM_OK);
    const double e_gl_eig = local_error(W, q, mu, g.r);
    std::printf("  global r in the local problem: error %.3e (Eigen %.3e)\n", e_gl, e_gl_eig);
    CHECK_MSG(e_gl <= 1e-6 && std::fabs(e_gl - e_gl_eig) <= 1e-6 * e_gl + 1e-14,
              "%s: global r has local error %.3e (Eigen %.3e)", file, e_gl, e_gl_eig);
    const Vec v_loc = msolve(H * l.r + f);
    double e_lg = -1.0;
    REQUIRE(cadmm_problem_error(gp.get(), l.r.data(), nullptr, v_loc.data(), &e_lg) == CADMM_OK);
    std::printf("  local r in the global problem: error %.3e\n", e_lg);
    CHECK_MSG(e_lg <= 1e-6, "%s: local r has global error %.3e", file, e_lg);
    const double du = (l.u - g.u).norm() / std::max(g.u.norm(), q.norm());
    std::printf("  ||u_local - u_global|| / max(||u||, ||q||) = %.3e\n", du);
    CHECK_MSG(du <= 1e-5, "%s: u differs between the forms: %.3e", file, du);
    if (w_pd) {
        const double dr = (l.r - g.r).norm() / g.r.norm();
        std::printf("  W positive definite: ||r_local - r_global|| / ||r|| = %.3e\n", dr);
        CHECK_MSG(dr <= 1e-5, "%s: r differs between the forms: %.3e", file, dr);
    } else {
        std::printf("  W singular: r is not unique, compared u and the error measures only\n");
    }
}

} // namespace

int main(int argc, char **argv)
{
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s FCLIB_DATA_DIR\n", argv[0]);
        return 2;
    }
    const std::string dir = argv[1];
    if (!tu_is_dir(dir.c_str())) {
        std::printf("SKIP: FCLib data directory '%s' not found\n", dir.c_str());
        return TU_SKIP;
    }
    std::printf("cadmm %s: Eigen reference checks (tol %g)\n", cadmm_version(), kTol);
    static_assert(sizeof(cadmm_csc) == 2 * sizeof(size_t) + 3 * sizeof(void *),
                  "cadmm_csc layout");
    for (const char *file : {"global/GFC3D_Example1.hdf5", "global/GFC3D_OneContact.hdf5",
                             "global/Box_Stacks-i0122-82-5.hdf5", "global/LMGC_GFC3D_CubeH8.hdf5"})
        check_file(dir, file);
    return tu_finish("test_eigen");
}
