/*
 * A board image (netduinoplus2, mps2-an386): the board (board.h), the port's glue to the firmware core (port.h), and the
 * main loop, which serves the link and the console between the interrupts that do the real-time work.
 */
#include "board.h"
#include "port.h"

int main(void)
{
    board_init();
    ug_config config;
    float um_pp_per_code = 1.0f;
    port_configure(&config, &um_pp_per_code);
    if (port_start(&config, um_pp_per_code) != UG_OK) {
        board_fault_stop();  /* a profile the core refuses: no output, ever */
    }
    board_carrier_start(port_block, port_lost);
    board_watchdog_start();  /* from here on, both marks or a reset */
    for (;;) {
        if (port_service()) {
            continue;  /* more to read before sleeping */
        }
        /* Sleep unless an interrupt left work since the last look. An interrupt between this test and the
           WFI is only heard at the next one (the next block, within 1 ms): the usual cure, masking
           interrupts around the WFI, leaves QEMU 7.2 asleep through the pending interrupt (its NVIC does
           not raise the line while PRIMASK masks it), which cost a 12 kHz stream most of its frames. */
        if (!port_take_work()) {
            board_wait_for_interrupt();
        }
    }
}
