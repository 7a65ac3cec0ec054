/* cadmm_ode_errors: bad input to cadmm_ode gets an error code and a message naming what is
 * wrong, never a crash; a valid step after the failures still works. */
#include "cadmm_ode.h"

#include <stdio.h>
#include <string.h>

static int failures = 0;

static void expect(cadmm_ode *ctx, cadmm_result got, cadmm_result want, const char *needle) {
    const char *msg = cadmm_ode_last_error(ctx);
    if (got != want || !strstr(msg, needle)) {
        printf("FAIL: code %d (want %d), message \"%s\" (want it to contain \"%s\")\n", got, want,
               msg, needle);
        failures++;
    } else {
        printf("ok: %s\n", msg);
    }
}

int main(void) {
    dInitODE2(0);
    dWorldID world = dWorldCreate();
    dSpaceID space = dSimpleSpaceCreate(0);
    dWorldSetGravity(world, 0, 0, -9.81);
    dGeomID ground = dCreatePlane(space, 0, 0, 1, 0);
    dBodyID bodies[2];
    dGeomID boxes[2];
    for (int i = 0; i < 2; i++) {
        dMass m;
        bodies[i] = dBodyCreate(world);
        dMassSetBoxTotal(&m, 1.0, 1, 1, 1);
        dBodySetMass(bodies[i], &m);
        dBodySetPosition(bodies[i], 3.0 * i, 0, 0.4999);
        boxes[i] = dCreateBox(space, 1, 1, 1);
        dGeomSetBody(boxes[i], bodies[i]);
    }
    dContactGeom c;
    memset(&c, 0, sizeof c);
    c.pos[2] = 0.0;
    c.normal[2] = 1.0;
    c.depth = 1e-4;
    c.g1 = boxes[0];
    c.g2 = ground;

    cadmm_ode_options opt = cadmm_ode_default_options();
    opt.mu = -1.0;
    if (cadmm_ode_new(&opt) != NULL) {
        printf("FAIL: a negative mu was accepted\n");
        failures++;
    }
    opt = cadmm_ode_default_options();
    cadmm_ode *ctx = cadmm_ode_new(&opt);
    cadmm_ode_step_info info;

    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.0, &info), CADMM_ERR_INVALID_VALUE,
           "time step");
    expect(ctx, cadmm_ode_step(ctx, NULL, bodies, 2, &c, 1, 0.01, &info), CADMM_ERR_NULL_POINTER,
           "world");
    expect(ctx, cadmm_ode_step(ctx, world, bodies + 1, 1, &c, 1, 0.01, &info),
           CADMM_ERR_INVALID_VALUE, "not in the bodies list");
    dBodyID twice[2] = {bodies[0], bodies[0]};
    expect(ctx, cadmm_ode_step(ctx, world, twice, 2, &c, 1, 0.01, &info), CADMM_ERR_INVALID_VALUE,
           "listed twice");
    dContactGeom swapped = c;
    swapped.g1 = ground;
    swapped.g2 = boxes[0];
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &swapped, 1, 0.01, &info),
           CADMM_ERR_INVALID_VALUE, "g1 has no body");
    dContactGeom tilted = c;
    tilted.normal[0] = 1.0;
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &tilted, 1, 0.01, &info),
           CADMM_ERR_INVALID_VALUE, "normal of length");
    expect(ctx, cadmm_ode_solve(ctx, &info), CADMM_ERR_UNSUPPORTED, "nothing assembled");

    /* A valid step still works: the box rests, pushed by nothing but gravity. */
    cadmm_result rc = cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.01, &info);
    if (rc != CADMM_OK || !info.solved || info.status != CADMM_STATUS_SOLVED ||
        info.error > 1e-8 || dBodyGetLinearVel(bodies[0])[2] < -1e-9) {
        printf("FAIL: a valid step after the failures: %s\n", cadmm_ode_last_error(ctx));
        failures++;
    } else {
        printf("ok: a valid step after the failures (error %.2g)\n", info.error);
    }
    cadmm_ode_free(ctx);
    dSpaceDestroy(space);
    dWorldDestroy(world);
    dCloseODE();
    printf("%s\n", failures ? "FAILED" : "all error checks passed");
    return failures ? 1 : 0;
}
