/* The test scenes of cadmm_ode_stack. */
#include "scenes.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

const char *const scene_names =
    "tower|mass-ratio-100|mass-ratio-1000|pyramid|slide|big-pyramid|wall|bin|vehicle|chain";

static const double side = 0.5; /* the stacks' boxes are 0.5 m cubes */
static const double gravity = 9.81;

/* Boxes start 0.5 mm into each other and into the ground: inside the 1 mm contact surface
 * layer, where resting contacts neither get pushed out nor lost to round-off, as after a
 * landing. Exactly touching boxes would lose their contacts at the first rounding. */
static const double sink = 0.0005;

/* The scenes' own random numbers (splitmix64): the same on every machine for a seed. */
typedef struct rng {
    uint64_t state;
} rng;

static uint64_t rng_next(rng *r) {
    uint64_t z = (r->state += 0x9e3779b97f4a7c15u);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
}

/* Uniform in [a, b). */
static double uniform(rng *r, double a, double b) {
    return a + (b - a) * (double)(rng_next(r) >> 11) * 0x1.0p-53;
}

/* A body with geom g, mass m, at p turned by R (NULL: not turned). */
static dBodyID add_body(scene *s, dGeomID g, const dMass *m, const double p[3], const dReal *R) {
    size_t i = s->n++;
    dBodyID b = dBodyCreate(s->world);
    dBodySetMass(b, m);
    dBodySetPosition(b, p[0], p[1], p[2]);
    if (R) dBodySetRotation(b, R);
    dGeomSetBody(g, b);
    s->bodies[i] = b;
    s->geoms[i] = g;
    for (int k = 0; k < 3; k++) s->start[i][k] = p[k];
    return b;
}

/* A box of half extents he and the given mass at (x, y, z), turned by R (NULL: not). */
static void add_box(scene *s, double mass, const double he[3], double x, double y, double z,
                    const dReal *R) {
    dMass m;
    dMassSetBoxTotal(&m, mass, 2 * he[0], 2 * he[1], 2 * he[2]);
    const double p[3] = {x, y, z};
    for (int k = 0; k < 3; k++) s->half[s->n][k] = he[k];
    add_body(s, dCreateBox(s->space, 2 * he[0], 2 * he[1], 2 * he[2]), &m, p, R);
}

static void add_cube(scene *s, double mass, double x, double y, double z) {
    const double he[3] = {side / 2, side / 2, side / 2};
    add_box(s, mass, he, x, y, z, NULL);
}

/* The height of the center of a cube in row `row` (0 on the ground). */
static double row_z(int row) { return side / 2 - sink + (side - sink) * row; }

/* Cubes on top of each other, from the ground up. */
static void column(scene *s, const double *masses, size_t count) {
    for (size_t i = 0; i < count; i++) add_cube(s, masses[i], 0, 0, row_z((int)i));
}

/* Rows of base, base - 1, ..., 1 unit-mass cubes 5 cm apart, each resting on two below. */
static void pyramid(scene *s, int base) {
    const double pitch = side + 0.05;
    for (int row = 0; row < base; row++)
        for (int k = 0; k < base - row; k++)
            add_cube(s, 1.0, pitch * (k - (base - 1 - row) / 2.0), 0, row_z(row));
}

/* Running bond along x: rows of 10 bricks (0.4 m along x, 0.2 m deep along y, 0.2 m high),
 * every other row shifted by half a brick, each brick 0.5 mm into its neighbors and the row
 * below (touching, as closely as the surface layer allows). The ball is thrown from 3 m in
 * front (-y) at 8 m/s along +y and upwards, from 0.6 of the wall's height back to it when it
 * reaches the wall's face: over t = k h the step's semi-implicit Euler (velocity first)
 * drops it by g t (t + h) / 2, so its upward speed is g (t + h) / 2. Its sideways offset is
 * drawn from the seed. */
static void wall(scene *s, long count, rng *r) {
    const double he[3] = {0.2, 0.1, 0.1};
    const double pitch = 2 * he[0] - sink, rise = 2 * he[2] - sink;
    for (long i = 0; i < count; i++) {
        long row = i / 10, k = i % 10;
        double x = pitch * ((double)k - 4.5) + (row % 2 ? pitch / 2 : 0);
        add_box(s, 2.0, he, x, 0, he[2] - sink + rise * (double)row, NULL);
    }
    const double height = rise * (double)((count + 9) / 10), speed = 8.0, radius = 0.25;
    const double h = 1.0 / 60, flight = (3.0 - he[1] - radius) / speed;
    s->ball.step = 60; /* 1 s */
    s->ball.radius = radius;
    s->ball.mass = 20.0;
    s->ball.from[0] = uniform(r, -0.3, 0.3);
    s->ball.from[1] = -3.0;
    s->ball.from[2] = 0.6 * height;
    s->ball.velocity[0] = 0;
    s->ball.velocity[1] = speed;
    s->ball.velocity[2] = gravity * (flight + h) / 2;
    s->in_motion = 1;
}

/* A 3 x 3 m bin (four static walls 0.2 m thick and 1 m high on the ground plane), and boxes
 * in layers of 8 x 8 at 0.36 m pitch, the first 0.3 m up, 0.4 m between layers: half
 * extents 0.12 to 0.18 m, 1 to 5 kg, turned by up to 0.3 rad about each axis and shifted by
 * up to 1 cm, all drawn from the seed. Large tilted neighbors start overlapping (up to about
 * 12 cm), and ODE's contact push-out parts them over the first steps. */
static void bin(scene *s, long count, rng *r) {
    for (int w = 0; w < 4; w++) {
        double at = w % 2 ? 1.6 : -1.6;
        int along_x = w < 2;
        dGeomID g = along_x ? dCreateBox(s->space, 3.4, 0.2, 1.0)
                            : dCreateBox(s->space, 0.2, 3.4, 1.0);
        if (along_x) dGeomSetPosition(g, 0, at, 0.5);
        else dGeomSetPosition(g, at, 0, 0.5);
    }
    for (long i = 0; i < count; i++) {
        long layer = i / 64, x = i % 8, y = (i / 8) % 8;
        double he[3], angle[3];
        for (int k = 0; k < 3; k++) he[k] = uniform(r, 0.12, 0.18);
        double mass = uniform(r, 1, 5);
        for (int k = 0; k < 3; k++) angle[k] = uniform(r, -0.3, 0.3);
        dMatrix3 R;
        dRFromEulerAngles(R, angle[0], angle[1], angle[2]);
        double dx = uniform(r, -0.01, 0.01), dy = uniform(r, -0.01, 0.01);
        add_box(s, mass, he, 0.36 * ((double)x - 3.5) + dx, 0.36 * ((double)y - 3.5) + dy,
                0.3 + 0.4 * (double)layer, R);
    }
    s->in_motion = 1;
}

/* A joint of the scene, its feedback set. */
static dJointID add_joint(scene *s, dJointID j) {
    dJointSetFeedback(j, &s->joint_feedback[s->n_joints]);
    s->joints[s->n_joints++] = j;
    return j;
}

/* Links of 0.3 m, 0.1 m apart along x, each on a ball joint to the one before at the middle
 * of their gap, the first on one to the world 0.2 m before its center, 9 m up; released
 * horizontal, the chain swings down through the box standing under its first 2 m, whose
 * place along y the seed draws. */
static void chain(scene *s, long count, rng *r) {
    const double he[3] = {0.15, 0.15, 0.15}, box_he[3] = {0.5, 0.5, 0.75}, pivot_z = 9.0;
    add_box(s, 5.0, box_he, 0.6, uniform(r, -0.3, 0.3), box_he[2] - sink, NULL);
    dBodyID prev = NULL;
    for (long k = 0; k < count; k++) {
        add_box(s, 1.0, he, 0.2 + 0.4 * (double)k, 0, pivot_z, NULL);
        dBodyID link = s->bodies[s->n - 1];
        dJointID j = add_joint(s, dJointCreateBall(s->world, 0));
        dJointAttach(j, link, prev); /* the first: to the world */
        dJointSetBallAnchor(j, 0.4 * (double)k, 0, pivot_z);
        prev = link;
    }
    s->in_motion = 1;
}

/* A car at full scale, ODE's demo_buggy grown to road size: a 1200 kg chassis box (4 x 1.7
 * x 0.5 m) on four 20 kg sphere wheels of radius 0.35 m (a 60:1 mass ratio across every
 * joint), wheelbase 2.6 m, track 1.7 m, each wheel on a dJointHinge2 anchored at its
 * center: axis 1 vertical on the chassis (steering, and the suspension along it), axis 2
 * along y on the wheel (spin). Spheres, not cylinders: ODE collides them with the plane
 * and the capsule as one contact each, and their inertia is isotropic, so the gyroscopic
 * term (implicit in ODE 0.16's steppers, explicit in cadmm_ode) is zero on the wheels.
 *
 * Suspension: a spring of 30 kN/m and a damper of 2.5 kN s/m per wheel (about 1.6 Hz and
 * 0.4 of critical damping on a quarter of the chassis), as ODE's ERP/CFM at this step:
 * ERP = h kp / (h kp + kd), CFM = 1 / (h kp + kd). The car starts at rest on it: the joints
 * are set with the chassis m g / (4 kp) = 9.8 cm higher, where the springs are at rest, and
 * the chassis then moved down to 0.55 m, so that they carry it from the first step. (Built
 * unloaded instead, the chassis sinks 10 cm over the first half second while the wheels,
 * hardly pressed onto the ground yet, spin under the motors.)
 *
 * Steering is locked by stops lo = hi = 0 on all four wheels (the front ones are the
 * steered axle of a car; the rear ones must be held too, or they would steer freely). The
 * rear wheels are driven by the hinge-2 motor on axis 2 towards 6 m/s (Vel2 = -v / r:
 * ODE's motor holds body 1's spin minus body 2's, and a wheel rolling along +x spins about
 * +y) with at most 800 N m each: 3.6 m/s^2 from rest, within the 1 g of grip mu 1 gives the
 * rear axle. It starts at rest, its front wheels 1.7 m before a 10 cm bump, half a capsule
 * of radius 0.1 m across the road: they reach it at 0.95 s at 3.3 m/s, the rear ones at
 * 1.6 s at 5.2 m/s, and it cruises at 6 m/s from 2.1 s (24.3 m in 5 s). */
#define WHEEL_R 0.35
#define VEHICLE_SPEED 6.0
static void vehicle(scene *s) {
    const double he[3] = {2.0, 0.85, 0.25}, chassis_mass = 1200, wheel_mass = 20;
    const double axle = 1.3, track = 0.85, chassis_z = 0.55;
    const double h = 1.0 / 60, kp = 30000, kd = 2500, sag = chassis_mass * gravity / (4 * kp);
    add_box(s, chassis_mass, he, 0, 0, chassis_z + sag, NULL);
    dBodyID chassis = s->bodies[0];
    static const double corner[4][2] = {{1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
    for (int k = 0; k < 4; k++) {
        dMass m;
        dMassSetSphereTotal(&m, wheel_mass, WHEEL_R);
        /* Touching the ground within the surface layer, as the stacks' boxes start. */
        const double p[3] = {axle * corner[k][0], track * corner[k][1], WHEEL_R - sink};
        for (int d = 0; d < 3; d++) s->half[s->n][d] = WHEEL_R;
        dBodyID w = add_body(s, dCreateSphere(s->space, WHEEL_R), &m, p, NULL);
        dJointID j = add_joint(s, dJointCreateHinge2(s->world, 0));
        dJointAttach(j, chassis, w);
        dJointSetHinge2Anchor(j, p[0], p[1], p[2]);
        const dReal a1[3] = {0, 0, 1}, a2[3] = {0, 1, 0};
        dJointSetHinge2Axes(j, a1, a2);
        dJointSetHinge2Param(j, dParamLoStop, 0);
        dJointSetHinge2Param(j, dParamHiStop, 0);
        dJointSetHinge2Param(j, dParamSuspensionERP, h * kp / (h * kp + kd));
        dJointSetHinge2Param(j, dParamSuspensionCFM, 1.0 / (h * kp + kd));
        if (corner[k][0] < 0) {
            dJointSetHinge2Param(j, dParamVel2, -VEHICLE_SPEED / WHEEL_R);
            dJointSetHinge2Param(j, dParamFMax2, 800);
        }
    }
    /* The joints keep their anchors in the bodies' frames: moved down, the chassis' anchors
     * sit `sag` below the wheels', the springs' preload. */
    dBodySetPosition(chassis, 0, 0, chassis_z);
    s->start[0][2] = chassis_z;
    s->wheel_radius = WHEEL_R;
    s->bump_radius = 0.1;
    s->bump_x = axle + 1.7 + s->bump_radius; /* 1.7 m of road before the bump's foot */
    dGeomID bump = dCreateCapsule(s->space, s->bump_radius, 4.0);
    dMatrix3 R;
    dRFromAxisAndAngle(R, 1, 0, 0, 1.5707963267948966); /* the capsule's axis (its z) along y */
    dGeomSetRotation(bump, R);
    dGeomSetPosition(bump, s->bump_x, 0, 0);
    s->mu = 1.0;
    s->in_motion = 1;
    s->vehicle = 1;
}

enum { TOWER = 1, RATIO100, RATIO1000, PYRAMID, SLIDE, BIG_PYRAMID, WALL, BIN, VEHICLE, CHAIN };

static int kind_of(const char *name) {
    static const char *const names[] = {"tower",   "mass-ratio-100", "mass-ratio-1000",
                                        "pyramid", "slide",          "big-pyramid",
                                        "wall",    "bin",            "vehicle",
                                        "chain"};
    for (int k = 0; k < (int)(sizeof names / sizeof names[0]); k++)
        if (!strcmp(name, names[k])) return k + 1;
    return 0;
}

int scene_build(scene *s, const char *name, long count, unsigned long seed) {
    memset(s, 0, sizeof *s);
    static const double tower[] = {1, 100, 1, 100, 1}, ratio100[] = {1, 100},
                        ratio1000[] = {1, 1000};
    int kind = kind_of(name);
    if (!kind) return -1;
    if (count < 0 || count > SCENE_MAX_COUNT || (kind == BIG_PYRAMID && count > SCENE_MAX_BASE) ||
        (kind == CHAIN && count > SCENE_MAX_LINKS))
        return -2;
    long base = count > 0 ? count : 15;
    size_t cap = kind == TOWER         ? 5
                 : kind == PYRAMID     ? 10
                 : kind == SLIDE       ? 1
                 : kind == BIG_PYRAMID ? (size_t)(base * (base + 1) / 2)
                 : kind == WALL        ? (size_t)(count > 0 ? count : 100) + 1 /* the ball */
                 : kind == BIN         ? (size_t)(count > 0 ? count : 512)
                 : kind == VEHICLE     ? 5
                 : kind == CHAIN       ? (size_t)(count > 0 ? count : 20) + 1 /* the box */
                                       : 2;
    size_t joints = kind == VEHICLE ? 4 : kind == CHAIN ? cap - 1 : 0;
    s->bodies = malloc(cap * sizeof *s->bodies);
    s->geoms = malloc(cap * sizeof *s->geoms);
    s->half = malloc(cap * sizeof *s->half);
    s->start = malloc(cap * sizeof *s->start);
    s->joints = malloc((joints + 1) * sizeof *s->joints);
    s->joint_feedback = malloc((joints + 1) * sizeof *s->joint_feedback);
    if (!s->bodies || !s->geoms || !s->half || !s->start || !s->joints || !s->joint_feedback) {
        scene_free(s);
        return -2;
    }
    s->cap = cap;
    s->world = dWorldCreate();
    /* The small stacks collide every pair (their contact order as it always was); the larger
     * scenes use ODE's multi-resolution hash grid. */
    s->space = kind < BIG_PYRAMID || kind == VEHICLE ? dSimpleSpaceCreate(0) : dHashSpaceCreate(0);
    dWorldSetGravity(s->world, 0, 0, -gravity);
    /* Contacts may sink 1 mm before being pushed out, so resting contacts persist. */
    dWorldSetContactSurfaceLayer(s->world, 0.001);
    s->ground = dCreatePlane(s->space, 0, 0, 1, 0);
    s->mu = 0.5;
    rng r = {(uint64_t)seed};
    if (kind == TOWER) column(s, tower, 5);
    if (kind == RATIO100) column(s, ratio100, 2);
    if (kind == RATIO1000) column(s, ratio1000, 2);
    if (kind == PYRAMID) pyramid(s, 4);
    if (kind == SLIDE) {
        /* 4 m/s: it stops after v^2 / (2 mu g) = 1.63 m at mu 0.5, in 0.82 s. */
        add_cube(s, 1.0, 0, 0, row_z(0));
        s->launch = 4.0;
        dBodySetLinearVel(s->bodies[0], s->launch, 0, 0);
    }
    if (kind == BIG_PYRAMID) pyramid(s, (int)base);
    if (kind == WALL) wall(s, count > 0 ? count : 100, &r);
    if (kind == BIN) bin(s, count > 0 ? count : 512, &r);
    if (kind == VEHICLE) vehicle(s);
    if (kind == CHAIN) chain(s, count > 0 ? count : 20, &r);
    /* The vehicle reports its chassis. */
    s->top = kind == VEHICLE ? 0 : s->n - 1;
    return 0;
}

void scene_before_step(scene *s, size_t step) {
    if (!(s->ball.radius > 0) || step != s->ball.step || s->n >= s->cap) return;
    dMass m;
    dMassSetSphereTotal(&m, s->ball.mass, s->ball.radius);
    for (int k = 0; k < 3; k++) s->half[s->n][k] = s->ball.radius;
    dBodyID b = add_body(s, dCreateSphere(s->space, s->ball.radius), &m, s->ball.from, NULL);
    dBodySetLinearVel(b, s->ball.velocity[0], s->ball.velocity[1], s->ball.velocity[2]);
}

void scene_free(scene *s) {
    if (s->space) dSpaceDestroy(s->space); /* destroys the geoms too */
    if (s->world) dWorldDestroy(s->world); /* and the bodies */
    free(s->bodies);
    free(s->geoms);
    free(s->half);
    free(s->start);
    free(s->joints);
    free(s->joint_feedback);
    memset(s, 0, sizeof *s);
}
