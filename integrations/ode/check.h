/* The driver's own copy of the error measure (docs/algorithms.md §3), written here from the
 * formula and not through cadmm, so that --check re-measures each step's answer on the
 * problem the integration built (cadmm_ode_last_problem):
 *
 *   e = ||-M v + H r + f|| / max(||f||, ||M v||, ||H r||)
 *     + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||),   u = H^T v + w,
 *
 * Phi(u) = (mu ||u_T||, 0, 0) per contact; a zero denominator is skipped. */
#ifndef CADMM_ODE_CHECK_H
#define CADMM_ODE_CHECK_H

#include "cadmm_ode.h"

/* The measure of impulses r (3 per contact) and velocities v (p->n) on p; +inf when a term
 * is not finite or memory runs out. 0 for a problem without contacts. */
double check_error(const cadmm_ode_problem *p, const double *r, const double *v);

#endif
