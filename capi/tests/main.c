/* Links against libcartpole_policy.a through the public header and prints the Q-values of
 * the observations given on the command line as hex bit patterns. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cartpole_policy.h"

int main(int argc, char **argv) {
    if ((argc - 1) % 4 != 0) {
        fprintf(stderr, "usage: %s x x_dot theta theta_dot [...]\n", argv[0]);
        return 2;
    }
    for (int i = 1; i < argc; i += 4) {
        float obs[4], q[2];
        unsigned int bits[2];
        for (int k = 0; k < 4; k++) obs[k] = strtof(argv[i + k], NULL);
        cartpole_policy_forward(obs, q);
        memcpy(bits, q, sizeof bits);
        printf("%08x %08x\n", bits[0], bits[1]);
    }
    return 0;
}
