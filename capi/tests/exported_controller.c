/* A policy of one's own through the whole controller, as C and as C++: the weights and the
 * rig of a header `policy-export export --format c` wrote (exported.h, test_policy and
 * test_policy_rig), built by INIT (cartpole_controller_init_mlpH or _qmlpH, defined by the
 * file that includes this one).
 *
 *   exported layout        sizeof, alignment and every field's offset of struct cartpole_rig
 *   exported rig           the bits of every field of test_policy_rig
 *   exported script FILE   INIT on a copy of test_policy_rig (overwritten at once: the
 *                          controller keeps none of it), then one step per `count CART POLE`
 *                          line, printed
 *   exported refusals      the header's codes, then the inits the library must refuse, their
 *                          codes and whether they wrote anything */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cartpole_policy.h"
#include "exported.h"

/* What a call that writes nothing leaves in its output. */
#define UNWRITTEN 0x5a

static int unwritten(const void *p, size_t n) {
    const unsigned char *b = (const unsigned char *)p;
    size_t i;
    for (i = 0; i < n; i++) {
        if (b[i] != UNWRITTEN) return 0;
    }
    return 1;
}

struct align_probe {
    char c;
    struct cartpole_rig x;
};

#define OFFSET(field) printf(" %lu", (unsigned long)offsetof(struct cartpole_rig, field))

static void layout(void) {
    printf("%lu %lu", (unsigned long)sizeof(struct cartpole_rig),
           (unsigned long)offsetof(struct align_probe, x));
    OFFSET(gravity);
    OFFSET(masscart);
    OFFSET(masspole);
    OFFSET(length);
    OFFSET(force_mag);
    OFFSET(motor_damping);
    OFFSET(tau);
    OFFSET(theta_threshold_radians);
    OFFSET(x_threshold);
    OFFSET(cart_friction);
    OFFSET(pole_friction);
    OFFSET(cart_counts_per_m);
    OFFSET(pole_counts_per_rev);
    OFFSET(dead_time);
    OFFSET(end_stop_margin);
    OFFSET(force_sd);
    OFFSET(accel_sd);
    printf("\n");
}

static void print_double(double v) {
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    printf("%08lx%08lx\n", (unsigned long)(bits >> 32), (unsigned long)(bits & 0xffffffffu));
}

static void rig(void) {
    const struct cartpole_rig *r = &test_policy_rig;
    print_double(r->gravity);
    print_double(r->masscart);
    print_double(r->masspole);
    print_double(r->length);
    print_double(r->force_mag);
    print_double(r->motor_damping);
    print_double(r->tau);
    print_double(r->theta_threshold_radians);
    print_double(r->x_threshold);
    print_double(r->cart_friction);
    print_double(r->pole_friction);
    printf("%lu\n%lu\n%lu\n", (unsigned long)r->cart_counts_per_m,
           (unsigned long)r->pole_counts_per_rev, (unsigned long)r->dead_time);
    print_double(r->end_stop_margin);
    print_double(r->force_sd);
    print_double(r->accel_sd[0]);
    print_double(r->accel_sd[1]);
}

static void print_step(int rc, const cartpole_command_t *out) {
    uint32_t q[2];
    if (rc != CARTPOLE_OK) {
        printf("refused %d\n", rc);
        return;
    }
    memcpy(q, out->q, sizeof q);
    printf("%d %ld %lu %lu %lu %08lx %08lx %ld %ld %lu\n", rc, (long)out->command,
           (unsigned long)out->direction, (unsigned long)out->duty, (unsigned long)out->faults,
           (unsigned long)q[0], (unsigned long)q[1], (long)out->q_int[0], (long)out->q_int[1],
           (unsigned long)out->step);
}

static int script(const char *path) {
    static cartpole_controller_t c;
    struct cartpole_rig copy = test_policy_rig;
    char line[256];
    long cart, pole;
    FILE *f = fopen(path, "r");
    if (f == NULL) return 2;
    printf("init %d\n", INIT(&c, &test_policy, &copy));
    memset(&copy, 0xff, sizeof copy);
    while (fgets(line, sizeof line, f) != NULL) {
        cartpole_command_t out;
        if (sscanf(line, "count %ld %ld", &cart, &pole) != 2) {
            fprintf(stderr, "not a call: %s", line);
            fclose(f);
            return 2;
        }
        print_step(cartpole_controller_step(&c, (int32_t)cart, (int32_t)pole, &out), &out);
    }
    fclose(f);
    return 0;
}

/* Each init refused on c, which holds UNWRITTEN bytes; then whether c still does, and a
 * step on it. */
static void refusals(void) {
    static cartpole_controller_t c;
    cartpole_command_t out;
    struct cartpole_rig bad[5];
    int r[8], k;
    memset(&c, UNWRITTEN, sizeof c);
    for (k = 0; k < 5; k++) bad[k] = test_policy_rig;
    bad[0].tau = NAN;
    bad[1].cart_counts_per_m = 0;
    bad[2].pole_counts_per_rev = 0;
    bad[3].masspole = -0.1;
    bad[4].dead_time = 17;
    r[0] = INIT(NULL, &test_policy, &test_policy_rig);
    r[1] = INIT(&c, NULL, &test_policy_rig);
    r[2] = INIT(&c, &test_policy, NULL);
    for (k = 0; k < 5; k++) r[3 + k] = INIT(&c, &test_policy, &bad[k]);
    printf("codes %d %d %d\n", CARTPOLE_ERR_NULL, CARTPOLE_ERR_RIG, CARTPOLE_ERR_UNINITIALISED);
    printf("refused");
    for (k = 0; k < 8; k++) printf(" %d", r[k]);
    printf(" %d\n", unwritten(&c, sizeof c));
    printf("step %d\n", cartpole_controller_step(&c, 0, 0, &out));
    printf("init %d\n", INIT(&c, &test_policy, &test_policy_rig));
}

int main(int argc, char **argv) {
    if (argc == 2 && strcmp(argv[1], "layout") == 0) {
        layout();
    } else if (argc == 2 && strcmp(argv[1], "rig") == 0) {
        rig();
    } else if (argc == 3 && strcmp(argv[1], "script") == 0) {
        return script(argv[2]);
    } else if (argc == 2 && strcmp(argv[1], "refusals") == 0) {
        refusals();
    } else {
        fprintf(stderr, "usage: %s layout | rig | script FILE | refusals\n", argv[0]);
        return 2;
    }
    return 0;
}
