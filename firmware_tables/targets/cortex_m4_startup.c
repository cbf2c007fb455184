/*
 * Minimal start-up for QEMU mps2-an386 (Cortex-M4), for the cross-target tests only: a vector
 * table, then newlib's semihosting start-up (_start from rdimon-crt0: stack, .bss, argv through
 * semihosting, main, exit). Exceptions stop QEMU through semihosting with a failure status.
 */
#include <stdint.h>

extern void _start(void);
extern char __stack[];
extern char __etext[], __data_start__[], __data_end__[];

void ecam_reset_handler(void);
void ecam_fault_handler(void);
/* SysTick: a program that enables the timer defines its own handler (pair_check.c). */
void ecam_systick_handler(void) __attribute__((weak, alias("ecam_fault_handler")));

__attribute__((section(".vectors"), used)) void (*const ecam_vectors[16])(void) = {
    (void (*)(void))(uintptr_t)__stack, ecam_reset_handler, ecam_fault_handler,
    ecam_fault_handler, ecam_fault_handler, ecam_fault_handler, ecam_fault_handler,
    0, 0, 0, 0, ecam_fault_handler, ecam_fault_handler, 0, ecam_fault_handler,
    ecam_systick_handler};

/* Copies .data from flash, then hands over to newlib. */
void ecam_reset_handler(void)
{
    char *src = __etext;
    char *dst = __data_start__;

    while (dst < __data_end__) {
        *dst++ = *src++;
    }
    _start();
    for (;;) {
    }
}

/* Any fault: semihosting SYS_EXIT with ADP_Stopped_RunTimeError, so QEMU exits non-zero. */
void ecam_fault_handler(void)
{
    register uint32_t op __asm__("r0") = 0x18u;
    register uint32_t arg __asm__("r1") = 0x20023u;

    __asm__ volatile("bkpt 0xab" : : "r"(op), "r"(arg) : "memory");
    for (;;) {
    }
}
