// CadmmConstraintSolver: a btConstraintSolver that solves each solver group (contacts with
// Coulomb friction cones, every enabled btTypedConstraint) with cadmm instead of sequential
// impulses. Drop-in:
//
//   cadmm_bullet::CadmmConstraintSolver solver;
//   btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
//
// What it does per group: the global problem of contact_problem.h (Baumgarte correction of
// penetration at rate m_erp2, no split impulse), one cadmm solver kept alive across steps
// (numeric refactorization only while the sizes and sparsity patterns stay the same), warm
// start from the impulses stored in the manifold points and the bodies' velocities (the
// constraint rows start from zero), impulses written back to the points, constraint
// impulses to the constraints and velocities to the bodies.
//
// Constraints: each enabled one through the rows it hands Bullet's own solver (buildJacobian,
// getInfo1, getInfo2, as btSequentialImpulseConstraintSolver::convertJoint), so every type
// Bullet 3.24 ships (point to point, hinge with limits and motor, slider, the three 6-DOF
// constraints and their springs and motors, cone twist, fixed, gear, hinge2, universal) and
// any constraint written the same way. Bullet's row k (Jacobian J, error e, cfm, impulse
// bounds, D = J M^-1 J^T from the bodies' inverse mass and world inertia) converges to
// J v + cfm D lambda = e + (1 - damping) J v_before, lambda within the bounds (clamped by
// the breaking threshold); cadmm solves that row exactly: G's column J, b the rest, compliance
// cfm D. m_globalCfm enters each constraint's first row, as Bullet's. Written back as
// Bullet's writeBackJoints: applied impulse (the last row's), btJointFeedback (J^T lambda / h
// per body), a row at the breaking threshold disables the constraint. Bullet's iteration
// counts mean nothing to cadmm, which solves to its tolerance (btGeneric6DofSpringConstraint
// still reads m_numIterations into its spring's target speed, as it does for Bullet).
//
// Rolling and spinning friction (a contact point with m_combinedRollingFriction > 0, as
// Bullet's convertContact): three rows on the bodies' relative angular velocity, about the
// normal (coefficient m_combinedSpinningFriction) and the two tangents (coefficient
// m_combinedRollingFriction), each bounded by its coefficient times the contact's normal
// impulse and, as Bullet caps it, by the coefficient itself; cadmm solves them with the
// contacts (rows bounded by a contact), its Newton phase off for such a group.
//
// What it refuses: solveGroup throws cadmm_bullet::Error out of stepSimulation, naming the
// object and the reason, before anything of the group was written back (bodies, contact
// points, constraint impulses: the step is not solved), for:
//  - a soft contact: contact CFM or stiffness and damping (BT_CONTACT_FLAG_HAS_CONTACT_CFM,
//    BT_CONTACT_FLAG_CONTACT_STIFFNESS_DAMPING), or m_globalCfm != 0 in a group with contact
//    points (Bullet makes every contact soft with it; cadmm's contacts are rigid). A group
//    without contact points takes it, as the joint rows' compliance. A contact ERP
//    (BT_CONTACT_FLAG_HAS_CONTACT_ERP) is only a Baumgarte rate and is mapped;
//  - anisotropic friction (sliding or rolling);
//  - a constraint switched to Bullet's obsolete solver (m_useSolveConstraintObsolete of
//    btPoint2PointConstraint and btGeneric6DofConstraint): it has no rows;
//  - a row that is no constraint: a non-finite Jacobian or CFM, a NaN, a negative CFM,
//    bounds that hold no impulse (lo > hi), an infinite target velocity with no bound;
//  - a dynamic body with a linear or angular factor other than (1, 1, 1) or an infinite mass
//    or inertia component, a body that is not a btRigidBody, a dynamic body in a contact or
//    constraint of the group but not in the group;
//  - a failed cadmm call.
// Not detectable, so not refused: a custom constraint that does its work in
// solveConstraintObsolete instead of rows.
#pragma once

#include "contact_problem.h"

#include <chrono>
#include <functional>

namespace cadmm_bullet {

// One group's solve as cadmm answered it: the problem handed to cadmm and the impulses,
// velocities and joint multipliers written back (3 per contact, n, 1 per joint row:
// ContactProblem::jointRow finds a constraint's).
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
  // Wall-clock budget of a whole step in seconds (0: none), for Bullet's several solveGroup
  // calls a step (prepareSolve begins a step; without it each call is a step). Each call
  // gets what the step has left in proportion to its rows (3 per contact, 1 per joint row)
  // against the rows the step had still to come the step before; with timeLimit too, the
  // smaller of the two.
  double stepTimeLimit = 0;
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
  double setupSeconds = 0;  // the part before the solve: assembly, solver built or updated, warm start
  int unsolved = 0;         // solves that ended above the tolerance (last iterate written back)
  int newSolvers = 0;       // solvers built or rebuilt because no kept one had the pattern
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
  void prepareSolve(int numBodies, int numManifolds) override;  // a new step begins
  void reset() override;  // drops the kept cadmm solvers
  // None of Bullet's solver types; btDiscreteDynamicsWorld does not branch on it.
  btConstraintSolverType getSolverType() const override { return btConstraintSolverType(1 << 8); }

  SolveStats takeStats();

 private:
  // A cadmm solver and the problem it was last given.
  struct Kept {
    cadmm_solver *solver = nullptr;
    ContactProblem problem;
    uint64_t lastUsed = 0;  // the solveGroup call that last used it
    uint64_t lastStep = 0;  // the step (prepareSolve) that last used it
  };
  // Bullet hands a step's islands to solveGroup in batches (islands gathered until a batch
  // passes m_minimumSolverBatchSize manifolds and constraints), so a solver is kept per
  // group pattern, not one per world: a group whose pattern is unchanged since the last
  // step finds its solver however many other groups were solved between.
  static constexpr size_t kKeptSolvers = 8;

  Kept &pushValues(const ContactProblem &p);
  double stepShare(size_t rows, double spentInCall) const;

  SolverOptions options_;
  cadmm_settings *settings_ = nullptr;
  std::vector<Kept> kept_;  // at most kKeptSolvers
  uint64_t calls_ = 0, step_ = 0;
  // The step's start (prepareSolve) and rows: those solved so far this step, and the
  // step before's in all, which shares stepTimeLimit among the calls.
  std::chrono::steady_clock::time_point stepStart_;
  size_t stepRows_ = 0, lastStepRows_ = 0;
  ContactProblem next_;
  SolveStats stats_;
};

}  // namespace cadmm_bullet
