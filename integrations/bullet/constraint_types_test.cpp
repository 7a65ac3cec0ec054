// cadmm_bullet_constraint_types: one of each constraint type Bullet 3.24 ships
// (btPoint2PointConstraint, btHingeConstraint with limits and a motor, btSliderConstraint,
// btGeneric6DofConstraint, btGeneric6DofSpringConstraint, btGeneric6DofSpring2Constraint,
// btConeTwistConstraint, btFixedConstraint, btGearConstraint, btHinge2Constraint,
// btUniversalConstraint), each in a small world stepped 1 s (60 steps) with the cadmm
// drop-in, and what the drop-in still refuses.
//
//   cadmm_bullet_constraint_types [--only SCENE] [--negative-control hinge-limit-off|
//                                                 motor-unsaturated|rolling-off|spinning-off]
//
// Every step of every scene: stepSimulation throws nothing (a refused constraint fails the
// scene), each group's solve ends solved, its answer (r, v, lambda) re-measured on the
// problem the drop-in built by cadmm_problem_error_with_multipliers and by the driver's own
// measure (solution_check.h) is at most the tolerance, and the scene's constraint has rows
// in the problem. The first steps' velocities agree with Bullet's own sequential impulses
// run to convergence on the same rows (the mapping's signs, bias, compliance and bounds),
// at Bullet's joint damping 1 and again at 0.5. Each scene adds a physical check: the joint
// holds, limits hold, a free axis keeps its speed, a motor its target, the gear its ratio,
// a spring its sag, a joint breaks at its threshold. Two closed forms on a bar of mass m and
// length L on a hinge at one end, held horizontal by gravity's torque m g L / 2 about it:
//  - hinge-limit: a limit holds the bar: the limit row's impulse is h m g L / 2, and the
//    joint feedback written back is the bar's weight;
//  - hinge-motor: a motor (target velocity 0) whose max impulse is half that saturates at
//    exactly its max impulse, and the bar's first step turns it at
//    (h m g L / 2 - max impulse) / I_pivot.
// Two closed forms of rolling and spinning friction on a ball (rolling-friction,
// spinning-friction): the deceleration 5/7 g e / R of a rolling ball, and the stop time
// I w0 / (e m g) of a spinning one.
// --negative-control runs one of those checks on a run where it must fail (the limit
// disabled; the motor's max impulse above the load) and reports it as it would.
//
// Prints one line per scene (figures) and exits 1 after one "CHECK FAILED: ..." line per
// failed check, 0 with "CHECK PASSED".
#include "cadmm_constraint_solver.h"
#include "solution_check.h"
#include "stack_scenes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

using namespace cadmm_bullet;

namespace {

const double kH = 1.0 / 60, kG = 9.81, kTolerance = 1e-8;
const int kSteps = 60;
// Bullet's own solver as the reference: its iterations, and the first steps compared (all
// scenes start apart from the ground, so these steps have joint rows only, where Bullet's
// rows and cadmm's mapping of them must give the same velocities).
const int kBulletIterations = 3000, kCompared = 5;
// Relative to the speed (at least 1 m/s or rad/s): the measure's tolerance is relative,
// and a rolling ball's 20 rad/s carry its rolling rows' error.
const double kAgreement = 1e-6;

std::vector<std::string> failures;

void fail(const std::string &scene, const std::string &why) {
  failures.push_back(scene + ": " + why);
}

// Each scene runs twice: first with Bullet's btSequentialImpulseConstraintSolver at
// kBulletIterations (its first steps' velocities kept, its checks not made), then with the
// drop-in and every check. The world's joint damping (btContactSolverInfo::m_damping) is
// gDamping; a second round at 0.5 compares with Bullet only (the scenes' physical checks
// assume Bullet's default 1).
bool gReferencePass = false, gSceneChecks = true;
double gDamping = 1;
std::vector<std::pair<std::string, std::vector<double>>> gReference;

std::string fmt(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

// A scene's world with the drop-in, and what every group's solve left: the worst errors
// and the multipliers of the rows a check asks for.
struct Run {
  std::string name;
  std::unique_ptr<StackWorld> world;
  btTypedConstraint *joint = nullptr;  // the scene's constraint, which must have rows
  int rowless = 0;                     // steps it may start without (see universal())
  // Rows whose multiplier a closed form reads: (constraint, its row), lambda of the step.
  std::vector<std::pair<btTypedConstraint *, int>> watch;
  std::vector<double> watched;  // this step's multipliers of `watch`, NaN when not mapped
  double worstCadmm = 0, worstDriver = 0, contacts = 0;
  int unsolved = 0, groups = 0, stepsWithRows = 0, jointRows = 0, bounded = 0, compliant = 0;
  bool refused = false;

  std::vector<double> firstSteps;  // the dynamic bodies' velocities after each of the first
                                   // kCompared steps
  int steps = 0;

  explicit Run(std::string n) : name(std::move(n)) {
    if (gDamping != 1) name += " (damping " + fmt(gDamping) + ")";
    SolverOptions o;
    o.tolerance = kTolerance;
    o.onSolved = [this](const SolvedGroup &g) { solved(g); };
    if (gReferencePass)
      world = std::make_unique<StackWorld>(std::make_unique<btSequentialImpulseConstraintSolver>());
    else
      world = std::make_unique<StackWorld>(std::make_unique<CadmmConstraintSolver>(o));
    btContactSolverInfo &info = world->world().getSolverInfo();
    // cadmm ignores the iteration count, but btGeneric6DofSpringConstraint's getInfo2 reads
    // it: both passes must have the reference's.
    info.m_numIterations = kBulletIterations;
    info.m_leastSquaresResidualThreshold = 0;
    info.m_damping = gDamping;
  }

  // A scene's own check failed (dropped in the reference pass and the damped round).
  void fail(const std::string &why) {
    if (!gReferencePass && gSceneChecks) ::fail(name, why);
  }

  void solved(const SolvedGroup &g) {
    const ContactProblem &p = g.problem;
    ++groups;
    unsolved += g.status != CADMM_STATUS_SOLVED;
    std::unique_ptr<cadmm_problem, void (*)(cadmm_problem *)> made(p.make(), cadmm_problem_free);
    double e = INFINITY;
    if (cadmm_problem_error_with_multipliers(made.get(), g.r, g.v, g.lambda, &e) != CADMM_OK)
      ::fail(name, std::string("cadmm_problem_error_with_multipliers: ") + cadmm_last_error());
    if (!(e <= worstCadmm)) worstCadmm = e;
    const double d = remeasureError(p, g.r, g.v, g.lambda);
    if (!(d <= worstDriver)) worstDriver = d;
    contacts = std::max(contacts, double(p.contacts()));
    jointRows = std::max(jointRows, int(p.jointRows()));
    int nb = 0, nc = 0;
    for (size_t k = 0; k < p.jointRows(); ++k) {
      nb += std::isfinite(p.lo[k]) || std::isfinite(p.hi[k]);
      nc += p.compliance[k] != 0;
    }
    bounded = std::max(bounded, nb), compliant = std::max(compliant, nc);
    if (joint && p.jointRow(joint, 0) >= 0) ++stepsWithRows;
    for (size_t i = 0; i < watch.size(); ++i) {
      const int col = p.jointRow(watch[i].first, watch[i].second);
      if (col >= 0) watched[i] = g.lambda[col];
    }
  }

  // Steps once; false (and the scene failed) when the drop-in refused the step.
  bool step() {
    watched.assign(watch.size(), NAN);
    try {
      world->world().stepSimulation(kH, 1, kH);
    } catch (const Error &e) {
      ::fail(name, std::string("the drop-in refused a step: ") + e.what());
      refused = true;
      return false;
    }
    if (++steps <= kCompared)
      for (int i = 0; i < world->world().getNumCollisionObjects(); ++i) {
        const btRigidBody *rb = btRigidBody::upcast(world->world().getCollisionObjectArray()[i]);
        if (!rb || rb->isStaticOrKinematicObject()) continue;
        for (int k = 0; k < 3; ++k) firstSteps.push_back(rb->getLinearVelocity()[k]);
        for (int k = 0; k < 3; ++k) firstSteps.push_back(rb->getAngularVelocity()[k]);
      }
    return true;
  }

  btRigidBody *box(const btVector3 &he, double mass, const btVector3 &at,
                   const btQuaternion &q = btQuaternion::getIdentity()) {
    return world->addBox(he, mass, at, q);
  }
  template <class J>
  J *add(std::unique_ptr<J> j) {
    J *raw = j.get();
    world->addJoint(std::move(j));
    return raw;
  }

  // The checks every scene shares, and its figures.
  void finish(const std::string &figures) {
    if (gReferencePass) {
      gReference.emplace_back(name, firstSteps);
      return;
    }
    if (refused) return;
    // Bullet's answer to the same first steps, when the reference pass ran this scene.
    double apart = NAN;
    for (const auto &[scene, v] : gReference)
      if (scene == name && v.size() == firstSteps.size()) {
        apart = 0;
        for (size_t i = 0; i < v.size(); ++i)
          apart = std::max(apart, std::fabs(v[i] - firstSteps[i]) / std::max(1.0, std::fabs(v[i])));
      } else if (scene == name) {
        ::fail(name, "Bullet's sequential impulses and cadmm ran different numbers of steps");
      }
    if (!std::isnan(apart) && !(apart <= kAgreement))
      ::fail(name, "the first " + std::to_string(kCompared) + " steps' velocities are " +
                     fmt(apart) + " (relative) away from Bullet's sequential impulses at " +
                     std::to_string(kBulletIterations) + " iterations");
    if (unsolved) ::fail(name, std::to_string(unsolved) + " solves ended above the tolerance");
    if (!(worstCadmm <= kTolerance))
      ::fail(name, "re-measured error (cadmm_problem_error_with_multipliers) " +
                     fmt(worstCadmm) + " above the tolerance " + fmt(kTolerance));
    if (!(worstDriver <= kTolerance))
      ::fail(name, "re-measured error (the driver's measure) " + fmt(worstDriver) +
                     " above the tolerance " + fmt(kTolerance));
    if (joint && stepsWithRows < kSteps - rowless)
      ::fail(name, "the constraint had rows in " + std::to_string(stepsWithRows) + " of " +
                     std::to_string(kSteps) + " steps");
    std::printf("%-20s groups %2d, joint rows %2d (bounded %d, compliant %d), contacts %.0f, "
                "error %.1e (driver %.1e), vs Bullet %.1e; %s\n",
                name.c_str(), groups, jointRows, bounded, compliant, contacts, worstCadmm,
                worstDriver, apart, figures.c_str());
  }
};

// The angle of a body's local axis a from the world direction d.
double angleFrom(const btRigidBody *b, const btVector3 &a, const btVector3 &d) {
  const btVector3 w = b->getWorldTransform().getBasis() * a;
  return std::acos(std::clamp(double(w.dot(d) / (w.length() * d.length())), -1.0, 1.0));
}

// How far a body's local point is from a world point: a ball joint's gap.
double gap(const btRigidBody *b, const btVector3 &local, const btVector3 &world) {
  return (b->getWorldTransform() * local - world).length();
}

// ---- one scene per constraint type ---------------------------------------------------

// A 20 cm box hanging 0.5 m from a world point by a ball joint, released horizontal.
void pointToPoint() {
  Run run("point2point");
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0.5, 4, 0));
  auto *j = run.add(std::make_unique<btPoint2PointConstraint>(*b, btVector3(-0.5, 0, 0)));
  run.joint = j;
  double open = 0;
  for (int s = 0; s < kSteps && run.step(); ++s)
    open = std::max(open, gap(b, j->getPivotInA(), j->getPivotInB()));
  if (!(open < 0.03)) run.fail("the joint opened by " + fmt(open) + " m");
  run.finish("max gap " + fmt(open) + " m");
}

// A 1 m bar on a hinge to a static anchor, limited to [-0.6, 0.6] rad, its motor driving it
// up at 3 rad/s with enough impulse to lift it: it swings up into a limit and stays.
void hinge() {
  Run run("hinge");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *bar = run.box(btVector3(0.5, 0.05, 0.05), 2, btVector3(0.5, 4, 0));
  auto *j = run.add(std::make_unique<btHingeConstraint>(*anchor, *bar, btVector3(0, 0, 0),
                                                        btVector3(-0.5, 0, 0), btVector3(0, 0, 1),
                                                        btVector3(0, 0, 1)));
  j->setLimit(-0.6, 0.6);
  j->enableAngularMotor(true, 3, 0.5);
  run.joint = j;
  double worst = 0;
  for (int s = 0; s < kSteps && run.step(); ++s)
    worst = std::max(worst, std::fabs(double(j->getHingeAngle())));
  const double end = j->getHingeAngle();
  if (!(worst <= 0.65)) run.fail("the hinge left its limits: " + fmt(worst) + " rad");
  if (!(std::fabs(end) > 0.5)) run.fail("the motor did not drive the bar into a limit");
  run.finish("max |angle| " + fmt(worst) + " rad, end " + fmt(end));
}

// A box on a vertical slider (its axis pointing down), free in [0, 0.5] m: it falls onto
// the limit 0.5 m below and rests there.
void slider() {
  Run run("slider");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 4, 0));
  const btTransform down(btQuaternion(btVector3(0, 0, 1), -SIMD_HALF_PI));  // x -> -y
  auto *j = run.add(std::make_unique<btSliderConstraint>(*anchor, *b, down, down, true));
  j->setLowerLinLimit(0);
  j->setUpperLinLimit(0.5);
  run.joint = j;
  double lowest = 4;
  for (int s = 0; s < kSteps && run.step(); ++s)
    lowest = std::min(lowest, double(b->getCenterOfMassPosition().y()));
  const btVector3 p = b->getCenterOfMassPosition();
  // A limit row appears once the box is past the limit: by up to a step's travel (5 cm).
  if (!(lowest > 3.5 - 0.06)) run.fail("the box went " + fmt(3.5 - lowest) + " m past the limit");
  if (!(std::fabs(p.y() - 3.5) < 0.01 && std::hypot(p.x(), p.z()) < 1e-3))
    run.fail("the box does not rest on the limit: at " + fmt(p.x()) + ", " + fmt(p.y()) +
             ", " + fmt(p.z()));
  run.finish("lowest y " + fmt(lowest) + ", end y " + fmt(p.y()));
}

// A box on a 6-DOF joint: linear x free, y limited to [-0.3, 0.3], z locked; angular x
// free with a motor (2 rad/s, up to 5 N m), y locked, z limited to [-0.4, 0.4] (y is the
// middle Euler angle, which must stay within +-pi/2: the free spin is about x); thrown
// along x and turning about z. The free x axis keeps its speed (1 m/s, no force along it),
// the box falls onto its y limit and turns onto its z limit, and the motor's row, inside
// its bounds, holds the spin about x at exactly its target.
void generic6Dof() {
  Run run("generic6dof");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 4, 0));
  auto *j = run.add(std::make_unique<btGeneric6DofConstraint>(
      *anchor, *b, btTransform::getIdentity(), btTransform::getIdentity(), true));
  j->setLinearLowerLimit(btVector3(1, -0.3, 0));  // lower > upper: free
  j->setLinearUpperLimit(btVector3(-1, 0.3, 0));
  j->setAngularLowerLimit(btVector3(1, 0, -0.4));
  j->setAngularUpperLimit(btVector3(-1, 0, 0.4));
  btRotationalLimitMotor *motor = j->getRotationalLimitMotor(0);
  motor->m_enableMotor = true, motor->m_targetVelocity = 2, motor->m_maxMotorForce = 5;
  b->setLinearVelocity(btVector3(1, 0, 0));
  b->setAngularVelocity(btVector3(0, 0, 2));
  run.joint = j;
  double lowest = 4, drift = 0, turn = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    lowest = std::min(lowest, double(b->getCenterOfMassPosition().y()));
    drift = std::max(drift, std::fabs(double(b->getCenterOfMassPosition().z())));
    turn = std::max(turn, std::fabs(double(j->getAngle(2))));
  }
  const double x = b->getCenterOfMassPosition().x();
  // The motor's row is along the x Euler axis as the step's getInfo2 computed it (getAxis(0)
  // is that step's; positions have moved since), J = (axis on the anchor, -axis on the box):
  // the box spins at minus the target.
  const double spin = j->getAxis(0).dot(b->getAngularVelocity());
  if (!(lowest > 3.7 - 0.06)) run.fail("y went " + fmt(3.7 - lowest) + " m past its limit");
  if (!(turn > 0.35 && turn < 0.4 + 0.06))
    run.fail("the turn about z reached " + fmt(turn) + " rad, its limit is 0.4");
  if (!(drift < 1e-9)) run.fail("the locked z axis moved " + fmt(drift) + " m");
  if (!(std::fabs(x - kSteps * kH) < 1e-6))
    run.fail("the free x axis went " + fmt(x) + " m in 1 s at 1 m/s");
  if (!(std::fabs(spin + 2) < 1e-6))
    run.fail("the motor turns the box at " + fmt(spin) + " rad/s, its target is -2");
  run.finish("x " + fmt(x) + " m, lowest y " + fmt(lowest) + ", max turn " + fmt(turn) +
             ", spin " + fmt(spin));
}

// A box on a btGeneric6DofSpringConstraint: y free in [-1, 1] with a spring, everything
// else locked; it bounces on the spring and never reaches the stops.
void generic6DofSpring() {
  Run run("generic6dof-spring");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 4, 0));
  auto *j = run.add(std::make_unique<btGeneric6DofSpringConstraint>(
      *anchor, *b, btTransform::getIdentity(), btTransform::getIdentity(), true));
  j->setLinearLowerLimit(btVector3(0, -1, 0));
  j->setLinearUpperLimit(btVector3(0, 1, 0));
  j->setAngularLowerLimit(btVector3(0, 0, 0));
  j->setAngularUpperLimit(btVector3(0, 0, 0));
  j->enableSpring(1, true);
  j->setStiffness(1, 100);
  j->setEquilibriumPoint();
  run.joint = j;
  double lowest = 4, drift = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    const btVector3 p = b->getCenterOfMassPosition();
    lowest = std::min(lowest, double(p.y()));
    drift = std::max(drift, double(std::hypot(p.x(), p.z())));
  }
  if (!(lowest > 3.0)) run.fail("the spring let the box reach its stop");
  if (!(lowest < 3.95)) run.fail("the box did not move on its spring");
  if (!(drift < 1e-3)) run.fail("the locked axes moved " + fmt(drift) + " m");
  run.finish("lowest y " + fmt(lowest) + ", drift " + fmt(drift));
}

// A box on a btGeneric6DofSpring2Constraint: y in [-0.5, 0.5] on a damped spring (k = 200,
// d = 5), everything else locked: it settles near y = -m g / k below the anchor.
void generic6DofSpring2() {
  Run run("generic6dof-spring2");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 4, 0));
  auto *j = run.add(std::make_unique<btGeneric6DofSpring2Constraint>(
      *anchor, *b, btTransform::getIdentity(), btTransform::getIdentity()));
  j->setLinearLowerLimit(btVector3(0, -0.5, 0));
  j->setLinearUpperLimit(btVector3(0, 0.5, 0));
  j->enableSpring(1, true);
  j->setStiffness(1, 200);
  j->setDamping(1, 5);
  j->setEquilibriumPoint(1, 0);
  run.joint = j;
  for (int s = 0; s < kSteps && run.step(); ++s) {
  }
  // 1 s is 2.3 periods at damping ratio 0.18: the swing is down to 8% of m g / k.
  const double sag = 4 - b->getCenterOfMassPosition().y(), expected = kG / 200;
  if (!(std::fabs(sag - expected) < 0.2 * expected))
    run.fail("the spring sags " + fmt(sag) + " m, m g / k = " + fmt(expected) + " m");
  run.finish("sag " + fmt(sag) + " m (m g / k " + fmt(expected) + ")");
}

// A 50 cm box hanging from a cone twist joint (swing spans 0.4 rad, twist span 0.3 rad),
// thrown sideways and twisted: it swings into the cone and twists into its limit.
void coneTwist() {
  Run run("cone-twist");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.05, 0.25, 0.05), 1, btVector3(0, 3.75, 0));
  const btQuaternion down(btVector3(0, 0, 1), -SIMD_HALF_PI);  // twist axis x -> -y
  auto *j = run.add(std::make_unique<btConeTwistConstraint>(
      *anchor, *b, btTransform(down), btTransform(down, btVector3(0, 0.25, 0))));
  j->setLimit(0.4, 0.4, 0.3);
  b->setLinearVelocity(btVector3(1.2, 0, 0));  // would swing to 0.78 rad
  b->setAngularVelocity(btVector3(0, 2, 0));
  run.joint = j;
  double swing = 0, open = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    swing = std::max(swing, angleFrom(b, btVector3(0, 1, 0), btVector3(0, 1, 0)));
    open = std::max(open, gap(b, btVector3(0, 0.25, 0), btVector3(0, 4, 0)));
  }
  if (!(swing > 0.35)) run.fail("the box did not swing into its cone");
  if (!(swing < 0.4 + 0.06)) run.fail("the box swung " + fmt(swing) + " rad, its cone is 0.4");
  if (!(open < 0.03)) run.fail("the joint opened by " + fmt(open) + " m");
  run.finish("max swing " + fmt(swing) + " rad, max gap " + fmt(open) + " m");
}

// Two boxes welded by a btFixedConstraint, the first hanging from a ball joint: they swing
// as one body.
void fixed() {
  Run run("fixed");
  btRigidBody *a = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0.3, 4, 0));
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0.6, 4, 0));
  run.add(std::make_unique<btPoint2PointConstraint>(*a, btVector3(-0.3, 0, 0)));
  const btQuaternion same = btQuaternion::getIdentity();
  auto *j = run.add(std::make_unique<btFixedConstraint>(
      *a, *b, btTransform(same, btVector3(0.15, 0, 0)), btTransform(same, btVector3(-0.15, 0, 0))));
  run.joint = j;
  double slip = 0, turn = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    const btTransform rel = a->getWorldTransform().inverse() * b->getWorldTransform();
    slip = std::max(slip, double((rel.getOrigin() - btVector3(0.3, 0, 0)).length()));
    turn = std::max(turn, double(rel.getRotation().getAngleShortestPath()));
  }
  if (!(slip < 0.01 && turn < 0.01))
    run.fail("the weld moved by " + fmt(slip) + " m and " + fmt(turn) + " rad");
  run.finish("max slip " + fmt(slip) + " m, max turn " + fmt(turn) + " rad");
}

// Two equal wheels on hinges at their centres, geared 2:1; the first spun at 3 rad/s. The
// gear row holds wA + 2 wB = 0 from the first step: an inelastic coupling that leaves
// wA = 3 * 4 / 5 = 2.4 rad/s (equal inertias), then nothing changes.
void gear() {
  Run run("gear");
  const btVector3 he(0.2, 0.2, 0.05), z(0, 0, 1);
  btRigidBody *a = run.box(he, 1, btVector3(0, 4, 0));
  btRigidBody *b = run.box(he, 1, btVector3(1, 4, 0));
  run.add(std::make_unique<btHingeConstraint>(*a, btVector3(0, 0, 0), z));
  run.add(std::make_unique<btHingeConstraint>(*b, btVector3(0, 0, 0), z));
  auto *j = run.add(std::make_unique<btGearConstraint>(*a, *b, z, z, 2));
  a->setAngularVelocity(btVector3(0, 0, 3));
  run.joint = j;
  double ratio = 0;
  for (int s = 0; s < kSteps && run.step(); ++s)
    ratio = std::max(ratio, std::fabs(double(a->getAngularVelocity().z() +
                                             2 * b->getAngularVelocity().z())));
  const double wA = a->getAngularVelocity().z();
  if (!(ratio < 1e-6)) run.fail("wA + 2 wB reached " + fmt(ratio) + " rad/s");
  if (!(std::fabs(wA - 2.4) < 1e-6))
    run.fail("wA is " + fmt(wA) + " rad/s, the coupling leaves 2.4");
  run.finish("max |wA + 2 wB| " + fmt(ratio) + ", wA " + fmt(wA) + " rad/s");
}

// A wheel (sphere, r 0.3 m) on a btHinge2Constraint below a static chassis: its suspension
// spring (k = 4 pi^2, rest at y = 0.5) cannot hold its weight, so it rests on the ground
// (contacts and joint rows in one group) while it spins about its axle.
void hinge2() {
  Run run("hinge2");
  btRigidBody *chassis = run.box(btVector3(0.3, 0.1, 0.3), 0, btVector3(0, 1.2, 0));
  btRigidBody *wheel = run.world->addSphere(0.3, 1, btVector3(0, 0.5, 0));
  btVector3 anchor(0, 0.5, 0), axis1(0, 1, 0), axis2(1, 0, 0);
  auto *j = run.add(std::make_unique<btHinge2Constraint>(*chassis, *wheel, anchor, axis1, axis2));
  wheel->setAngularVelocity(btVector3(5, 0, 0));
  run.joint = j;
  double drift = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    const btVector3 p = wheel->getCenterOfMassPosition();
    drift = std::max(drift, double(std::hypot(p.x(), p.z())));
  }
  const double y = wheel->getCenterOfMassPosition().y();
  if (!(drift < 1e-3)) run.fail("the wheel left its suspension axis by " + fmt(drift) + " m");
  if (!(std::fabs(y - 0.3) < 0.01)) run.fail("the wheel does not rest on the ground: y " + fmt(y));
  if (!(run.contacts > 0)) run.fail("the wheel never touched the ground");
  run.finish("end y " + fmt(y) + ", drift " + fmt(drift));
}

// A 50 cm box hanging from a universal joint (axes z on the anchor, x on the box), thrown
// sideways and twisted about its long axis: it swings about both axes, never twists.
void universal() {
  Run run("universal");
  btRigidBody *anchor = run.box(btVector3(0.05, 0.05, 0.05), 0, btVector3(0, 4, 0));
  btRigidBody *b = run.box(btVector3(0.05, 0.25, 0.05), 1, btVector3(0, 3.75, 0));
  auto *j = run.add(std::make_unique<btUniversalConstraint>(
      *anchor, *b, btVector3(0, 4, 0), btVector3(0, 0, 1), btVector3(1, 0, 0)));
  b->setLinearVelocity(btVector3(1, 0, 1));
  b->setAngularVelocity(btVector3(0, 2, 0));
  run.joint = j;
  // btGeneric6DofConstraint gives an axis exactly at its lock no row (its limit test is
  // strict, in Bullet's solver too): the first step, all aligned, has none and the box
  // twists freely by 2 h; from then on the locked axis holds and its ERP turns it back.
  run.rowless = 1;
  double open = 0, twist = 0, end = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    open = std::max(open, gap(b, btVector3(0, 0.25, 0), btVector3(0, 4, 0)));
    // The twist: the box's x axis (axis2) leaving the plane normal to the anchor's z.
    end = std::fabs(SIMD_HALF_PI - angleFrom(b, btVector3(1, 0, 0), btVector3(0, 0, 1)));
    twist = std::max(twist, end);
  }
  if (!(open < 0.03)) run.fail("the joint opened by " + fmt(open) + " m");
  if (!(twist < 2 * kH + 1e-3 && end < 1e-3))
    run.fail("the box twisted by " + fmt(twist) + " rad (" + fmt(end) + " at the end)");
  run.finish("max gap " + fmt(open) + " m, max twist " + fmt(twist) + " rad, end " + fmt(end));
}

// ---- closed forms on a hinged bar ------------------------------------------------------

// The bar: 1 m x 10 cm x 10 cm, 2 kg, on a hinge about z at its left end (single-body
// hinge to the world), horizontal. Bullet's default hinge moves the pivot rows' torque to
// the limit row's partner rows for a static partner (frame offset): the textbook rows here.
const double kBarMass = 2, kBarLength = 1, kBarWidth = 0.1;
const double kLoad = kH * kBarMass * kG * kBarLength / 2;  // gravity's impulse about the hinge
const double kPivotInertia = kBarMass * (kBarLength * kBarLength + kBarWidth * kBarWidth) / 12 +
                             kBarMass * kBarLength * kBarLength / 4;

struct Bar {
  btRigidBody *body;
  btHingeConstraint *hinge;
};

Bar bar(Run &run) {
  btRigidBody *b = run.box(btVector3(kBarLength / 2, kBarWidth / 2, kBarWidth / 2), kBarMass,
                           btVector3(kBarLength / 2, 4, 0));
  auto *h = run.add(std::make_unique<btHingeConstraint>(*b, btVector3(-kBarLength / 2, 0, 0),
                                                        btVector3(0, 0, 1)));
  h->setUseFrameOffset(false);
  run.joint = h;
  return {b, h};
}

// A limit at the horizontal (the bar falls towards negative hinge angles, into the lower
// limit 0):
// once the bar rests on it, the limit row (the hinge's 6th) carries gravity's whole torque
// about the hinge, h m g L / 2 (its pivot rows act at the hinge). After 1 s what is left of
// the Baumgarte correction of the first steps' overshoot (1e-4 rad) moves it by 1e-4.
void hingeLimit(bool limited) {
  Run run(limited ? "hinge-limit" : "hinge-limit-off");
  const Bar b = bar(run);
  if (limited) b.hinge->setLimit(0, 1);
  btJointFeedback feedback;
  b.hinge->setJointFeedback(&feedback);
  run.watch = {{b.hinge, 5}};
  for (int s = 0; s < kSteps && run.step(); ++s) {
  }
  const double lambda = run.watched[0], angle = b.hinge->getHingeAngle();
  if (!(std::fabs(std::fabs(lambda) / kLoad - 1) < 1e-3))
    run.fail("the limit row's impulse is " + fmt(lambda) + ", not h m g L / 2 = " + fmt(kLoad));
  if (!(std::fabs(angle) < 1e-3))
    run.fail("the bar rests at " + fmt(angle) + " rad, not on its limit");
  // What the drop-in writes back, as Bullet's writeBackJoints: the last row's impulse, and
  // J^T lambda / h summed over the rows: the bar at rest is held up by its weight, m g,
  // with no torque about its centre (the limit's cancels the pivot force's).
  const double weight = kBarMass * kG;
  const btVector3 force = feedback.m_appliedForceBodyA, torque = feedback.m_appliedTorqueBodyA;
  if (!(b.hinge->getAppliedImpulse() == lambda))
    run.fail("the applied impulse " + fmt(b.hinge->getAppliedImpulse()) +
             " is not the last row's " + fmt(lambda));
  if (!((force - btVector3(0, weight, 0)).length() < 1e-3 * weight &&
        torque.length() < 1e-3 * weight * kBarLength))
    run.fail("the joint feedback on the bar is force (" + fmt(force.x()) + ", " + fmt(force.y()) +
             ", " + fmt(force.z()) + "), torque " + fmt(torque.length()) + ", not its weight " +
             fmt(weight) + " N with no torque");
  run.finish("limit impulse " + fmt(lambda) + " (h m g L / 2 " + fmt(kLoad) + "), angle " +
             fmt(angle) + ", feedback force " + fmt(force.y()) + " N, torque " +
             fmt(torque.length()));
}

// A motor holding the bar (target velocity 0) with a max impulse of half the load (or,
// unsaturated, twice it): while the bar turns it brakes at exactly its max impulse, and the
// first step turns the bar at (h m g L / 2 - max impulse) / I_pivot.
void hingeMotor(bool saturated) {
  Run run(saturated ? "hinge-motor" : "motor-unsaturated");
  const Bar b = bar(run);
  const double maxImpulse = (saturated ? 0.5 : 2) * kLoad;
  b.hinge->enableAngularMotor(true, 0, maxImpulse);
  run.watch = {{b.hinge, 5}};
  double first = NAN, worst = 0;
  int turning = 0;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    const double w = b.body->getAngularVelocity().z(), lambda = run.watched[0];
    if (s == 0) first = w;
    if (std::fabs(w) > 1e-3 || s == 0) {  // turning (or the first step, turning by the closed form)
      ++turning;
      worst = std::max(worst, std::fabs(std::fabs(lambda) / maxImpulse - 1));
    }
  }
  const double expected = -(kLoad - maxImpulse) / kPivotInertia;
  if (!(worst < 1e-9))
    run.fail("the motor's impulse is off its max impulse " + fmt(maxImpulse) + " by " +
             fmt(100 * worst) + "% while the bar turns");
  if (!(std::fabs(first - expected) < 1e-6 * std::max(std::fabs(expected), 1.0)))
    run.fail("the first step turns the bar at " + fmt(first) + " rad/s, not (h m g L / 2 - " +
             "max impulse) / I_pivot = " + fmt(expected));
  run.finish("first w " + fmt(first) + " rad/s (closed form " + fmt(expected) + "), " +
             std::to_string(turning) + " steps at max impulse within " + fmt(worst));
}

// A 1 kg box on a ball joint that breaks at half the impulse that holds it: the first step
// clamps the vertical row at the threshold, so the box falls at half gravity's rate, and
// disables the joint (Bullet's writeBackJoints); then it falls freely.
void breaking() {
  Run run("breaking");
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 8, 0));  // lands after 1 s
  auto *j = run.add(std::make_unique<btPoint2PointConstraint>(*b, btVector3(0, 0.1, 0)));
  j->setBreakingImpulseThreshold(0.5 * kH * kG);
  run.joint = j;
  run.rowless = kSteps - 1;  // a disabled constraint has none
  double first = NAN;
  bool broken = false;
  for (int s = 0; s < kSteps && run.step(); ++s)
    if (s == 0) first = b->getLinearVelocity().y(), broken = !j->isEnabled();
  const double end = b->getLinearVelocity().y();
  if (!broken) run.fail("the joint is still enabled after a row reached its breaking threshold");
  if (!(std::fabs(first + kG * kH / 2) < 1e-9))
    run.fail("the first step leaves the box at " + fmt(first) + " m/s, not -g h / 2");
  if (!(std::fabs(end - first + (kSteps - 1) * kG * kH) < 1e-9))
    run.fail("the box did not fall freely once the joint broke: " + fmt(end) + " m/s");
  run.finish("first step " + fmt(first) + " m/s, enabled " + (j->isEnabled() ? "yes" : "no"));
}

// ---- rolling and spinning friction --------------------------------------------------------

// A ball of 1 kg resting on the ground whose contact has the rolling and spinning
// coefficients given: Bullet combines a pair's as e_0 mu_1 + e_1 mu_0 (btManifoldResult),
// so the ground has none and the ball e / mu_ground.
btRigidBody *ballOnGround(Run &run, double R, double rolling, double spinning) {
  btRigidBody *ground = btRigidBody::upcast(run.world->world().getCollisionObjectArray()[0]);
  ground->setRollingFriction(0), ground->setSpinningFriction(0);
  btRigidBody *ball = run.world->addSphere(R, 1, btVector3(0, R, 0));
  ball->setRollingFriction(rolling / ground->getFriction());
  ball->setSpinningFriction(spinning / ground->getFriction());
  return ball;
}

// A 10 cm ball of 1 kg rolling without slipping at 2 m/s, rolling friction e = 0.01 m: the
// rolling rows brake it at a = 5/7 g e / R, each step exactly h a (the contact's normal
// impulse m g h = 0.16 keeps e r_n under Bullet's cap e).
void rollingFriction(bool on) {
  Run run(on ? "rolling-friction" : "rolling-friction-off");
  const double R = 0.1, v0 = 2, e = 0.01, a = 5.0 / 7 * kG * e / R;
  btRigidBody *ball = ballOnGround(run, R, on ? e : 0, 0);
  ball->setLinearVelocity(btVector3(v0, 0, 0));
  ball->setAngularVelocity(btVector3(0, 0, -v0 / R));
  double worst = 0;
  for (int s = 0; s < kSteps && run.step(); ++s)
    worst = std::max(worst, std::fabs(ball->getLinearVelocity().x() - (v0 - (s + 1) * kH * a)));
  const double end = ball->getLinearVelocity().x();
  if (!(worst < 1e-6))
    run.fail("the ball's speed is " + fmt(worst) + " m/s off v0 - 5/7 g e t / R (" +
             fmt(v0 - a) + " m/s after 1 s, it has " + fmt(end) + ")");
  run.finish("speed after 1 s " + fmt(end) + " m/s (closed form " + fmt(v0 - a) + "), off by " +
             fmt(worst));
}

// The same ball spinning at 10 rad/s about the vertical, spinning friction e = 0.005 m: it
// slows at e m g / I a step and stops at T = I w0 / (e m g) = 0.8155 s, then stays still.
// (Bullet gives a contact its spinning row only with rolling friction: 0.01 here.)
void spinningFriction(bool on) {
  Run run(on ? "spinning-friction" : "spinning-friction-off");
  const double R = 0.1, w0 = 10, e = 0.005, I = 0.4 * R * R, rate = e * kG / I;
  btRigidBody *ball = ballOnGround(run, R, 0.01, on ? e : 0);
  ball->setAngularVelocity(btVector3(0, w0, 0));
  double worst = 0, stop = NAN;
  for (int s = 0; s < kSteps && run.step(); ++s) {
    const double w = ball->getAngularVelocity().y();
    worst = std::max(worst, std::fabs(w - std::max(w0 - (s + 1) * kH * rate, 0.0)));
    if (std::isnan(stop) && std::fabs(w) < 1e-9) stop = (s + 1) * kH;
  }
  const double T = I * w0 / (e * kG);
  // The normal impulse is m g h up to Bullet's penetration correction (the ball settles
  // into the ground by round-off and slop): the decay holds to 1e-5 of w0 over the run.
  if (!(worst < 1e-5 * w0 && std::fabs(stop - T) <= kH))
    run.fail("the spin is " + fmt(worst) + " rad/s off its linear decay, stopped at " + fmt(stop) +
             " s (closed form " + fmt(T) + " s)");
  run.finish("stopped at " + fmt(stop) + " s (closed form " + fmt(T) + " s), off by " + fmt(worst));
}

// ---- what stays refused ------------------------------------------------------------------

// Steps a world once and expects the drop-in to refuse it with a message containing `what`.
void expectRefused(const std::string &name, const std::string &what,
                   const std::function<void(Run &)> &build) {
  Run run(name);
  build(run);
  try {
    run.world->world().stepSimulation(kH, 1, kH);
  } catch (const Error &e) {
    if (std::strstr(e.what(), what.c_str()))
      std::printf("%-20s refused: %s\n", name.c_str(), e.what());
    else
      fail(name, std::string("refused with another message: ") + e.what());
    return;
  }
  fail(name, "not refused (expected a message with \"" + what + "\")");
}

void refusals() {
  expectRefused("anisotropic-rolling", "anisotropic friction", [](Run &run) {
    btRigidBody *ball = ballOnGround(run, 0.1, 0.01, 0);
    ball->setAnisotropicFriction(btVector3(1, 0.5, 1),
                                 btCollisionObject::CF_ANISOTROPIC_ROLLING_FRICTION);
  });
  expectRefused("global-cfm-contact", "m_globalCfm", [](Run &run) {
    run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0, 0.099, 0));
    run.world->world().getSolverInfo().m_globalCfm = 1e-4;
  });
  expectRefused("obsolete-p2p", "obsolete solver", [](Run &run) {
    btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0.5, 4, 0));
    run.add(std::make_unique<btPoint2PointConstraint>(*b, btVector3(-0.5, 0, 0)))
        ->m_useSolveConstraintObsolete = true;
  });
  // Options the drop-in refuses when it is built, naming the option.
  auto with = [](auto set) {
    SolverOptions o;
    set(o);
    return o;
  };
  const std::vector<std::tuple<std::string, SolverOptions, std::string>> options = {
      {"negative-time-limit", with([](SolverOptions &o) { o.timeLimit = -1; }),
       "invalid time limit"},
      {"negative-step-limit", with([](SolverOptions &o) { o.stepTimeLimit = -0.01; }),
       "invalid step time limit"},
      {"nan-step-limit", with([](SolverOptions &o) { o.stepTimeLimit = NAN; }),
       "invalid step time limit"},
      {"zero-tolerance", with([](SolverOptions &o) { o.tolerance = 0; }), "invalid tolerance"},
  };
  for (const auto &[name, o, what] : options) {
    try {
      CadmmConstraintSolver solver(o);
      fail(name, "not refused (expected a message with \"" + what + "\")");
    } catch (const Error &e) {
      if (std::strstr(e.what(), what.c_str()))
        std::printf("%-20s refused: %s\n", name.c_str(), e.what());
      else
        fail(name, std::string("refused with another message: ") + e.what());
    }
  }
}

// The global CFM without contacts: the first row of each constraint is compliant (as in
// Bullet's convertJoint), c = cfm D, and the answer is measured with it.
void globalCfmJoint() {
  Run run("global-cfm-joint");
  run.world->world().getSolverInfo().m_globalCfm = 1e-3;
  btRigidBody *b = run.box(btVector3(0.1, 0.1, 0.1), 1, btVector3(0.5, 4, 0));
  run.joint = run.add(std::make_unique<btPoint2PointConstraint>(*b, btVector3(-0.5, 0, 0)));
  for (int s = 0; s < kSteps && run.step(); ++s) {
  }
  if (run.compliant != 1) run.fail(std::to_string(run.compliant) + " compliant rows, expected 1");
  run.finish("compliant rows " + std::to_string(run.compliant));
}

}  // namespace

int main(int argc, char **argv) {
  std::string only, negative;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--only" && i + 1 < argc) only = argv[++i];
    else if (k == "--negative-control" && i + 1 < argc) negative = argv[++i];
    else {
      std::fprintf(stderr, "usage: cadmm_bullet_constraint_types [--only SCENE] "
                           "[--negative-control hinge-limit-off|motor-unsaturated|"
                           "rolling-off|spinning-off]\n");
      return 64;
    }
  }
  if (negative == "hinge-limit-off") {
    hingeLimit(false);
  } else if (negative == "motor-unsaturated") {
    hingeMotor(false);
  } else if (negative == "rolling-off") {
    rollingFriction(false);
  } else if (negative == "spinning-off") {
    spinningFriction(false);
  } else if (!negative.empty()) {
    std::fprintf(stderr, "unknown negative control %s\n", negative.c_str());
    return 64;
  } else {
    const std::vector<std::pair<std::string, std::function<void()>>> scenes = {
        {"point2point", pointToPoint},
        {"hinge", hinge},
        {"slider", slider},
        {"generic6dof", generic6Dof},
        {"generic6dof-spring", generic6DofSpring},
        {"generic6dof-spring2", generic6DofSpring2},
        {"cone-twist", coneTwist},
        {"fixed", fixed},
        {"gear", gear},
        {"hinge2", hinge2},
        {"universal", universal},
        {"hinge-limit", [] { hingeLimit(true); }},
        {"hinge-motor", [] { hingeMotor(true); }},
        {"global-cfm-joint", globalCfmJoint},
        {"breaking", breaking},
        {"rolling-friction", [] { rollingFriction(true); }},
        {"spinning-friction", [] { spinningFriction(true); }},
    };
    bool ran = false;
    for (double damping : {1.0, 0.5}) {
      gDamping = damping, gSceneChecks = damping == 1;
      for (bool reference : {true, false}) {
        gReferencePass = reference;
        for (const auto &[name, scene] : scenes)
          if (only.empty() || only == name) scene(), ran = true;
      }
      gReference.clear();
    }
    gDamping = 1, gSceneChecks = true;
    if (only.empty() || only == "refusals") refusals(), ran = true;
    if (!ran) {
      std::fprintf(stderr, "unknown scene %s\n", only.c_str());
      return 64;
    }
  }
  for (const std::string &f : failures) std::printf("CHECK FAILED: %s\n", f.c_str());
  if (!failures.empty()) return 1;
  std::printf("CHECK PASSED\n");
  return 0;
}
