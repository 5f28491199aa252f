/* cortex_m.c - see cortex_m.h. Written for ultraglide, no vendor code. */
#include "cortex_m.h"

#include "board.h"
#include "ug_safety.h"

#define CM_REG32(address) (*(volatile uint32_t *)(uintptr_t)(address))
#define CM_SCB_VTOR CM_REG32(0xE000ED08u)
#define CM_SCB_AIRCR CM_REG32(0xE000ED0Cu)
#define CM_SCB_CFSR CM_REG32(0xE000ED28u)
#define CM_SCB_CPACR CM_REG32(0xE000ED88u)
#define CM_AIRCR_VECTKEY (0x05FAu << 16)
#define CM_AIRCR_SYSRESETREQ (1u << 2)

volatile uint32_t board_dac_stopped;
volatile uint32_t board_silent_at;

static uint32_t reset_reason;
static ug_reset_record_t reset_record;

extern uint32_t _data_load, _data_start, _data_end, _bss_start, _bss_end;
extern int main(void);

void cortex_m_start(const void *vectors)
{
    uint32_t *from = &_data_load;
    for (uint32_t *to = &_data_start; to < &_data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = &_bss_start; to < &_bss_end;) {
        *to++ = 0u;
    }
    CM_SCB_CPACR |= (0xFu << 20);  /* CP10 and CP11 full access: the FPU, before any float instruction */
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    CM_SCB_VTOR = (uint32_t)(uintptr_t)vectors;
    (void)main();
    for (;;) {
        __asm__ volatile("wfi");
    }
}

uint32_t cortex_m_reset_read(int from_ram)
{
    reset_reason = from_ram ? ug_reset_take_from_ram(&reset_record) : ug_reset_take(&reset_record);
    return reset_reason;
}

void cortex_m_reset_reason_set(uint32_t reason)
{
    reset_reason = reason;
}

uint32_t board_reset_reason(void)
{
    return reset_reason;
}

const ug_reset_record_t *board_reset_record(void)
{
    return &reset_record;
}

static uint32_t silent_after_us(void)
{
    if (ug_reset_record.injected == 0u) {
        return UG_NOT_INJECTED;
    }
    return (board_silent_at - ug_reset_record.fault_at) / BOARD_CLOCK_PER_US;  /* both in the board's clock */
}

void board_reset(uint32_t reason, uint32_t detail)
{
    __asm__ volatile("cpsid i" ::: "memory");
    if (!board_dac_stopped) {
        board_output_off();
    }
    ug_reset_note(reason, detail, silent_after_us());
    __asm__ volatile("dsb" ::: "memory");
    CM_SCB_AIRCR = CM_AIRCR_VECTKEY | CM_AIRCR_SYSRESETREQ;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
        __asm__ volatile("nop");  /* the reset comes within a few cycles */
    }
}

void board_fault_reset(void)
{
    board_reset(UG_RESET_FAULT, CM_SCB_CFSR);
}
