/*
 * The netduinoplus2 board: clocks, USART1 (the host link), the SysTick millisecond tick, the carrier
 * output (DAC1 paced by TIM6 through DMA1 stream 5 on hardware; a TIM2 interrupt pacing the same
 * refill under QEMU, which models neither DAC nor DMA) and the sensing piezo's ADC.
 */
#ifndef UG_BOARD_H
#define UG_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define BOARD_CORE_HZ 168000000u   /* the STM32F405 at full speed; QEMU's netduinoplus2 fixes this clock */
#define BOARD_APB1_HZ 42000000u    /* HCLK / 4 */
#define BOARD_APB2_HZ 84000000u    /* HCLK / 2: USART1's clock */
#define BOARD_TIMER_APB1_HZ 84000000u  /* APB1 timers run at twice APB1 when it is divided */
#define BOARD_BAUD 921600u         /* the host's default (docs/protocol.md) */
#define BOARD_TICK_HZ 1000u        /* SysTick */

void board_init(void);
uint32_t board_millis(void);

/* Bytes the host sent, taken from the receive ring (filled by the USART1 interrupt). */
size_t board_uart_read(uint8_t *data, size_t capacity);
/* Queue bytes for the host, all or none; false when the transmit ring has no room. */
bool board_uart_write(const uint8_t *data, size_t length);
/* Bytes lost: receive ring full (the main loop fell behind), the USART's own overrun, transmit ring full. */
uint32_t board_uart_rx_dropped(void);
uint32_t board_uart_tx_dropped(void);

/* Safe state: carrier output to mid-scale (no drive), its timers and DMA stopped, interrupts off. */
void board_fault_stop(void);

/* Sleep until the next interrupt. */
void board_wait_for_interrupt(void);

#endif
