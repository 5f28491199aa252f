/* The STM32F405's independent watchdog: see iwdg.h. */
#include "iwdg.h"

void ug_iwdg_divider(uint32_t timeout_us, uint32_t lsi_hz, uint32_t *pr, uint32_t *rlr)
{
    uint32_t code = 0u;
    uint64_t ticks = 0u;
    for (; code <= 6u; code++) {
        uint32_t divider = 4u << code;
        ticks = (uint64_t)timeout_us * lsi_hz / (1000000ull * divider);
        if (ticks <= 4095u) {
            break;
        }
    }
    if (code > 6u) {
        code = 6u;
        ticks = 4095u;
    }
    *pr = code;
    *rlr = ticks < 1u ? 1u : (uint32_t)ticks;
}

uint32_t ug_iwdg_start(uint32_t timeout_us, uint32_t lsi_hz)
{
    uint32_t pr, rlr;
    ug_iwdg_divider(timeout_us, lsi_hz, &pr, &rlr);
    UG_IWDG_WRITE(IWDG_KR_OFFSET, IWDG_KEY_UNLOCK);
    UG_IWDG_WRITE(IWDG_PR_OFFSET, pr);
    UG_IWDG_WRITE(IWDG_RLR_OFFSET, rlr);
    for (uint32_t i = 0; i < IWDG_SR_WAIT && (UG_IWDG_READ(IWDG_SR_OFFSET) & (IWDG_SR_PVU | IWDG_SR_RVU)); i++) {
    }
    UG_IWDG_WRITE(IWDG_KR_OFFSET, IWDG_KEY_START);
    UG_IWDG_WRITE(IWDG_KR_OFFSET, IWDG_KEY_REFRESH);
    return rlr;
}

void ug_iwdg_refresh(void)
{
    UG_IWDG_WRITE(IWDG_KR_OFFSET, IWDG_KEY_REFRESH);
}
