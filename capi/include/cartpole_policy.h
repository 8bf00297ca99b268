/* cartpole_policy.h: the C API of the cart-pole balance controller, from the Rust crate
 * `firmware`. Link libcartpole_policy.a (cargo build --release -p capi --target <target>).
 *
 * Call once per control period of the rig the policy was trained for (the shipped
 * policy's is shipped::policy::RIG.params.tau) with the state obs = {x (m), x_dot (m/s),
 * theta (rad), theta_dot (rad/s)}; push the cart right (+x) with the full force iff
 * q[1] > q[0]. Allocation-free, no global state, safe to call from an interrupt; a few
 * hundred bytes of stack (measured per target in docs/QUANTISATION.md). The caller checks
 * its readings: a NaN anywhere in one gives finite Q-values that answer the network's biases
 * alone (ReLU takes each first-layer unit's NaN to 0), a push either way that means nothing;
 * cartpole_controller_step checks its readings itself and coasts on one that is not finite.
 * A NULL argument makes a call write nothing.
 *
 * cartpole_policy_forward runs the policy compiled into the library. cartpole_mlpH_forward
 * runs any weights of width H, such as the `static const struct cartpole_mlpH` that
 * `policy-export export --format c` writes, and cartpole_mlp64xA_forward those of a policy
 * of A duty levels (q[A]); the structs and functions below are declared as
 * those headers declare them (guarded, so both can be included). Every function computes the
 * Rust firmware's forward pass, bit for bit. cartpole_policy_forward_int and
 * cartpole_qmlpH_forward are the integer network's (`export --quant int8` headers). The
 * exported headers carry the machine the policy was trained for too, a struct cartpole_rig
 * (declared here as there), which the whole controller below is built on.
 */
#ifndef CARTPOLE_POLICY_H
#define CARTPOLE_POLICY_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* obs: 4 floats, read only; q: 2 floats, written. */
void cartpole_policy_forward(const float obs[4], float q[2]);

/* The same policy in integers, for cores without an FPU: obs in Q3.12 (SI units times 4096,
 * saturated to int16), q = the advantages Q - mean(Q) in the integer network's scale; push
 * right iff q[1] > q[0]. No floating-point operation. */
void cartpole_policy_forward_int(const int16_t obs[4], int32_t q[2]);

#ifdef __cplusplus
}
#endif

/* One macro per network format declares a shape's struct and function as every exported
 * header of that shape does: S names the shape (the width H for the paper's two outputs,
 * HxA for A outputs); each expansion sits under the exported headers' own guard, so either
 * header may come first. The macros are undefined at the end: they are not the header's to
 * export. */
#ifdef __cplusplus
#define CARTPOLE_EXTERN_C extern "C"
#else
#define CARTPOLE_EXTERN_C
#endif

/* A 4-H-H-A Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<H, A>.
 * q = the A Q-values of w, one per duty level (two: [Q(obs, left), Q(obs, right)]), in
 * the Rust firmware's summation order (bit for bit); the largest drives its level (two:
 * push right iff q[1] > q[0]). From libcartpole_policy.a. A NULL argument makes it write
 * nothing. */
#define CARTPOLE_DECLARE_MLP(S, H, A)                                               \
    struct cartpole_mlp##S {                                                        \
        float fc1_weight[H][4];                                                     \
        float fc1_bias[H];                                                          \
        float fc2_weight[H][H];                                                     \
        float fc2_bias[H];                                                          \
        float fc3_weight[A][H];                                                     \
        float fc3_bias[A];                                                          \
    };                                                                              \
    CARTPOLE_EXTERN_C void cartpole_mlp##S##_forward(const struct cartpole_mlp##S *w,\
                                                     const float obs[4], float q[A])

/* A 4-H-H-A Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<H, A>.
 * q = the A outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * the largest drives its level (two: push right iff q[1] > q[0]). No floating point.
 * From libcartpole_policy.a; a NULL argument makes it write nothing. */
#define CARTPOLE_DECLARE_QMLP(S, H, A)                                              \
    struct cartpole_qmlp##S {                                                       \
        int32_t fc1_bias[H];                                                        \
        int32_t fc2_bias[H];                                                        \
        int32_t fc3_bias[A];                                                        \
        struct cartpole_requant fc1_requant[H];                                     \
        struct cartpole_requant fc2_requant[H];                                     \
        int8_t fc1_weight[H][4];                                                    \
        int8_t fc2_weight[H][H];                                                    \
        int8_t fc3_weight[A][H];                                                    \
    };                                                                              \
    CARTPOLE_EXTERN_C void cartpole_qmlp##S##_forward(const struct cartpole_qmlp##S *w,\
                                                      const int16_t obs[4], int32_t q[A])

#ifndef CARTPOLE_MLP16_DEFINED
#define CARTPOLE_MLP16_DEFINED
CARTPOLE_DECLARE_MLP(16, 16, 2);
#endif
#ifndef CARTPOLE_MLP64_DEFINED
#define CARTPOLE_MLP64_DEFINED
CARTPOLE_DECLARE_MLP(64, 64, 2);
#endif
#ifndef CARTPOLE_MLP128_DEFINED
#define CARTPOLE_MLP128_DEFINED
CARTPOLE_DECLARE_MLP(128, 128, 2);
#endif
#ifndef CARTPOLE_MLP64X3_DEFINED
#define CARTPOLE_MLP64X3_DEFINED
CARTPOLE_DECLARE_MLP(64x3, 64, 3);
#endif
#ifndef CARTPOLE_MLP64X5_DEFINED
#define CARTPOLE_MLP64X5_DEFINED
CARTPOLE_DECLARE_MLP(64x5, 64, 5);
#endif
#ifndef CARTPOLE_MLP64X7_DEFINED
#define CARTPOLE_MLP64X7_DEFINED
CARTPOLE_DECLARE_MLP(64x7, 64, 7);
#endif
#ifndef CARTPOLE_MLP64X9_DEFINED
#define CARTPOLE_MLP64X9_DEFINED
CARTPOLE_DECLARE_MLP(64x9, 64, 9);
#endif

#ifndef CARTPOLE_REQUANT_DEFINED
#define CARTPOLE_REQUANT_DEFINED
#include <stdint.h>
/* acc -> u8 activation: t = min(max(acc, 0) >> pre_shift, 32767);
 * y = min((t * multiplier + (2^post_shift >> 1)) >> post_shift, 255), in uint32_t. */
struct cartpole_requant {
    uint16_t multiplier;
    uint8_t pre_shift;
    uint8_t post_shift;
};
#endif

#ifndef CARTPOLE_QMLP16_DEFINED
#define CARTPOLE_QMLP16_DEFINED
CARTPOLE_DECLARE_QMLP(16, 16, 2);
#endif
#ifndef CARTPOLE_QMLP64_DEFINED
#define CARTPOLE_QMLP64_DEFINED
CARTPOLE_DECLARE_QMLP(64, 64, 2);
#endif
#ifndef CARTPOLE_QMLP128_DEFINED
#define CARTPOLE_QMLP128_DEFINED
CARTPOLE_DECLARE_QMLP(128, 128, 2);
#endif
#ifndef CARTPOLE_QMLP64X3_DEFINED
#define CARTPOLE_QMLP64X3_DEFINED
CARTPOLE_DECLARE_QMLP(64x3, 64, 3);
#endif
#ifndef CARTPOLE_QMLP64X5_DEFINED
#define CARTPOLE_QMLP64X5_DEFINED
CARTPOLE_DECLARE_QMLP(64x5, 64, 5);
#endif
#ifndef CARTPOLE_QMLP64X7_DEFINED
#define CARTPOLE_QMLP64X7_DEFINED
CARTPOLE_DECLARE_QMLP(64x7, 64, 7);
#endif
#ifndef CARTPOLE_QMLP64X9_DEFINED
#define CARTPOLE_QMLP64X9_DEFINED
CARTPOLE_DECLARE_QMLP(64x9, 64, 9);
#endif

#ifndef CARTPOLE_RIG_DEFINED
#define CARTPOLE_RIG_DEFINED
#include <stdint.h>
/* A cart-pole machine as its board sees it, the fields of Rust's firmware::rig::Rig in
 * its order: the physics, the encoders, the dead time, the end-stop margin, the
 * observer's tuning. */
struct cartpole_rig {
    /* gravitational acceleration, m/s^2 */
    double gravity;
    /* the cart's mass, kg */
    double masscart;
    /* the pole's mass, kg */
    double masspole;
    /* pivot to the pole's centre of mass, m (half a uniform pole's length) */
    double length;
    /* the motor's force on the cart at full duty and standstill (its stall force), N */
    double force_mag;
    /* the force the cart's speed takes from the motor's (back-EMF, drag), N s/m */
    double motor_damping;
    /* the control period, s */
    double tau;
    /* the pole has fallen beyond this angle from upright, rad */
    double theta_threshold_radians;
    /* the end stops' distance from the track's centre, m */
    double x_threshold;
    /* Coulomb friction between cart and track, dimensionless */
    double cart_friction;
    /* viscous friction at the pivot, N m s/rad */
    double pole_friction;
    /* cart encoder counts per metre of travel */
    uint32_t cart_counts_per_m;
    /* pole encoder counts per revolution of the pivot */
    uint32_t pole_counts_per_rev;
    /* periods from the reading a command is decided on to the motor applying it */
    uint32_t dead_time;
    /* how near an end stop the controller stops pushing and coasts, m */
    double end_stop_margin;
    /* observer: standard deviation of an unmodelled force on the cart, N */
    double force_sd;
    /* observer: standard deviations of unmodelled accelerations of the cart (m/s^2)
     * and of the pole (rad/s^2) */
    double accel_sd[2];
};
#endif

#undef CARTPOLE_DECLARE_QMLP
#undef CARTPOLE_DECLARE_MLP
#undef CARTPOLE_EXTERN_C

/* The whole controller: one control period of the Rust firmware's
 * firmware::controller::Controller::step, the period the trainer, the simulator, the
 * self-test and the Rust boards run, built from a policy and the rig it was trained for
 * (the observer's plant, encoders, dead time and tuning, the dead-time predictor, the
 * track's limits, the control period): the shipped policy and its RIG, or an exported
 * header's weights and struct cartpole_rig (cartpole_controller_init_mlpH; for a policy of
 * more outputs, its levels too: cartpole_controller_init_mlp64xA). A board:
 *
 *     static cartpole_controller_t ctl;
 *     uint32_t period_us;
 *     cartpole_controller_init(&ctl, CARTPOLE_POLICY_INT);   once, at start-up
 *     cartpole_controller_period_us(&ctl, &period_us);       start a timer at this period
 *     each period:
 *         cartpole_command_t cmd;
 *         cartpole_controller_step(&ctl, cart_counts(), pole_counts(), &cmd);
 *         if the direction pin changes: the enable's duty to 0 first (break before make)
 *         direction pin = cmd.direction; the enable's duty = cmd.duty of CARTPOLE_DUTY_MAX
 *         (a partial duty for a policy of more levels than the full pushes)
 *
 * Every function returns CARTPOLE_OK (0) or a negative CARTPOLE_ERR_*, and a refused call
 * writes nothing and runs nothing. No heap, no global state: each cartpole_controller_t is
 * one controller, caller-allocated (static, or on a stack that outlives its use); copying
 * one copies the controller. Steps of one instance must not run concurrently. */

/* The bytes of cartpole_controller_t, on every target: the library checks at compile time
 * that each policy's controller fits. Its alignment is its union's: that of uint64_t, double
 * and void * (8 on Cortex-M, RISC-V and 64-bit hosts). */
#define CARTPOLE_CONTROLLER_SIZE 1152
/* Full scale of cartpole_command_t's duty: the motor's full push. */
#define CARTPOLE_DUTY_MAX 1000
/* The fault bits of cartpole_command_t: channel (0 x, 1 x_dot, 2 theta, 3 theta_dot) NaN or
 * infinite, or beyond the rig's limits (near the track's end stops, a fallen pole). */
#define CARTPOLE_FAULT_NON_FINITE(channel) (1u << (channel))
#define CARTPOLE_FAULT_OUT_OF_RANGE(channel) (1u << (4 + (channel)))
/* Under the runtime monitor (cartpole_controller_monitor): the period was decided by the LQR
 * fallback; the monitor has stopped the controller (duty off); the reading came from the
 * observer's model alone, its encoders found frozen. */
#define CARTPOLE_FAULT_FALLBACK (1u << 10)
#define CARTPOLE_FAULT_STOPPED (1u << 11)
#define CARTPOLE_FAULT_MODEL_ONLY (1u << 12)

/* Return codes. */
enum cartpole_status {
    CARTPOLE_OK = 0,
    CARTPOLE_ERR_NULL = -1,          /* a pointer argument was NULL */
    CARTPOLE_ERR_UNINITIALISED = -2, /* c was not initialised by a cartpole_controller_init* */
    CARTPOLE_ERR_POLICY_KIND = -3,   /* no such policy kind */
    CARTPOLE_ERR_INPUT = -4,         /* counts to an instance that has read states, or back */
    CARTPOLE_ERR_RIG = -5,           /* a struct cartpole_rig field no machine has, or no
                                        finite observer gain for the rig; to
                                        cartpole_controller_monitor, another rig than c's */
    CARTPOLE_ERR_ENVELOPE = -6,      /* an envelope bound NaN, infinite or negative; the
                                        runtime monitor and refined levels together */
    CARTPOLE_ERR_LEVELS = -7,        /* duty levels not one per output, beyond [-1000, 1000]
                                        or not strictly increasing; refined levels asked of
                                        a two-output policy */
    CARTPOLE_ERR_NO_STARTUP = -8,    /* cartpole_controller_phase without a start-up */
    CARTPOLE_ERR_FLAGS = -9          /* cartpole_controller_startup flags other than
                                        CARTPOLE_STARTUP_*, or cartpole_controller_refine's
                                        on neither 0 nor 1 */
};

/* The shipped policies. */
enum cartpole_policy_kind {
    CARTPOLE_POLICY_F32 = 1, /* the float network (a core with an FPU) */
    CARTPOLE_POLICY_INT = 2  /* the integer network, integer from the estimate to the decision */
};

/* cartpole_command_t's command. */
enum cartpole_push {
    CARTPOLE_PUSH_LEFT = -1,
    CARTPOLE_COAST = 0, /* duty off: the reading was rejected */
    CARTPOLE_PUSH_RIGHT = 1
};

/* One controller; opaque. Initialise it with cartpole_controller_init (or _init_mlpH,
 * _init_qmlpH) before any other call: others refuse memory no init initialised
 * (CARTPOLE_ERR_UNINITIALISED). */
typedef struct cartpole_controller {
    union {
        unsigned char bytes[CARTPOLE_CONTROLLER_SIZE];
        uint64_t align_u64;
        double align_double;
        void *align_pointer;
    } opaque;
} cartpole_controller_t;

/* What one period decided and what its H-bridge pins are now. */
typedef struct cartpole_command {
    int32_t command;    /* the commanded duty's sign: CARTPOLE_PUSH_LEFT, CARTPOLE_COAST (also a
                           level of zero duty) or CARTPOLE_PUSH_RIGHT */
    uint32_t direction; /* direction pin: 1 high (pushes towards +x), 0 low; kept when coasting */
    uint32_t duty;      /* enable's duty: 0 (off) to CARTPOLE_DUTY_MAX (the full push) */
    uint32_t faults;    /* CARTPOLE_FAULT_* bits of this period's reading; 0 if accepted */
    float q[2];         /* the float policy's [Q(left), Q(right)]; NaN if rejected; 0 for int;
                           0 for a policy of more than two outputs (see its _forward) */
    int32_t q_int[2];   /* the integer policy's outputs; 0 if rejected; 0 for float; 0 for a
                           policy of more than two outputs */
    uint32_t step;      /* the period's number, from 0 */
    int32_t signed_duty; /* the commanded duty in thousandths of the full push, + towards +x:
                            the chosen output's level (-1000 or 1000 of two outputs); 0 when
                            coasting. The pins' direction and duty drive it. */
} cartpole_command_t;

/* Totals since cartpole_controller_init; they saturate rather than wrap. */
typedef struct cartpole_counters {
    uint32_t steps;             /* periods run */
    uint32_t rejected_readings; /* periods that coasted on a rejected reading */
    uint32_t sensor_errors;     /* readings the sensor failed to give */
    uint32_t non_finite;        /* channels read as NaN or infinite */
    uint32_t out_of_range;      /* channels read beyond the rig's limits */
    uint32_t actuator_errors;   /* periods whose pin or duty write failed */
    uint32_t overruns;          /* ticks reported by cartpole_controller_record_overruns */
    uint32_t model_only;        /* readings from the model alone, encoders frozen (monitored) */
    uint32_t fallbacks;         /* switches from the policy to the LQR fallback */
    uint32_t recoveries;        /* switches back to the policy */
    uint32_t fallback_periods;  /* periods the fallback decided */
    uint32_t non_finite_scores; /* periods whose policy scores were not finite */
    uint32_t safe_stops;        /* times the monitor stopped the controller */
} cartpole_counters_t;

/* cartpole_phase_t's phase: where the start-up (cartpole_controller_startup) is. */
enum cartpole_phase {
    CARTPOLE_PHASE_ZEROING = 0,     /* motor off, taking the pole's hanging zero */
    CARTPOLE_PHASE_WAITING = 1,     /* motor off until a hand lifts the pole into the catch
                                       region */
    CARTPOLE_PHASE_SWINGING_UP = 2, /* the energy-based swing-up drives */
    CARTPOLE_PHASE_CATCHING = 3,    /* inside the catch region, not yet for long enough */
    CARTPOLE_PHASE_BALANCING = 4,   /* the balance controller drives */
    CARTPOLE_PHASE_FALLEN = 5,      /* motor off until the pole is below horizontal */
    CARTPOLE_PHASE_HOMING = 6       /* the cart driven against the -x end stop, then to the
                                       centre */
};

/* The start-up's phase after the last step, and its transitions since it began. */
typedef struct cartpole_phase_state {
    uint32_t phase;   /* enum cartpole_phase */
    uint32_t zeroed;  /* zeros taken */
    uint32_t entered; /* entries into the catch region */
    uint32_t caught;  /* hand-overs to the balance controller */
    uint32_t missed;  /* catches abandoned before the hand-over */
    uint32_t fell;    /* falls while balancing: past the release angle or the track's end */
    float trim;       /* the pole's zero refined while balancing so far, rad: integral action
                         that keeps the cart centred */
    uint32_t homed;   /* centres found by homing */
} cartpole_phase_t;

#ifdef __cplusplus
extern "C" {
#endif

/* Makes *c a controller of the shipped policy policy_kind (enum cartpole_policy_kind) that
 * has run no period; again on an instance, starts it afresh. Solves the observer's gain:
 * call it at start-up, not in the control interrupt (CARTPOLE_ERR_RIG, writing nothing,
 * should it not be finite; the shipped rigs' is). */
int cartpole_controller_init(cartpole_controller_t *c, int policy_kind);

/* The same for a policy of one's own: the weights w and the machine rig it was trained for,
 * NAME and NAME_rig of a header `policy-export export --format c` wrote (--quant int8: the
 * qmlp functions, integer from the estimate to the decision), built as the shipped policy's:
 * the rig's observer, its dead-time predictor if dead_time > 0, its limits, its period.
 * Solves the observer's gain: call it at start-up, not in the control interrupt.
 *
 * *c keeps w, not a copy: the weights must outlive the controller and every copy of it (the
 * exported headers' static const ones do). *rig is read during the call only.
 *
 * Refused with CARTPOLE_ERR_RIG, writing nothing, unless every field of *rig is finite and
 * within these ranges (a rig file's are narrower at their low ends: a gram, a millimetre):
 * gravity (0, 100], masscart and masspole (0, 1000],
 * length (0, 100], force_mag (0, 1e4], motor_damping [0, 1e4], tau [0.002, 0.05],
 * theta_threshold_radians (0, pi/2], x_threshold (0, 100], cart_friction [0, 1],
 * pole_friction [0, 0.1], cart_counts_per_m [16, 2^26], pole_counts_per_rev [16, 2^24],
 * dead_time [0, 16], end_stop_margin [0, x_threshold), force_sd and accel_sd (0, 1e4],
 * and unless the observer's Kalman gain for them is finite (a cart and a pole of 1e-300 kg,
 * each within its range, overflow it). */
int cartpole_controller_init_mlp16(cartpole_controller_t *c, const struct cartpole_mlp16 *w,
                                   const struct cartpole_rig *rig);
int cartpole_controller_init_mlp64(cartpole_controller_t *c, const struct cartpole_mlp64 *w,
                                   const struct cartpole_rig *rig);
int cartpole_controller_init_mlp128(cartpole_controller_t *c, const struct cartpole_mlp128 *w,
                                    const struct cartpole_rig *rig);
int cartpole_controller_init_qmlp16(cartpole_controller_t *c, const struct cartpole_qmlp16 *w,
                                    const struct cartpole_rig *rig);
int cartpole_controller_init_qmlp64(cartpole_controller_t *c, const struct cartpole_qmlp64 *w,
                                    const struct cartpole_rig *rig);
int cartpole_controller_init_qmlp128(cartpole_controller_t *c,
                                     const struct cartpole_qmlp128 *w,
                                     const struct cartpole_rig *rig);

/* The same for a policy of A > 2 outputs, each driving a duty level: NAME, NAME_levels and
 * NAME_rig of an exported header, output i driving levels[i] thousandths of the full push
 * (+ towards +x); levels points at n_levels int16_t, read during the call only. Refused,
 * writing nothing: CARTPOLE_ERR_LEVELS unless n_levels is A and the levels lie in
 * [-1000, 1000], strictly increasing; CARTPOLE_ERR_RIG as above. cartpole_controller_step
 * then drives the chosen output's level: cmd.signed_duty, the pins' partial duty. */
#define CARTPOLE_DECLARE_INIT(S)                                                        \
    int cartpole_controller_init_mlp##S(cartpole_controller_t *c,                       \
                                        const struct cartpole_mlp##S *w,                \
                                        const int16_t *levels, uint32_t n_levels,       \
                                        const struct cartpole_rig *rig);                \
    int cartpole_controller_init_qmlp##S(cartpole_controller_t *c,                      \
                                         const struct cartpole_qmlp##S *w,              \
                                         const int16_t *levels, uint32_t n_levels,      \
                                         const struct cartpole_rig *rig)
CARTPOLE_DECLARE_INIT(64x3);
CARTPOLE_DECLARE_INIT(64x5);
CARTPOLE_DECLARE_INIT(64x7);
CARTPOLE_DECLARE_INIT(64x9);
#undef CARTPOLE_DECLARE_INIT

/* One control period on this period's encoder counts (cart: counts per metre of travel,
 * pole: counts per revolution, zero upright, as the RIG's encoders; the first counts are
 * taken at rest), read through the rig's observer; the command in *out. Under a start-up
 * (cartpole_controller_startup), the counts as the encoders count from power-on, and the
 * period the start-up's: cartpole_controller_phase says which. */
int cartpole_controller_step(cartpole_controller_t *c, int32_t cart_counts,
                             int32_t pole_counts, cartpole_command_t *out);

/* The same period on a measured state {x (m), x_dot (m/s), theta (rad), theta_dot
 * (rad/s)}, for a board that reads the state, not encoders. A NaN, infinite or out-of-range
 * channel is not an error: the controller rejects the reading, coasts and flags it. The
 * integer policy takes the state in Q3.12 (SI units times 4096, rounded, saturated), where
 * a channel NaN or beyond the format is flagged out of range. An instance reads counts or
 * states, whichever its first step was given; under a start-up, counts
 * (CARTPOLE_ERR_INPUT). */
int cartpole_controller_step_state(cartpole_controller_t *c, const float state[4],
                                   cartpole_command_t *out);

/* The totals in *out. */
int cartpole_controller_counters(const cartpole_controller_t *c, cartpole_counters_t *out);

/* Counts ticks timer ticks that arrived while the last step still ran: the loop pacing the
 * controller knows them, the controller does not. */
int cartpole_controller_record_overruns(cartpole_controller_t *c, uint32_t ticks);

/* The control period of the rig the policy was trained for, in microseconds (rounded). */
int cartpole_controller_period_us(const cartpole_controller_t *c, uint32_t *period_us);

/* Puts *c under the runtime monitor from its next period (docs/FAULTS.md): the policy drives
 * while the reading lies inside envelope {x (m), x_dot (m/s), theta (rad), theta_dot
 * (rad/s)}, bounds on each channel's magnitude (NULL: the shipped policy's, measured by
 * `host-sim envelope`); LQR designed for rig drives outside it (its force as the nearest of
 * the policy's duty levels or full duty: bang-bang for two levels), after 3 faulty
 * readings in a row and on non-finite scores, until 25 sound periods inside 0.8 of the
 * envelope; 3 readings in a row past the rig's failure angle or at the end of its track
 * stop the controller (duty off) until it is initialised again. The observer then watches
 * for frozen encoders. rig must be the machine c was initialised for (NAME_rig; NULL: the
 * shipped policies'). Solves the LQR gain: call it at start-up. Refused, writing nothing:
 * CARTPOLE_ERR_ENVELOPE (also for an instance whose levels are refined), CARTPOLE_ERR_RIG (a
 * rig no machine has, or not c's). */
int cartpole_controller_monitor(cartpole_controller_t *c, const float envelope[4],
                                const struct cartpole_rig *rig);

/* With on 1, *c's policy drives from its next step the duty between its levels where its
 * scores peak (the parabola through the chosen output's score and its two neighbours';
 * docs/CONTROL.md, "Between the levels"), never past the midpoints the chosen level shares
 * with them; the end levels drive themselves. With on 0, its levels again (as initialised).
 * Refused, writing nothing: CARTPOLE_ERR_FLAGS (on neither 0 nor 1); with on 1,
 * CARTPOLE_ERR_LEVELS (a policy of two outputs, both ends) and CARTPOLE_ERR_ENVELOPE (under
 * the runtime monitor, whose envelope is measured for the plain levels). */
int cartpole_controller_refine(cartpole_controller_t *c, int on);

/* cartpole_controller_startup's flags, or'ed. */
#define CARTPOLE_STARTUP_SWING_UP 1 /* swing the pole up rather than wait for a hand */
#define CARTPOLE_STARTUP_HOME 2     /* first drive the cart gently against the -x end stop,
                                       then to the centre, instead of centring it by hand */

/* Runs *c's next steps inside the start-up from power-on (docs/STARTUP.md), its values
 * suggested for rig (the machine c was initialised for; NULL: the shipped policies'): the
 * cart homed (CARTPOLE_STARTUP_HOME), motor off while the pole's zero is taken hanging (at
 * rest or swinging), then the pole swung up (CARTPOLE_STARTUP_SWING_UP) or waited for until
 * a hand lifts it into the catch region, caught, balanced, and after a fall (past the
 * release angle, the cart at its track's end) motor off until the pole is down, then again.
 * Steps then take counts as the encoders count from power-on: centre the cart before it,
 * unless it homes. Refused, writing nothing: CARTPOLE_ERR_FLAGS (other bits),
 * CARTPOLE_ERR_RIG (a rig no machine has, or not c's), CARTPOLE_ERR_INPUT (c has read
 * states). */
int cartpole_controller_startup(cartpole_controller_t *c, const struct cartpole_rig *rig,
                                int flags);

/* The start-up's phase and transitions in *out. Refused, writing nothing:
 * CARTPOLE_ERR_NO_STARTUP. */
int cartpole_controller_phase(const cartpole_controller_t *c, cartpole_phase_t *out);

#ifdef __cplusplus
}
#endif

#endif /* CARTPOLE_POLICY_H */
