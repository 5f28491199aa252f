/*
 * The netduinoplus2 board: clocks, USART1 (the host link), USART2 (the debug console), the SysTick
 * millisecond tick, the carrier output and the sensing piezo's ADC.
 *
 * Carrier output on hardware: DAC1 (PA4) converts on each TIM6 update at BOARD_DAC_RATE_HZ; DMA1
 * stream 5 (channel 7) feeds it from a circular buffer of two blocks, and its half- and full-transfer
 * interrupts call the refill for the half just played. Under QEMU, which models neither DAC nor DMA nor
 * TIM6, TIM2 (modelled) interrupts at the block rate and calls the same refill on a RAM buffer.
 * Sensing on hardware: ADC1 converts the sensing piezo (PA1) continuously into a circular DMA2 buffer;
 * each refill gets the peak-to-peak of the last block in ADC codes.
 */
#ifndef UG_BOARD_H
#define UG_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define BOARD_CORE_HZ 168000000u   /* the STM32F405 at full speed; QEMU's netduinoplus2 fixes this clock */
#define BOARD_APB1_HZ 42000000u    /* HCLK / 4: USART2 */
#define BOARD_APB2_HZ 84000000u    /* HCLK / 2: USART1 */
#define BOARD_TIMER_APB1_HZ 84000000u  /* APB1 timers run at twice APB1 when it is divided */
#define BOARD_QEMU_TIMER_HZ 48000000u  /* QEMU's TIM2..5 count at 48 MHz whatever the RCC says */
#define BOARD_BAUD 921600u         /* the host's default (docs/protocol.md) */
#define BOARD_CONSOLE_BAUD 115200u
#define BOARD_TICK_HZ 1000u        /* SysTick */
#define BOARD_DAC_RATE_HZ 250000u  /* carrier samples a second: 10 a period at 25 kHz */
#define BOARD_BLOCK_SAMPLES 250u   /* one refill: 1 ms of carrier */
#define BOARD_SENSE_SAMPLES 512u   /* ADC1 samples of the sensing piezo kept (about 0.7 ms at 778 kS/s) */

/* Fill one block of DAC codes (12-bit, mid-scale 2048 = no drive); ``sensed_pp`` is the sensing piezo's
   peak-to-peak over the last block in ADC codes (0 under QEMU). Runs in the carrier interrupt. */
typedef void (*board_refill_fn)(uint16_t *codes, uint32_t count, uint32_t sensed_pp);

void board_init(void);
uint32_t board_millis(void);

/* Bytes the host sent, taken from the receive ring (filled by the USART1 interrupt). */
size_t board_uart_read(uint8_t *data, size_t capacity);
/* Queue bytes for the host, all or none; false when the transmit ring has no room. */
bool board_uart_write(const uint8_t *data, size_t length);
/* Bytes lost: receive ring full or the USART's own overrun; transmit ring full. */
uint32_t board_uart_rx_dropped(void);
uint32_t board_uart_tx_dropped(void);

/* A line for the debug console (USART2), dropped whole when its ring is full. */
void board_console_write(const char *text);

/* Start the carrier's block clock: ``refill`` is called for each block from then on. */
void board_carrier_start(board_refill_fn refill);

/* Safe state: DAC to mid-scale (no drive), its timers and DMA stopped, interrupts off, wait. */
void board_fault_stop(void);

/* Sleep until the next interrupt. */
void board_wait_for_interrupt(void);

#endif
