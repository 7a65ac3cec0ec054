/* The test scenes of cadmm_ode_stack: boxes stacked on a static ground plane. */
#ifndef CADMM_ODE_SCENES_H
#define CADMM_ODE_SCENES_H

#include <ode/ode.h>
#include <stddef.h>

#define SCENE_MAX_BODIES 16

typedef struct scene {
    dWorldID world;
    dSpaceID space;
    dGeomID ground;
    size_t n;   /* bodies */
    size_t top; /* the body whose drift is reported */
    dBodyID bodies[SCENE_MAX_BODIES];
    dGeomID geoms[SCENE_MAX_BODIES];
    double half[SCENE_MAX_BODIES][3];  /* box half extents */
    double start[SCENE_MAX_BODIES][3]; /* initial positions */
    double launch; /* "slide": the box's initial speed along +x (m/s); 0 for the stacks */
} scene;

/* Builds "tower", "mass-ratio-100", "mass-ratio-1000", "pyramid" or "slide" (one box on the
 * ground launched along x at `launch`); 0 on success, -1 for an unknown name. The world has
 * gravity -9.81 z and ODE's default parameters except a 1 mm contact surface layer. */
int scene_build(scene *s, const char *name);
void scene_free(scene *s);

/* Names accepted by scene_build, for messages. */
extern const char *const scene_names;

#endif
