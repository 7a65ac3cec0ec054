// The driver's own copy of the error measure (docs/algorithms.md §3), written here from the
// formula and not through cadmm, so that --check re-measures each answer cadmm hands back on
// the problem the integration built:
//
//   e = ||-M v + H r + G lambda + f|| / max(||f||, ||M v||, ||H r + G lambda||)
//     + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),        u = H^T v + w
//     + ||rho_J|| / max(||G^T v||, ||b||, || |G|^T |diag(M)^-1 f| ||, ||lambda_B||)
//                                                                        (joints only)
//
// Phi(u) = (mu ||u_T||, 0, 0) per contact; a zero denominator is skipped. Joint row k's
// residual rho_J,k is its velocity y_k = G_k^T v + b_k + c_k lambda_k for an equality (both
// bounds infinite), the natural map lambda_k - clamp(lambda_k - y_k, lo_k, hi_k) for a
// bounded row; lambda_B are the bounded rows' multipliers.
#pragma once

#include "contact_problem.h"

namespace cadmm_bullet {

// The measure of (r, v, lambda) on p; +inf when a term is not finite.
double remeasureError(const ContactProblem &p, const double *r, const double *v,
                      const double *lambda);

}  // namespace cadmm_bullet
