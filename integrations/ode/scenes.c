/* The test scenes of cadmm_ode_stack. */
#include "scenes.h"

#include <string.h>

const char *const scene_names = "tower|mass-ratio-100|mass-ratio-1000|pyramid|slide";

static const double side = 0.5; /* every box is a 0.5 m cube */

/* Boxes start 0.5 mm into each other and into the ground: inside the 1 mm contact surface
 * layer, where resting contacts neither get pushed out nor lost to round-off, as after a
 * landing. Exactly touching boxes would lose their contacts at the first rounding. */
static const double sink = 0.0005;

static void add_box(scene *s, double mass, double x, double y, double z) {
    size_t i = s->n++;
    dBodyID b = dBodyCreate(s->world);
    dMass m;
    dMassSetBoxTotal(&m, mass, side, side, side);
    dBodySetMass(b, &m);
    dBodySetPosition(b, x, y, z);
    dGeomID g = dCreateBox(s->space, side, side, side);
    dGeomSetBody(g, b);
    s->bodies[i] = b;
    s->geoms[i] = g;
    s->start[i][0] = x;
    s->start[i][1] = y;
    s->start[i][2] = z;
    for (int k = 0; k < 3; k++) s->half[i][k] = side / 2;
}

/* The height of the center of a box in row `row` (0 on the ground). */
static double row_z(int row) { return side / 2 - sink + (side - sink) * row; }

/* Boxes on top of each other, from the ground up. */
static void column(scene *s, const double *masses, size_t count) {
    for (size_t i = 0; i < count; i++) add_box(s, masses[i], 0, 0, row_z((int)i));
}

int scene_build(scene *s, const char *name) {
    memset(s, 0, sizeof *s);
    static const double tower[] = {1, 100, 1, 100, 1}, ratio100[] = {1, 100},
                        ratio1000[] = {1, 1000};
    int kind = !strcmp(name, "tower")             ? 1
               : !strcmp(name, "mass-ratio-100")  ? 2
               : !strcmp(name, "mass-ratio-1000") ? 3
               : !strcmp(name, "pyramid")         ? 4
               : !strcmp(name, "slide")           ? 5
                                                  : 0;
    if (!kind) return -1;
    s->world = dWorldCreate();
    s->space = dSimpleSpaceCreate(0);
    dWorldSetGravity(s->world, 0, 0, -9.81);
    /* Contacts may sink 1 mm before being pushed out, so resting contacts persist. */
    dWorldSetContactSurfaceLayer(s->world, 0.001);
    s->ground = dCreatePlane(s->space, 0, 0, 1, 0);
    if (kind == 1) column(s, tower, 5);
    if (kind == 2) column(s, ratio100, 2);
    if (kind == 3) column(s, ratio1000, 2);
    if (kind == 4) {
        /* Four rows of unit-mass boxes 5 cm apart, each resting on two below. */
        const double pitch = side + 0.05;
        for (int row = 0; row < 4; row++)
            for (int k = 0; k < 4 - row; k++)
                add_box(s, 1.0, pitch * (k - (3 - row) / 2.0), 0, row_z(row));
    }
    if (kind == 5) {
        /* 4 m/s: it stops after v^2 / (2 mu g) = 1.63 m at mu 0.5, in 0.82 s. */
        add_box(s, 1.0, 0, 0, row_z(0));
        s->launch = 4.0;
        dBodySetLinearVel(s->bodies[0], s->launch, 0, 0);
    }
    s->top = s->n - 1;
    return 0;
}

void scene_free(scene *s) {
    if (s->space) dSpaceDestroy(s->space); /* destroys the geoms too */
    if (s->world) dWorldDestroy(s->world); /* and the bodies */
    memset(s, 0, sizeof *s);
}
