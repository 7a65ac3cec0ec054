// The cadmm global problem of one Bullet solver group (bodies, persistent manifolds,
// constraints), with the maps back to Bullet's objects.
//
//   M v = H r + G lambda + f,   u = H^T v + w,   r_i in K_{mu_i},
//   per joint row k: y_k = G_k^T v + b_k + c_k lambda_k, lo_k <= lambda_k <= hi_k
//   (y_k = 0 inside the bounds, >= 0 at lo_k, <= 0 at hi_k; an equality when both are infinite)
//
// Unknowns: the 6 velocities (linear, then angular, world frame, about the centre of mass)
// of every dynamic body of the group, in the group's order. Static and kinematic bodies are
// fixed: they have no unknowns and their velocity enters w (and b). Each contact point gets
// the frame (n, t1, t2), n = the manifold's m_normalWorldOnB (from body 1 towards body 0) and
// t1, t2 = btPlaneSpace1(n), so r_N >= 0 pushes body 0 along n, body 1 along -n, and
// u_N = n . (velocity of body 0's point - velocity of body 1's point) + w_N.
//
// Joint rows are the rows each enabled btTypedConstraint hands Bullet's own solver
// (getInfo1/getInfo2, as btSequentialImpulseConstraintSolver::convertJoint reads them): G's
// column is the row's Jacobian, lambda the row's impulse, and Bullet's row equation
// J v + cfm D lambda = error + (1 - damping) J v_before becomes b and c (contact_problem.cpp,
// addConstraint). A contact point with rolling friction adds Bullet's three torsional rows
// after the constraints' (addTorsionRows): the relative angular velocity about the normal
// (spinning friction) and about the two tangents of btPlaneSpace1 (rolling friction), each
// bounded by its coefficient times the contact's normal impulse (cadmm's rows bounded by a
// contact) and by the coefficient itself, as Bullet caps them.
#pragma once

#include <btBulletDynamicsCommon.h>
#include <cadmm.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

static_assert(sizeof(btScalar) == sizeof(double),
              "cadmm_bullet needs Bullet in double precision (BT_USE_DOUBLE_PRECISION, the "
              "*-float64 libraries)");

namespace cadmm_bullet {

// What the integration refuses (an unmapped constraint type, an unsupported body or contact
// setting) or a failed cadmm call. The message names the object and the reason.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A sparse matrix in compressed sparse columns, as cadmm_csc wants it.
struct Csc {
  size_t nrows = 0, ncols = 0;
  std::vector<int64_t> colptr{0}, rowind;
  std::vector<double> values;

  void clear(size_t rows);
  void push(int64_t row, double value) { rowind.push_back(row), values.push_back(value); }
  void endColumn() { colptr.push_back(int64_t(rowind.size())), ++ncols; }
  cadmm_csc view() const { return {nrows, ncols, colptr.data(), rowind.data(), values.data()}; }
  bool samePattern(const Csc &o) const {
    return nrows == o.nrows && ncols == o.ncols && colptr == o.colptr && rowind == o.rowind;
  }
};

// How the normal velocity is biased to remove penetration (w_N).
struct Correction {
  double erp = 0.2;           // fraction of the penetration removed per step (Baumgarte)
  bool splitImpulse = false;  // Bullet's split impulse: shallow penetration is not in w_N
  double splitThreshold = -0.04;
};

class ContactProblem {
 public:
  // Reads the group; throws Error for anything it cannot map (see the .cpp).
  void assemble(btCollisionObject **bodies, int numBodies, btPersistentManifold **manifolds,
                int numManifolds, btTypedConstraint **constraints, int numConstraints,
                const btContactSolverInfo &info, const Correction &correction);

  size_t velocities() const { return f.size(); }
  size_t contacts() const { return mu.size(); }
  size_t jointRows() const { return b.size(); }
  // Which joint rows are bounded is part of the pattern: cadmm's solver keeps the bounded
  // rows apart from the equalities (cadmm_solver_update refuses a change of them).
  bool samePattern(const ContactProblem &o) const {
    return M.samePattern(o.M) && H.samePattern(o.H) && G.samePattern(o.G) &&
           boundedRows() == o.boundedRows() && frictionContact == o.frictionContact;
  }
  // Whether a joint row is bounded or compliant: then cadmm needs the bounds and
  // compliance calls, which cadmm_solver_update_values does not take.
  bool beyondEqualities() const;

  // A new cadmm problem with these values; throws Error with cadmm's message.
  cadmm_problem *make() const;

  // The column of G (the index in lambda) of row k of constraint c, rows numbered as c's
  // getInfo2 fills them; -1 when c is not mapped in this problem or Bullet's solver would
  // leave that row inert (no dynamic body along it).
  int jointRow(const btTypedConstraint *c, int k) const;

  // Impulses stored in the manifold points (m_appliedImpulse, m_appliedImpulseLateral1/2)
  // read in this problem's frames: the warm start of the next solve. bulletFrames: the
  // lateral impulses are along Bullet's own m_lateralFrictionDir1/2 (as its sequential
  // impulse solver leaves them), with two directions or one.
  std::vector<double> storedImpulses(bool bulletFrames = false, bool twoDirections = true) const;
  // The bodies' current velocities, in this problem's order.
  std::vector<double> bodyVelocities() const;
  // The velocities without contact or joint impulse (M^-1 f): external forces applied.
  const std::vector<double> &freeVelocities() const { return vfree_; }

  // Writes impulses to the manifold points (and their frames to m_lateralFrictionDir1/2),
  // joint impulses to the constraints (as btSequentialImpulseConstraintSolver's
  // writeBackJoints: applied impulse, btJointFeedback, breaking) and velocities to the bodies.
  void writeBack(const double *r, const double *v, const double *lambda) const;

 private:
  struct Point {
    btManifoldPoint *cp;
    btVector3 n, t1, t2;
  };
  int index(const btCollisionObject *o) const;  // body's first unknown, or -1 when fixed
  void addBody(btRigidBody *rb, const btContactSolverInfo &info);
  void addContact(btPersistentManifold *m, btManifoldPoint &cp, const btContactSolverInfo &info,
                  const Correction &c);
  void addConstraint(btTypedConstraint &c, const btContactSolverInfo &info);
  void addTorsionRows();
  std::vector<bool> boundedRows() const;
  // One column of H: the relative velocity along d of point pA on A and pB on B;
  // returns the part of that velocity from fixed bodies (their velocity is no unknown).
  double addRow(Csc &J, const btCollisionObject *A, const btVector3 &pA,
                const btCollisionObject *B, const btVector3 &pB, const btVector3 &d);

  std::vector<btRigidBody *> bodies_;
  std::unordered_map<const btCollisionObject *, int> index_;
  std::vector<Point> points_;
  // One row of a mapped constraint: its Jacobian (kept for the joint feedback) and its
  // column of G, -1 for a row Bullet's solver leaves inert.
  struct JointRow {
    int column;
    btVector3 j1lin, j1ang, j2lin, j2ang;
  };
  struct Joint {
    btTypedConstraint *c;
    size_t first, count;  // its rows in rows_
  };
  std::vector<JointRow> rows_;
  // getInfo2's output for one row, as Bullet's btSolverConstraint lays it out for it: each
  // Jacobian block a btVector3 (getInfo2 writes 3 scalars, some through a btVector3), the
  // error, cfm and limits; rowskip is this struct's size in scalars.
  struct InfoRow {
    btVector3 j1lin, j1ang, j2lin, j2ang;
    btScalar error, cfm, lo, hi;
  };
  std::vector<InfoRow> info_;
  std::vector<Joint> joints_;                   // the enabled constraints, mapped
  // A torsional friction row of a contact point, added once the constraints' are.
  struct Torsion {
    const btCollisionObject *A, *B;
    btVector3 axis;
    double coefficient;
    int64_t contact;
  };
  std::vector<Torsion> torsion_;
  std::vector<btTypedConstraint *> allJoints_;  // every constraint of the group
  std::vector<double> vfree_;
  double h_ = 0;  // time step

 public:
  Csc M, H, G;
  std::vector<double> f, w, mu, b;
  // Per joint row: the bounds of its multiplier (-INFINITY, INFINITY for none) and its
  // compliance (0 for a rigid row).
  std::vector<double> lo, hi, compliance;
  // Per joint row: the contact whose normal impulse also bounds it (-1 for none) and the
  // coefficient of that bound (0 for none): the rolling and spinning friction rows.
  std::vector<int64_t> frictionContact;
  std::vector<double> friction;
  bool hasContactBounds() const;
};

}  // namespace cadmm_bullet
