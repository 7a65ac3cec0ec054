#include "stack_scenes.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace cadmm_bullet {

namespace {
// Bullet multiplies the two bodies' frictions: sqrt(0.5) each gives mu = 0.5 at every contact.
const double kFriction = std::sqrt(0.5);
const btVector3 kCube(0.5, 0.5, 0.5);  // 1 m boxes
}  // namespace

StackWorld::StackWorld(std::unique_ptr<btConstraintSolver> solver) : solver_(std::move(solver)) {
  world_ = std::make_unique<btDiscreteDynamicsWorld>(&dispatcher_, &broadphase_, solver_.get(),
                                                     &config_);
  world_->setGravity(btVector3(0, -9.81, 0));
  addBox(btVector3(20, 0.5, 20), 0, btVector3(0, -0.5, 0));  // ground, top face at y = 0
}

StackWorld::~StackWorld() {
  for (auto &j : joints_) world_->removeConstraint(j.get());
  for (auto &b : bodies_) world_->removeRigidBody(b.get());
}

btRigidBody *StackWorld::addBody(std::unique_ptr<btCollisionShape> shape, double mass,
                                 const btTransform &at) {
  btVector3 inertia(0, 0, 0);
  if (mass > 0) shape->calculateLocalInertia(mass, inertia);
  shapes_.push_back(std::move(shape));
  states_.push_back(std::make_unique<btDefaultMotionState>(at));
  btRigidBody::btRigidBodyConstructionInfo ci(mass, states_.back().get(), shapes_.back().get(), inertia);
  ci.m_friction = kFriction;
  bodies_.push_back(std::make_unique<btRigidBody>(ci));
  btRigidBody *b = bodies_.back().get();
  b->setActivationState(DISABLE_DEACTIVATION);  // every step is solved, none skipped by sleeping
  world_->addRigidBody(b);
  return b;
}

btRigidBody *StackWorld::addBox(const btVector3 &he, double mass, const btVector3 &p,
                                const btQuaternion &q) {
  btRigidBody *b = addBody(std::make_unique<btBoxShape>(he), mass, btTransform(q, p));
  if (mass > 0) boxes.push_back(b), rest.push_back(p);
  return b;
}

btRigidBody *StackWorld::addSphere(double rad, double mass, const btVector3 &p) {
  return addBody(std::make_unique<btSphereShape>(rad), mass,
                 btTransform(btQuaternion::getIdentity(), p));
}

btRigidBody *StackWorld::addCapsule(double rad, double height, double mass, const btTransform &at) {
  btRigidBody *b = addBody(std::make_unique<btCapsuleShape>(rad, height), mass, at);
  boxes.push_back(b), rest.push_back(at.getOrigin());
  return b;
}

void StackWorld::addJoint(std::unique_ptr<btTypedConstraint> j) {
  joints_.push_back(std::move(j));
  world_->addConstraint(joints_.back().get(), true);
}

StackWorld::Penetration StackWorld::penetration(double erp) const {
  Penetration p;
  for (int i = 0; i < dispatcher_.getNumManifolds(); ++i) {
    const btPersistentManifold *m = dispatcher_.getManifoldByIndexInternal(i);
    const btTransform &a = m->getBody0()->getWorldTransform();
    const btTransform &b = m->getBody1()->getWorldTransform();
    for (int j = 0; j < m->getNumContacts(); ++j) {
      const btManifoldPoint &cp = m->getContactPoint(j);
      // As btPersistentManifold::refreshContactPoints measures it, without changing the point.
      const double before = -cp.getDistance(),
                   after = -(a(cp.m_localPointA) - b(cp.m_localPointB)).dot(cp.m_normalWorldOnB);
      p.depth = std::max(p.depth, before);
      p.excess = std::max(p.excess, after - (1 - erp) * std::max(before, 0.0));
    }
  }
  return p;
}

namespace {

// Running bond: rows of 10 bricks, every other row shifted by half a brick; the bricks of a
// row touch side to side (no gap), as a real wall's do.
void buildWall(StackWorld &w, int count, std::mt19937 &rng) {
  const btVector3 brick(0.2, 0.1, 0.1);
  for (int i = 0; i < count; ++i) {
    const int row = i / 10, k = i % 10;
    w.addBox(brick, 2, btVector3(0.4 * (k - 4.5) + (row % 2 ? 0.2 : 0), 0.1 + 0.2 * row, 0));
  }
  std::uniform_real_distribution<double> aim(-0.3, 0.3);
  const double top = 0.2 * ((count + 9) / 10);
  w.ball = {1.0, 0.25, 20, btVector3(aim(rng), 0.6 * top + 0.3, -3), btVector3(0, 1.5, 8)};
  w.inMotion = true;
}

// Layers of 8 x 8 boxes above a 3 x 3 m bin (static floor and walls 1 m high).
void buildBin(StackWorld &w, int count, std::mt19937 &rng) {
  for (int side = 0; side < 4; ++side) {
    const double s = side % 2 ? 1.6 : -1.6;
    const bool alongX = side < 2;
    w.addBox(alongX ? btVector3(1.7, 0.5, 0.1) : btVector3(0.1, 0.5, 1.7), 0,
             alongX ? btVector3(0, 0.5, s) : btVector3(s, 0.5, 0));
  }
  std::uniform_real_distribution<double> half(0.12, 0.18), mass(1, 5), tilt(-0.3, 0.3),
      shift(-0.01, 0.01);
  for (int i = 0; i < count; ++i) {
    const int layer = i / 64, x = i % 8, z = (i / 8) % 8;
    const btVector3 he(half(rng), half(rng), half(rng));
    const double m = mass(rng);
    const btQuaternion q(tilt(rng), tilt(rng), tilt(rng));  // yaw, pitch, roll
    w.addBox(he, m, btVector3(0.36 * (x - 3.5) + shift(rng), 0.3 + 0.4 * layer, 0.36 * (z - 3.5) + shift(rng)), q);
  }
  w.inMotion = true;
}

// Links of 30 cm, 10 cm apart, joined at the middle of the gaps; the first hangs from a fixed
// point 9 m up. Released horizontal, the chain swings down into a 1.5 m box standing below.
void buildChain(StackWorld &w, int count) {
  const btVector3 pivot(0, 9, 0), link(0.15, 0.15, 0.15);
  btRigidBody *prev = nullptr;
  for (int k = 0; k < count; ++k) {
    btRigidBody *b = w.addBox(link, 1, pivot + btVector3(0.2 + 0.4 * k, 0, 0));
    if (prev)
      w.addJoint(std::make_unique<btPoint2PointConstraint>(*prev, *b, btVector3(0.2, 0, 0),
                                                           btVector3(-0.2, 0, 0)));
    else
      w.addJoint(std::make_unique<btPoint2PointConstraint>(*b, btVector3(-0.2, 0, 0)));
    prev = b;
  }
  w.addBox(btVector3(0.5, 0.75, 0.5), 5, btVector3(0.6, 0.75, 0));
  w.inMotion = true;
}

// A 7-joint arm held out along x, 3 m up (held, it touches nothing), the payload welded to
// its last link: at 100 kg, 100 times the lightest link, the first joint carries 2 250 N m.
// The motors (target velocity 0) are all that holds the pose: a motor only stops its
// joint's rotation, nothing pulls it back, so whatever a solve leaves unstopped stays as sag.
void buildArm(StackWorld &w, double payloadMass) {
  const double masses[] = {2, 2, 1.5, 1.5, 1, 1, 1};  // kg, heavier near the base
  const int links = 7;
  const double length = 0.3, payloadHalf = 0.1;
  // Twice the static torque: a motor at its max impulse while holding would give way.
  const double margin = 2;
  const btVector3 base(0, 3, 0), half(length / 2, length / 2, length / 2), end(length / 2, 0, 0);
  std::vector<btRigidBody *> bodies;
  std::vector<btHingeConstraint *> hinges;
  for (int k = 0; k < links; ++k) {
    btRigidBody *b = w.addBox(half, masses[k], base + btVector3(length * (k + 0.5), 0, 0));
    // Alternating axes: the pitch joints (z) carry gravity's torque in this pose, the yaw
    // joints (y) none, but they must hold the arm's bending.
    const btVector3 axis = k % 2 ? btVector3(0, 1, 0) : btVector3(0, 0, 1);
    auto j = bodies.empty()
                 ? std::make_unique<btHingeConstraint>(*b, -end, axis)  // to the world
                 : std::make_unique<btHingeConstraint>(*bodies.back(), *b, end, -end, axis, axis);
    j->setLimit(-2 * SIMD_PI / 3, 2 * SIMD_PI / 3);
    hinges.push_back(j.get());
    w.addJoint(std::move(j));
    bodies.push_back(b);
  }
  btRigidBody *payload = w.addBox(btVector3(1, 1, 1) * payloadHalf, payloadMass,
                                  base + btVector3(length * links + payloadHalf, 0, 0));
  w.addJoint(std::make_unique<btFixedConstraint>(
      *bodies.back(), *payload, btTransform(btQuaternion::getIdentity(), end),
      btTransform(btQuaternion::getIdentity(), btVector3(-payloadHalf, 0, 0))));
  bodies.push_back(payload);
  w.tip = payload;

  // Each motor's max impulse over a step from the static torque of everything beyond its
  // joint: its magnitude, not its component along the axis, which is zero for the yaw
  // joints (a motor with nothing to give would leave its joint free).
  const btVector3 g = w.world().getGravity();
  for (int k = 0; k < links; ++k) {
    const btVector3 pivot = base + btVector3(length * k, 0, 0);
    btVector3 torque(0, 0, 0);
    for (size_t i = size_t(k); i < bodies.size(); ++i)
      torque += (bodies[i]->getCenterOfMassPosition() - pivot).cross(g / bodies[i]->getInvMass());
    hinges[size_t(k)]->enableAngularMotor(true, 0, margin * torque.length() * kTimeStep);
  }
}

// A ragdoll of 71 kg, 1.76 m, built standing (feet at y = 0, facing +z, arms down, every
// joint's frames aligned, so no joint starts open or at a cone's limit), then placed leaning
// forward at the edge of a landing 2.2 m high with 10 steps below it. It falls over the
// edge and tumbles down: contacts come and go, limits engage and release on every joint.
void buildRagdoll(StackWorld &w) {
  const int steps = 10;
  const double rise = 0.2, tread = 0.3;
  for (int k = 0; k <= steps; ++k) {  // k = 0: the landing, 1.2 m deep
    const double top = rise * (steps + 1 - k), back = k ? tread * (k - 1) : -1.2,
                 front = tread * k;
    w.addBox(btVector3(1, top / 2, (front - back) / 2), 0,
             btVector3(0, top / 2, (front + back) / 2));
  }

  // Leaning 30 degrees forward, turned 0.1 rad so that it does not fall symmetrically,
  // feet 5 cm above the landing and 30 cm behind its edge, moving forward at 1 m/s.
  const btTransform place(btQuaternion(0.1, 0.5, 0),  // yaw, pitch: +x turns the head to +z
                          btVector3(0, rise * (steps + 1) + 0.05, -0.3));
  struct Part {
    btRigidBody *body;
    btVector3 centre;  // built standing
  };
  // A capsule along y, `length` from end to end.
  auto capsule = [&](double rad, double length, double mass, const btVector3 &c) {
    const btTransform at = place * btTransform(btQuaternion::getIdentity(), c);
    return Part{w.addCapsule(rad, length - 2 * rad, mass, at), c};
  };
  const Part pelvis{w.addBox(btVector3(0.16, 0.1, 0.1), 10, place * btVector3(0, 1, 0),
                             place.getRotation()),
                    btVector3(0, 1, 0)};
  const Part spine = capsule(0.13, 0.4, 22, btVector3(0, 1.3, 0));
  const Part head = capsule(0.1, 0.26, 5, btVector3(0, 1.63, 0));
  // Twist axis (the frames' x) along the limb, y: the same frames in both bodies.
  const btQuaternion along(btVector3(0, 0, 1), SIMD_HALF_PI);
  auto cone = [&](const Part &a, const Part &b, const btVector3 &pivot, double swing,
                  double twist) {
    auto j = std::make_unique<btConeTwistConstraint>(*a.body, *b.body,
                                                     btTransform(along, pivot - a.centre),
                                                     btTransform(along, pivot - b.centre));
    j->setLimit(swing, swing, twist);
    w.addJoint(std::move(j));
  };
  // Knees and elbows turn about x; the hinge angle is minus B's turn about the axis, so a
  // knee (foot backwards, to -z) bends to negative angles, an elbow (hand forwards) to
  // positive ones. Both start straight, at a limit.
  auto hinge = [&](const Part &a, const Part &b, const btVector3 &pivot, double lo, double hi) {
    auto j = std::make_unique<btHingeConstraint>(*a.body, *b.body, pivot - a.centre,
                                                 pivot - b.centre, btVector3(1, 0, 0),
                                                 btVector3(1, 0, 0));
    j->setLimit(lo, hi);
    w.addJoint(std::move(j));
  };
  cone(pelvis, spine, btVector3(0, 1.1, 0), 0.5, 0.3);                // lower back
  cone(spine, head, btVector3(0, 1.5, 0), SIMD_PI / 4, SIMD_PI / 3);  // neck
  for (double side : {-1.0, 1.0}) {
    const Part thigh = capsule(0.07, 0.4, 9, btVector3(0.09 * side, 0.7, 0));
    const Part shin = capsule(0.05, 0.46, 4.5, btVector3(0.09 * side, 0.27, 0));  // with the foot
    const Part upperArm = capsule(0.05, 0.3, 2, btVector3(0.22 * side, 1.3, 0));
    const Part forearm = capsule(0.04, 0.3, 1.5, btVector3(0.22 * side, 1, 0));  // with the hand
    cone(pelvis, thigh, btVector3(0.09 * side, 0.9, 0), SIMD_PI / 4, SIMD_PI / 8);      // hip
    hinge(thigh, shin, btVector3(0.09 * side, 0.5, 0), -2.3, 0);                       // knee
    cone(spine, upperArm, btVector3(0.22 * side, 1.45, 0), SIMD_HALF_PI, SIMD_PI / 4);  // shoulder
    hinge(upperArm, forearm, btVector3(0.22 * side, 1.15, 0), 0, 2.3);                 // elbow
  }
  for (btRigidBody *b : w.boxes) b->setLinearVelocity(btVector3(0, 0, 1));
  w.inMotion = true;
}

}  // namespace

bool buildScene(const std::string &name, StackWorld &w, int count, unsigned seed) {
  std::mt19937 rng(seed);
  if (name == "big-pyramid") {
    const int base = count > 0 ? count : 15;
    for (int row = 0; row < base; ++row)
      for (int k = 0; k < base - row; ++k)
        w.addBox(kCube, 1, btVector3(1.05 * (k - (base - 1 - row) / 2.0), 0.5 + row, 0));
  } else if (name == "pyramids" || name == "pyramids-hit") {  // separate islands
    const int pyramids = count > 0 ? count : 3;
    for (int p = 0; p < pyramids; ++p)
      for (int row = 0; row < 12; ++row)
        for (int k = 0; k < 12 - row; ++k)
          w.addBox(kCube, 1, btVector3(1.05 * (k - (11 - row) / 2.0), 0.5 + row, 3.0 * p));
    if (name == "pyramids-hit") {  // the last pyramid hit from its far side after 0.5 s
      std::uniform_real_distribution<double> aim(-2, 2);
      const double z = 3.0 * (pyramids - 1);
      w.ball = {0.5, 0.25, 20, btVector3(aim(rng), 2.5, z + 3), btVector3(0, 1, -8)};
      w.inMotion = true;
    }
  } else if (name == "wall") {
    buildWall(w, count > 0 ? count : 100, rng);
  } else if (name == "bin") {
    buildBin(w, count > 0 ? count : 512, rng);
  } else if (name == "chain") {
    buildChain(w, count > 0 ? count : 20);
  } else if (name == "arm") {
    buildArm(w, count > 0 ? count : 100);
  } else if (name == "ragdoll") {
    buildRagdoll(w);
  } else if (name == "tower") {  // five boxes, masses 1, 100, 1, 100, 1 from the bottom
    for (int i = 0; i < 5; ++i) w.addBox(kCube, i % 2 ? 100 : 1, btVector3(0, 0.5 + i, 0));
  } else if (name == "drop") {  // the tower with 10 cm gaps: contacts appear as it settles
    for (int i = 0; i < 5; ++i) {
      w.addBox(kCube, i % 2 ? 100 : 1, btVector3(0, 0.6 + 1.1 * i, 0));
      w.rest.back() = btVector3(0, 0.5 + i, 0);
    }
  } else if (name == "mass-ratio-100" || name == "mass-ratio-1000") {
    w.addBox(kCube, 1, btVector3(0, 0.5, 0));
    w.addBox(kCube, name == "mass-ratio-100" ? 100 : 1000, btVector3(0, 1.5, 0));
  } else if (name == "pyramid") {  // rows of 4, 3, 2, 1 boxes, 5 cm apart within a row
    for (int row = 0; row < 4; ++row)
      for (int k = 0; k < 4 - row; ++k)
        w.addBox(kCube, 1, btVector3(1.05 * (k - (3 - row) / 2.0), 0.5 + row, 0));
  } else if (name == "pendulum") {  // two boxes hanging by ball joints, swinging down
    btRigidBody *a = w.addBox(kCube, 1, btVector3(1, 5, 0));
    btRigidBody *b = w.addBox(kCube, 1, btVector3(2.5, 5, 0));
    w.addJoint(std::make_unique<btPoint2PointConstraint>(*a, btVector3(-1, 0, 0)));
    w.addJoint(std::make_unique<btPoint2PointConstraint>(*a, *b, btVector3(1, 0, 0),
                                                         btVector3(-0.5, 0, 0)));
  } else if (name == "simple-pendulum") {  // a 10 cm cube 0.5 m below its joint, at 20 degrees
    StackWorld::Swing &s = w.swing;
    s.pivot = btVector3(0, 3, 0), s.length = 0.5, s.amplitude = 20 * SIMD_PI / 180, s.side = 0.1;
    const btQuaternion turn(btVector3(0, 0, 1), s.amplitude);
    const btVector3 centre = s.pivot + quatRotate(turn, btVector3(0, -s.length, 0));
    btRigidBody *bob = w.addBox(btVector3(1, 1, 1) * (s.side / 2), 1, centre, turn);
    w.addJoint(std::make_unique<btPoint2PointConstraint>(*bob, btVector3(0, s.length, 0)));
  } else {
    return false;
  }
  return true;
}

void addHinge(StackWorld &w) {
  btRigidBody &a = *w.boxes.at(0), &b = *w.boxes.at(1);
  w.addJoint(std::make_unique<btHingeConstraint>(a, b, btVector3(0, 0.5, 0), btVector3(0, -0.5, 0),
                                                 btVector3(1, 0, 0), btVector3(1, 0, 0)));
}

double jointGap(const btTypedConstraint &c) {
  btVector3 a, b;  // the pivot in A's and in B's frame
  if (auto *j = dynamic_cast<const btPoint2PointConstraint *>(&c))
    a = j->getPivotInA(), b = j->getPivotInB();
  else if (auto *j = dynamic_cast<const btHingeConstraint *>(&c))
    a = j->getAFrame().getOrigin(), b = j->getBFrame().getOrigin();
  else if (auto *j = dynamic_cast<const btConeTwistConstraint *>(&c))
    a = j->getAFrame().getOrigin(), b = j->getBFrame().getOrigin();
  else if (auto *j = dynamic_cast<const btGeneric6DofSpring2Constraint *>(&c))  // btFixedConstraint
    a = j->getFrameOffsetA().getOrigin(), b = j->getFrameOffsetB().getOrigin();
  else if (auto *j = dynamic_cast<const btGeneric6DofConstraint *>(&c))
    a = j->getFrameOffsetA().getOrigin(), b = j->getFrameOffsetB().getOrigin();
  else
    return 0;
  return (c.getRigidBodyA().getWorldTransform() * a - c.getRigidBodyB().getWorldTransform() * b)
      .length();
}

}  // namespace cadmm_bullet
