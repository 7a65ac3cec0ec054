// Bullet's own btSequentialImpulseConstraintSolver, timed, with the error measure of its
// answer: the impulses and velocities it leaves are measured by cadmm_problem_error on the
// velocity-level problem it solves (contact_problem.h with Bullet's bias: split impulse keeps
// shallow penetration out of w_N; its friction directions projected on the problem's frame;
// joint rows with least-squares multipliers, which know nothing of bounds: Bullet keeps only
// each constraint's last row's impulse).
#pragma once

#include "cadmm_constraint_solver.h"

#include <cmath>
#include <functional>
#include <utility>

namespace cadmm_bullet {

class BulletReferenceSolver : public btSequentialImpulseConstraintSolver {
 public:
  // onAssembled: called with each group's problem before Bullet solves it (may be empty).
  explicit BulletReferenceSolver(std::function<void(const ContactProblem &)> onAssembled = {})
      : onAssembled_(std::move(onAssembled)) {}

  btScalar solveGroup(btCollisionObject **bodies, int numBodies, btPersistentManifold **manifolds,
                      int numManifolds, btTypedConstraint **constraints, int numConstraints,
                      const btContactSolverInfo &info, btIDebugDraw *debugDrawer,
                      btDispatcher *dispatcher) override;

  // As CadmmConstraintSolver::takeStats; error is NaN when the group could not be measured
  // (something contact_problem.cpp does not map).
  SolveStats takeStats() { return std::exchange(stats_, SolveStats{}); }

 private:
  std::function<void(const ContactProblem &)> onAssembled_;
  ContactProblem problem_;
  SolveStats stats_;
};

}  // namespace cadmm_bullet
