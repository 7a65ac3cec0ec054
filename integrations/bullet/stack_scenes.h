// The benchmark scenes: boxes stacked on a static ground box, y up, 60 Hz, mu 0.5.
#pragma once

#include <btBulletDynamicsCommon.h>

#include <memory>
#include <string>
#include <vector>

namespace cadmm_bullet {

// A Bullet world that owns its parts, with the given constraint solver.
class StackWorld {
 public:
  explicit StackWorld(std::unique_ptr<btConstraintSolver> solver);
  ~StackWorld();
  StackWorld(const StackWorld &) = delete;
  StackWorld &operator=(const StackWorld &) = delete;

  // A box (half extents he) of the given mass (0: static) centred at p, turned by q.
  btRigidBody *addBox(const btVector3 &he, double mass, const btVector3 &p,
                      const btQuaternion &q = btQuaternion::getIdentity());
  // A joint between bodies of this world (collisions between them disabled, as usual).
  void addJoint(std::unique_ptr<btTypedConstraint> j);
  btDiscreteDynamicsWorld &world() { return *world_; }
  btConstraintSolver &solver() { return *solver_; }
  // Penetration of the contact points (m, >= 0). depth: the deepest, as collision detection
  // found it at the start of the last step. excess: how much deeper any point is at the
  // bodies' places after the step than the Baumgarte correction at rate erp leaves it,
  // (1 - erp) of its depth at the start of the step (0 for a point that was apart).
  struct Penetration {
    double depth = 0, excess = 0;
  };
  Penetration penetration(double erp) const;

  std::vector<btRigidBody *> boxes;  // the dynamic boxes, bottom first
  std::vector<btVector3> rest;       // where each box should come to rest

  // Scene "simple-pendulum": a cube of side `side` hanging by a ball joint at `pivot`, its
  // centre `length` below it, released at rest `amplitude` radians from the vertical,
  // swinging in the x-y plane. length == 0 for the other scenes.
  struct Swing {
    btVector3 pivot{0, 0, 0};
    double length = 0, amplitude = 0, side = 0;
  } swing;

 private:
  btDefaultCollisionConfiguration config_;
  btCollisionDispatcher dispatcher_{&config_};
  btDbvtBroadphase broadphase_;
  std::unique_ptr<btConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;
  std::vector<std::unique_ptr<btMotionState>> states_;
  std::vector<std::unique_ptr<btTypedConstraint>> joints_;
};

// Fills the world with scene "tower", "drop" (the tower falling into place), "mass-ratio-100",
// "mass-ratio-1000", "pyramid", "pendulum" (two boxes on btPoint2PointConstraint joints) or
// "simple-pendulum" (one small box on one, see StackWorld::Swing); false for an unknown name.
bool buildScene(const std::string &name, StackWorld &w);
// Adds a hinge between the two lowest boxes (a joint type the cadmm solver refuses).
void addHinge(StackWorld &w);

}  // namespace cadmm_bullet
