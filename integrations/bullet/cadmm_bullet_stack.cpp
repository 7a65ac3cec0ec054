// cadmm_bullet_stack: runs a stacking scene with cadmm's constraint solver or Bullet's
// sequential impulse solver and prints one JSON line of figures.
//
//   cadmm_bullet_stack --scene tower|drop|mass-ratio-100|mass-ratio-1000|pyramid|
//                               pendulum|simple-pendulum|big-pyramid|pyramids|pyramids-hit|wall|bin|chain|arm|ragdoll
//                      --solver cadmm|bullet [--seconds S] [--bullet-iterations N] [--cold]
//                      [--json] [--trace FILE.csv] [--check] [--with-hinge]
//                      [--tolerance T] [--max-iterations N] [--check-tolerance T]
//                      [--damping D] [--count N] [--seed N] [--time-limit S] [--step-time-limit S]
//                      [--dump STEP,STEP,... --dump-dir DIR] [--max-new-solvers N]
//                      [--one-group]
//
// --count and --seed size and vary the larger scenes (stack_scenes.h; the arm's count is
// its payload's mass in kg). --time-limit is the
// cadmm drop-in's budget per solveGroup (SolverOptions::timeLimit), --step-time-limit its budget
// per step (SolverOptions::stepTimeLimit). --one-group has Bullet hand the whole world to
// one solveGroup call a step (its islands not split), as an engine that hands cadmm all its
// contacts at once does. --dump writes the
// problem of every group solved at the given steps to DIR/SCENE-stepN-groupK.hdf5 (FCLib;
// needs a cadmm built with CADMM_WITH_FCLIB), with either solver.
//
// --check exits with 1 when the scene failed, after printing one "CHECK FAILED: ..." line
// per failed check:
//  - a body fell (more than a quarter of a box below or beside where it should rest) or the
//    top body drifted 1 mm or more horizontally (stacks at rest, not the scenes in motion);
//  - a joint opened by kJointGap or more (pendulums, the arm);
//  - the arm's tip (its payload's centre) moved kTipDrift or more from where it started, at
//    any step;
//  - the simple pendulum's zero crossings or swing amplitudes left the exact pendulum's
//    (kCrossingSlack, kAmplitudeSlack);
//  - a contact ended a step deeper than the Baumgarte correction leaves it, by more than
//    kMaxPenetrationExcess (scenes at rest);
//  - (cadmm) a solve ended above its tolerance, or an answer re-measured by the driver's own
//    copy of the error measure (solution_check.h) on the problem handed to cadmm is above the
//    check tolerance (--check-tolerance, default the solver's --tolerance, default 1e-8);
//  - (cadmm, with --max-new-solvers N) the drop-in built or rebuilt more than N solvers: a
//    scene whose groups keep their contacts keeps one solver per group.
// A refused step (cadmm_bullet::Error) exits with 2. --tolerance and --max-iterations set
// cadmm's, --damping the bodies' linear and angular damping (Bullet's, applied before the
// solve); CTest uses them to show that the checks fire.
//
// The joint gap (max_joint_gap) is the largest distance between a joint's pivot as its two
// bodies carry it, over every joint with one pivot (stack_scenes.h, jointGap) and every
// step. The arm reports its tip's distance from where it started in mm, at the end
// (tip_drift_mm) and the largest over the run (max_tip_drift_mm).
#include "bullet_reference_solver.h"
#include "cadmm_constraint_solver.h"
#include "solution_check.h"
#include "stack_scenes.h"

#include <BulletCollision/CollisionDispatch/btSimulationIslandManager.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

using namespace cadmm_bullet;

namespace {

// Velocity-level joints drift in position between the ERP corrections: a swinging 1 m arm at
// 60 Hz opens by about 2 cm with either solver. A joint that is not enforced opens by metres.
const double kJointGap = 0.03;

// The arm's motors (target velocity 0) hold its pose at the velocity level and nothing
// restores an angle a motor let go: a solve that stops every joint leaves the tip where it
// was (cadmm's moves it by 1e-7 mm in 5 s at tolerance 1e-8, 0.04 mm at 1e-4), a solve
// that does not lets the arm sag, and the sag stays.
const double kTipDrift = 1e-3;

// A contact is solved at the velocity level with a Baumgarte bias: a step that starts d deep
// ends at most (1 - erp) d deep, and one that starts apart ends touching, up to the contact
// points' motion being linearized over the step (second order: h^2 omega^2 r, under 0.1 mm
// for boxes turning slower than 0.5 rad/s, as in every scene here; 2e-8 m measured). Landings
// are not bounded in depth: collision detection finds a contact only once a falling box is
// up to one step's travel (2 cm) deep. One step of unopposed gravity sinks a resting box
// g h^2 = 2.7 mm at 60 Hz, 27 times the bound; a solve stopped at tolerance 0.1 leaves 0.5 mm.
const double kMaxPenetrationExcess = 1e-4;

// The simple pendulum (60 Hz, T = 1.43 s) against the exact pendulum. Semi-implicit Euler
// released from rest runs half a step ahead (its first velocity is a whole step of gravity,
// the midpoint rule's half), so crossing k is expected at (2k + 1) T / 4 - h / 2; its period
// is (omega h)^2 / 24 = 2e-4 too long, 0.4 ms by the third crossing, and the joint's ERP
// correction adds its own (0.8 ms measured). 2 ms also tells the exact period from the
// small-angle one (0.8% shorter at 20 degrees: 3, 9 and 14 ms off at the three crossings).
const double kCrossingSlack = 2e-3;
// Nothing damps the swing: an amplitude 1% off (0.3% measured) is energy the solver made or
// lost.
const double kAmplitudeSlack = 0.01;

struct Args {
  std::string scene = "tower", solver = "cadmm", trace, dumpDir;
  double seconds = 5, tolerance = 1e-8, checkTolerance = 0;  // 0: the solver's tolerance
  double damping = 0, timeLimit = 0, stepTimeLimit = 0;
  int bulletIterations = 10, maxIterations = 0;               // 0: cadmm's default
  int count = 0, seed = 1;
  int maxNewSolvers = -1;  // -1: not checked
  std::vector<int> dump;  // steps whose groups are written as FCLib files
  bool cold = false, json = false, check = false, hinge = false, oneGroup = false;
};

[[noreturn]] void usage(const char *msg) {
  std::fprintf(stderr,
               "cadmm_bullet_stack: %s\nusage: cadmm_bullet_stack --scene tower|drop|mass-ratio-100|"
               "mass-ratio-1000|pyramid|pendulum|simple-pendulum|big-pyramid|pyramids|pyramids-hit|wall|"
               "bin|chain|arm|"
               "ragdoll --solver cadmm|bullet "
               "[--seconds S] [--bullet-iterations N] [--cold] [--json] [--trace FILE.csv] "
               "[--check] [--with-hinge] [--tolerance T] [--max-iterations N] "
               "[--check-tolerance T] [--damping D] [--count N] [--seed N] [--time-limit S] "
               "[--step-time-limit S] "
               "[--dump STEP,STEP,... --dump-dir DIR] [--max-new-solvers N] [--one-group]\n",
               msg);
  std::exit(64);
}

Args parse(int argc, char **argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + k).c_str());
      return argv[++i];
    };
    if (k == "--scene") a.scene = value();
    else if (k == "--solver") a.solver = value();
    else if (k == "--seconds") a.seconds = std::atof(value().c_str());
    else if (k == "--bullet-iterations") a.bulletIterations = std::atoi(value().c_str());
    else if (k == "--trace") a.trace = value();
    else if (k == "--tolerance") a.tolerance = std::atof(value().c_str());
    else if (k == "--check-tolerance") {
      a.checkTolerance = std::atof(value().c_str());
      if (!(a.checkTolerance > 0)) usage("--check-tolerance must be positive");
    }
    else if (k == "--max-iterations") a.maxIterations = std::atoi(value().c_str());
    else if (k == "--damping") a.damping = std::atof(value().c_str());
    else if (k == "--count") a.count = std::atoi(value().c_str());
    else if (k == "--seed") a.seed = std::atoi(value().c_str());
    else if (k == "--time-limit") a.timeLimit = std::atof(value().c_str());
    else if (k == "--step-time-limit") a.stepTimeLimit = std::atof(value().c_str());
    else if (k == "--dump-dir") a.dumpDir = value();
    else if (k == "--max-new-solvers") {
      a.maxNewSolvers = std::atoi(value().c_str());
      if (a.maxNewSolvers < 0) usage("--max-new-solvers must be at least 0");
    }
    else if (k == "--dump") {
      const std::string list = value();
      for (size_t at = 0; at < list.size();) {
        const size_t comma = std::min(list.find(',', at), list.size());
        a.dump.push_back(std::atoi(list.substr(at, comma - at).c_str()));
        if (a.dump.back() < 1) usage("--dump takes step numbers from 1");
        at = comma + 1;
      }
    }
    else if (k == "--cold") a.cold = true;
    else if (k == "--json") a.json = true;
    else if (k == "--check") a.check = true;
    else if (k == "--with-hinge") a.hinge = true;
    else if (k == "--one-group") a.oneGroup = true;
    else usage(("unknown option " + k).c_str());
  }
  if (a.solver != "cadmm" && a.solver != "bullet") usage("--solver must be cadmm or bullet");
  if (!(a.seconds > 0)) usage("--seconds must be positive");
  if (a.bulletIterations < 1) usage("--bullet-iterations must be at least 1");
  if (!(a.tolerance > 0)) usage("--tolerance must be positive");
  if (a.maxIterations < 0) usage("--max-iterations must be at least 1");
  if (!(a.damping >= 0 && a.damping <= 1)) usage("--damping must be in [0, 1]");
  if (a.checkTolerance == 0) a.checkTolerance = a.tolerance;
  if (a.count < 0) usage("--count must be at least 1");
  if (!(a.timeLimit >= 0)) usage("--time-limit must be positive (0: none)");
  if (!(a.stepTimeLimit >= 0)) usage("--step-time-limit must be positive (0: none)");
  if (!a.dump.empty() && a.dumpDir.empty()) usage("--dump needs --dump-dir");
  return a;
}

// The exact period of the physical pendulum of StackWorld::Swing released at rest at angle
// a: T0 / AGM(1, cos(a / 2)), T0 = 2 pi sqrt(I / (m g L)) its small-angle period, I the
// cube's moment about the pivot (side^2 / 6 about its centre, plus L^2), per unit mass.
double pendulumPeriod(const StackWorld::Swing &s, double g) {
  double a = 1, b = std::cos(s.amplitude / 2);
  for (int i = 0; i < 40 && a != b; ++i) {
    const double m = (a + b) / 2;
    b = std::sqrt(a * b), a = m;
  }
  const double inertia = s.side * s.side / 6 + s.length * s.length;
  return 2 * SIMD_PI * std::sqrt(inertia / (g * s.length)) / a;
}

// A figure for a message (inf and nan as such), or for JSON (null for them).
std::string shown(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}
std::string number(double x) { return std::isfinite(x) ? shown(x) : "null"; }

// The q-quantile of xs (nearest rank).
double percentile(std::vector<double> xs, double q) {
  if (xs.empty()) return NAN;
  std::sort(xs.begin(), xs.end());
  return xs[std::min(xs.size() - 1, size_t(std::ceil(q * double(xs.size()))) - 1)];
}

}  // namespace

int main(int argc, char **argv) {
  const Args args = parse(argc, argv);
  const double h = kTimeStep;

  CadmmConstraintSolver *cadmm = nullptr;
  BulletReferenceSolver *bullet = nullptr;
  std::unique_ptr<btConstraintSolver> solver;
  // The driver's re-measure of every answer cadmm hands back (solution_check.h).
  double maxChecked = 0;
  // --dump: the groups of the chosen steps as FCLib files.
  int step = 0, group = 0;
  auto dump = [&](const ContactProblem &p) {
    if (std::find(args.dump.begin(), args.dump.end(), step) == args.dump.end()) return;
    const std::string path = args.dumpDir + '/' + args.scene + "-step" + std::to_string(step) +
                             "-group" + std::to_string(group++) + ".hdf5";
    std::unique_ptr<cadmm_problem, void (*)(cadmm_problem *)> made(p.make(), cadmm_problem_free);
    if (cadmm_problem_write_fclib(made.get(), path.c_str()) != CADMM_OK)
      std::fprintf(stderr, "cannot dump %s: %s\n", path.c_str(), cadmm_last_error());
  };
  if (args.solver == "cadmm") {
    SolverOptions o;
    o.warmStart = !args.cold;
    o.tolerance = args.tolerance;
    o.maxIterations = uint32_t(args.maxIterations);
    o.timeLimit = args.timeLimit;
    o.stepTimeLimit = args.stepTimeLimit;
    o.onSolved = [&maxChecked, &dump](const SolvedGroup &g) {
      const double e = remeasureError(g.problem, g.r, g.v, g.lambda);
      if (!(e <= maxChecked)) maxChecked = e;
      dump(g.problem);
    };
    solver = std::make_unique<CadmmConstraintSolver>(o);
    cadmm = static_cast<CadmmConstraintSolver *>(solver.get());
  } else {
    solver = std::make_unique<BulletReferenceSolver>(dump);
    bullet = static_cast<BulletReferenceSolver *>(solver.get());
  }
  StackWorld w(std::move(solver));
  w.world().getSolverInfo().m_numIterations = args.bulletIterations;
  if (args.oneGroup) w.world().getSimulationIslandManager()->setSplitIslands(false);
  if (!buildScene(args.scene, w, args.count, unsigned(args.seed)))
    usage(("unknown scene " + args.scene).c_str());
  if (args.hinge) addHinge(w);
  for (btRigidBody *b : w.boxes) b->setDamping(args.damping, args.damping);
  const double erp = w.world().getSolverInfo().m_erp2;  // the contacts' Baumgarte rate

  btRigidBody *top = w.boxes.back();
  const btVector3 top0 = top->getCenterOfMassPosition();
  const btVector3 tip0 = w.tip ? w.tip->getCenterOfMassPosition() : btVector3(0, 0, 0);

  // The simple pendulum: its angle from the vertical at every step, the times it crosses the
  // vertical (linear interpolation between steps) and its largest angle between crossings.
  const bool swing = w.swing.length > 0;
  std::vector<double> crossings, peaks;
  double angle = w.swing.amplitude, peak = 0;
  std::ofstream trace;
  if (!args.trace.empty()) {
    trace.open(args.trace);
    if (!trace) usage(("cannot write " + args.trace).c_str());
    trace << "step,time,solve_ms,iterations,error,top_height,penetration\n";
  }

  const int steps = int(std::lround(args.seconds / h));
  std::vector<double> stepMs;
  double sumIt = 0, maxIt = 0, sumMs = 0, sumSetupMs = 0, maxMs = 0, maxPen = 0, maxDrift = 0, maxErr = 0,
         maxGap = 0, maxExcess = 0, tipDrift = NAN, maxTipDrift = NAN;
  int unsolved = 0, newSolvers = 0;
  size_t sumContacts = 0;
  bool fell = false, errUnknown = false;
  for (int s = 1; s <= steps; ++s) {
    step = s, group = 0;
    if (w.ball.radius > 0 && s == int(std::lround(w.ball.time / h)))
      w.addSphere(w.ball.radius, w.ball.mass, w.ball.from)->setLinearVelocity(w.ball.velocity);
    try {
      w.world().stepSimulation(h, 1, h);
    } catch (const Error &e) {
      std::fprintf(stderr, "step %d refused: %s\n", s, e.what());
      return 2;
    }
    const SolveStats st = cadmm ? cadmm->takeStats() : bullet->takeStats();
    const StackWorld::Penetration pen = w.penetration(erp);
    const double ms = 1e3 * st.seconds;
    sumIt += double(st.iterations), maxIt = std::max(maxIt, double(st.iterations));
    stepMs.push_back(ms);
    sumMs += ms, sumSetupMs += 1e3 * st.setupSeconds;
    maxMs = std::max(maxMs, ms), maxPen = std::max(maxPen, pen.depth);
    maxExcess = std::max(maxExcess, pen.excess);
    if (std::isnan(st.error)) errUnknown = true;
    else maxErr = std::max(maxErr, st.error);
    unsolved += st.unsolved, newSolvers += st.newSolvers, sumContacts += st.contacts;

    const btVector3 p = top->getCenterOfMassPosition();
    maxDrift = std::max(maxDrift, double(std::hypot(p.x() - top0.x(), p.z() - top0.z())));
    for (size_t i = 0; i < w.boxes.size() && args.scene != "pendulum" && !w.inMotion; ++i) {
      const btVector3 d = w.boxes[i]->getCenterOfMassPosition() - w.rest[i];
      if (std::hypot(d.x(), d.z()) > 0.25 || d.y() < -0.25) fell = true;
    }
    for (int j = 0; j < w.world().getNumConstraints(); ++j)
      maxGap = std::max(maxGap, jointGap(*w.world().getConstraint(j)));
    if (w.tip) {
      tipDrift = 1e3 * double((w.tip->getCenterOfMassPosition() - tip0).length());
      maxTipDrift = std::isnan(maxTipDrift) ? tipDrift : std::max(maxTipDrift, tipDrift);
    }
    if (swing) {
      const btVector3 d = top->getCenterOfMassPosition() - w.swing.pivot;
      const double now = std::atan2(double(d.x()), double(-d.y()));
      if ((angle > 0) != (now > 0)) {
        crossings.push_back((s - 1) * h + h * angle / (angle - now));
        if (crossings.size() > 1) peaks.push_back(peak);
        peak = 0;
      }
      angle = now, peak = std::max(peak, std::fabs(now));
    }
    if (trace)
      trace << s << ',' << s * h << ',' << ms << ',' << st.iterations << ',' << number(st.error)
            << ',' << p.y() << ',' << pen.depth << '\n';
  }

  // The simple pendulum against the exact pendulum: the k-th crossing of the vertical at
  // (2k + 1) T / 4 (less half a step, see kCrossingSlack), every swing back to the release
  // angle (nothing damps it unless --damping).
  double period = NAN, maxCrossingError = NAN, maxAmplitudeError = NAN;
  size_t expectedCrossings = 0;
  if (swing) {
    period = pendulumPeriod(w.swing, -double(w.world().getGravity().y()));
    while ((2 * double(expectedCrossings) + 1) * period / 4 < steps * h - period / 8)
      ++expectedCrossings;  // the crossings well inside the run
    maxCrossingError = maxAmplitudeError = 0;
    for (size_t k = 0; k < crossings.size(); ++k)
      maxCrossingError = std::max(maxCrossingError,
                                  std::fabs(crossings[k] - (2 * double(k) + 1) * period / 4 + h / 2));
    for (double p : peaks)
      maxAmplitudeError = std::max(maxAmplitudeError, std::fabs(p / w.swing.amplitude - 1));
  }

  // The summary: one JSON line with --json, else one "key value" per line.
  const std::vector<std::pair<std::string, std::string>> fields = {
      {"scene", '"' + args.scene + '"'},
      {"solver", '"' + args.solver + '"'},
      {"bullet_iterations", bullet ? std::to_string(args.bulletIterations) : "null"},
      {"warm_start", cadmm ? (args.cold ? "false" : "true") : "null"},
      {"steps", std::to_string(steps)},
      {"mean_iterations", number(sumIt / steps)},
      {"max_iterations", number(maxIt)},
      {"count", std::to_string(args.count)},
      {"seed", std::to_string(args.seed)},
      {"contacts_per_step", number(double(sumContacts) / steps)},
      {"mean_solve_ms", number(sumMs / steps)},
      {"p99_solve_ms", number(percentile(stepMs, 0.99))},
      {"max_solve_ms", number(maxMs)},
      {"mean_setup_ms", cadmm ? number(sumSetupMs / steps) : "null"},
      {"max_penetration", number(maxPen)},
      {"max_penetration_excess", number(maxExcess)},
      {"max_drift", number(maxDrift)},
      {"fell", fell ? "true" : "false"},
      {"max_error", errUnknown ? "null" : number(maxErr)},
      {"unsolved_steps", std::to_string(unsolved)},
      {"new_solvers", std::to_string(newSolvers)},
      {"max_joint_gap", number(maxGap)},
      {"tip_drift_mm", number(tipDrift)},
      {"max_tip_drift_mm", number(maxTipDrift)},
      {"max_checked_error", cadmm ? number(maxChecked) : "null"},
      {"pendulum_period", number(period)},
      {"crossings", swing ? std::to_string(crossings.size()) : "null"},
      {"max_crossing_error", number(maxCrossingError)},
      {"max_amplitude_error", number(maxAmplitudeError)},
  };
  std::string out = args.json ? "{" : "";
  for (size_t i = 0; i < fields.size(); ++i)
    out += args.json ? (i ? "," : "") + ('"' + fields[i].first + "\":" + fields[i].second)
                     : fields[i].first + ' ' + fields[i].second + '\n';
  std::printf("%s%s", out.c_str(), args.json ? "}\n" : "");

  if (args.check) {
    std::vector<std::string> failed;
    const bool pendulum = args.scene == "pendulum" || swing;
    const bool stack = !pendulum && !w.inMotion && !w.tip;
    if ((pendulum || w.tip) && !(maxGap < kJointGap))
      failed.push_back("the joint opened by " + shown(maxGap) + " m");
    if (stack && fell) failed.push_back("a body fell");
    if (stack && !(maxDrift < 1e-3))
      failed.push_back("the top body drifted " + shown(maxDrift) + " m");
    if (w.tip && !(maxTipDrift < 1e3 * kTipDrift))
      failed.push_back("the arm's tip drifted " + shown(maxTipDrift) +
                       " mm from where it started (" + shown(tipDrift) + " mm at the end)");
    if (swing) {
      if (crossings.size() < std::max<size_t>(expectedCrossings, 1))
        failed.push_back("the pendulum crossed the vertical " + std::to_string(crossings.size()) +
                         " times, the exact pendulum " + std::to_string(expectedCrossings));
      if (!(maxCrossingError <= kCrossingSlack))
        failed.push_back("the pendulum crossed the vertical " + shown(maxCrossingError) +
                         " s away from the exact pendulum (period " + shown(period) + " s)");
      if (!(maxAmplitudeError <= kAmplitudeSlack))
        failed.push_back("the pendulum's swing amplitude is off by " +
                         shown(100 * maxAmplitudeError) + "%");
    }
    // The bound holds for slowly turning bodies (kMaxPenetrationExcess): not for bricks
    // tumbling off a wall, whose excess the summary still reports.
    if (!w.inMotion && !(maxExcess <= kMaxPenetrationExcess))
      failed.push_back("a contact penetrated " + shown(maxExcess) +
                       " m deeper than the Baumgarte correction leaves it");
    if (cadmm && unsolved)
      failed.push_back(std::to_string(unsolved) + " unsolved steps (solve above its tolerance)");
    if (cadmm && !(maxChecked <= args.checkTolerance))
      failed.push_back("re-measured error " + shown(maxChecked) + " above the check tolerance " +
                       shown(args.checkTolerance));
    if (cadmm && args.maxNewSolvers >= 0 && newSolvers > args.maxNewSolvers)
      failed.push_back(std::to_string(newSolvers) + " solvers built, at most " +
                       std::to_string(args.maxNewSolvers) + " expected");
    for (const std::string &why : failed)
      std::printf("CHECK FAILED: %s (%s, solver %s)\n", why.c_str(), args.scene.c_str(),
                  args.solver.c_str());
    if (!failed.empty()) return 1;
    std::printf("CHECK PASSED\n");
  }
  return 0;
}
