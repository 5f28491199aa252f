/*
 * Start-up of the netduinoplus2 port: the vector table, the reset handler (copy .data, zero .bss,
 * enable the FPU, call main) and the default handlers. Written for ultraglide, no vendor code.
 */
#include <stdint.h>

#include "stm32f405.h"

extern uint32_t _data_load, _data_start, _data_end, _bss_start, _bss_end, _stack_top;
extern int main(void);

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
    [2] = Default_Handler,    /* NMI */
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
    uint32_t *from = &_data_load;
    for (uint32_t *to = &_data_start; to < &_data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = &_bss_start; to < &_bss_end;) {
        *to++ = 0u;
    }
    SCB_CPACR |= (0xFu << 20);  /* CP10 and CP11 full access: the FPU, before any float instruction */
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    SCB_VTOR = (uint32_t)(uintptr_t)vector_table;
    (void)main();
    for (;;) {
        __asm__ volatile("wfi");
    }
}

/* An unexpected interrupt or a fault: the plate must not be left driven. The board's safe-state
   routine cuts the DAC output and the timers, then the core waits for the watchdog reset. */
extern void board_fault_stop(void);

void Default_Handler(void)
{
    board_fault_stop();
}

void HardFault_Handler(void)
{
    board_fault_stop();
}
