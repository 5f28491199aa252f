#include "port_logic.h"

#include <math.h>

uint32_t ug_usart_brr(uint32_t pclk_hz, uint32_t baud)
{
    if (baud == 0u) {
        return 0u;
    }
    return (uint32_t)(((uint64_t)pclk_hz + baud / 2u) / baud);
}

uint32_t ug_usart_baud(uint32_t pclk_hz, uint32_t brr)
{
    return brr == 0u ? 0u : (uint32_t)(((uint64_t)pclk_hz + brr / 2u) / brr);
}

uint32_t ug_timer_arr(uint32_t timer_hz, uint32_t rate_hz)
{
    if (rate_hz == 0u) {
        return 0xFFFFFFFFu;
    }
    uint32_t ticks = (uint32_t)(((uint64_t)timer_hz + rate_hz / 2u) / rate_hz);
    return ticks < 2u ? 1u : ticks - 1u;
}

uint32_t ug_timer_rate_hz(uint32_t timer_hz, uint32_t arr)
{
    uint64_t ticks = (uint64_t)arr + 1u;
    return (uint32_t)(((uint64_t)timer_hz + ticks / 2u) / ticks);
}

void ug_dac_block(const int16_t *samples, uint16_t *words, uint32_t count)
{
    for (uint32_t i = 0; i < count; i++) {
        words[i] = ug_dac_word(samples[i]);
    }
}

uint32_t ug_dma_ring_head(uint32_t ndtr, uint32_t size)
{
    return ndtr == 0u || ndtr > size ? 0u : (size - ndtr) % size;
}

uint32_t ug_clock_samples_since_block(uint32_t now, uint32_t next_due, uint32_t ticks_per_block,
                                      uint32_t samples_per_block)
{
    if (ticks_per_block == 0u || samples_per_block == 0u) {
        return 0u;
    }
    uint32_t elapsed = now - (next_due - ticks_per_block);  /* since the last block's end, modulo 2^32 */
    if (elapsed >= 0x80000000u) {
        return 0u;  /* before it: never ahead */
    }
    if (elapsed >= ticks_per_block) {
        return samples_per_block - 1u;  /* the next block is due and has not run */
    }
    return elapsed * samples_per_block / ticks_per_block;  /* floor: the samples whole by now */
}

uint32_t ug_dma_samples_since_block(uint32_t ndtr, uint32_t half_transfers, uint32_t oversample, uint32_t pending)
{
    if (half_transfers == 0u || oversample == 0u) {
        return 0u;
    }
    uint32_t block = half_transfers / oversample;
    if (block == 0u) {
        return 0u;
    }
    if (pending) {
        return block - 1u;
    }
    uint32_t in_half = ug_dma_ring_head(ndtr, 2u * half_transfers) % half_transfers;
    return in_half / oversample;
}

uint32_t ug_adc_peak_to_peak(const uint16_t *codes, uint32_t count)
{
    if (count == 0u) {
        return 0u;
    }
    uint16_t low = codes[0], high = codes[0];
    for (uint32_t i = 1; i < count; i++) {
        if (codes[i] < low) {
            low = codes[i];
        }
        if (codes[i] > high) {
            high = codes[i];
        }
    }
    return (uint32_t)(high - low);
}

char *ug_append_text(char *out, char *end, const char *text)
{
    while (*text != '\0' && out < end - 1) {
        *out++ = *text++;
    }
    *out = '\0';
    return out;
}

char *ug_append_u32(char *out, char *end, uint32_t value)
{
    char digits[10];
    uint32_t n = 0;
    do {
        digits[n++] = (char)('0' + value % 10u);
        value /= 10u;
    } while (value != 0u);
    while (n > 0u && out < end - 1) {
        *out++ = digits[--n];
    }
    *out = '\0';
    return out;
}

void ug_sense_init(ug_sense_t *sense, float adc_rate_hz, float um_pp_per_code, float mid_code)
{
    sense->um_pp_per_code = um_pp_per_code;
    sense->mid_code = mid_code;
    sense->adc_rate_hz = adc_rate_hz;
    ug_sense_set_carrier(sense, 0.25f * adc_rate_hz);
}

void ug_sense_set_carrier(ug_sense_t *sense, float carrier_hz)
{
    float w = 6.2831853f * carrier_hz / sense->adc_rate_hz;
    float s = sinf(w);
    sense->two_cos = 2.0f * cosf(w);
    sense->inv_sin2 = s * s > 1e-6f ? 1.0f / (s * s) : 0.0f;  /* a carrier at 0 or Nyquist: nothing to measure */
}

/* The rounding of each ADC sample to a code adds noise of variance 1/12 code^2 to it; a pair's quadratic
   form then carries 2 x 1/12 of it on average whatever the signal, and the two pairs 2 x 2/12: taken off, so
   that the estimate is not biased high (by 1e-4 at 4 um p-p on the QEMU image's scale). */
#define UG_SENSE_NOISE_ENERGY (4.0f / 12.0f)

float ug_sense_block(ug_sense_t *sense, const uint16_t *codes, uint32_t n_drive, uint32_t per_drive,
                     float *amplitude_um_pp)
{
    const float mid = sense->mid_code, two_cos = sense->two_cos, inv_sin2 = 0.5f * sense->inv_sin2;
    const float to_um_pp = 2.0f * sense->um_pp_per_code;  /* amplitude A in codes: a swing of 2A codes */
    float sum = 0.0f, largest = 0.0f;
    const uint16_t *last = codes + per_drive - 3u;  /* the drive sample's last three ADC samples: two pairs */
    for (uint32_t j = 0; j < n_drive; j++, last += per_drive) {
        float a = (float)last[0] - mid, b = (float)last[1] - mid, c = (float)last[2] - mid;
        float energy = (a * a + c * c) + 2.0f * b * b - two_cos * b * (a + c) - UG_SENSE_NOISE_ENERGY;
        float a2 = energy * inv_sin2;
        float amplitude = a2 > 0.0f ? sqrtf(a2) * to_um_pp : 0.0f;
        amplitude_um_pp[j] = amplitude;
        largest = amplitude > largest ? amplitude : largest;
        sum += a + b + c;
    }
    if (n_drive > 0u) {
        sense->mid_code += sum / (float)(3u * n_drive) * (1.0f / 64.0f);  /* the bias, followed over ~64 blocks */
    }
    return largest;
}

char *ug_append_fixed(char *out, char *end, float value, uint32_t decimals)
{
    if (value != value) {
        return ug_append_text(out, end, "nan");
    }
    if (value < 0.0f) {
        out = ug_append_text(out, end, "-");
        value = -value;
    }
    if (value > 4.0e9f) {
        return ug_append_text(out, end, isinf(value) ? "inf" : "4000000000");
    }
    uint32_t scale = 1u;
    decimals = decimals > 6u ? 6u : decimals;
    for (uint32_t i = 0; i < decimals; i++) {
        scale *= 10u;
    }
    uint64_t scaled = (uint64_t)((double)value * (double)scale + 0.5);
    out = ug_append_u32(out, end, (uint32_t)(scaled / scale));
    if (decimals > 0u) {
        out = ug_append_text(out, end, ".");
        uint32_t fraction = (uint32_t)(scaled % scale);
        for (uint32_t div = scale / 10u; div > 0u; div /= 10u) {
            char digit[2] = {(char)('0' + (fraction / div) % 10u), '\0'};
            out = ug_append_text(out, end, digit);
        }
    }
    return out;
}
