/* The processor-in-the-loop target in C: the link of docs/LINK.md written from the
 * document (COBS, CRC-32, the messages, the session's rules, the FNV-1a digests), the
 * controller from the C API (cartpole_controller_t, libcartpole_policy.a), the policy and
 * rig from headers `policy-export export --format c` wrote. It answers a host's world as the
 * Rust application does (selftest-app's pil), over the semihosting console in QEMU's
 * mps2-an386, timed on SysTick; `host-sim eval --pil qemu:thumbv7em-none-eabihf --pil-elf
 * c-pil.elf` drives it and compares every answer with the Rust reference (docs/PIL.md).
 *
 * What the C API has no call for is refused with reason 10: a Missed reading, the
 * alpha-beta filter, a dead time without the predictor; and what it refuses: refined
 * levels, the shipped policy's two being both ends. */

#include <stdint.h>
#include <string.h>

#include "cartpole_policy.h"
#include "shipped.h"
#include "shipped_int.h"

enum { MAX_FRAME = 56, MAX_PAYLOAD = 50, VERSION = 3, CLOCK_HZ = 25000000 };
/* A reply's body before its scores, and the most scores it carries. */
enum { REPLY_FIXED = 10, MAX_OUTPUTS = 9 };
enum { HELLO = 0x01, START = 0x02, STATE = 0x03, COUNTS = 0x04, MISSED = 0x05 };
enum { INFO = 0x81, STARTED = 0x82, REPLY = 0x83, REFUSED = 0xFF };
enum { R_VERSION = 1, R_KIND = 2, R_LENGTH = 3, R_CRC = 4, R_OVERSIZED = 5, R_ENCODING = 6 };
enum { R_SEQUENCE = 7, R_NOT_STARTED = 8, R_MODE = 9, R_UNSUPPORTED = 10 };

/* ---- semihosting and the clock ---- */

static int semihost(int op, void *args)
{
    register int r0 __asm("r0") = op;
    register void *r1 __asm("r1") = args;
    __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void semihosting_exit(int status)
{
    /* SYS_EXIT with ADP_Stopped_ApplicationExit or ADP_Stopped_RunTimeErrorUnknown. */
    semihost(0x18, (void *)(uintptr_t)(status == 0 ? 0x20026 : 0x20023));
    for (;;) {
    }
}

static int console(uint32_t mode)
{
    uint32_t args[3] = {(uint32_t)(uintptr_t) ":tt", mode, 3};
    return semihost(0x01, args);
}

#define SYST_CSR (*(volatile uint32_t *)0xE000E010)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018)

/* SysTick counts down from 2^24 - 1 at the core clock; this counts up. */
static uint32_t now(void)
{
    return 0xFFFFFFu - SYST_CVR;
}

/* ---- the frame: CRC-32, COBS ---- */

static uint32_t crc32(const uint8_t *p, uint32_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (uint32_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) {
            c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
        }
    }
    return ~c;
}

/* Decodes f[0..n) in place; the decoded length, or -1 if it is no COBS encoding. */
static int cobs_decode(uint8_t *f, int n)
{
    int in = 0, out = 0;
    while (in < n) {
        int code = f[in++];
        if (code == 0 || in + code - 1 > n) {
            return -1;
        }
        for (int k = 1; k < code; k++) {
            f[out++] = f[in++];
        }
        if (code < 0xFF && in < n) {
            f[out++] = 0;
        }
    }
    return out;
}

/* Encodes p[0..n) into out with its delimiter; the bytes written. */
static int cobs_encode(const uint8_t *p, int n, uint8_t *out)
{
    int code_at = 0, o = 1, code = 1;
    for (int i = 0; i < n; i++) {
        if (p[i] == 0) {
            out[code_at] = (uint8_t)code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = p[i];
            if (++code == 0xFF) {
                out[code_at] = (uint8_t)code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = (uint8_t)code;
    out[o++] = 0;
    return o;
}

/* ---- little-endian fields ---- */

struct writer {
    uint8_t b[MAX_PAYLOAD + 4];
    int n;
};

static void put(struct writer *w, const void *p, int n)
{
    memcpy(w->b + w->n, p, (size_t)n);
    w->n += n;
}

static uint32_t u32_at(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* ---- the digests: FNV-1a 64 over the parameters' bytes (docs/LINK.md) ---- */

static uint64_t fnv(uint64_t h, const void *p, uint32_t n)
{
    const uint8_t *b = p;
    for (uint32_t i = 0; i < n; i++) {
        h = (h ^ b[i]) * 0x100000001B3ull;
    }
    return h;
}

#define FNV_START 0xCBF29CE484222325ull
#define FIELD(h, x) fnv((h), &(x), sizeof(x))

static uint64_t mlp_digest(const struct cartpole_mlp64 *m)
{
    uint64_t h = FIELD(FNV_START, m->fc1_weight);
    h = FIELD(h, m->fc1_bias);
    h = FIELD(h, m->fc2_weight);
    h = FIELD(h, m->fc2_bias);
    h = FIELD(h, m->fc3_weight);
    return FIELD(h, m->fc3_bias);
}

/* Each requant is its multiplier (two bytes, little-endian) and its two shifts: the four
 * bytes of the struct. */
static uint64_t qmlp_digest(const struct cartpole_qmlp64 *m)
{
    uint64_t h = FIELD(FNV_START, m->fc1_bias);
    h = FIELD(h, m->fc2_bias);
    h = FIELD(h, m->fc3_bias);
    h = FIELD(h, m->fc1_requant);
    h = FIELD(h, m->fc2_requant);
    h = FIELD(h, m->fc1_weight);
    h = FIELD(h, m->fc2_weight);
    return FIELD(h, m->fc3_weight);
}

/* The policy's digest goes on over the duty level of each output, in thousandths. The
 * headers of a two-output policy carry no levels: the C API's two-output controller always
 * drives the two full pushes, so they are written here. */
static const int16_t shipped_levels[2] = {-1000, 1000};

static uint64_t rig_digest(const struct cartpole_rig *r)
{
    uint64_t h = FIELD(FNV_START, r->gravity);
    const double physics[10] = {r->masscart, r->masspole, r->length, r->force_mag,
                                r->motor_damping, r->tau, r->theta_threshold_radians,
                                r->x_threshold, r->cart_friction, r->pole_friction};
    const uint32_t counts[3] = {r->cart_counts_per_m, r->pole_counts_per_rev, r->dead_time};
    const double tuning[4] = {r->end_stop_margin, r->force_sd, r->accel_sd[0], r->accel_sd[1]};
    h = FIELD(h, physics);
    h = FIELD(h, counts);
    return FIELD(h, tuning);
}

/* ---- the target: the session's rules and the controller ---- */

static struct {
    int hello, started, counts, format;
    uint16_t seq;
    int fresh_dead_time; /* the dead time `fresh` was built for; -1 for none */
    cartpole_controller_t fresh, running;
} t = {.fresh_dead_time = -1};

static int refuse(struct writer *w, int reason)
{
    uint8_t r = (uint8_t)reason;
    t.started = 0;
    put(w, &r, 1);
    return REFUSED;
}

static int info(struct writer *w, const uint8_t *body, uint16_t seq)
{
    t.seq = seq;
    t.hello = 1;
    t.started = 0;
    t.format = body[0];
    t.fresh_dead_time = -1;
    uint16_t hidden = 64;
    uint64_t network = t.format ? qmlp_digest(&shipped_int) : mlp_digest(&shipped);
    uint64_t policy = FIELD(network, shipped_levels);
    uint64_t rig = rig_digest(&shipped_rig);
    uint32_t period_ns = (uint32_t)(shipped_rig.tau * 1e9 + 0.5), clock = CLOCK_HZ;
    put(w, body, 1);
    put(w, &hidden, 2);
    put(w, &policy, 8);
    put(w, &rig, 8);
    put(w, &period_ns, 4);
    put(w, &clock, 4);
    return INFO;
}

/* A controller on the rig with `dead_time`; the last one built is copied, not solved
 * again. */
static int start(struct writer *w, const uint8_t *body, uint16_t seq)
{
    int sensing = body[0], predict = body[1] & 1, monitor = body[1] & 2, refine = body[1] & 4;
    int dead_time = body[2];
    struct cartpole_rig rig = shipped_rig;
    if (!t.hello) {
        return refuse(w, R_NOT_STARTED);
    }
    t.seq = seq;
    if (sensing == 2 || (dead_time > 0 && !predict)) {
        return refuse(w, R_UNSUPPORTED);
    }
    rig.dead_time = (uint32_t)dead_time;
    if (dead_time != t.fresh_dead_time) {
        int ok = t.format ? cartpole_controller_init_qmlp64(&t.fresh, &shipped_int, &rig)
                          : cartpole_controller_init_mlp64(&t.fresh, &shipped, &rig);
        if (ok != CARTPOLE_OK) {
            return refuse(w, R_UNSUPPORTED);
        }
        t.fresh_dead_time = dead_time;
    }
    t.running = t.fresh;
    /* The shipped policy's two levels are both ends: the library refuses to refine them. */
    if (refine && cartpole_controller_refine(&t.running, 1) != CARTPOLE_OK) {
        return refuse(w, R_UNSUPPORTED);
    }
    /* Solved on every monitored Start: an instance of the C API keeps no gain for another. */
    if (monitor && cartpole_controller_monitor(&t.running, NULL, &rig) != CARTPOLE_OK) {
        return refuse(w, R_UNSUPPORTED);
    }
    t.started = 1;
    t.counts = sensing == 1;
    return STARTED;
}

static int period(struct writer *w, int kind, const uint8_t *body, uint32_t arrived)
{
    if (kind == MISSED) {
        return refuse(w, R_UNSUPPORTED);
    }
    cartpole_command_t cmd;
    if (kind == COUNTS) {
        cartpole_controller_step(&t.running, (int32_t)u32_at(body), (int32_t)u32_at(body + 4), &cmd);
    } else {
        float state[4];
        memcpy(state, body, sizeof state);
        cartpole_controller_step_state(&t.running, state, &cmd);
    }
    uint32_t ticks = (now() - arrived) & 0xFFFFFFu;
    /* The shipped policy has no level of zero duty, so a command of 0 is a coast. */
    int16_t duty = cmd.command == CARTPOLE_COAST ? INT16_MIN : (int16_t)cmd.signed_duty;
    uint8_t type_count[2] = {(uint8_t)t.format, 2};
    uint16_t faults = (uint16_t)cmd.faults;
    put(w, &duty, 2);
    put(w, &faults, 2);
    put(w, &ticks, 4);
    put(w, type_count, 2);
    put(w, t.format ? (const void *)cmd.q_int : (const void *)cmd.q, 8);
    return REPLY;
}

/* Every kind and its body's length (docs/LINK.md; a reply's longest); -1 for an unknown
 * kind. */
static int body_len(int kind)
{
    static const uint8_t kinds[9][2] = {{HELLO, 1}, {START, 7}, {STATE, 16}, {COUNTS, 8},
                                        {MISSED, 0}, {INFO, 27}, {STARTED, 0}, {REPLY, REPLY_FIXED + 4 * MAX_OUTPUTS},
                                        {REFUSED, 1}};
    for (int i = 0; i < 9; i++) {
        if (kinds[i][0] == kind) {
            return kinds[i][1];
        }
    }
    return -1;
}

/* Whether a body of `len` bytes fits `kind` and its fields are in their ranges (a target's
 * kinds too, which are refused as kinds once read): a format, a sensing, the options, a
 * discount only with the filter, a duty or a coast, a scores' type, a count of scores the
 * length agrees with, a reason. */
static int body_valid(int kind, const uint8_t *body, int len)
{
    if (kind == REPLY) {
        int duty = (int16_t)(body[0] | body[1] << 8), count = len < REPLY_FIXED ? 0 : body[9];
        return len == REPLY_FIXED + 4 * count && count >= 1 && count <= MAX_OUTPUTS &&
               (duty == INT16_MIN || (duty >= -1000 && duty <= 1000)) && body[8] <= 1;
    }
    if (len != body_len(kind)) {
        return 0;
    }
    switch (kind) {
    case HELLO: return body[0] <= 1;
    case START: return body[0] <= 2 && body[1] <= 7 && (body[0] == 2 || u32_at(body + 3) == 0);
    case INFO: return body[0] <= 1;
    case REFUSED: return body[0] >= R_VERSION && body[0] <= R_UNSUPPORTED;
    default: return 1;
    }
}

/* A reading's checks in the session's order (started, kind, sequence), then its period. */
static int reading(struct writer *w, int kind, uint16_t s, const uint8_t *body, uint32_t arrived)
{
    if (kind >= 0x80) {
        return refuse(w, R_KIND);
    }
    if (!t.started) {
        return refuse(w, R_NOT_STARTED);
    }
    if (kind != MISSED && (kind == COUNTS) != t.counts) {
        return refuse(w, R_MODE);
    }
    if (s != (uint16_t)(t.seq + 1)) {
        return refuse(w, R_SEQUENCE);
    }
    t.seq = s;
    return period(w, kind, body, arrived);
}

/* The answer's kind, its body in w, for the payload p[0..n); *seq the answer's number. */
static int answer(const uint8_t *p, int n, uint16_t *seq, struct writer *w, uint32_t arrived)
{
    if (n < 4) {
        return refuse(w, R_LENGTH);
    }
    int kind = p[1], len = body_len(kind);
    if (p[0] != VERSION) {
        return refuse(w, R_VERSION);
    }
    if (len < 0) {
        return refuse(w, R_KIND);
    }
    if (!body_valid(kind, p + 4, n - 4)) {
        return refuse(w, R_LENGTH);
    }
    *seq = (uint16_t)(p[2] | p[3] << 8);
    switch (kind) {
    case HELLO: return info(w, p + 4, *seq);
    case START: return start(w, p + 4, *seq);
    default: return reading(w, kind, *seq, p + 4, arrived);
    }
}

/* Answers the frame f[0..n), its last byte come at `arrived`; `oversized` if bytes were
 * dropped. */
static void frame(int out, uint8_t *f, int n, int oversized, uint32_t arrived)
{
    struct writer w = {.n = 4};
    uint16_t seq = t.seq;
    int kind, got = oversized ? -1 : cobs_decode(f, n);
    if (oversized) {
        kind = refuse(&w, R_OVERSIZED);
    } else if (got < 0) {
        kind = refuse(&w, R_ENCODING);
    } else if (got < 8) {
        kind = refuse(&w, R_LENGTH);
    } else if (crc32(f, (uint32_t)got - 4) != u32_at(f + got - 4)) {
        kind = refuse(&w, R_CRC);
    } else {
        kind = answer(f, got - 4, &seq, &w, arrived);
    }
    w.b[0] = VERSION;
    w.b[1] = (uint8_t)kind;
    w.b[2] = (uint8_t)seq;
    w.b[3] = (uint8_t)(seq >> 8);
    uint32_t crc = crc32(w.b, (uint32_t)w.n);
    put(&w, &crc, 4);
    uint8_t wire[MAX_FRAME + 8];
    uint32_t args[3] = {(uint32_t)out, (uint32_t)(uintptr_t)wire, 0};
    args[2] = (uint32_t)cobs_encode(w.b, w.n, wire);
    semihost(0x05, args);
}

int main(void)
{
    int in = console(0), out = console(4);
    if (in < 0 || out < 0) {
        return 1;
    }
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 5; /* the core clock, no interrupt, enabled */
    static uint8_t buf[64], f[MAX_FRAME];
    int n = 0, oversized = 0;
    for (;;) {
        uint32_t args[3] = {(uint32_t)in, (uint32_t)(uintptr_t)buf, sizeof buf};
        int got = (int)sizeof buf - semihost(0x06, args);
        if (got <= 0) {
            return 0; /* the host closed the link */
        }
        for (int i = 0; i < got; i++) {
            if (buf[i] != 0) {
                if (n < MAX_FRAME - 1) {
                    f[n++] = buf[i];
                } else {
                    oversized = 1;
                }
                continue;
            }
            if (n > 0 || oversized) {
                frame(out, f, n, oversized, now());
            }
            n = 0;
            oversized = 0;
        }
    }
}
