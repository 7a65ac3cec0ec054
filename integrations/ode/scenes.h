/* The test scenes of cadmm_ode_stack: boxes (and a vehicle) on a static ground plane, z up. */
#ifndef CADMM_ODE_SCENES_H
#define CADMM_ODE_SCENES_H

#include <ode/ode.h>
#include <stddef.h>

/* The largest --count a scene takes (big-pyramid's count is its base row). */
#define SCENE_MAX_COUNT 100000
#define SCENE_MAX_BASE 300
/* The longest chain. */
#define SCENE_MAX_LINKS 1000

typedef struct scene {
    dWorldID world;
    dSpaceID space;
    dGeomID ground;
    size_t n;   /* bodies */
    size_t cap; /* room in the arrays below (the wall's ball is added during the run) */
    size_t top; /* the body whose drift is reported */
    dBodyID *bodies;
    dGeomID *geoms;
    double (*half)[3];  /* box half extents (a sphere's radius thrice) */
    double (*start)[3]; /* initial positions */
    double launch; /* "slide": the box's initial speed along +x (m/s); 0 for the stacks */
    /* "wall", "bin": bodies fall, topple and collide, so the at-rest checks (fell, drift,
     * the resting penetration bound) do not apply. */
    int in_motion;
    /* "wall": a sphere of this radius and mass created at the start of step `step` (0-based)
     * at `from` with velocity `velocity` (radius 0: none). */
    struct {
        size_t step;
        double radius, mass, from[3], velocity[3];
    } ball;
    double mu; /* the friction coefficient of every contact (0.5; the vehicle's tyres 1) */
    /* The scene's joints, each with its feedback (set, so that ODE's solvers hand back their
     * joint forces): the vehicle's hinge-2s, the chain's balls; n_joints is 0 for the other
     * scenes. */
    size_t n_joints;
    dJointID *joints;
    dJointFeedback *joint_feedback;
    /* "vehicle": its joints go from the chassis (body 0) to wheel k (body k + 1: front
     * left, front right, rear left, rear right); the wheels' radius, and the bump: a static
     * capsule across the road (along y) of radius bump_radius, its axis at x = bump_x on
     * the ground. */
    int vehicle;
    double wheel_radius, bump_x, bump_radius;
} scene;

/* Builds "tower", "mass-ratio-100", "mass-ratio-1000", "pyramid", "slide" (one box on the
 * ground launched along x at `launch`), "vehicle" (a car of 1280 kg on four hinge-2 wheels,
 * the rear ones driven, starting at rest with its front wheels 1.7 m before a 10 cm bump;
 * scenes.c gives its dimensions), or one of the scenes sized by `count` (0: its default)
 * and varied by `seed`:
 *  - "big-pyramid": rows of count (15), count - 1, ..., 1 unit-mass boxes (120), 5 cm apart
 *    in a row, each resting on two below;
 *  - "wall": count (100) bricks of 0.4 x 0.2 x 0.2 m and 2 kg in running bond, rows of 10
 *    touching side to side, hit at 1 s by a 20 kg sphere of radius 0.25 m thrown at 8 m/s
 *    towards 0.6 of the wall's height, sideways offset drawn from seed in [-0.3, 0.3] m;
 *  - "bin": count (512) boxes of 1 to 5 kg, half extents 0.12 to 0.18 m and tilts within
 *    0.3 rad drawn from seed, in layers of 8 x 8, dropped into a 3 x 3 m bin whose four
 *    walls (1 m high) are static geoms;
 *  - "chain": count (20) links, 0.3 m cubes of 1 kg 10 cm apart along x, on ball joints at
 *    the middle of the gaps, the first hung from a fixed point 9 m up: released horizontal,
 *    the chain swings down into a 5 kg box (1 x 1 x 1.5 m) standing below. The seed moves
 *    the box along y by up to 0.3 m, so that the links strike it elsewhere.
 * The other scenes ignore count and seed. The world has gravity -9.81 z and ODE's default
 * parameters except a 1 mm contact surface layer. 0 on success, -1 for an unknown name, -2
 * when out of memory or count is above SCENE_MAX_COUNT (big-pyramid: SCENE_MAX_BASE;
 * chain: SCENE_MAX_LINKS). */
int scene_build(scene *s, const char *name, long count, unsigned long seed);

/* Called before each step (0-based): adds the wall's ball at its step (its room is kept
 * by scene_build). */
void scene_before_step(scene *s, size_t step);

void scene_free(scene *s);

/* Names accepted by scene_build, for messages. */
extern const char *const scene_names;

#endif
