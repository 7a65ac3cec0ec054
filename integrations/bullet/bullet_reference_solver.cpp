#include "bullet_reference_solver.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <utility>

namespace cadmm_bullet {

btScalar BulletReferenceSolver::solveGroup(btCollisionObject **bodies, int numBodies,
                                           btPersistentManifold **manifolds, int numManifolds,
                                           btTypedConstraint **constraints, int numConstraints,
                                           const btContactSolverInfo &info, btIDebugDraw *debugDrawer,
                                           btDispatcher *dispatcher) {
  // The problem is read before the solve changes the bodies; not timed.
  bool measurable = true;
  try {
    Correction bias{info.m_erp2, bool(info.m_splitImpulse), info.m_splitImpulsePenetrationThreshold};
    problem_.assemble(bodies, numBodies, manifolds, numManifolds, constraints, numConstraints, info,
                      bias);
  } catch (const Error &) {
    measurable = false;
  }

  if (measurable && onAssembled_) onAssembled_(problem_);
  m_analyticsData.m_numIterationsUsed = -1;  // set by the solve when it iterates
  const auto start = std::chrono::steady_clock::now();
  btSequentialImpulseConstraintSolver::solveGroup(bodies, numBodies, manifolds, numManifolds,
                                                  constraints, numConstraints, info, debugDrawer,
                                                  dispatcher);
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ++stats_.groups;
  if (m_analyticsData.m_numIterationsUsed > 0) stats_.iterations += m_analyticsData.m_numIterationsUsed;

  if (!measurable) {
    stats_.error = NAN;
  } else if ((problem_.contacts() > 0 || problem_.jointRows() > 0) && problem_.velocities() > 0) {
    const bool two = info.m_solverMode & SOLVER_USE_2_FRICTION_DIRECTIONS;
    const std::vector<double> r = problem_.storedImpulses(true, two), v = problem_.bodyVelocities();
    std::unique_ptr<cadmm_problem, void (*)(cadmm_problem *)> p(problem_.make(), cadmm_problem_free);
    double e = NAN;
    if (cadmm_problem_error(p.get(), r.data(), nullptr, v.data(), &e) != CADMM_OK) e = NAN;
    stats_.error = std::isnan(stats_.error) ? stats_.error : std::max(stats_.error, e);
    stats_.contacts += problem_.contacts();
  }
  return 0;
}

}  // namespace cadmm_bullet
