#include "cadmm_constraint_solver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
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
  for (const auto &[name, value] : {std::pair{"time limit", options_.timeLimit},
                                     std::pair{"step time limit", options_.stepTimeLimit}}) {
    if (value >= 0) continue;  // NaN fails too
    cadmm_settings_free(settings_);
    throw Error(std::string("cadmm_bullet: invalid ") + name + " " + std::to_string(value) +
                " (seconds, 0 for none)");
  }
  // A solver built with a time limit starts its solves with sweeps (a budget's solver);
  // each solve's own limit is set in solveGroup.
  const double limit = options_.timeLimit > 0 && options_.stepTimeLimit > 0
                           ? std::min(options_.timeLimit, options_.stepTimeLimit)
                           : std::max(options_.timeLimit, options_.stepTimeLimit);
  if (limit > 0 && cadmm_settings_set_time_limit(settings_, limit) != CADMM_OK) {
    cadmm_settings_free(settings_);
    throw Error("cadmm_bullet: invalid time limit " + std::to_string(limit));
  }
  kept_.reserve(kKeptSolvers);  // a kept solver's address holds through a solveGroup
}

CadmmConstraintSolver::~CadmmConstraintSolver() {
  reset();
  cadmm_settings_free(settings_);
}

void CadmmConstraintSolver::prepareSolve(int, int) {
  ++step_;
  stepStart_ = std::chrono::steady_clock::now();
  lastStepRows_ = std::exchange(stepRows_, 0);
}

// What this call may spend of the step's budget, from now: the step's time left in
// proportion to the call's rows against those still to come, as the step before had them
// (all of it on a first step, or a call no prepareSolve began).
double CadmmConstraintSolver::stepShare(size_t rows, double spentInCall) const {
  if (step_ == 0) return options_.stepTimeLimit - spentInCall;
  const double left =
      options_.stepTimeLimit -
      std::chrono::duration<double>(std::chrono::steady_clock::now() - stepStart_).count();
  const size_t ahead = lastStepRows_ > stepRows_ ? lastStepRows_ - stepRows_ : 0;
  return left * double(rows) / double(std::max(rows, ahead));
}

void CadmmConstraintSolver::reset() {
  for (Kept &k : kept_) cadmm_solver_free(k.solver);
  kept_.clear();
}

SolveStats CadmmConstraintSolver::takeStats() { return std::exchange(stats_, SolveStats{}); }

// Hands a group's values to cadmm. A kept solver whose problem has the group's sizes and
// sparsity patterns takes the value arrays straight (same order of the matrix values;
// numeric refactorization only, no cadmm problem built), with the joint rows' bounds and
// compliance while either problem has some. Else a kept solver no group of this step has
// used is rebuilt in its memory, the one nearest the group in contacts (in a scene in
// motion, the solver this group had the step before, its memory the right size and warm);
// a new one is built only when every kept solver serves this step, while fewer than
// kKeptSolvers are kept, and past that the nearest is rebuilt.
CadmmConstraintSolver::Kept &CadmmConstraintSolver::pushValues(const ContactProblem &p) {
  ++calls_;
  for (Kept &k : kept_) {
    if (!p.samePattern(k.problem)) continue;
    k.lastUsed = calls_, k.lastStep = step_;
    const bool joints = p.jointRows() > 0;  // G and b only for a problem with joints
    check(cadmm_solver_update_values(k.solver, p.M.values.data(), p.H.values.data(),
                                     joints ? p.G.values.data() : nullptr, p.f.data(), p.w.data(),
                                     joints ? p.b.data() : nullptr, p.mu.data()),
          "cadmm_solver_update_values", k.solver);
    if (p.beyondEqualities() || k.problem.beyondEqualities())
      check(cadmm_solver_update_joint_rows(k.solver, p.lo.data(), p.hi.data(), p.compliance.data()),
            "cadmm_solver_update_joint_rows", k.solver);
    if (p.hasContactBounds())  // the same rows on the same contacts (samePattern)
      check(cadmm_solver_update_joint_friction(k.solver, p.friction.data()),
            "cadmm_solver_update_joint_friction", k.solver);
    return k;
  }
  std::unique_ptr<cadmm_problem, void (*)(cadmm_problem *)> problem(p.make(), cadmm_problem_free);
  ++stats_.newSolvers;
  auto gap = [&](const Kept &k) {  // how far a kept solver's sizes are from the group's
    return std::abs(double(k.problem.contacts()) - double(p.contacts()));
  };
  // The kept solver nearest the group among those `eligible`, the most recent of equals.
  auto nearest = [&](auto eligible) {
    Kept *best = nullptr;
    for (Kept &k : kept_)
      if (eligible(k) && (!best || gap(k) < gap(*best) ||
                          (gap(k) == gap(*best) && k.lastUsed > best->lastUsed)))
        best = &k;
    return best;
  };
  Kept *reused = nearest([&](const Kept &k) { return k.lastStep != step_; });
  if (!reused && kept_.size() == kKeptSolvers) reused = nearest([](const Kept &) { return true; });
  if (!reused) {
    cadmm_solver *solver = nullptr;
    check(cadmm_solver_new(problem.get(), settings_, &solver), "cadmm_solver_new");
    kept_.push_back(Kept{solver, {}, calls_, step_});
    return kept_.back();
  }
  // The kept problem describes the solver again once the solve hands this group's over;
  // until then it matches nothing, so a refused rebuild or solve cannot leave it matching
  // a pattern the solver does not have.
  reused->problem.M.clear(0);
  check(cadmm_solver_rebuild(reused->solver, problem.get()), "cadmm_solver_rebuild", reused->solver);
  reused->lastUsed = calls_, reused->lastStep = step_;
  return *reused;
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

  Kept &kept = pushValues(next_);
  cadmm_solver *solver = kept.solver;
  if (options_.warmStart) {
    // Impulses from the manifold points and the bodies' velocities, i.e. the last step's
    // solution: with r alone ADMM restarts from u~ = 0 and needs ~10 iterations even at rest.
    const std::vector<double> r0 = next_.storedImpulses(), v0 = next_.bodyVelocities();
    check(cadmm_solver_warm_start(solver, r0.data(), v0.data()), "cadmm_solver_warm_start",
          solver);
  }
  const size_t rows = 3 * next_.contacts() + next_.jointRows();
  if (options_.timeLimit > 0 || options_.stepTimeLimit > 0) {
    // The budget is the whole solveGroup's: the solve gets what assembly, the values'
    // factorization and the warm start left of it (a little at least, so that it measures
    // the warm start and hands back its best iterate).
    const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    double budget = options_.timeLimit > 0 ? options_.timeLimit - spent : INFINITY;
    if (options_.stepTimeLimit > 0) budget = std::min(budget, stepShare(rows, spent));
    check(cadmm_settings_set_time_limit(settings_, std::max(budget, 1e-6)),
          "cadmm_settings_set_time_limit");
    check(cadmm_solver_update_settings(solver, settings_), "cadmm_solver_update_settings", solver);
  }
  stepRows_ += rows;
  const auto setupEnd = std::chrono::steady_clock::now();
  cadmm_status status = 0;
  check(cadmm_solver_solve(solver, &status), "cadmm_solver_solve", solver);

  std::vector<double> r(3 * next_.contacts()), v(next_.velocities()), lambda(next_.jointRows());
  check(cadmm_solver_get_solution(solver, r.data(), nullptr, v.data()), "get_solution", solver);
  check(cadmm_solver_get_joint_multipliers(solver, lambda.data(), nullptr), "get_joint_multipliers",
        solver);
  cadmm_stats st{};
  st.struct_size = sizeof st;
  check(cadmm_solver_get_stats(solver, &st), "cadmm_solver_get_stats", solver);
  next_.writeBack(r.data(), v.data(), lambda.data());
  std::swap(kept.problem, next_);

  ++stats_.groups;
  stats_.iterations += st.iterations;
  stats_.error = std::max(stats_.error, st.error);
  stats_.unsolved += status != CADMM_STATUS_SOLVED;
  stats_.contacts += kept.problem.contacts();
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats_.setupSeconds += std::chrono::duration<double>(setupEnd - start).count();
  if (options_.onSolved) options_.onSolved({kept.problem, r.data(), v.data(), lambda.data(), status});
  return 0;
}

}  // namespace cadmm_bullet
