// cadmm_bullet_stack: runs a stacking scene with cadmm's constraint solver or Bullet's
// sequential impulse solver and prints one JSON line of figures.
//
//   cadmm_bullet_stack --scene tower|drop|mass-ratio-100|mass-ratio-1000|pyramid|
//                               pendulum
//                      --solver cadmm|bullet [--seconds S] [--bullet-iterations N] [--cold]
//                      [--json] [--trace FILE.csv] [--check] [--with-hinge]
//
// --check exits with 1 when the scene failed: a body fell (more than a quarter of a box below
// or beside where it should rest) or the top body drifted 1 mm or more horizontally (stacks), or a joint
// opened by kJointGap or more (pendulum). A refused step (cadmm_bullet::Error) exits with 2.
#include "bullet_reference_solver.h"
#include "cadmm_constraint_solver.h"
#include "stack_scenes.h"

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

struct Args {
  std::string scene = "tower", solver = "cadmm", trace;
  double seconds = 5;
  int bulletIterations = 10;
  bool cold = false, json = false, check = false, hinge = false;
};

[[noreturn]] void usage(const char *msg) {
  std::fprintf(stderr,
               "cadmm_bullet_stack: %s\nusage: cadmm_bullet_stack --scene tower|drop|mass-ratio-100|"
               "mass-ratio-1000|pyramid|pendulum --solver cadmm|bullet [--seconds S] "
               "[--bullet-iterations N] [--cold] [--json] [--trace FILE.csv] [--check] "
               "[--with-hinge]\n",
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
    else if (k == "--cold") a.cold = true;
    else if (k == "--json") a.json = true;
    else if (k == "--check") a.check = true;
    else if (k == "--with-hinge") a.hinge = true;
    else usage(("unknown option " + k).c_str());
  }
  if (a.solver != "cadmm" && a.solver != "bullet") usage("--solver must be cadmm or bullet");
  if (!(a.seconds > 0)) usage("--seconds must be positive");
  if (a.bulletIterations < 1) usage("--bullet-iterations must be at least 1");
  return a;
}

std::string number(double x) {
  if (!std::isfinite(x)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

}  // namespace

int main(int argc, char **argv) {
  const Args args = parse(argc, argv);
  const double h = 1.0 / 60;

  CadmmConstraintSolver *cadmm = nullptr;
  BulletReferenceSolver *bullet = nullptr;
  std::unique_ptr<btConstraintSolver> solver;
  if (args.solver == "cadmm") {
    SolverOptions o;
    o.warmStart = !args.cold;
    solver = std::make_unique<CadmmConstraintSolver>(o);
    cadmm = static_cast<CadmmConstraintSolver *>(solver.get());
  } else {
    solver = std::make_unique<BulletReferenceSolver>();
    bullet = static_cast<BulletReferenceSolver *>(solver.get());
  }
  StackWorld w(std::move(solver));
  w.world().getSolverInfo().m_numIterations = args.bulletIterations;
  if (!buildScene(args.scene, w)) usage(("unknown scene " + args.scene).c_str());
  if (args.hinge) addHinge(w);

  btRigidBody *top = w.boxes.back();
  const btVector3 top0 = top->getCenterOfMassPosition();

  std::ofstream trace;
  if (!args.trace.empty()) {
    trace.open(args.trace);
    if (!trace) usage(("cannot write " + args.trace).c_str());
    trace << "step,time,solve_ms,iterations,error,top_height,penetration\n";
  }

  const int steps = int(std::lround(args.seconds / h));
  double sumIt = 0, maxIt = 0, sumMs = 0, maxMs = 0, maxPen = 0, maxDrift = 0, maxErr = 0,
         maxGap = 0;
  int unsolved = 0, newSolvers = 0;
  bool fell = false, errUnknown = false;
  for (int s = 1; s <= steps; ++s) {
    try {
      w.world().stepSimulation(h, 1, h);
    } catch (const Error &e) {
      std::fprintf(stderr, "step %d refused: %s\n", s, e.what());
      return 2;
    }
    const SolveStats st = cadmm ? cadmm->takeStats() : bullet->takeStats();
    const double ms = 1e3 * st.seconds, pen = w.maxPenetration();
    sumIt += double(st.iterations), maxIt = std::max(maxIt, double(st.iterations));
    sumMs += ms, maxMs = std::max(maxMs, ms), maxPen = std::max(maxPen, pen);
    if (std::isnan(st.error)) errUnknown = true;
    else maxErr = std::max(maxErr, st.error);
    unsolved += st.unsolved, newSolvers += st.newSolvers;

    const btVector3 p = top->getCenterOfMassPosition();
    maxDrift = std::max(maxDrift, double(std::hypot(p.x() - top0.x(), p.z() - top0.z())));
    for (size_t i = 0; i < w.boxes.size() && args.scene != "pendulum"; ++i) {
      const btVector3 d = w.boxes[i]->getCenterOfMassPosition() - w.rest[i];
      if (std::hypot(d.x(), d.z()) > 0.25 || d.y() < -0.25) fell = true;
    }
    for (int j = 0; j < w.world().getNumConstraints(); ++j)
      if (auto *p2p = dynamic_cast<btPoint2PointConstraint *>(w.world().getConstraint(j)))
        maxGap = std::max(maxGap, double((p2p->getRigidBodyA().getWorldTransform() * p2p->getPivotInA() -
                                          p2p->getRigidBodyB().getWorldTransform() * p2p->getPivotInB())
                                             .length()));
    if (trace)
      trace << s << ',' << s * h << ',' << ms << ',' << st.iterations << ',' << number(st.error)
            << ',' << p.y() << ',' << pen << '\n';
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
      {"mean_solve_ms", number(sumMs / steps)},
      {"max_solve_ms", number(maxMs)},
      {"max_penetration", number(maxPen)},
      {"max_drift", number(maxDrift)},
      {"fell", fell ? "true" : "false"},
      {"max_error", errUnknown ? "null" : number(maxErr)},
      {"unsolved_steps", std::to_string(unsolved)},
      {"new_solvers", std::to_string(newSolvers)},
      {"max_joint_gap", number(maxGap)},
  };
  std::string out = args.json ? "{" : "";
  for (size_t i = 0; i < fields.size(); ++i)
    out += args.json ? (i ? "," : "") + ('"' + fields[i].first + "\":" + fields[i].second)
                     : fields[i].first + ' ' + fields[i].second + '\n';
  std::printf("%s%s", out.c_str(), args.json ? "}\n" : "");

  if (args.check) {
    std::string why;
    if (args.scene == "pendulum") {
      if (!(maxGap < kJointGap)) why = "the joint opened by " + number(maxGap) + " m";
    } else if (fell) {
      why = "a body fell";
    } else if (!(maxDrift < 1e-3)) {
      why = "the top body drifted " + number(maxDrift) + " m";
    }
    if (!why.empty()) {
      std::printf("CHECK FAILED: %s (%s, solver %s)\n", why.c_str(), args.scene.c_str(),
                  args.solver.c_str());
      return 1;
    }
    std::printf("CHECK PASSED\n");
  }
  return 0;
}
