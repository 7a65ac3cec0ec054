#include "cadmm_constraint_solver.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <utility>

namespace cadmm_bullet {

namespace {

void check(cadmm_result rc, const char *what, const cadmm_solver *sv = nullptr) {
  if (rc != CADMM_OK)
    throw Error(std::string("cadmm_bullet: ") + what + ": " +
                (sv ? cadmm_solver_last_error(sv) : cadmm_last_error()));
}

}  // namespace

CadmmConstraintSolver::CadmmConstraintSolver(SolverOptions options) : options_(options) {
  check(cadmm_settings_new(&settings_), "cadmm_settings_new");
  if (cadmm_settings_set_tolerance(settings_, options_.tolerance) != CADMM_OK) {
    cadmm_settings_free(settings_);
    throw Error("cadmm_bullet: invalid tolerance " + std::to_string(options_.tolerance));
  }
  if (options_.maxIterations > 0 &&
      cadmm_settings_set_max_iterations(settings_, options_.maxIterations) != CADMM_OK) {
    cadmm_settings_free(settings_);
    throw Error("cadmm_bullet: invalid iteration limit " + std::to_string(options_.maxIterations));
  }
  if (options_.timeLimit > 0 &&
      cadmm_settings_set_time_limit(settings_, options_.timeLimit) != CADMM_OK) {
    cadmm_settings_free(settings_);
    throw Error("cadmm_bullet: invalid time limit " + std::to_string(options_.timeLimit));
  }
}

CadmmConstraintSolver::~CadmmConstraintSolver() {
  cadmm_solver_free(solver_);
  cadmm_settings_free(settings_);
}

void CadmmConstraintSolver::reset() {
  cadmm_solver_free(solver_);
  solver_ = nullptr;
}

SolveStats CadmmConstraintSolver::takeStats() { return std::exchange(stats_, SolveStats{}); }

// Hands a time step's values to cadmm: when the sizes and sparsity patterns are those of the
// solver's problem, the value arrays go straight to the solver (same order of the matrix
// values; numeric refactorization only, no cadmm problem built), with the joint rows'
// bounds and compliance while either step has some; else the solver is rebuilt for the new
// pattern (a new solver the first time).
void CadmmConstraintSolver::pushValues(const ContactProblem &p) {
  if (solver_ && p.samePattern(current_)) {
    const bool joints = p.jointRows() > 0;  // G and b only for a problem with joints
    check(cadmm_solver_update_values(solver_, p.M.values.data(), p.H.values.data(),
                                     joints ? p.G.values.data() : nullptr, p.f.data(), p.w.data(),
                                     joints ? p.b.data() : nullptr, p.mu.data()),
          "cadmm_solver_update_values", solver_);
    if (p.beyondEqualities() || current_.beyondEqualities())
      check(cadmm_solver_update_joint_rows(solver_, p.lo.data(), p.hi.data(), p.compliance.data()),
            "cadmm_solver_update_joint_rows", solver_);
    if (p.hasContactBounds())  // the same rows on the same contacts (samePattern)
      check(cadmm_solver_update_joint_friction(solver_, p.friction.data()),
            "cadmm_solver_update_joint_friction", solver_);
    return;
  }
  std::unique_ptr<cadmm_problem, void (*)(cadmm_problem *)> problem(p.make(), cadmm_problem_free);
  if (solver_) {  // rebuilt in the memory it holds
    check(cadmm_solver_rebuild(solver_, problem.get()), "cadmm_solver_rebuild", solver_);
  } else {
    check(cadmm_solver_new(problem.get(), settings_, &solver_), "cadmm_solver_new");
  }
  ++stats_.newSolvers;
}

btScalar CadmmConstraintSolver::solveGroup(btCollisionObject **bodies, int numBodies,
                                           btPersistentManifold **manifolds, int numManifolds,
                                           btTypedConstraint **constraints, int numConstraints,
                                           const btContactSolverInfo &info, btIDebugDraw *,
                                           btDispatcher *) {
  const auto start = std::chrono::steady_clock::now();
  Correction correction;
  correction.erp = options_.erp >= 0 ? options_.erp : info.m_erp2;
  next_.assemble(bodies, numBodies, manifolds, numManifolds, constraints, numConstraints, info,
                 correction);
  if (next_.velocities() == 0) return 0;
  if (next_.contacts() == 0 && next_.jointRows() == 0) {  // free motion: nothing to solve
    next_.writeBack(nullptr, next_.freeVelocities().data(), nullptr);
    return 0;
  }

  pushValues(next_);
  if (options_.warmStart) {
    // Impulses from the manifold points and the bodies' velocities, i.e. the last step's
    // solution: with r alone ADMM restarts from u~ = 0 and needs ~10 iterations even at rest.
    const std::vector<double> r0 = next_.storedImpulses(), v0 = next_.bodyVelocities();
    check(cadmm_solver_warm_start(solver_, r0.data(), v0.data()), "cadmm_solver_warm_start",
          solver_);
  }
  if (options_.timeLimit > 0) {
    // The budget is the whole solveGroup's: the solve gets what assembly, the values'
    // factorization and the warm start left of it (a little at least, so that it measures
    // the warm start and hands back its best iterate).
    const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    check(cadmm_settings_set_time_limit(settings_, std::max(options_.timeLimit - spent, 1e-6)),
          "cadmm_settings_set_time_limit");
    check(cadmm_solver_update_settings(solver_, settings_), "cadmm_solver_update_settings", solver_);
  }
  const auto setupEnd = std::chrono::steady_clock::now();
  cadmm_status status = 0;
  check(cadmm_solver_solve(solver_, &status), "cadmm_solver_solve", solver_);

  std::vector<double> r(3 * next_.contacts()), v(next_.velocities()), lambda(next_.jointRows());
  check(cadmm_solver_get_solution(solver_, r.data(), nullptr, v.data()), "get_solution", solver_);
  check(cadmm_solver_get_joint_multipliers(solver_, lambda.data(), nullptr), "get_joint_multipliers",
        solver_);
  cadmm_stats st{};
  st.struct_size = sizeof st;
  check(cadmm_solver_get_stats(solver_, &st), "cadmm_solver_get_stats", solver_);
  next_.writeBack(r.data(), v.data(), lambda.data());
  std::swap(current_, next_);

  ++stats_.groups;
  stats_.iterations += st.iterations;
  stats_.error = std::max(stats_.error, st.error);
  stats_.unsolved += status != CADMM_STATUS_SOLVED;
  stats_.contacts += current_.contacts();
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats_.setupSeconds += std::chrono::duration<double>(setupEnd - start).count();
  if (options_.onSolved) options_.onSolved({current_, r.data(), v.data(), lambda.data(), status});
  return 0;
}

}  // namespace cadmm_bullet
