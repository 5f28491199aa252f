/*
 * ug_sim.h - the software-in-the-loop port: the core in a shared library, driven from Python
 * (ultraglide.devices.firmware, through ctypes) by the simulated plate, whose physics stays in Python.
 *
 * Time is what the caller renders: ug_sim_render() produces drive samples at config.sample_rate_hz and
 * calls ug_core_tick() every millisecond of them, polling the core after each tick (telemetry, SENSORS);
 * ug_sim_sense() hands the core the plate's measured amplitude (and forces) for the samples just
 * rendered. ug_sim_receive() feeds bytes from the link and polls. The caller serialises the calls (one
 * lock): the critical sections here do nothing.
 */
#ifndef UG_SIM_H
#define UG_SIM_H

#include "ug_core.h"

#define UG_SIM_FAULT_QUEUE 8u

typedef struct ug_sim {
    ug_core core;
    uint32_t samples_to_tick; /* drive samples until the next tick */
    uint8_t fault_kind[UG_SIM_FAULT_QUEUE];
    uint16_t fault_ms[UG_SIM_FAULT_QUEUE];
    uint8_t faults_queued;
    uint32_t quiet_until_ms; /* an excused stall: the core's clock catches up to here without telemetry */
    uint8_t quiet;           /* quiet_until_ms holds */
    uint8_t telemetry_owed;  /* telemetry fell due while quiet: one frame once the clock is there */
    uint32_t output_safe_calls; /* ug_port_output_safe() calls so far, and the last one's UG_SAFE_* */
    uint8_t output_safe_why;
    uint32_t samples_since_block; /* drive samples the real clock is past the core's (ug_port_samples_since_block):
                                     set for one ug_sim_receive */
} ug_sim;

size_t ug_sim_size(void);
size_t ug_sim_config_size(void);
size_t ug_sim_status_size(void);
size_t ug_sim_event_size(void);
void ug_sim_config_defaults(ug_config *config);
int ug_sim_init(ug_sim *sim, const ug_config *config);
bool ug_sim_set_breaks(ug_sim *sim, uint32_t breaks);
const char *ug_sim_break_rule(unsigned which);
const char *ug_sim_sources_digest(void);

void ug_sim_poll(ug_sim *sim);
/* lag_ms: how far the caller's real time is ahead of the core's clock (its output stage sleeps, or was
   descheduled): a valid frame among these bytes feeds the watchdog, and setpoints the stream, at the real
   time, as on a board */
size_t ug_sim_receive(ug_sim *sim, const uint8_t *data, size_t n, uint32_t lag_ms);
/* how many drive samples the caller's real time is past the samples rendered and sensed, for the next
   ug_sim_receive only (a CLOCK request among its bytes states the sensor clock at the real time, as a board's DMA
   position would) */
void ug_sim_set_samples_since_block(ug_sim *sim, uint32_t samples);
size_t ug_sim_take_tx(ug_sim *sim, uint8_t *out, size_t max);
void ug_sim_render(ug_sim *sim, float *drive, size_t n);
size_t ug_sim_sense(ug_sim *sim, const float *amplitude_um_pp, const float *normal_force_n,
                    const float *lateral_force_n, size_t n);
void ug_sim_dac(ug_sim *sim, int16_t *out, size_t n_dac);
void ug_sim_set_stage_hot(ug_sim *sim, int hot);
/* the caller did not run for ms (a loaded machine; its clock catches up next): that time is not the host's
   silence, and the telemetry it would have sent meanwhile is not made up afterwards
   (it would report the buffer as it was before the frames that waited on the link): one frame, when the
   core's clock has caught up, says how things are then */
void ug_sim_excuse(ug_sim *sim, uint32_t ms);

void ug_sim_status(const ug_sim *sim, ug_status *out);
int ug_sim_next_event(ug_sim *sim, ug_event *out);
/* blocks' time lost by a port (ug_core_lost_time), ms */
void ug_sim_lost_time(ug_sim *sim, uint32_t ms);
/* how many times the core asked for a silent output (ug_port_output_safe), and why the last time */
uint32_t ug_sim_output_safe_calls(const ug_sim *sim, uint8_t *why);
int ug_sim_take_fault(ug_sim *sim, uint8_t *kind, uint16_t *duration_ms);

#endif /* UG_SIM_H */
