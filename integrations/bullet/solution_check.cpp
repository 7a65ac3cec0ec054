#include "solution_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace cadmm_bullet {

namespace {

const double kTiny = 1.5e-8;  // denominators at or below this are skipped

double relative(double num, double den) { return den > kTiny ? num / den : num; }

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
    std::vector<double> jr(nj);
    for (size_t k = 0; k < nj; ++k) jr[k] = gv[k] + p.b[k];
    e += relative(norm(jr), std::max(norm(gv), norm(p.b)));
  }
  return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

}  // namespace cadmm_bullet
