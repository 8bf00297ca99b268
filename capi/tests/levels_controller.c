/* A policy of A > 2 outputs through the whole controller, as C and as C++: test_policy,
 * test_policy_levels and test_policy_rig of a header `policy-export export --format c`
 * wrote (exported.h), built by INIT (cartpole_controller_init_mlpHxA or _qmlpHxA, defined,
 * with A, by the file that includes this one).
 *
 *   levels steps X V T W ...   INIT, then one cartpole_controller_step_state per state, each
 *                              printed as `command direction duty signed_duty faults`
 *   levels refined X V T W ... the same, refined between the levels (cartpole_controller_refine),
 *                              after the codes of refine calls it must refuse, writing nothing
 *                              (and of the runtime monitor beside the refinement)
 *   levels unrefined X V T W . the same, refined and then not, and half way through refined
 *                              and initialised again: the levels as they are
 *   levels refusals            INIT's code on good levels, then on levels the library must
 *                              refuse, each code and whether the call wrote anything */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cartpole_policy.h"
#include "exported.h"

/* What a call that writes nothing leaves in the controller. */
#define UNWRITTEN 0x5a

static cartpole_controller_t ctl;

static int unwritten(void) {
    size_t i;
    for (i = 0; i < sizeof ctl; i++) {
        if (ctl.opaque.bytes[i] != UNWRITTEN) return 0;
    }
    return 1;
}

/* INIT on `n` levels `levels` of a controller filled with UNWRITTEN: its code, and whether
 * it left the controller as it was. */
static void refused(const int16_t *levels, uint32_t n) {
    int code;
    memset(&ctl, UNWRITTEN, sizeof ctl);
    code = INIT(&ctl, &test_policy, levels, n, &test_policy_rig);
    printf("%d %d\n", code, unwritten());
}

static int refusals(void) {
    int16_t bad[A + 1];
    int code;
    memcpy(bad, test_policy_levels, sizeof test_policy_levels);
    code = INIT(&ctl, &test_policy, test_policy_levels, A, &test_policy_rig);
    printf("%d\n", code);
    bad[1] = bad[0]; /* not strictly increasing */
    refused(bad, A);
    memcpy(bad, test_policy_levels, sizeof test_policy_levels);
    bad[0] = bad[1];
    bad[1] = test_policy_levels[0]; /* unsorted */
    refused(bad, A);
    memcpy(bad, test_policy_levels, sizeof test_policy_levels);
    bad[A - 1] = 1001; /* beyond the full push */
    refused(bad, A);
    memcpy(bad, test_policy_levels, sizeof test_policy_levels);
    bad[0] = -32768;
    refused(bad, A);
    memcpy(bad, test_policy_levels, sizeof test_policy_levels);
    refused(bad, A - 1); /* one level short */
    bad[A] = 1000;
    refused(bad, A + 1); /* one level over */
    refused(NULL, A);
    return 0;
}

static int init(void) {
    return INIT(&ctl, &test_policy, test_policy_levels, A, &test_policy_rig);
}

/* The refusals of cartpole_controller_refine, and of the runtime monitor beside it: each
 * code, and whether ctl is as it was. Leaves ctl refined. */
static void refine_refusals(void) {
    cartpole_controller_t before = ctl;
    int code = cartpole_controller_refine(&ctl, 2);
    printf("%d %d\n", code, memcmp(&before, &ctl, sizeof ctl) == 0);
    code = cartpole_controller_refine(&ctl, -1);
    printf("%d %d\n", code, memcmp(&before, &ctl, sizeof ctl) == 0);
    printf("%d\n", cartpole_controller_refine(NULL, 1));
    code = cartpole_controller_monitor(&ctl, NULL, &test_policy_rig);
    before = ctl;
    printf("%d %d", code, cartpole_controller_refine(&ctl, 1));
    printf(" %d\n", memcmp(&before, &ctl, sizeof ctl) == 0);
    code = init();
    code = code ? code : cartpole_controller_refine(&ctl, 1);
    before = ctl;
    printf("%d %d", code, cartpole_controller_monitor(&ctl, NULL, &test_policy_rig));
    printf(" %d\n", memcmp(&before, &ctl, sizeof ctl) == 0);
}

/* `refine` 1: refined after its refusals; 2: refined, then not, and half way through
 * refined and initialised again, which drives the levels as they are. */
static int steps(int argc, char **argv, int refine) {
    int k, j;
    int code = init();
    if (code == CARTPOLE_OK && refine == 1) refine_refusals();
    if (code == CARTPOLE_OK && refine == 2) {
        code = cartpole_controller_refine(&ctl, 1);
        code = code ? code : cartpole_controller_refine(&ctl, 0);
    }
    if (code != CARTPOLE_OK) {
        printf("init %d\n", code);
        return 1;
    }
    for (k = 2; k + 3 < argc; k += 4) {
        if (refine == 2 && k == 2 + 4 * ((argc - 2) / 8)) {
            code = cartpole_controller_refine(&ctl, 1);
            code = code ? code : init();
            if (code != CARTPOLE_OK) return 1;
        }
        float state[4];
        cartpole_command_t cmd;
        for (j = 0; j < 4; j++) state[j] = strtof(argv[k + j], NULL);
        code = cartpole_controller_step_state(&ctl, state, &cmd);
        if (code != CARTPOLE_OK) {
            printf("step %d\n", code);
            return 1;
        }
        printf("%ld %lu %lu %ld %lu\n", (long)cmd.command, (unsigned long)cmd.direction,
               (unsigned long)cmd.duty, (long)cmd.signed_duty, (unsigned long)cmd.faults);
    }
    return 0;
}

int main(int argc, char **argv) {
    if (argc >= 2 && strcmp(argv[1], "steps") == 0) return steps(argc, argv, 0);
    if (argc >= 2 && strcmp(argv[1], "refined") == 0) return steps(argc, argv, 1);
    if (argc >= 2 && strcmp(argv[1], "unrefined") == 0) return steps(argc, argv, 2);
    if (argc >= 2 && strcmp(argv[1], "refusals") == 0) return refusals();
    return 2;
}
