#include "contact_problem.h"

#include <cmath>

namespace cadmm_bullet {

namespace {

std::string name(const btCollisionObject *o) {
  return "body at (" + std::to_string(o->getWorldTransform().getOrigin().x()) + ", " +
         std::to_string(o->getWorldTransform().getOrigin().y()) + ", " +
         std::to_string(o->getWorldTransform().getOrigin().z()) + ")";
}

bool fixed(const btCollisionObject *o) { return o->isStaticOrKinematicObject(); }

// Velocity of a body at world point p, from its current velocity (kinematic bodies move,
// static ones do not).
btVector3 pointVelocity(const btCollisionObject *o, const btVector3 &p) {
  const btRigidBody *rb = btRigidBody::upcast(o);
  return rb ? rb->getVelocityInLocalPoint(p - o->getWorldTransform().getOrigin())
            : btVector3(0, 0, 0);
}

const char *typeName(int type) {
  switch (type) {
    case POINT2POINT_CONSTRAINT_TYPE: return "btPoint2PointConstraint";
    case HINGE_CONSTRAINT_TYPE: return "btHingeConstraint";
    case CONETWIST_CONSTRAINT_TYPE: return "btConeTwistConstraint";
    case D6_CONSTRAINT_TYPE: return "btGeneric6DofConstraint";
    case SLIDER_CONSTRAINT_TYPE: return "btSliderConstraint";
    case CONTACT_CONSTRAINT_TYPE: return "btContactConstraint";
    case D6_SPRING_CONSTRAINT_TYPE: return "btGeneric6DofSpringConstraint";
    case GEAR_CONSTRAINT_TYPE: return "btGearConstraint";
    case FIXED_CONSTRAINT_TYPE: return "btFixedConstraint";
    case D6_SPRING_2_CONSTRAINT_TYPE: return "btGeneric6DofSpring2Constraint";
    default: return "unknown btTypedConstraint type";
  }
}

}  // namespace

void Csc::clear(size_t rows) {
  nrows = rows, ncols = 0;
  colptr.assign(1, 0), rowind.clear(), values.clear();
}

int ContactProblem::index(const btCollisionObject *o) const {
  auto it = index_.find(o);
  if (it != index_.end()) return it->second;
  if (!fixed(o))
    throw Error("cadmm_bullet: dynamic " + name(o) +
                " takes part in a contact or joint of the group but is not in the group");
  return -1;
}

void ContactProblem::assemble(btCollisionObject **bodies, int numBodies,
                              btPersistentManifold **manifolds, int numManifolds,
                              btTypedConstraint **constraints, int numConstraints,
                              const btContactSolverInfo &info, const Correction &correction) {
  if (info.m_globalCfm != 0)
    throw Error("cadmm_bullet: m_globalCfm != 0 (soft constraints) is not supported");
  h_ = info.m_timeStep;
  bodies_.clear(), index_.clear(), points_.clear(), joints_.clear();
  f.clear(), vfree_.clear(), w.clear(), mu.clear(), b.clear();

  for (int i = 0; i < numBodies; ++i) {
    btRigidBody *rb = btRigidBody::upcast(bodies[i]);
    if (!rb) throw Error("cadmm_bullet: " + name(bodies[i]) + " is not a btRigidBody");
    if (!fixed(rb)) index_[rb] = int(6 * bodies_.size()), bodies_.push_back(rb);
  }
  const size_t n = 6 * bodies_.size();
  M.clear(n), H.clear(n), G.clear(n);
  for (btRigidBody *rb : bodies_) addBody(rb, info);

  for (int k = 0; k < numManifolds; ++k) {
    btPersistentManifold *m = manifolds[k];
    if (fixed(m->getBody0()) && fixed(m->getBody1())) continue;  // as Bullet: no response
    for (int j = 0; j < m->getNumContacts(); ++j) {
      btManifoldPoint &cp = m->getContactPoint(j);
      if (cp.getDistance() <= m->getContactProcessingThreshold())
        addContact(m, cp, info, correction);
    }
  }

  // Joints: every enabled one must be mapped, or the whole group is refused.
  for (int k = 0; k < numConstraints; ++k) {
    btTypedConstraint *c = constraints[k];
    if (!c->isEnabled()) continue;
    if (c->getConstraintType() != POINT2POINT_CONSTRAINT_TYPE)
      throw Error(std::string("cadmm_bullet: joint type ") + typeName(c->getConstraintType()) +
                  " is not supported (only btPoint2PointConstraint is mapped); the step was "
                  "not solved");
    addPointToPoint(*static_cast<btPoint2PointConstraint *>(c), info);
    joints_.push_back(c);
  }
}

void ContactProblem::addBody(btRigidBody *rb, const btContactSolverInfo &info) {
  const btVector3 one(1, 1, 1), inv = rb->getInvInertiaDiagLocal();
  if (rb->getLinearFactor() != one || rb->getAngularFactor() != one)
    throw Error("cadmm_bullet: " + name(rb) +
                " has a linear or angular factor other than (1, 1, 1): not supported");
  if (!(rb->getInvMass() > 0) || !(inv.x() > 0) || !(inv.y() > 0) || !(inv.z() > 0))
    throw Error("cadmm_bullet: dynamic " + name(rb) +
                " has an infinite mass or inertia component: not supported");
  const double h = info.m_timeStep, mass = 1 / rb->getInvMass();
  const btMatrix3x3 &R = rb->getWorldTransform().getBasis();
  const btMatrix3x3 I = R.scaled(btVector3(1 / inv.x(), 1 / inv.y(), 1 / inv.z())) * R.transpose();
  const btMatrix3x3 &Iinv = rb->getInvInertiaTensorWorld();

  // External forces over the step, and the gyroscopic term, as btSequentialImpulseConstraintSolver
  // applies them before its iterations (initSolverBody, convertBodies).
  btVector3 v = rb->getLinearVelocity() + rb->getTotalForce() * rb->getInvMass() * h;
  btVector3 om = rb->getAngularVelocity() + Iinv * rb->getTotalTorque() * h;
  const int flags = rb->getFlags();
  if (flags & BT_ENABLE_GYROSCOPIC_FORCE_EXPLICIT)
    om -= Iinv * rb->computeGyroscopicForceExplicit(info.m_maxGyroscopicForce) * h;
  if (flags & BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_WORLD)
    om += rb->computeGyroscopicImpulseImplicit_World(h);
  if (flags & BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY)
    om += rb->computeGyroscopicImpulseImplicit_Body(h);

  const int i0 = index_.at(rb);
  for (int k = 0; k < 3; ++k) M.push(i0 + k, mass), M.endColumn();
  for (int k = 0; k < 3; ++k) {  // symmetrized: R diag R^T rounds differently on each side
    for (int row = 0; row < 3; ++row) M.push(i0 + 3 + row, 0.5 * (I[row][k] + I[k][row]));
    M.endColumn();
  }
  const btVector3 Iom = I * om;
  for (int k = 0; k < 3; ++k) f.push_back(mass * v[k]), vfree_.push_back(v[k]);
  for (int k = 0; k < 3; ++k) f.push_back(Iom[k]), vfree_.push_back(om[k]);
}

double ContactProblem::addRow(Csc &J, const btCollisionObject *A, const btVector3 &pA,
                              const btCollisionObject *B, const btVector3 &pB,
                              const btVector3 &d) {
  double fixedPart = 0;
  const btCollisionObject *side[2] = {A, B};
  const btVector3 *point[2] = {&pA, &pB};
  for (int s = 0; s < 2; ++s) {
    const double sign = s == 0 ? 1 : -1;
    const int i0 = index(side[s]);
    if (i0 < 0) {
      fixedPart += sign * d.dot(pointVelocity(side[s], *point[s]));
      continue;
    }
    const btVector3 arm = (*point[s] - side[s]->getWorldTransform().getOrigin()).cross(d);
    for (int k = 0; k < 3; ++k) J.push(i0 + k, sign * d[k]);
    for (int k = 0; k < 3; ++k) J.push(i0 + 3 + k, sign * arm[k]);
  }
  J.endColumn();
  return fixedPart;
}

void ContactProblem::addContact(btPersistentManifold *m, btManifoldPoint &cp,
                                const btContactSolverInfo &info, const Correction &c) {
  const btCollisionObject *A = m->getBody0(), *B = m->getBody1();
  if (cp.m_combinedRollingFriction > 0 || cp.m_combinedSpinningFriction > 0)
    throw Error("cadmm_bullet: rolling or spinning friction between " + name(A) + " and " +
                name(B) + " is not supported");
  if (cp.m_contactPointFlags &
      (BT_CONTACT_FLAG_HAS_CONTACT_CFM | BT_CONTACT_FLAG_CONTACT_STIFFNESS_DAMPING))
    throw Error("cadmm_bullet: soft contact (CFM, stiffness/damping) between " + name(A) +
                " and " + name(B) + " is not supported");
  if (A->hasAnisotropicFriction() || B->hasAnisotropicFriction())
    throw Error("cadmm_bullet: anisotropic friction on " + name(A) + " or " + name(B) +
                " is not supported");

  Point pt{&cp, cp.m_normalWorldOnB, {}, {}};
  btPlaneSpace1(pt.n, pt.t1, pt.t2);
  const btVector3 pA = cp.getPositionWorldOnA(), pB = cp.getPositionWorldOnB();
  double wN = addRow(H, A, pA, B, pB, pt.n);
  const double wT1 = addRow(H, A, pA, B, pB, pt.t1);
  const double wT2 = addRow(H, A, pA, B, pB, pt.t2);

  // Normal bias, as btSequentialImpulseConstraintSolver::setupContactConstraint: a gap d > 0
  // may close within the step; a penetration is removed at rate erp per step (Baumgarte),
  // unless split impulse handles it outside the velocities.
  const double h = info.m_timeStep, d = cp.getDistance() + info.m_linearSlop;
  const double erp = (cp.m_contactPointFlags & BT_CONTACT_FLAG_HAS_CONTACT_ERP) ? cp.m_contactERP
                                                                                : c.erp;
  if (d > 0)
    wN += d / h;
  else if (!(c.splitImpulse && d > c.splitThreshold))
    wN += erp * d / h;
  // Restitution as Bullet's restitutionCurve: a bounce velocity above the threshold.
  const btVector3 vA = pointVelocity(A, pA), vB = pointVelocity(B, pB);
  const double approach = -pt.n.dot(vA - vB);
  if (cp.m_combinedRestitution > 0 && std::fabs(approach) >= info.m_restitutionVelocityThreshold &&
      approach > 0)
    wN -= cp.m_combinedRestitution * approach;

  w.push_back(wN), w.push_back(wT1), w.push_back(wT2);
  mu.push_back(cp.m_combinedFriction);
  points_.push_back(pt);
}

void ContactProblem::addPointToPoint(btPoint2PointConstraint &j, const btContactSolverInfo &info) {
  const btRigidBody &A = j.getRigidBodyA(), &B = j.getRigidBodyB();
  const btVector3 pA = A.getWorldTransform() * j.getPivotInA();
  const btVector3 pB = B.getWorldTransform() * j.getPivotInB();
  const double rate = info.m_erp / info.m_timeStep;  // Bullet's joint ERP (info2.erp)
  for (int k = 0; k < 3; ++k) {
    btVector3 e(0, 0, 0);
    e[k] = 1;
    b.push_back(addRow(G, &A, pA, &B, pB, e) + rate * (pA[k] - pB[k]));
  }
}

cadmm_problem *ContactProblem::make() const {
  const cadmm_csc m = M.view(), h = H.view(), g = G.view();
  cadmm_problem *p = nullptr;
  if (cadmm_problem_new_global(velocities(), contacts(), &m, &h, f.data(), w.data(), mu.data(),
                               &p) != CADMM_OK)
    throw Error(std::string("cadmm_bullet: cadmm_problem_new_global: ") + cadmm_last_error());
  if (jointRows() && cadmm_problem_set_joints(p, &g, b.data()) != CADMM_OK) {
    const std::string msg = cadmm_last_error();
    cadmm_problem_free(p);
    throw Error("cadmm_bullet: cadmm_problem_set_joints: " + msg);
  }
  return p;
}

std::vector<double> ContactProblem::storedImpulses(bool bulletFrames, bool twoDirections) const {
  std::vector<double> r;
  r.reserve(3 * points_.size());
  for (const Point &p : points_) {
    const btManifoldPoint &cp = *p.cp;
    r.push_back(cp.m_appliedImpulse);
    if (!bulletFrames) {  // written by writeBack in the frame btPlaneSpace1(n)
      r.push_back(cp.m_appliedImpulseLateral1), r.push_back(cp.m_appliedImpulseLateral2);
      continue;
    }
    btVector3 F = cp.m_appliedImpulseLateral1 * cp.m_lateralFrictionDir1;
    if (twoDirections) F += cp.m_appliedImpulseLateral2 * cp.m_lateralFrictionDir2;
    r.push_back(F.dot(p.t1)), r.push_back(F.dot(p.t2));
  }
  return r;
}

std::vector<double> ContactProblem::bodyVelocities() const {
  std::vector<double> v;
  v.reserve(velocities());
  for (const btRigidBody *rb : bodies_) {
    for (int k = 0; k < 3; ++k) v.push_back(rb->getLinearVelocity()[k]);
    for (int k = 0; k < 3; ++k) v.push_back(rb->getAngularVelocity()[k]);
  }
  return v;
}

void ContactProblem::writeBack(const double *r, const double *v, const double *lambda) const {
  for (size_t i = 0; i < points_.size(); ++i) {
    btManifoldPoint &cp = *points_[i].cp;
    cp.m_appliedImpulse = r[3 * i];
    cp.m_appliedImpulseLateral1 = r[3 * i + 1];
    cp.m_appliedImpulseLateral2 = r[3 * i + 2];
    cp.m_lateralFrictionDir1 = points_[i].t1;
    cp.m_lateralFrictionDir2 = points_[i].t2;
  }
  for (size_t k = 0; k < joints_.size(); ++k) {
    btTypedConstraint *c = joints_[k];
    const btVector3 impulse(lambda[3 * k], lambda[3 * k + 1], lambda[3 * k + 2]);
    c->internalSetAppliedImpulse(impulse.length());
    if (btJointFeedback *fb = c->getJointFeedback()) {
      auto *p2p = static_cast<btPoint2PointConstraint *>(c);
      const btRigidBody &A = c->getRigidBodyA(), &B = c->getRigidBodyB();
      const btVector3 force = impulse / h_;  // Bullet reports forces, impulse / step
      const btVector3 rA = A.getWorldTransform().getBasis() * p2p->getPivotInA();
      const btVector3 rB = B.getWorldTransform().getBasis() * p2p->getPivotInB();
      fb->m_appliedForceBodyA = force, fb->m_appliedTorqueBodyA = rA.cross(force);
      fb->m_appliedForceBodyB = -force, fb->m_appliedTorqueBodyB = -rB.cross(force);
    }
  }
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const double *x = v + 6 * i;
    bodies_[i]->setLinearVelocity(btVector3(x[0], x[1], x[2]));
    bodies_[i]->setAngularVelocity(btVector3(x[3], x[4], x[5]));
  }
}

}  // namespace cadmm_bullet
