/*
 * The board ports' pure arithmetic (the netduinoplus2's registers among it): register values from clocks and rates, and sample
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

/* A carrier sample, signed 16-bit full scale, as the word the DMA writes to DAC1's 12-bit left-aligned
   holding register (DHR12L1): offset binary, sample + 32768, of which the DAC converts the top 12 bits,
   2048 + floor(sample / 16) (0..4095; mid-scale 2048 is no drive). The conversion is one XOR a sample
   where a right-aligned code would need a rounded division; truncation biases the carrier by half a code
   (0.4 mV of DC, which the amplifier's coupling removes). */
static inline uint16_t ug_dac_word(int16_t sample)
{
    return (uint16_t)((uint16_t)sample ^ 0x8000u);
}

/* The 12-bit code the DAC converts from a DHR12L1 word. */
static inline uint16_t ug_dac_code(uint16_t word)
{
    return (uint16_t)(word >> 4);
}

/* Convert a block of carrier samples to DAC words (the DMA's half-buffer). */
void ug_dac_block(const int16_t *samples, uint16_t *words, uint32_t count);

/* Where a circular DMA receiving into a buffer of `size` bytes will write next, from its stream's NDTR
   (the transfers left in this lap, counting down from size: NDTR = size means the start). */
uint32_t ug_dma_ring_head(uint32_t ndtr, uint32_t size);

/* Drive samples taken since the last block ran, from a free-running board clock (the QEMU images' block clock:
   the netduinoplus2's TIM5, the mps2-an386's TIMER1): `now` its count, `next_due` its count when the next block
   falls due (the block last run ended at next_due - ticks_per_block), both wrapping at 2^32. Never ahead of the
   blocks: a block due but not run yet (the block interrupt masked or late) gives samples_per_block - 1, the most a
   block's worth can say; a count before the last block's end (never, but a clock read out of order) gives 0.
   ticks_per_block * samples_per_block must fit in 32 bits. */
uint32_t ug_clock_samples_since_block(uint32_t now, uint32_t next_due, uint32_t ticks_per_block,
                                      uint32_t samples_per_block);

/* The same from a circular ADC DMA over two halves of `half_transfers` conversions, `oversample` conversions a
   drive sample (the netduinoplus2's hardware image: DMA2 stream 0): `ndtr` the stream's transfers left in its lap,
   `pending` a half's completion flagged and not yet given to the block function (read with the block interrupt
   masked): the samples of the half filling now, and with a half pending samples_per_block - 1 as above. */
uint32_t ug_dma_samples_since_block(uint32_t ndtr, uint32_t half_transfers, uint32_t oversample, uint32_t pending);

/* The peak-to-peak swing of a block of sensing-piezo samples (12-bit ADC codes): max − min, in ADC
   codes (a peak detector over the block; at least one carrier period must fit in it). */
uint32_t ug_adc_peak_to_peak(const uint16_t *codes, uint32_t count);

/*
 * The sensing piezo's amplitude for each drive sample, from ADC codes sampled in step with the DAC.
 * The core wants one measured amplitude per drive sample (ug_core_adc_block); the ADC samples the
 * piezo `per_drive` (>= 3) times a drive sample. For a sinusoid x[k] = A sin(wk + p) about the mid-scale
 * (w: the carrier in radians per ADC sample), x[k]^2 - 2 cos(w) x[k] x[k-1] + x[k-1]^2 = A^2 sin^2(w)
 * for every k: two consecutive samples give the amplitude exactly, whatever the phase, with no peak to
 * wait for. Each drive sample's amplitude averages that over the two pairs of its last three samples
 * (the others are not needed: the same quantisation noise would cost twice the arithmetic), reported in
 * um peak-to-peak (2 A um_pp_per_code). The mid-scale is tracked (the conditioning's bias: a slow average).
 * Off the carrier (a transient ringing at the plate's own resonance) the estimate ripples at the beat
 * frequency around the true envelope.
 */
typedef struct {
    float um_pp_per_code;   /* um peak-to-peak per ADC code of peak-to-peak swing */
    float mid_code;         /* the tracked mid-scale, codes */
    float two_cos;          /* 2 cos(w) */
    float inv_sin2;         /* 1 / sin^2(w) */
    float adc_rate_hz;
} ug_sense_t;

void ug_sense_init(ug_sense_t *sense, float adc_rate_hz, float um_pp_per_code, float mid_code);
/* The carrier the plate is driven at (its frequency decides w); call when it changes. */
void ug_sense_set_carrier(ug_sense_t *sense, float carrier_hz);
/* One block of n_drive × per_drive codes → n_drive amplitudes (um p-p); returns their largest. */
float ug_sense_block(ug_sense_t *sense, const uint16_t *codes, uint32_t n_drive, uint32_t per_drive,
                     float *amplitude_um_pp);

/* Text for the debug console without printf (newlib's pulls in malloc, and the image links no heap):
   append a string or an unsigned decimal at ``out``, never writing past ``end`` (which stays for the
   terminating NUL); return the new end of the text. */
char *ug_append_text(char *out, char *end, const char *text);
char *ug_append_u32(char *out, char *end, uint32_t value);
/* A number with `decimals` digits after the point (0 to 6), rounded to nearest; NaN and infinities
   as "nan", "inf", "-inf"; magnitudes beyond 4e9 clamp there. */
char *ug_append_fixed(char *out, char *end, float value, uint32_t decimals);
#endif
