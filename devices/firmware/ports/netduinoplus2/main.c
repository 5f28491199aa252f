/*
 * The netduinoplus2 image: the board, the host link, the carrier's block clock and the debug console
 * (USART2: one line per event, ``ev NAME key=value ...``, read by devices/firmware/qemu.py).
 * The QEMU image drives the emulated plate (emulated_plate.h) from the carrier's refill.
 */
#include "board.h"
#include "emulated_plate.h"
#include "emulation_config.h"
#include "port_logic.h"

static volatile uint32_t blocks;
static volatile uint32_t link_bytes;
#ifdef UG_BOARD_QEMU
static ug_emulated_plate_t plate;
#endif

static void refill(uint16_t *codes, uint32_t count, uint32_t sensed_pp)
{
    (void)sensed_pp;
    for (uint32_t i = 0; i < count; i++) {
        codes[i] = 2048u;  /* mid-scale: no drive */
    }
#ifdef UG_BOARD_QEMU
    (void)ug_emulated_plate_step(&plate, 0.0f, plate.resonance_hz, (float)count / (float)BOARD_DAC_RATE_HZ);
#endif
    blocks++;
}

static void console_stats(void)
{
    char line[120];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "ev stats blocks=");
    at = ug_append_u32(at, end, blocks);
    at = ug_append_text(at, end, " link_bytes=");
    at = ug_append_u32(at, end, link_bytes);
    at = ug_append_text(at, end, " rx_dropped=");
    at = ug_append_u32(at, end, board_uart_rx_dropped());
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

int main(void)
{
    board_init();
#ifdef UG_BOARD_QEMU
    ug_emulated_plate_init(&plate, ug_emulation.resonance_hz, ug_emulation.q, ug_emulation.drift_hz_per_s,
                           ug_emulation.full_scale_um_pp);
#endif
    board_carrier_start(refill);
    char line[120];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "ev boot board=netduinoplus2");
#ifdef UG_BOARD_QEMU
    at = ug_append_text(at, end, " plate_resonance_hz=");
    at = ug_append_u32(at, end, (uint32_t)(ug_emulation.resonance_hz + 0.5f));
    at = ug_append_text(at, end, " plate_q=");
    at = ug_append_u32(at, end, (uint32_t)(ug_emulation.q + 0.5f));
#endif
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
    uint32_t last_stats = board_millis();
    for (;;) {
        uint8_t buffer[64];
        size_t n;
        while ((n = board_uart_read(buffer, sizeof buffer)) != 0u) {
            link_bytes += (uint32_t)n;
        }
        if (board_millis() - last_stats >= 1000u) {
            last_stats += 1000u;
            console_stats();
        }
        board_wait_for_interrupt();
    }
}
