/* Start-up for the Cortex-M4F of QEMU's mps2-an386, CMSIS style and no vendor SDK: the
 * vector table, a reset handler that copies .data, clears .bss and turns the FPU on, and
 * the semihosting exit the application's return ends in. */

#include <stdint.h>

extern uint32_t __data_load, __data_start, __data_end, __bss_start, __bss_end, __stack_top;
int main(void);
void semihosting_exit(int status);

void Reset_Handler(void);
void Default_Handler(void);

void Reset_Handler(void)
{
    const uint32_t *from = &__data_load;
    for (uint32_t *to = &__data_start; to < &__data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = &__bss_start; to < &__bss_end;) {
        *to++ = 0;
    }
    /* CPACR: full access to CP10 and CP11, the FPU, before any float instruction. */
    *(volatile uint32_t *)0xE000ED88 |= 0xFu << 20;
    __asm volatile("dsb\n\tisb" ::: "memory");
    semihosting_exit(main());
}

/* A fault ends the run with a failure rather than spinning where no one looks. */
void Default_Handler(void)
{
    semihosting_exit(1);
}

/* The stack's top, then the handlers; 0 for the reserved entries. */
#define H(f) ((uintptr_t)(f))
__attribute__((section(".vectors"), used)) static const uintptr_t vectors[16] = {
    (uintptr_t)&__stack_top, H(Reset_Handler),
    H(Default_Handler), H(Default_Handler), H(Default_Handler), H(Default_Handler),
    H(Default_Handler), 0, 0, 0, 0,
    H(Default_Handler), H(Default_Handler), 0, H(Default_Handler), H(Default_Handler),
};
