/*
 * The netduinoplus2 image: the board, the host link and the debug console. (Bring-up: echoes the link
 * until the portable core is wired in.)
 */
#include "board.h"

int main(void)
{
    board_init();
    board_console_write("ev boot board=netduinoplus2\n");
    for (;;) {
        uint8_t buffer[64];
        size_t n = board_uart_read(buffer, sizeof buffer);
        if (n) {
            (void)board_uart_write(buffer, n);
        }
        board_wait_for_interrupt();
    }
}
