// The benchmark scenes: boxes stacked on a static ground box, y up, 60 Hz, mu 0.5.
#pragma once

#include <btBulletDynamicsCommon.h>

#include <memory>
#include <string>
#include <vector>

namespace cadmm_bullet {

// The step the scenes are made for (the driver's; the arm's motors are sized with it).
constexpr double kTimeStep = 1.0 / 60;

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
  // A sphere of radius rad and the given mass centred at p (dynamic, not one of `boxes`).
  btRigidBody *addSphere(double rad, double mass, const btVector3 &p);
  // A dynamic capsule along its local y axis (radius rad, cylinder `height` between the
  // caps) placed at `at`; one of `boxes`, as the ragdoll's parts are its bodies.
  btRigidBody *addCapsule(double rad, double height, double mass, const btTransform &at);
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

  std::vector<btRigidBody *> boxes;  // the dynamic boxes (and capsules), bottom first
  std::vector<btVector3> rest;       // where each box should come to rest

  // Scene "simple-pendulum": a cube of side `side` hanging by a ball joint at `pivot`, its
  // centre `length` below it, released at rest `amplitude` radians from the vertical,
  // swinging in the x-y plane. length == 0 for the other scenes.
  struct Swing {
    btVector3 pivot{0, 0, 0};
    double length = 0, amplitude = 0, side = 0;
  } swing;

  // Scenes in motion ("wall", "bin", "chain", "ragdoll"): bodies fall, topple and collide,
  // so the at-rest checks (fell, drift) do not apply.
  bool inMotion = false;
  // Scene "arm": the payload at its tip, which the motors hold where it started (the
  // driver reports its drift; the stacks' checks do not apply).
  btRigidBody *tip = nullptr;
  // Scene "wall": a ball of this radius and mass thrown from `from` at `velocity` (m/s) once
  // the run reaches `time` seconds (radius 0: no ball).
  struct Throw {
    double time = 0, radius = 0, mass = 0;
    btVector3 from{0, 0, 0}, velocity{0, 0, 0};
  } ball;

 private:
  // A body of this shape and mass (0: static) placed at `at`, owned by the world.
  btRigidBody *addBody(std::unique_ptr<btCollisionShape> shape, double mass, const btTransform &at);

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
// "mass-ratio-1000", "pyramid", "pendulum" (two boxes on btPoint2PointConstraint joints),
// "simple-pendulum" (one small box on one, see StackWorld::Swing), or one of the larger scenes
// sized by `count` (0: its default) and varied by `seed`:
//  - "big-pyramid": rows of count (15), count - 1, ..., 1 boxes (120), 5 cm apart in a row;
//  - "pyramids": count (3) pyramids of 12 rows (78 boxes each, as "big-pyramid"), 3 m apart:
//    islands large enough that Bullet hands each to its own solveGroup call;
//  - "pyramids-hit": the same, the last one hit after 0.5 s by a 20 kg ball at 8 m/s from
//    its far side (aim along x drawn from seed): one island in motion beside resting ones;
//  - "wall": count (100) bricks of 40 x 20 x 20 cm in running bond, rows of 10, touching,
//    hit by a 20 kg ball at 8 m/s after 1 s (StackWorld::Throw), its aim varied by seed;
//  - "bin": count (512) boxes of 1 to 5 kg and 24 to 36 cm, dropped in layers into a 3 x 3 m
//    bin, sizes, masses and tilts drawn from seed;
//  - "chain": count (20) boxes of 30 cm on btPoint2PointConstraint joints, hanging from a
//    fixed point, released horizontal, swinging into a standing box;
//  - "arm": a serial arm of 7 links (30 cm boxes, 2 to 1 kg from the base out) on
//    btHingeConstraint joints about z, y, z, ... (limits +-120 degrees, motors at target
//    velocity 0 with twice the static torque as max impulse), its first joint fixed to the
//    world 3 m up, held horizontal along x with a box of count kg (100) welded to its tip
//    (btFixedConstraint): StackWorld::tip;
//  - "ragdoll": a 71 kg ragdoll of 11 parts (a box pelvis, capsules for the rest) on
//    btConeTwistConstraint (lower back, neck, hips, shoulders) and btHingeConstraint (knees,
//    elbows) joints with limits, dropped leaning forward at the top of 10 static steps (20 cm
//    high, 30 cm deep), down which it tumbles.
// False for an unknown name.
bool buildScene(const std::string &name, StackWorld &w, int count = 0, unsigned seed = 1);
// Adds a hinge between the two lowest boxes (about x, at their shared face).
void addHinge(StackWorld &w);
// How far apart the joint's pivot is as each of its two bodies carries it (m): its position
// error. For the joints with one pivot (point to point, hinge, cone twist, the 6-DOF family
// and btFixedConstraint); 0 for the others.
double jointGap(const btTypedConstraint &c);

}  // namespace cadmm_bullet
