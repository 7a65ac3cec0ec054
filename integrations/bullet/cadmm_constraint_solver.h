// CadmmConstraintSolver: a btConstraintSolver that solves each solver group (contacts with
// Coulomb friction cones, btPoint2PointConstraint joints) with cadmm instead of sequential
// impulses. Drop-in:
//
//   cadmm_bullet::CadmmConstraintSolver solver;
//   btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
//
// What it does per group: the global problem of contact_problem.h (Baumgarte correction of
// penetration at rate m_erp2, no split impulse), one cadmm solver kept alive across steps
// (numeric refactorization only while the sizes and sparsity patterns stay the same), warm
// start from the impulses stored in the manifold points, impulses written back to the points
// and velocities to the bodies.
//
// What it refuses: a group with anything contact_problem.cpp does not map (a joint other than
// btPoint2PointConstraint, rolling friction, soft contacts, locked axes...) or a failed cadmm
// call makes solveGroup throw cadmm_bullet::Error out of stepSimulation before any body or
// contact point of the group was changed: the step is not solved, and says why.
#pragma once

#include "contact_problem.h"

#include <functional>

namespace cadmm_bullet {

// One group's solve as cadmm answered it: the problem handed to cadmm and the impulses,
// velocities and joint multipliers written back (3 per contact, n, 3 per joint).
struct SolvedGroup {
  const ContactProblem &problem;
  const double *r, *v, *lambda;
  cadmm_status status;
};

struct SolverOptions {
  double tolerance = 1e-8;
  uint32_t maxIterations = 0;  // cadmm's iteration limit; 0: cadmm's default
  bool warmStart = true;       // start from the previous step's impulses and velocities
  double erp = -1;             // Baumgarte rate of the contacts; < 0: the world's m_erp2
  // Wall-clock budget of one solveGroup in seconds (0: none): the solve gets cadmm's time
  // limit set to what assembly and factorization left of it. A solve stopped by it hands
  // back its best measured iterate, counted in `unsolved`.
  double timeLimit = 0;
  // Called after each group's solve, once its answer is written back: lets a caller check
  // the answer on its own (the driver's --check re-measures it).
  std::function<void(const SolvedGroup &)> onSolved;
};

// Summed over the solveGroup calls since the last takeStats().
struct SolveStats {
  int groups = 0;           // groups solved by cadmm
  uint64_t iterations = 0;  // ADMM iterations and Newton steps
  double error = 0;         // worst final error measure
  double seconds = 0;       // wall time in solveGroup: assembly, factorization, solve, write-back
  int unsolved = 0;         // solves that ended above the tolerance (last iterate written back)
  int newSolvers = 0;       // solvers built because the pattern changed
  size_t contacts = 0;
};

class CadmmConstraintSolver : public btConstraintSolver {
 public:
  explicit CadmmConstraintSolver(SolverOptions options = {});
  ~CadmmConstraintSolver() override;
  CadmmConstraintSolver(const CadmmConstraintSolver &) = delete;
  CadmmConstraintSolver &operator=(const CadmmConstraintSolver &) = delete;

  btScalar solveGroup(btCollisionObject **bodies, int numBodies, btPersistentManifold **manifolds,
                      int numManifolds, btTypedConstraint **constraints, int numConstraints,
                      const btContactSolverInfo &info, btIDebugDraw *debugDrawer,
                      btDispatcher *dispatcher) override;
  void reset() override;  // drops the cached cadmm solver
  // None of Bullet's solver types; btDiscreteDynamicsWorld does not branch on it.
  btConstraintSolverType getSolverType() const override { return btConstraintSolverType(1 << 8); }

  SolveStats takeStats();

 private:
  void pushValues(const ContactProblem &p);

  SolverOptions options_;
  cadmm_settings *settings_ = nullptr;
  cadmm_solver *solver_ = nullptr;
  ContactProblem next_, current_;  // current_: the problem solver_ was last given
  SolveStats stats_;
};

}  // namespace cadmm_bullet
