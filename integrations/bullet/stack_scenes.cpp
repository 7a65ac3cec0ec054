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

}  // namespace

bool buildScene(const std::string &name, StackWorld &w, int count, unsigned seed) {
  std::mt19937 rng(seed);
  if (name == "big-pyramid") {
    const int base = count > 0 ? count : 15;
    for (int row = 0; row < base; ++row)
      for (int k = 0; k < base - row; ++k)
        w.addBox(kCube, 1, btVector3(1.05 * (k - (base - 1 - row) / 2.0), 0.5 + row, 0));
  } else if (name == "wall") {
    buildWall(w, count > 0 ? count : 100, rng);
  } else if (name == "bin") {
    buildBin(w, count > 0 ? count : 512, rng);
  } else if (name == "chain") {
    buildChain(w, count > 0 ? count : 20);
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

}  // namespace cadmm_bullet
