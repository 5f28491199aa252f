/* Bring-up image: echoes the link's bytes and says hello; proves the vector table, clocks, SysTick and
   USART1 under QEMU before the core arrives. */
#include "board.h"

int main(void)
{
    board_init();
    static const uint8_t hello[] = "ultraglide netduinoplus2 bring-up\n";
    (void)board_uart_write(hello, sizeof hello - 1u);
    uint32_t last = 0;
    for (;;) {
        uint8_t buffer[64];
        size_t n = board_uart_read(buffer, sizeof buffer);
        if (n) {
            (void)board_uart_write(buffer, n);
        }
        uint32_t now = board_millis();
        if (now - last >= 1000u) {
            last = now;
            static const uint8_t tick[] = "tick\n";
            (void)board_uart_write(tick, sizeof tick - 1u);
        }
        board_wait_for_interrupt();
    }
}
