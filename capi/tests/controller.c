/* The whole controller through the public header, as C and as C++.
 *
 *   controller script FILE   runs FILE's calls, one a line, on one cartpole_controller_t and
 *                            prints what each returned and wrote:
 *                              init KIND | monitor | count CART POLE | state X XDOT THETA
 *                              THETADOT (f32 bits in hex) | overrun TICKS | counters | period
 *   controller refusals KIND prints the layout and the constants, then the calls the library
 *                            must refuse, their codes and whether they wrote anything. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cartpole_policy.h"

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

static void print_step(int rc, const cartpole_command_t *out) {
    uint32_t q[2];
    if (rc != CARTPOLE_OK) {
        printf("refused %d %d\n", rc, unwritten(out, sizeof *out));
        return;
    }
    memcpy(q, out->q, sizeof q);
    printf("%d %ld %lu %lu %lu %08lx %08lx %ld %ld %lu\n", rc, (long)out->command,
           (unsigned long)out->direction, (unsigned long)out->duty, (unsigned long)out->faults,
           (unsigned long)q[0], (unsigned long)q[1], (long)out->q_int[0], (long)out->q_int[1],
           (unsigned long)out->step);
}

static void print_counters(const cartpole_controller_t *c) {
    cartpole_counters_t n;
    int rc = cartpole_controller_counters(c, &n);
    printf("counters %d %lu %lu %lu %lu %lu %lu %lu", rc, (unsigned long)n.steps,
           (unsigned long)n.rejected_readings, (unsigned long)n.sensor_errors,
           (unsigned long)n.non_finite, (unsigned long)n.out_of_range,
           (unsigned long)n.actuator_errors, (unsigned long)n.overruns);
    printf(" %lu %lu %lu %lu %lu %lu\n", (unsigned long)n.model_only, (unsigned long)n.fallbacks,
           (unsigned long)n.recoveries, (unsigned long)n.fallback_periods,
           (unsigned long)n.non_finite_scores, (unsigned long)n.safe_stops);
}

static void print_phase(const cartpole_controller_t *c) {
    cartpole_phase_t p;
    uint32_t trim;
    int rc;
    memset(&p, UNWRITTEN, sizeof p);
    rc = cartpole_controller_phase(c, &p);
    if (rc != CARTPOLE_OK) {
        printf("phase refused %d %d\n", rc, unwritten(&p, sizeof p));
        return;
    }
    memcpy(&trim, &p.trim, sizeof trim);
    printf("phase %d %lu %lu %lu %lu %lu %lu %08lx %lu\n", rc, (unsigned long)p.phase,
           (unsigned long)p.zeroed, (unsigned long)p.entered, (unsigned long)p.caught,
           (unsigned long)p.missed, (unsigned long)p.fell, (unsigned long)trim,
           (unsigned long)p.homed);
}

/* One line of a script; 0 if it is none of the calls. */
static int run_line(cartpole_controller_t *c, const char *line) {
    cartpole_command_t out;
    unsigned long bits[4], ticks;
    long cart, pole;
    int kind;
    memset(&out, UNWRITTEN, sizeof out);
    if (sscanf(line, "init %d", &kind) == 1) {
        printf("init %d\n", cartpole_controller_init(c, kind));
    } else if (sscanf(line, "count %ld %ld", &cart, &pole) == 2) {
        print_step(cartpole_controller_step(c, (int32_t)cart, (int32_t)pole, &out), &out);
    } else if (sscanf(line, "state %lx %lx %lx %lx", &bits[0], &bits[1], &bits[2], &bits[3]) ==
               4) {
        uint32_t words[4];
        float state[4];
        int k;
        for (k = 0; k < 4; k++) words[k] = (uint32_t)bits[k];
        memcpy(state, words, sizeof state);
        print_step(cartpole_controller_step_state(c, state, &out), &out);
    } else if (sscanf(line, "overrun %lu", &ticks) == 1) {
        printf("overrun %d\n", cartpole_controller_record_overruns(c, (uint32_t)ticks));
    } else if (strncmp(line, "monitor", 7) == 0) {
        printf("monitor %d\n", cartpole_controller_monitor(c, NULL, NULL));
    } else if (sscanf(line, "startup %d", &kind) == 1) {
        printf("startup %d\n", cartpole_controller_startup(c, NULL, kind));
    } else if (strncmp(line, "phase", 5) == 0) {
        print_phase(c);
    } else if (strncmp(line, "counters", 8) == 0) {
        print_counters(c);
    } else if (strncmp(line, "period", 6) == 0) {
        uint32_t us = 0;
        int rc = cartpole_controller_period_us(c, &us);
        printf("period %d %lu\n", rc, (unsigned long)us);
    } else {
        return 0;
    }
    return 1;
}

static int script(const char *path) {
    static cartpole_controller_t c;
    char line[256];
    FILE *f = fopen(path, "r");
    if (f == NULL) return 2;
    while (fgets(line, sizeof line, f) != NULL) {
        if (!run_line(&c, line)) {
            fprintf(stderr, "not a call: %s", line);
            fclose(f);
            return 2;
        }
    }
    fclose(f);
    return 0;
}

struct align_probe {
    char c;
    cartpole_controller_t x;
};

static void layout(void) {
    printf("sizes %lu %lu %lu %lu\n", (unsigned long)sizeof(cartpole_controller_t),
           (unsigned long)offsetof(struct align_probe, x),
           (unsigned long)sizeof(cartpole_command_t), (unsigned long)sizeof(cartpole_counters_t));
    printf("constants %d %lu %lu %lu %d %d %d %d %d %d %d %d %d %d\n", CARTPOLE_CONTROLLER_SIZE,
           (unsigned long)CARTPOLE_DUTY_MAX, (unsigned long)CARTPOLE_FAULT_NON_FINITE(2),
           (unsigned long)CARTPOLE_FAULT_OUT_OF_RANGE(3), CARTPOLE_OK, CARTPOLE_ERR_NULL,
           CARTPOLE_ERR_UNINITIALISED, CARTPOLE_ERR_POLICY_KIND, CARTPOLE_ERR_INPUT,
           CARTPOLE_POLICY_F32, CARTPOLE_POLICY_INT, CARTPOLE_PUSH_LEFT, CARTPOLE_COAST,
           CARTPOLE_PUSH_RIGHT);
    printf("counters-offsets %lu %lu %lu %lu %lu %lu %lu %lu %lu %lu %lu %lu\n",
           (unsigned long)offsetof(cartpole_counters_t, rejected_readings),
           (unsigned long)offsetof(cartpole_counters_t, sensor_errors),
           (unsigned long)offsetof(cartpole_counters_t, non_finite),
           (unsigned long)offsetof(cartpole_counters_t, out_of_range),
           (unsigned long)offsetof(cartpole_counters_t, actuator_errors),
           (unsigned long)offsetof(cartpole_counters_t, overruns),
           (unsigned long)offsetof(cartpole_counters_t, model_only),
           (unsigned long)offsetof(cartpole_counters_t, fallbacks),
           (unsigned long)offsetof(cartpole_counters_t, recoveries),
           (unsigned long)offsetof(cartpole_counters_t, fallback_periods),
           (unsigned long)offsetof(cartpole_counters_t, non_finite_scores),
           (unsigned long)offsetof(cartpole_counters_t, safe_stops));
    printf("monitor-constants %d %d %lu %lu %lu\n", CARTPOLE_ERR_RIG, CARTPOLE_ERR_ENVELOPE,
           (unsigned long)CARTPOLE_FAULT_FALLBACK, (unsigned long)CARTPOLE_FAULT_STOPPED,
           (unsigned long)CARTPOLE_FAULT_MODEL_ONLY);
    printf("startup-constants %d %d %d %d %d %d %d %d %d %d %d %lu %lu %lu\n",
           CARTPOLE_ERR_NO_STARTUP, CARTPOLE_ERR_FLAGS, CARTPOLE_PHASE_ZEROING,
           CARTPOLE_PHASE_WAITING, CARTPOLE_PHASE_SWINGING_UP, CARTPOLE_PHASE_CATCHING,
           CARTPOLE_PHASE_BALANCING, CARTPOLE_PHASE_FALLEN, CARTPOLE_PHASE_HOMING,
           CARTPOLE_STARTUP_SWING_UP, CARTPOLE_STARTUP_HOME,
           (unsigned long)sizeof(cartpole_phase_t), (unsigned long)offsetof(cartpole_phase_t, fell),
           (unsigned long)offsetof(cartpole_phase_t, trim));
}

/* Every call on c and on NULL outputs, then whether the outputs are as they were. */
static void refused_calls(const char *what, cartpole_controller_t *c) {
    const float state[4] = {0.0f, 0.0f, 0.05f, 0.0f};
    cartpole_command_t out;
    cartpole_counters_t n;
    uint32_t us;
    int r[7];
    memset(&out, UNWRITTEN, sizeof out);
    memset(&n, UNWRITTEN, sizeof n);
    memset(&us, UNWRITTEN, sizeof us);
    r[0] = cartpole_controller_step(c, 1, 2, &out);
    r[1] = cartpole_controller_step_state(c, state, &out);
    r[2] = cartpole_controller_counters(c, &n);
    r[3] = cartpole_controller_record_overruns(c, 1);
    r[4] = cartpole_controller_period_us(c, &us);
    r[5] = cartpole_controller_monitor(c, NULL, NULL);
    r[6] = cartpole_controller_refine(c, 1);
    printf("%s %d %d %d %d %d %d %d %d\n", what, r[0], r[1], r[2], r[3], r[4], r[5], r[6],
           unwritten(&out, sizeof out) && unwritten(&n, sizeof n) && unwritten(&us, sizeof us));
}

static void refusals(int kind) {
    static cartpole_controller_t c;
    cartpole_command_t out;
    cartpole_counters_t n;
    uint32_t us;
    int r[4];
    layout();
    memset(&c, 0, sizeof c);
    refused_calls("zeroed", &c);
    memset(&c, 0xab, sizeof c);
    refused_calls("garbage", &c);
    r[0] = cartpole_controller_init(&c, 0);
    r[1] = cartpole_controller_init(&c, 3);
    r[2] = cartpole_controller_init(&c, -1);
    printf("kinds %d %d %d\n", r[0], r[1], r[2]);
    refused_calls("after-bad-kinds", &c);
    printf("init-null %d\n", cartpole_controller_init(NULL, kind));
    refused_calls("null", NULL);
    printf("init %d\n", cartpole_controller_init(&c, kind));
    memset(&out, UNWRITTEN, sizeof out);
    r[0] = cartpole_controller_step(&c, 1, 2, NULL);
    r[1] = cartpole_controller_step_state(&c, NULL, &out);
    r[2] = cartpole_controller_counters(&c, NULL);
    r[3] = cartpole_controller_period_us(&c, NULL);
    printf("null-outputs %d %d %d %d %d\n", r[0], r[1], r[2], r[3], unwritten(&out, sizeof out));
    {
        const float negative[4] = {1.0f, -1.0f, 0.1f, 1.0f};
        const float huge[4] = {1e30f, 1e38f, 1e38f, 1e38f};
        r[0] = cartpole_controller_monitor(&c, negative, NULL);
        r[1] = cartpole_controller_monitor(&c, huge, NULL);
        printf("monitor %d %d\n", r[0], r[1]);
    }
    memset(&n, 0, sizeof n);
    us = 0;
    r[0] = cartpole_controller_counters(&c, &n);
    r[1] = cartpole_controller_period_us(&c, &us);
    printf("ran %d %lu %d %lu\n", r[0], (unsigned long)n.steps, r[1], (unsigned long)us);
}

int main(int argc, char **argv) {
    if (argc == 3 && strcmp(argv[1], "script") == 0) return script(argv[2]);
    if (argc == 3 && strcmp(argv[1], "refusals") == 0) {
        refusals(atoi(argv[2]));
        return 0;
    }
    fprintf(stderr, "usage: %s script FILE | refusals KIND\n", argv[0]);
    return 2;
}
