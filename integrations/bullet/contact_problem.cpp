#include "contact_problem.h"

#include <algorithm>
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
    default: return "btTypedConstraint of an unknown type";
  }
}

// A constraint as a message names it: its class (btHinge2Constraint and
// btUniversalConstraint share their base's type number) and its bodies.
std::string describe(const btTypedConstraint &c) {
  std::string type = typeName(c.getConstraintType());
  if (dynamic_cast<const btHinge2Constraint *>(&c)) type = "btHinge2Constraint";
  if (dynamic_cast<const btUniversalConstraint *>(&c)) type = "btUniversalConstraint";
  return type + " (user id " + std::to_string(c.getUserConstraintId()) + ") between " +
         name(&c.getRigidBodyA()) + " and " + name(&c.getRigidBodyB());
}

// The constraints a user can switch to Bullet's pre-getInfo2 solver (a public
// m_useSolveConstraintObsolete; the hinge's and cone twist's are private, fixed at false when
// Bullet is built): they then hand out no rows and expect solveConstraintObsolete between
// iterations, which has no place here.
bool usesObsoleteSolver(const btTypedConstraint &c) {
  if (auto *j = dynamic_cast<const btPoint2PointConstraint *>(&c))
    return j->m_useSolveConstraintObsolete;
  if (auto *j = dynamic_cast<const btGeneric6DofConstraint *>(&c))
    return j->m_useSolveConstraintObsolete;
  return false;
}

// Bullet's "no limit" is SIMD_INFINITY, which is DBL_MAX in double precision; cadmm's is
// INFINITY.
double bound(double x) { return x >= 1e30 ? INFINITY : x <= -1e30 ? -INFINITY : x; }

bool finite(const btVector3 &v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
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
  h_ = info.m_timeStep;
  bodies_.clear(), index_.clear(), points_.clear(), rows_.clear(), joints_.clear();
  allJoints_.clear();
  f.clear(), vfree_.clear(), w.clear(), mu.clear(), b.clear();
  lo.clear(), hi.clear(), compliance.clear(), frictionContact.clear(), friction.clear();
  torsion_.clear();

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

  // Constraints: every enabled one is mapped through its rows, or the whole group is
  // refused. buildJacobian on all of them, as btSequentialImpulseConstraintSolver::
  // convertJoints does before it asks the enabled ones for their rows.
  for (int k = 0; k < numConstraints; ++k) {
    btTypedConstraint *c = constraints[k];
    c->buildJacobian();
    allJoints_.push_back(c);
    if (c->isEnabled()) addConstraint(*c, info);
  }
  addTorsionRows();
}

void ContactProblem::addBody(btRigidBody *rb, const btContactSolverInfo &info) {
  const btVector3 one(1, 1, 1), inv = rb->getInvInertiaDiagLocal();
  if (rb->getLinearFactor() != one || rb->getAngularFactor() != one)
    throw Error("cadmm_bullet: " + name(rb) +
                " has a linear or angular factor other than (1, 1, 1): not supported (cadmm's M "
                "moves every body in all 6 directions)");
  if (!(rb->getInvMass() > 0) || !(inv.x() > 0) || !(inv.y() > 0) || !(inv.z() > 0))
    throw Error("cadmm_bullet: dynamic " + name(rb) +
                " has an infinite mass or inertia component: not supported (cadmm's M must be "
                "positive definite)");
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
  const double signs[2] = {1, -1};
  const int first[2] = {index(A), index(B)};
  // The body with the lower velocity index first, so that each column's row indices come
  // sorted and cadmm takes the arrays as they are (no sort, no permutation kept for the
  // updates' values).
  const bool swap = first[1] >= 0 && first[1] < first[0];
  for (int t = 0; t < 2; ++t) {
    const int s = swap ? 1 - t : t;
    const double sign = signs[s];
    const int i0 = first[s];
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
  if (cp.m_contactPointFlags &
      (BT_CONTACT_FLAG_HAS_CONTACT_CFM | BT_CONTACT_FLAG_CONTACT_STIFFNESS_DAMPING))
    throw Error("cadmm_bullet: soft contact (CFM, stiffness/damping) between " + name(A) +
                " and " + name(B) + " is not supported: cadmm's contacts are rigid");
  // Bullet's setupContactConstraint gives every contact the global CFM: a soft contact.
  // (Joint rows take it, as compliance: addConstraint.)
  if (info.m_globalCfm != 0)
    throw Error("cadmm_bullet: m_globalCfm = " + std::to_string(info.m_globalCfm) +
                " makes the contact between " + name(A) + " and " + name(B) +
                " soft, which cadmm's rigid contacts cannot be (a group without contact "
                "points takes it)");
  const int anisotropic =
      btCollisionObject::CF_ANISOTROPIC_FRICTION | btCollisionObject::CF_ANISOTROPIC_ROLLING_FRICTION;
  if (A->hasAnisotropicFriction(anisotropic) || B->hasAnisotropicFriction(anisotropic))
    throw Error("cadmm_bullet: anisotropic friction on " + name(A) + " or " + name(B) +
                " is not supported: cadmm's friction cones and rolling rows are isotropic");

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

  // Rolling friction, as btSequentialImpulseConstraintSolver::convertContact: with a
  // rolling coefficient, the spinning row about n and the rolling rows about btPlaneSpace1(n)
  // (a zero coefficient's row holds nothing and is left out).
  if (cp.m_combinedRollingFriction > 0) {
    const int64_t contact = int64_t(mu.size());
    if (cp.m_combinedSpinningFriction > 0)
      torsion_.push_back({A, B, pt.n, cp.m_combinedSpinningFriction, contact});
    for (const btVector3 &axis : {pt.t1, pt.t2})
      torsion_.push_back({A, B, axis.normalized(), cp.m_combinedRollingFriction, contact});
  }
  w.push_back(wN), w.push_back(wT1), w.push_back(wT2);
  mu.push_back(cp.m_combinedFriction);
  points_.push_back(pt);
}

void ContactProblem::addTorsionRows() {
  for (const Torsion &t : torsion_) {
    // Bullet's row: the relative angular velocity (w_B - w_A) . axis, target 0, no CFM; a
    // fixed body's angular velocity moves to b.
    double fixedPart = 0;
    const btCollisionObject *side[2] = {t.A, t.B};
    for (int s = 0; s < 2; ++s) {
      const double sign = s == 0 ? -1 : 1;
      const int i0 = index(side[s]);
      if (i0 < 0) {
        const btRigidBody *rb = btRigidBody::upcast(side[s]);
        if (rb) fixedPart += sign * t.axis.dot(rb->getAngularVelocity());
        continue;
      }
      for (int k = 0; k < 3; ++k) G.push(i0 + k, 0.0);  // the pattern of a joint row's block
      for (int k = 0; k < 3; ++k) G.push(i0 + 3 + k, sign * t.axis[k]);
    }
    G.endColumn();
    b.push_back(fixedPart);
    // Bullet bounds the row by min(e r_n, e): the contact's bound, capped by e itself.
    lo.push_back(-t.coefficient), hi.push_back(t.coefficient), compliance.push_back(0);
    frictionContact.push_back(t.contact), friction.push_back(t.coefficient);
  }
}

void ContactProblem::addConstraint(btTypedConstraint &c, const btContactSolverInfo &info) {
  if (usesObsoleteSolver(c))
    throw Error("cadmm_bullet: " + describe(c) +
                " uses Bullet's obsolete solver (m_useSolveConstraintObsolete): it has no rows "
                "to map");
  btTypedConstraint::btConstraintInfo1 info1{0, 0};
  c.getInfo1(&info1);
  const int n = info1.m_numConstraintRows;
  joints_.push_back({&c, rows_.size(), size_t(std::max(n, 0))});
  if (n <= 0) return;

  // The rows as convertJoint hands them to getInfo2: zeroed, unbounded, and the global
  // CFM in the first row only (the others keep the zero of Bullet's memset; the 6-DOF
  // constraints read info2.cfm[0] as the global CFM).
  info_.assign(size_t(n), InfoRow{});
  for (InfoRow &r : info_) {
    r.j1lin.setZero(), r.j1ang.setZero(), r.j2lin.setZero(), r.j2ang.setZero();
    r.error = 0, r.cfm = 0, r.lo = -SIMD_INFINITY, r.hi = SIMD_INFINITY;
  }
  info_[0].cfm = info.m_globalCfm;
  static_assert(sizeof(InfoRow) % sizeof(btScalar) == 0, "rowskip counts whole scalars");
  btTypedConstraint::btConstraintInfo2 info2;
  info2.fps = 1 / info.m_timeStep;
  info2.erp = info.m_erp;
  info2.m_J1linearAxis = info_[0].j1lin.m_floats;
  info2.m_J1angularAxis = info_[0].j1ang.m_floats;
  info2.m_J2linearAxis = info_[0].j2lin.m_floats;
  info2.m_J2angularAxis = info_[0].j2ang.m_floats;
  info2.rowskip = int(sizeof(InfoRow) / sizeof(btScalar));
  info2.m_constraintError = &info_[0].error;
  info2.cfm = &info_[0].cfm;
  info2.m_lowerLimit = &info_[0].lo;
  info2.m_upperLimit = &info_[0].hi;
  info2.m_numIterations = info.m_numIterations;
  info2.m_damping = info.m_damping;
  c.getInfo2(&info2);

  const btRigidBody &A = c.getRigidBodyA(), &B = c.getRigidBodyB();
  const int iA = index(&A), iB = index(&B);
  // The velocities before the solve as convertJoint reads them: a dynamic body's with the
  // external impulse of the step (and the gyroscopic term: the free velocities of f), a
  // fixed body's as it is (static or kinematic, no external impulse).
  auto before = [&](const btRigidBody &rb, int i0, btVector3 &lin, btVector3 &ang) {
    if (i0 < 0) {
      lin = rb.getLinearVelocity(), ang = rb.getAngularVelocity();
      return;
    }
    lin.setValue(vfree_[i0], vfree_[i0 + 1], vfree_[i0 + 2]);
    ang.setValue(vfree_[i0 + 3], vfree_[i0 + 4], vfree_[i0 + 5]);
  };
  btVector3 vA, wA, vB, wB;
  before(A, iA, vA, wA);
  before(B, iB, vB, wB);
  // The damping as getInfo2 left it: btPoint2PointConstraint sets its own (m_setting).
  const double threshold = c.getBreakingImpulseThreshold(), damping = info2.m_damping;

  for (int k = 0; k < n; ++k) {
    const InfoRow &r = info_[size_t(k)];
    auto row = [&] { return "row " + std::to_string(k) + " of " + describe(c); };
    if (!finite(r.j1lin) || !finite(r.j1ang) || !finite(r.j2lin) || !finite(r.j2ang) ||
        !std::isfinite(r.cfm) || std::isnan(r.error) || std::isnan(r.lo) || std::isnan(r.hi))
      throw Error("cadmm_bullet: " + row() + " has a non-finite Jacobian or CFM, or a NaN");
    if (r.cfm < 0)
      throw Error("cadmm_bullet: " + row() + " has a negative CFM " + std::to_string(r.cfm) +
                  ": a negative compliance is not a constraint cadmm solves");

    // Bullet's impulse bounds, clamped by the breaking threshold as convertJoint does.
    double l = bound(std::max<double>(r.lo, -threshold));
    double u = bound(std::min<double>(r.hi, threshold));
    // D = J M^-1 J^T, as convertJoint sums it (Bullet's 1 / m_jacDiagABInv).
    const double D = A.getInvMass() * r.j1lin.length2() +
                     r.j1ang.dot(A.getInvInertiaTensorWorld() * r.j1ang) +
                     B.getInvMass() * r.j2lin.length2() +
                     r.j2ang.dot(B.getInvInertiaTensorWorld() * r.j2ang);
    if (!(std::fabs(D) > SIMD_EPSILON) || (iA < 0 && iB < 0)) {
      // convertJoint's m_jacDiagABInv = 0: Bullet's row never moves from a zero impulse
      // (and a row between fixed bodies moves nothing here).
      rows_.push_back({-1, r.j1lin, r.j1ang, r.j2lin, r.j2ang});
      continue;
    }
    double error = r.error;
    if (std::isinf(bound(error))) {
      // An infinite target velocity (btGeneric6DofSpring2Constraint's
      // BT_6DOF_FLAGS_USE_INFINITE_ERROR): Bullet's row ends at the bound it pushes towards.
      const double at = error > 0 ? u : l;
      if (std::isinf(at))
        throw Error("cadmm_bullet: " + row() +
                    " asks for an infinite velocity with no bound on its impulse");
      l = u = at, error = 0;
    }
    if (!(l <= u) || l == INFINITY || u == -INFINITY)
      throw Error("cadmm_bullet: " + row() + " has impulse bounds [" + std::to_string(l) + ", " +
                  std::to_string(u) + "] that hold no impulse");

    // Bullet's row converges to J v + cfm D lambda = error + (1 - damping) J v_before, J v
    // summed over both bodies; a fixed body's part of J v is known and moves to b.
    const double jvBefore = r.j1lin.dot(vA) + r.j1ang.dot(wA) + r.j2lin.dot(vB) + r.j2ang.dot(wB);
    double fixedPart = 0;
    if (iA < 0)
      fixedPart += r.j1lin.dot(A.getLinearVelocity()) + r.j1ang.dot(A.getAngularVelocity());
    if (iB < 0)
      fixedPart += r.j2lin.dot(B.getLinearVelocity()) + r.j2ang.dot(B.getAngularVelocity());

    // Column: 6 entries per dynamic body, zeros included, so that the pattern stays while
    // the axes turn; the two blocks add up when A and B are the same body.
    const int column = int(G.ncols);
    if (iA >= 0 && iA == iB) {
      for (int i = 0; i < 3; ++i) G.push(iA + i, r.j1lin[i] + r.j2lin[i]);
      for (int i = 0; i < 3; ++i) G.push(iA + 3 + i, r.j1ang[i] + r.j2ang[i]);
    } else {
      if (iA >= 0) {
        for (int i = 0; i < 3; ++i) G.push(iA + i, r.j1lin[i]);
        for (int i = 0; i < 3; ++i) G.push(iA + 3 + i, r.j1ang[i]);
      }
      if (iB >= 0) {
        for (int i = 0; i < 3; ++i) G.push(iB + i, r.j2lin[i]);
        for (int i = 0; i < 3; ++i) G.push(iB + 3 + i, r.j2ang[i]);
      }
    }
    G.endColumn();
    b.push_back(fixedPart - error - (1 - damping) * jvBefore);
    lo.push_back(l), hi.push_back(u), compliance.push_back(r.cfm * D);
    frictionContact.push_back(-1), friction.push_back(0);
    rows_.push_back({column, r.j1lin, r.j1ang, r.j2lin, r.j2ang});
  }
}

int ContactProblem::jointRow(const btTypedConstraint *c, int k) const {
  for (const Joint &j : joints_)
    if (j.c == c) return k >= 0 && size_t(k) < j.count ? rows_[j.first + size_t(k)].column : -1;
  return -1;
}

std::vector<bool> ContactProblem::boundedRows() const {
  std::vector<bool> out(lo.size());
  for (size_t k = 0; k < lo.size(); ++k) out[k] = std::isfinite(lo[k]) || std::isfinite(hi[k]);
  return out;
}

bool ContactProblem::hasContactBounds() const {
  for (int64_t c : frictionContact)
    if (c >= 0) return true;
  return false;
}

bool ContactProblem::beyondEqualities() const {
  for (size_t k = 0; k < lo.size(); ++k)
    if (std::isfinite(lo[k]) || std::isfinite(hi[k]) || compliance[k] != 0) return true;
  return false;
}

cadmm_problem *ContactProblem::make() const {
  const cadmm_csc m = M.view(), h = H.view(), g = G.view();
  cadmm_problem *p = nullptr;
  if (cadmm_problem_new_global(velocities(), contacts(), &m, &h, f.data(), w.data(), mu.data(),
                               &p) != CADMM_OK)
    throw Error(std::string("cadmm_bullet: cadmm_problem_new_global: ") + cadmm_last_error());
  // Bounds and compliance only when a row has them: a problem of equalities stays as it
  // was before they existed (and can be written as an FCLib file).
  const char *failed = nullptr;
  const bool beyond = beyondEqualities();
  if (jointRows() && cadmm_problem_set_joints(p, &g, b.data()) != CADMM_OK)
    failed = "cadmm_problem_set_joints";
  else if (beyond && cadmm_problem_set_joint_bounds(p, lo.data(), hi.data()) != CADMM_OK)
    failed = "cadmm_problem_set_joint_bounds";
  else if (beyond && cadmm_problem_set_joint_compliance(p, compliance.data()) != CADMM_OK)
    failed = "cadmm_problem_set_joint_compliance";
  else if (hasContactBounds() &&
           cadmm_problem_set_joint_friction(p, frictionContact.data(), friction.data()) != CADMM_OK)
    failed = "cadmm_problem_set_joint_friction";
  if (failed) {
    const std::string msg = cadmm_last_error();
    cadmm_problem_free(p);
    throw Error(std::string("cadmm_bullet: ") + failed + ": " + msg);
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
  // As btSequentialImpulseConstraintSolver: every constraint of the group starts from no
  // impulse and no feedback (convertJoints), then each row of an enabled one adds its
  // impulse (writeBackJoints): the feedback sums J^T lambda / h per body, the applied
  // impulse is the last row's, and a row at the breaking threshold disables the constraint.
  for (btTypedConstraint *c : allJoints_) {
    c->internalSetAppliedImpulse(0);
    if (btJointFeedback *fb = c->getJointFeedback()) {
      fb->m_appliedForceBodyA.setZero(), fb->m_appliedTorqueBodyA.setZero();
      fb->m_appliedForceBodyB.setZero(), fb->m_appliedTorqueBodyB.setZero();
    }
  }
  for (const Joint &j : joints_) {
    btTypedConstraint *c = j.c;
    btJointFeedback *fb = c->getJointFeedback();
    const btRigidBody &A = c->getRigidBodyA(), &B = c->getRigidBodyB();
    for (size_t k = j.first; k < j.first + j.count; ++k) {
      const JointRow &row = rows_[k];
      const double impulse = row.column >= 0 ? lambda[row.column] : 0;
      if (fb) {  // with the bodies' factors, as Bullet (other than 1 on fixed bodies only)
        fb->m_appliedForceBodyA += row.j1lin * A.getLinearFactor() * (impulse / h_);
        fb->m_appliedTorqueBodyA += row.j1ang * A.getAngularFactor() * (impulse / h_);
        fb->m_appliedForceBodyB += row.j2lin * B.getLinearFactor() * (impulse / h_);
        fb->m_appliedTorqueBodyB += row.j2ang * B.getAngularFactor() * (impulse / h_);
      }
      c->internalSetAppliedImpulse(impulse);
      if (std::fabs(impulse) >= c->getBreakingImpulseThreshold()) c->setEnabled(false);
    }
  }
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const double *x = v + 6 * i;
    bodies_[i]->setLinearVelocity(btVector3(x[0], x[1], x[2]));
    bodies_[i]->setAngularVelocity(btVector3(x[3], x[4], x[5]));
  }
}

}  // namespace cadmm_bullet
