/* The driver's own copy of the error measure (docs/algorithms.md §3), written here from the
 * formula and not through cadmm, so that --check re-measures each step's answer on the
 * problem the integration built (cadmm_ode_last_problem):
 *
 *   e = ||-M v + H r + G lambda + f|| / max(||f||, ||M v||, ||H r + G lambda||)
 *     + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),   u = H^T v + w,
 *     + ||rho_J|| / max(||G^T v||, ||b||, || |G|^T |D^-1 f| ||, ||lambda_B||)  (joints only)
 *
 * Phi(u) = (mu ||u_T||, 0, 0) per contact; joint row k's residual rho_J,k is its velocity
 * y_k = G_k^T v + b_k + c_k lambda_k for an equality (lo, hi infinite) and the natural map
 * lambda_k - P_[lo_k, hi_k](lambda_k - y_k) for a bounded row (its bounds intersected
 * with -+ e r_n for a row bounded by a contact's normal impulse); D is M's diagonal,
 * lambda_B the bounded rows' multipliers; a zero denominator is skipped. */
#ifndef CADMM_ODE_CHECK_H
#define CADMM_ODE_CHECK_H

#include "cadmm_ode.h"

/* The measure of impulses r (3 per contact), velocities v (p->n) and joint multipliers
 * lambda (p->n_joint_rows; NULL without joint rows) on p; +inf when a term is not finite,
 * lambda is missing or memory runs out. 0 for a problem without contacts and joint rows. */
double check_error(const cadmm_ode_problem *p, const double *r, const double *v,
                   const double *lambda);

#endif
