#include "port_logic.h"

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

uint16_t ug_dac_code(int16_t sample)
{
    int32_t scaled = (int32_t)sample >= 0 ? ((int32_t)sample + 8) / 16 : -((-(int32_t)sample + 8) / 16);
    int32_t code = 2048 + scaled;
    if (code < 0) {
        code = 0;
    } else if (code > 4095) {
        code = 4095;
    }
    return (uint16_t)code;
}

void ug_dac_block(const int16_t *samples, uint16_t *codes, uint32_t count)
{
    for (uint32_t i = 0; i < count; i++) {
        codes[i] = ug_dac_code(samples[i]);
    }
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
