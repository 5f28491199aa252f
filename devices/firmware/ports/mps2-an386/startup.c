/*
 * Start-up of the mps2-an386 port: the vector table, the reset handler (copy .data, zero .bss, enable the FPU,
 * call main), the NMI (the CMSDK watchdog's first expiry) and the fault handlers. Written for ultraglide, no
 * vendor code.
 */
#include <stdint.h>

#include "cortex_m.h"

#include "cmsdk.h"

extern uint32_t _stack_top;

void Reset_Handler(void);
void Default_Handler(void);
void HardFault_Handler(void);
void NMI_Handler(void);

/* the board's handlers (board.c) */
void UART0RX_Handler(void) __attribute__((weak, alias("Default_Handler")));
void UART1RX_Handler(void) __attribute__((weak, alias("Default_Handler")));
void TIMER0_Handler(void) __attribute__((weak, alias("Default_Handler")));

#define VECTORS (16u + 32u)  /* the 16 system exceptions and the AN386's 32 interrupts */

typedef void (*vector_t)(void);

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverride-init"
__attribute__((section(".isr_vector"), used))
static const vector_t vector_table[VECTORS] = {
    [2 ... VECTORS - 1] = Default_Handler,  /* every slot handled; the named ones below override */
    [0] = (vector_t)(uintptr_t)&_stack_top,
    [1] = Reset_Handler,
    [2] = NMI_Handler,        /* the CMSDK watchdog's interrupt */
    [3] = HardFault_Handler,
    [4] = HardFault_Handler,  /* MemManage: the stack's guard */
    [5] = HardFault_Handler,  /* BusFault */
    [6] = HardFault_Handler,  /* UsageFault */
    [11] = Default_Handler,   /* SVCall */
    [14] = Default_Handler,   /* PendSV */
    [15] = Default_Handler,   /* SysTick: unused */
    [16 + UART0_RX_IRQn] = UART0RX_Handler,
    [16 + UART1_RX_IRQn] = UART1RX_Handler,
    [16 + TIMER0_IRQn] = TIMER0_Handler,
};
#pragma GCC diagnostic pop

void Reset_Handler(void)
{
    __asm__ volatile("ldr sp, =_stack_top");  /* as the vector table says; a debugger's reset may not load it */
    cortex_m_start(vector_table);  /* ports/common/cortex_m.c: .data, .bss, the FPU, the vector table, main */
}

/* The NMI: the watchdog's C handler (board.c) gets the exception frame, to note where the processor was. */
__attribute__((naked)) void NMI_Handler(void)
{
    __asm__ volatile("mov r0, sp\n\t"
                     "b board_watchdog_expired\n\t");
}

/* A fault or an unexpected interrupt: the plate must not be left driven. Before any C (whose stack may be what
   failed), the handler moves the stack pointer back to the top of the stack and stops the emulated DAC, stamps
   the clock (TIMER1 counts down: its complement counts up); then C notes why and resets the board. */
__attribute__((naked)) void HardFault_Handler(void)
{
    __asm__ volatile(
        "cpsid i\n\t"
        "ldr r0, =_stack_top\n\t"
        "mov sp, r0\n\t"
        "ldr r0, =board_dac_stopped\n\t"
        "movs r1, #1\n\t"
        "str r1, [r0]\n\t"
        "ldr r0, =0x40001004\n\t" /* TIMER1 VALUE */
        "ldr r1, [r0]\n\t"
        "mvns r1, r1\n\t"
        "ldr r0, =board_silent_at\n\t"
        "str r1, [r0]\n\t"
        "b board_fault_reset\n\t"
        ".ltorg\n\t");
}

void Default_Handler(void)
{
    HardFault_Handler();
}
