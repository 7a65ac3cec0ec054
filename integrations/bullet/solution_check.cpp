#include "solution_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace cadmm_bullet {

namespace {

// No floor (docs/algorithms.md §3): a zero denominator leaves the residual as it is.
double relative(double num, double den) { return den > 0.0 ? num / den : num; }

double norm(const std::vector<double> &x) {
  double s = 0;
  for (double e : x) s += e * e;
  return std::sqrt(s);
}

// y += A x (A in compressed columns).
void mulAdd(const Csc &A, const double *x, std::vector<double> &y) {
  for (size_t j = 0; j < A.ncols; ++j)
    for (int64_t k = A.colptr[j]; k < A.colptr[j + 1]; ++k)
      y[size_t(A.rowind[k])] += A.values[size_t(k)] * x[j];
}

// y += A^T x.
void mulTransAdd(const Csc &A, const double *x, std::vector<double> &y) {
  for (size_t j = 0; j < A.ncols; ++j)
    for (int64_t k = A.colptr[j]; k < A.colptr[j + 1]; ++k)
      y[j] += A.values[size_t(k)] * x[A.rowind[k]];
}

// y += |A|^T x.
void absTransAdd(const Csc &A, const double *x, std::vector<double> &y) {
  for (size_t j = 0; j < A.ncols; ++j)
    for (int64_t k = A.colptr[j]; k < A.colptr[j + 1]; ++k)
      y[j] += std::fabs(A.values[size_t(k)] * x[A.rowind[k]]);
}

// Entry (i, i) of A, zero when the pattern has none.
double diagonal(const Csc &A, size_t i) {
  for (int64_t k = A.colptr[i]; k < A.colptr[i + 1]; ++k)
    if (size_t(A.rowind[k]) == i) return A.values[size_t(k)];
  return 0.0;
}

// Projection of z onto K_mu = {||z_T|| <= mu z_N} (zN >= 0 too, which matters for mu = 0).
void projectCone(double mu, const double z[3], double out[3]) {
  const double t = std::hypot(z[1], z[2]);
  if (z[0] >= 0 && t <= mu * z[0]) {
    out[0] = z[0], out[1] = z[1], out[2] = z[2];
  } else if (mu * t + z[0] <= 0) {
    out[0] = out[1] = out[2] = 0;
  } else {  // t > 0 here: t = 0 falls in one of the two cases above
    const double a = (z[0] + mu * t) / (1 + mu * mu);
    out[0] = a, out[1] = mu * a * z[1] / t, out[2] = mu * a * z[2] / t;
  }
}

}  // namespace

double remeasureError(const ContactProblem &p, const double *r, const double *v,
                      const double *lambda) {
  const size_t n = p.velocities(), nc = p.contacts(), nj = p.jointRows();
  std::vector<double> mv(n, 0.0), hr(n, 0.0), u(p.w), gv(nj, 0.0);
  mulAdd(p.M, v, mv);
  mulAdd(p.H, r, hr);
  if (nj) mulAdd(p.G, lambda, hr);
  mulTransAdd(p.H, v, u);

  std::vector<double> eq(n);
  for (size_t i = 0; i < n; ++i) eq[i] = -mv[i] + hr[i] + p.f[i];
  double e = relative(norm(eq), std::max({norm(p.f), norm(mv), norm(hr)}));

  std::vector<double> res(3 * nc), rr(r, r + 3 * nc);
  for (size_t c = 0; c < nc; ++c) {
    const double *uc = &u[3 * c], *rc = &r[3 * c];
    const double z[3] = {rc[0] - (uc[0] + p.mu[c] * std::hypot(uc[1], uc[2])), rc[1] - uc[1],
                         rc[2] - uc[2]};
    double proj[3];
    projectCone(p.mu[c], z, proj);
    for (int k = 0; k < 3; ++k) res[3 * c + k] = rc[k] - proj[k];
  }
  e += relative(norm(res), std::max(norm(u), norm(rr)));

  if (nj) {
    mulTransAdd(p.G, v, gv);
    std::vector<double> jr(nj), freeV(nj, 0.0), freeAbs(n, 0.0), bounded;
    for (size_t k = 0; k < nj; ++k) {
      const double y = gv[k] + p.b[k] + p.compliance[k] * lambda[k];
      double l = p.lo[k], u = p.hi[k];
      const int64_t c = p.frictionContact[k];
      if (c >= 0) {  // also bounded by e r_n of its contact
        const double t = p.friction[k] * std::max(r[3 * c], 0.0);
        l = std::max(l, -t), u = std::min(u, t);
      }
      if (std::isinf(l) && std::isinf(u)) {
        jr[k] = y;
      } else {
        jr[k] = lambda[k] - std::clamp(lambda[k] - y, l, u);
        bounded.push_back(lambda[k]);
      }
    }
    // The velocities the joint rows see under free motion: |G|^T |diag(M)^-1 f|.
    for (size_t i = 0; i < n; ++i) {
      const double d = diagonal(p.M, i);
      freeAbs[i] = d > 0 ? std::fabs(p.f[i] / d) : 0.0;
    }
    absTransAdd(p.G, freeAbs.data(), freeV);
    e += relative(norm(jr), std::max({norm(gv), norm(p.b), norm(freeV), norm(bounded)}));
  }
  return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

}  // namespace cadmm_bullet
