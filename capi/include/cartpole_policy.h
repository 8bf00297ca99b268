/* cartpole_policy.h: the C API of the cart-pole balance controller, from the Rust crate
 * `firmware`. Link libcartpole_policy.a (cargo build --release -p capi --target <target>).
 *
 * Call once per 20 ms control period with the state obs = {x (m), x_dot (m/s), theta (rad),
 * theta_dot (rad/s)}; push the cart right (+x) with the full force iff q[1] > q[0].
 * Allocation-free, no global state, safe to call from an interrupt; about 600 bytes of stack
 * on a Cortex-M4F. The caller checks its readings: a NaN gives NaN Q-values (and "left").
 * A NULL argument makes a call write nothing.
 *
 * cartpole_policy_forward runs the policy compiled into the library. cartpole_mlpH_forward
 * runs any weights of width H, such as the `static const struct cartpole_mlpH` that
 * `policy-export export --format c` writes; the struct and function blocks below are the
 * ones those headers carry (guarded, so both can be included). Every function computes the
 * Rust firmware's forward pass, bit for bit. cartpole_policy_forward_int and
 * cartpole_qmlpH_forward are the integer network's (`export --quant int8` headers).
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

#ifndef CARTPOLE_MLP16_DEFINED
#define CARTPOLE_MLP16_DEFINED
/* A 4-16-16-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<16>. */
struct cartpole_mlp16 {
    float fc1_weight[16][4];
    float fc1_bias[16];
    float fc2_weight[16][16];
    float fc2_bias[16];
    float fc3_weight[2][16];
    float fc3_bias[2];
};
/* q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_mlp16_forward(const struct cartpole_mlp16 *w, const float obs[4], float q[2]);
#endif

#ifndef CARTPOLE_MLP32_DEFINED
#define CARTPOLE_MLP32_DEFINED
/* A 4-32-32-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<32>. */
struct cartpole_mlp32 {
    float fc1_weight[32][4];
    float fc1_bias[32];
    float fc2_weight[32][32];
    float fc2_bias[32];
    float fc3_weight[2][32];
    float fc3_bias[2];
};
/* q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_mlp32_forward(const struct cartpole_mlp32 *w, const float obs[4], float q[2]);
#endif

#ifndef CARTPOLE_MLP64_DEFINED
#define CARTPOLE_MLP64_DEFINED
/* A 4-64-64-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<64>. */
struct cartpole_mlp64 {
    float fc1_weight[64][4];
    float fc1_bias[64];
    float fc2_weight[64][64];
    float fc2_bias[64];
    float fc3_weight[2][64];
    float fc3_bias[2];
};
/* q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_mlp64_forward(const struct cartpole_mlp64 *w, const float obs[4], float q[2]);
#endif

#ifndef CARTPOLE_MLP128_DEFINED
#define CARTPOLE_MLP128_DEFINED
/* A 4-128-128-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<128>. */
struct cartpole_mlp128 {
    float fc1_weight[128][4];
    float fc1_bias[128];
    float fc2_weight[128][128];
    float fc2_bias[128];
    float fc3_weight[2][128];
    float fc3_bias[2];
};
/* q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_mlp128_forward(const struct cartpole_mlp128 *w, const float obs[4], float q[2]);
#endif

#ifndef CARTPOLE_MLP256_DEFINED
#define CARTPOLE_MLP256_DEFINED
/* A 4-256-256-2 Q-network in PyTorch's nn.Linear layout (weight[out][in]); the layout
 * of Rust's firmware::network::Mlp<256>. */
struct cartpole_mlp256 {
    float fc1_weight[256][4];
    float fc1_bias[256];
    float fc2_weight[256][256];
    float fc2_bias[256];
    float fc3_weight[2][256];
    float fc3_bias[2];
};
/* q = [Q(obs, left), Q(obs, right)] of w, in the Rust firmware's summation order
 * (bit for bit); push right iff q[1] > q[0]. From libcartpole_policy.a. A NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_mlp256_forward(const struct cartpole_mlp256 *w, const float obs[4], float q[2]);
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
/* A 4-16-16-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<16>. */
struct cartpole_qmlp16 {
    int32_t fc1_bias[16];
    int32_t fc2_bias[16];
    int32_t fc3_bias[2];
    struct cartpole_requant fc1_requant[16];
    struct cartpole_requant fc2_requant[16];
    int8_t fc1_weight[16][4];
    int8_t fc2_weight[16][16];
    int8_t fc3_weight[2][16];
};
/* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_qmlp16_forward(const struct cartpole_qmlp16 *w, const int16_t obs[4], int32_t q[2]);
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
#ifndef CARTPOLE_QMLP32_DEFINED
#define CARTPOLE_QMLP32_DEFINED
/* A 4-32-32-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<32>. */
struct cartpole_qmlp32 {
    int32_t fc1_bias[32];
    int32_t fc2_bias[32];
    int32_t fc3_bias[2];
    struct cartpole_requant fc1_requant[32];
    struct cartpole_requant fc2_requant[32];
    int8_t fc1_weight[32][4];
    int8_t fc2_weight[32][32];
    int8_t fc3_weight[2][32];
};
/* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_qmlp32_forward(const struct cartpole_qmlp32 *w, const int16_t obs[4], int32_t q[2]);
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
#ifndef CARTPOLE_QMLP64_DEFINED
#define CARTPOLE_QMLP64_DEFINED
/* A 4-64-64-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<64>. */
struct cartpole_qmlp64 {
    int32_t fc1_bias[64];
    int32_t fc2_bias[64];
    int32_t fc3_bias[2];
    struct cartpole_requant fc1_requant[64];
    struct cartpole_requant fc2_requant[64];
    int8_t fc1_weight[64][4];
    int8_t fc2_weight[64][64];
    int8_t fc3_weight[2][64];
};
/* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_qmlp64_forward(const struct cartpole_qmlp64 *w, const int16_t obs[4], int32_t q[2]);
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
#ifndef CARTPOLE_QMLP128_DEFINED
#define CARTPOLE_QMLP128_DEFINED
/* A 4-128-128-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<128>. */
struct cartpole_qmlp128 {
    int32_t fc1_bias[128];
    int32_t fc2_bias[128];
    int32_t fc3_bias[2];
    struct cartpole_requant fc1_requant[128];
    struct cartpole_requant fc2_requant[128];
    int8_t fc1_weight[128][4];
    int8_t fc2_weight[128][128];
    int8_t fc3_weight[2][128];
};
/* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_qmlp128_forward(const struct cartpole_qmlp128 *w, const int16_t obs[4], int32_t q[2]);
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
#ifndef CARTPOLE_QMLP256_DEFINED
#define CARTPOLE_QMLP256_DEFINED
/* A 4-256-256-2 Q-network in integers (weight[out][in]); the layout of Rust's
 * firmware::network::int::QMlp<256>. */
struct cartpole_qmlp256 {
    int32_t fc1_bias[256];
    int32_t fc2_bias[256];
    int32_t fc3_bias[2];
    struct cartpole_requant fc1_requant[256];
    struct cartpole_requant fc2_requant[256];
    int8_t fc1_weight[256][4];
    int8_t fc2_weight[256][256];
    int8_t fc3_weight[2][256];
};
/* q = the two outputs of w (exported policies: the advantages Q - mean(Q)) in its
 * integer scale, obs = {x, x_dot, theta, theta_dot} in Q3.12 (SI units times 4096);
 * push right iff q[1] > q[0]. No floating point. From libcartpole_policy.a; a NULL
 * argument makes it write nothing. */
#ifdef __cplusplus
extern "C"
#endif
void cartpole_qmlp256_forward(const struct cartpole_qmlp256 *w, const int16_t obs[4], int32_t q[2]);
#endif

#endif /* CARTPOLE_POLICY_H */
