/*
 * The netduinoplus2 port's pure arithmetic: register values from clocks and rates, and sample
 * format conversions. No register access, so the host compiles and tests it
 * (tests/test_firmware_board.py) and QEMU's missing peripherals (DAC, DMA, TIM6) still have their
 * numbers checked.
 */
#ifndef UG_PORT_LOGIC_H
#define UG_PORT_LOGIC_H

#include <stdint.h>

/* USART_BRR for a baud rate at 16× oversampling (RM0090 §30.3.4): the divider pclk / baud in 1/16
   steps, rounded to nearest. 84 MHz, 921 600 baud: 91 (0x5B), 923 077 baud, +0.16 %. */
uint32_t ug_usart_brr(uint32_t pclk_hz, uint32_t baud);

/* The baud rate a BRR value gives: pclk / BRR. */
uint32_t ug_usart_baud(uint32_t pclk_hz, uint32_t brr);

/* Auto-reload value of a timer counting at timer_hz that overflows rate_hz times a second
   (prescaler 1): round(timer_hz / rate_hz) − 1, at least 1. */
uint32_t ug_timer_arr(uint32_t timer_hz, uint32_t rate_hz);

/* The rate a timer really runs at for an auto-reload value: timer_hz / (arr + 1). */
uint32_t ug_timer_rate_hz(uint32_t timer_hz, uint32_t arr);

/* A carrier sample, signed 16-bit full scale, as the 12-bit right-aligned DAC code around
   mid-scale 2048: 2048 + sample / 16, rounded to nearest (ties away from zero), within 0..4095. */
uint16_t ug_dac_code(int16_t sample);

/* Convert a block of carrier samples to DAC codes (the DMA's half-buffer). */
void ug_dac_block(const int16_t *samples, uint16_t *codes, uint32_t count);

/* The peak-to-peak swing of a block of sensing-piezo samples (12-bit ADC codes): max − min, in ADC
   codes (a peak detector over the block; at least one carrier period must fit in it). */
uint32_t ug_adc_peak_to_peak(const uint16_t *codes, uint32_t count);



/* Text for the debug console without printf (newlib's pulls in malloc, and the image links no heap):
   append a string or an unsigned decimal at ``out``, never writing past ``end`` (which stays for the
   terminating NUL); return the new end of the text. */
char *ug_append_text(char *out, char *end, const char *text);
char *ug_append_u32(char *out, char *end, uint32_t value);
#endif
