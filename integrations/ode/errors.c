/* cadmm_ode_errors: bad input to cadmm_ode gets an error code and a message naming what is
 * wrong, never a crash; so do the joints and contact surfaces it cannot express; a valid
 * step after the failures still works. */
#include "cadmm_ode.h"

#include <math.h>
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

    /* Joints the host cannot express are refused, naming their type; each is destroyed
     * after its check. */
    struct {
        dJointID j;
        const char *name;
    } refused[] = {
        {dJointCreateAMotor(world, 0), "dJointTypeAMotor"},
        {dJointCreateLMotor(world, 0), "dJointTypeLMotor"},
        {dJointCreatePlane2D(world, 0), "dJointTypePlane2D"},
        {dJointCreatePR(world, 0), "dJointTypePR"},
        {dJointCreatePU(world, 0), "dJointTypePU"},
        {dJointCreatePiston(world, 0), "dJointTypePiston"},
        {dJointCreateDBall(world, 0), "dJointTypeDBall"},
        {dJointCreateDHinge(world, 0), "dJointTypeDHinge"},
    };
    for (size_t k = 0; k < sizeof refused / sizeof refused[0]; k++) {
        dJointAttach(refused[k].j, bodies[0], 0);
        expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.01, &info),
               CADMM_ERR_UNSUPPORTED, refused[k].name);
        dJointDestroy(refused[k].j);
    }
    dContact user_contact;
    memset(&user_contact, 0, sizeof user_contact);
    user_contact.geom = c;
    dJointID j = dJointCreateContact(world, 0, &user_contact);
    dJointAttach(j, bodies[0], 0);
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.01, &info), CADMM_ERR_UNSUPPORTED,
           "contact joints made by the user are not supported");
    dJointDestroy(j);

    /* A joint to a body missing from the list, to a kinematic body, with a negative CFM. */
    j = dJointCreateBall(world, 0);
    dJointAttach(j, bodies[0], bodies[1]);
    dJointSetBallAnchor(j, 1.5, 0, 0.5);
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 1, &c, 1, 0.01, &info),
           CADMM_ERR_INVALID_VALUE, "its other body is not in the bodies list");
    dBodySetKinematic(bodies[1]);
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.01, &info), CADMM_ERR_UNSUPPORTED,
           "touches a kinematic body");
    dBodySetDynamic(bodies[1]);
    dJointSetBallParam(j, dParamCFM, -1e-3);
    expect(ctx, cadmm_ode_step(ctx, world, bodies, 2, &c, 1, 0.01, &info),
           CADMM_ERR_INVALID_VALUE, "negative CFM");
    dJointDestroy(j);

    /* Contact surfaces (cadmm_ode_assemble_contacts): the modes the problem cannot
     * express, a NaN rolling coefficient, and a mu that is not a friction coefficient. */
    dContact full;
    memset(&full, 0, sizeof full);
    full.geom = c;
    full.surface.mu = 0.3;
    full.surface.mode = dContactRolling | dContactAxisDep;
    full.surface.mu2 = 0.2;
    full.surface.rho = full.surface.rho2 = full.surface.rhoN = 0.01;
    expect(ctx, cadmm_ode_assemble_contacts(ctx, world, bodies, 2, &full, 1, 0.01),
           CADMM_ERR_UNSUPPORTED, "dContactMu2/dContactAxisDep with mu2 = 0.2 != mu = 0.3");
    full.surface.mu2 = 0.3;
    full.surface.rhoN = NAN;
    expect(ctx, cadmm_ode_assemble_contacts(ctx, world, bodies, 2, &full, 1, 0.01),
           CADMM_ERR_INVALID_VALUE, "rolling friction coefficient (rho, rho2, rhoN) is NaN");
    full.surface.mode = dContactBounce;
    expect(ctx, cadmm_ode_assemble_contacts(ctx, world, bodies, 2, &full, 1, 0.01),
           CADMM_ERR_UNSUPPORTED, "dContactBounce");
    full.surface.mode = dContactApprox1;
    full.surface.mu = dInfinity;
    expect(ctx, cadmm_ode_assemble_contacts(ctx, world, bodies, 2, &full, 1, 0.01),
           CADMM_ERR_INVALID_VALUE, "surface.mu");
    /* dContactApprox1 is accepted, and each contact keeps its own mu. */
    full.surface.mu = 0.3;
    cadmm_ode_problem problem;
    cadmm_result got = cadmm_ode_assemble_contacts(ctx, world, bodies, 2, &full, 1, 0.01);
    if (got == CADMM_OK) got = cadmm_ode_last_problem(ctx, &problem);
    if (got != CADMM_OK || problem.n_contacts != 1 || problem.mu[0] != 0.3) {
        printf("FAIL: a dContact with dContactApprox1 and mu 0.3: code %d, %s\n", got,
               cadmm_ode_last_error(ctx));
        failures++;
    } else {
        printf("ok: a dContact with dContactApprox1 is taken with its mu %.2g\n", problem.mu[0]);
    }

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
