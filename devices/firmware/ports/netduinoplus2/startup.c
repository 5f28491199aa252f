/*
 * Start-up of the netduinoplus2 port: the vector table, the reset handler (copy .data, zero .bss,
 * enable the FPU, call main) and the default handlers. Written for ultraglide, no vendor code.
 */
#include <stdint.h>

#include "cortex_m.h"

#include "stm32f405.h"

extern uint32_t _stack_top;

void Reset_Handler(void);
void Default_Handler(void);
void HardFault_Handler(void);

/* the board's handlers (board.c); any left undefined fall back to Default_Handler */
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void USART1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USART2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Stream5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Stream0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));

#define VECTORS (16u + 82u)  /* the 16 system exceptions and the STM32F405's 82 interrupts */

typedef void (*vector_t)(void);

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverride-init"
__attribute__((section(".isr_vector"), used))
static const vector_t vector_table[VECTORS] = {
    [2 ... VECTORS - 1] = Default_Handler,  /* every slot handled; the named ones below override */
    [0] = (vector_t)(uintptr_t)&_stack_top,
    [1] = Reset_Handler,
    [2] = HardFault_Handler,  /* NMI (the clock security system): the same safe path */
    [3] = HardFault_Handler,
    [4] = HardFault_Handler,  /* MemManage */
    [5] = HardFault_Handler,  /* BusFault */
    [6] = HardFault_Handler,  /* UsageFault */
    [11] = Default_Handler,   /* SVCall */
    [14] = Default_Handler,   /* PendSV */
    [15] = SysTick_Handler,
    [16 + TIM2_IRQn] = TIM2_IRQHandler,
    [16 + USART1_IRQn] = USART1_IRQHandler,
    [16 + USART2_IRQn] = USART2_IRQHandler,
    [16 + DMA1_Stream5_IRQn] = DMA1_Stream5_IRQHandler,
    [16 + 56] = DMA2_Stream0_IRQHandler,
};
#pragma GCC diagnostic pop

void Reset_Handler(void)
{
    __asm__ volatile("ldr sp, =_stack_top");  /* as the vector table says; a debugger's reset may not load it */
    cortex_m_start(vector_table);  /* ports/common/cortex_m.c: .data, .bss, the FPU, the vector table, main */
}

/* An unexpected interrupt or a fault: the plate must not be left driven. Before any C (whose stack may be what
   failed), the handler moves the stack pointer back to the top of the stack and silences the output in
   assembly: hardware, the DAC's DMA (DMA1 stream 5) and trigger (TIM2) stopped, the DAC left enabled without a
   trigger and mid-scale written (it reaches the pin one APB1 clock later); QEMU, the emulated DAC stopped. It
   stamps the time; then C notes why (the fault status register) and resets the board (board_fault_reset). */
#ifdef UG_BOARD_QEMU
#define OUTPUT_OFF_ASM                                                                                             \
    "ldr r0, =board_dac_stopped\n\t"                                                                           \
    "movs r1, #1\n\t"                                                                                          \
    "str r1, [r0]\n\t"
#else
#define OUTPUT_OFF_ASM                                                                                             \
    "ldr r0, =0x40026088\n\t" /* DMA1 stream 5 CR: 0 */                                                       \
    "movs r1, #0\n\t"                                                                                          \
    "str r1, [r0]\n\t"                                                                                         \
    "ldr r0, =0x40000000\n\t" /* TIM2 CR1: 0 */                                                               \
    "str r1, [r0]\n\t"                                                                                         \
    "ldr r0, =0x40007400\n\t" /* DAC CR: EN1 only */                                                          \
    "movs r1, #1\n\t"                                                                                          \
    "str r1, [r0]\n\t"                                                                                         \
    "ldr r0, =0x4000740C\n\t" /* DAC DHR12L1: mid-scale */                                                    \
    "ldr r1, =0x8000\n\t"                                                                                      \
    "str r1, [r0]\n\t"                                                                                         \
    "ldr r0, =board_dac_stopped\n\t"                                                                           \
    "movs r1, #1\n\t"                                                                                          \
    "str r1, [r0]\n\t"
#endif

__attribute__((naked)) void HardFault_Handler(void)
{
    __asm__ volatile(
        "cpsid i\n\t"
        "ldr r0, =_stack_top\n\t"
        "mov sp, r0\n\t"
        OUTPUT_OFF_ASM
        "ldr r0, =0x40000C24\n\t" /* TIM5's count: the clock when the output went silent */
        "ldr r1, [r0]\n\t"
        "ldr r0, =board_silent_at\n\t"
        "str r1, [r0]\n\t"
        "b board_fault_reset\n\t"
        ".ltorg\n\t");
}

void Default_Handler(void)
{
    HardFault_Handler();
}
