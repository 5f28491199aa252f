/*
 * The boards' glue (port.c, shared by every board port): one firmware core, the port interface it calls (ug_port.h),
 * the link's and the blocks' hand-over to it, and the debug console's lines. main.c runs it; bench.c
 * times it (docs/firmware.md, budgets).
 */
#ifndef UG_PORT_GLUE_H
#define UG_PORT_GLUE_H

#include <stdbool.h>
#include <stdint.h>

#include "ug_core.h"

/* The core's configuration for this board (the QEMU image: the profile in its emulation block) and the
   sensing chain's gain, um p-p per ADC code. */
void port_configure(ug_config *config, float *um_pp_per_code);
/* Start the core (prints the boot line, or the error); UG_OK or UG_BAD_CONFIG. */
int port_start(const ug_config *config, float um_pp_per_code);
ug_core *port_core(void);

/* One block (the block interrupt): measure the ADC half, feed the core, fill the DAC half, tick. */
void port_block(uint32_t half);
/* Blocks whose time was lost (a late block interrupt): the core's clock moves on without output. */
void port_lost(uint32_t blocks);

/* One turn of the main loop: poll the core, start the transmitter, print events and statistics; true
   when there is more to do at once. */
bool port_service(void);
#ifdef UG_BOARD_BENCH
/* The budget image: masked sections since the last call and the longest, instructions (then forgotten). */
void port_critical_figures(uint32_t *count, uint32_t *longest);
#endif
/* Whether an interrupt left work since the last call (and forget it). */
bool port_take_work(void);

#endif
