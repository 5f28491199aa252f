/* ug_sim.c - the software-in-the-loop port (see ug_sim.h). */
#include <string.h>

#include "ug_sim.h"

/* ---- the port's hooks ---- */
void ug_port_critical_enter(void *port) { (void)port; }
void ug_port_critical_exit(void *port) { (void)port; }
void ug_port_tx_ready(void *port) { (void)port; }
/* the simulated plate's drive is the core's own drive block: it is silent from the next sample the core
   makes after the output went off, so there is nothing of the port's to blank */
void ug_port_output_safe(void *port, uint8_t why) {
    ug_sim *sim = port;
    if (sim != NULL) {
        sim->output_safe_calls++;
        sim->output_safe_why = why;
    }
}

/* the caller's real time past the core's samples (set for one ug_sim_receive): the sensor clock a CLOCK_REPLY states */
uint32_t ug_port_samples_since_block(void *port) {
    const ug_sim *sim = port;
    return sim != NULL ? sim->samples_since_block : 0u;
}

void ug_sim_set_samples_since_block(ug_sim *sim, uint32_t samples) { sim->samples_since_block = samples; }

void ug_port_sim_fault(void *port, uint8_t kind, uint16_t duration_ms) {
    ug_sim *sim = port;
    if (sim->faults_queued < UG_SIM_FAULT_QUEUE) {
        sim->fault_kind[sim->faults_queued] = kind;
        sim->fault_ms[sim->faults_queued] = duration_ms;
        sim->faults_queued++;
    }
}

void ug_sim_lost_time(ug_sim *sim, uint32_t ms) { ug_core_lost_time(&sim->core, ms); }

uint32_t ug_sim_output_safe_calls(const ug_sim *sim, uint8_t *why) {
    *why = sim->output_safe_why;
    return sim->output_safe_calls;
}

/* ---- sizes, for the binding to check its structures against ---- */
size_t ug_sim_size(void) { return sizeof(ug_sim); }
size_t ug_sim_config_size(void) { return sizeof(ug_config); }
size_t ug_sim_status_size(void) { return sizeof(ug_status); }
size_t ug_sim_event_size(void) { return sizeof(ug_event); }
void ug_sim_config_defaults(ug_config *config) { ug_config_defaults(config); }
const char *ug_sim_break_rule(unsigned which) { return ug_break_rule(which); }

#ifndef UG_SOURCES_DIGEST
#define UG_SOURCES_DIGEST ""
#endif
/* SHA-256 of the sources this library was built from (setup.py), for the binding to check */
const char *ug_sim_sources_digest(void) { return UG_SOURCES_DIGEST; }

int ug_sim_init(ug_sim *sim, const ug_config *config) {
    memset(sim, 0, sizeof *sim);
    int result = ug_core_init(&sim->core, config, sim);
    sim->samples_to_tick = config->sample_rate_hz / 1000u;
    return result;
}

bool ug_sim_set_breaks(ug_sim *sim, uint32_t breaks) { return ug_core_set_breaks(&sim->core, breaks); }

void ug_sim_poll(ug_sim *sim) { ug_core_poll(&sim->core); }

size_t ug_sim_receive(ug_sim *sim, const uint8_t *data, size_t n, uint32_t lag_ms) {
    size_t fed = 0;
    uint32_t frames = sim->core.frames_ok, setpoints = sim->core.setpoints;
    while (fed < n) {
        size_t room = ug_core_rx_room(&sim->core);
        size_t chunk = n - fed < room ? n - fed : room;
        ug_core_uart_rx(&sim->core, data + fed, chunk);
        fed += chunk;
        ug_core_poll(&sim->core);
    }
    ug_core_poll(&sim->core);
    sim->samples_since_block = 0u; /* the samples rendered next take the clock on */
    if (sim->core.frames_ok != frames && lag_ms > 0u && sim->core.state != UG_OFF) {
        sim->core.last_frame_ms = sim->core.now_ms + lag_ms; /* ahead of the core's clock: the tick compares signed */
    }
    if (sim->core.setpoints != setpoints && lag_ms > 0u) {
        sim->core.last_setpoints_ms = sim->core.now_ms + lag_ms; /* and the stream's gap: signed too */
    }
    return fed;
}

size_t ug_sim_take_tx(ug_sim *sim, uint8_t *out, size_t max) { return ug_core_uart_tx(&sim->core, out, max); }

/* after a tick: telemetry due while an excused stall is caught up waits for the catch-up's end */
static void hold_telemetry(ug_sim *sim) {
    ug_core *core = &sim->core;
    if (!sim->quiet) {
        return;
    }
    if ((int32_t)(core->now_ms - sim->quiet_until_ms) < 0) {
        sim->telemetry_owed |= core->telemetry_due;
        core->telemetry_due = 0;
        return;
    }
    core->telemetry_due |= sim->telemetry_owed;
    sim->telemetry_owed = 0;
    sim->quiet = 0;
}

void ug_sim_render(ug_sim *sim, float *drive, size_t n) {
    while (n > 0u) {
        size_t chunk = n < sim->samples_to_tick ? n : sim->samples_to_tick;
        ug_core_drive_block(&sim->core, drive, chunk);
        drive += chunk;
        n -= chunk;
        sim->samples_to_tick -= (uint32_t)chunk;
        if (sim->samples_to_tick == 0u) {
            ug_core_tick(&sim->core);
            hold_telemetry(sim);
            ug_core_poll(&sim->core);
            sim->samples_to_tick = sim->core.config.sample_rate_hz / 1000u;
        }
    }
}

size_t ug_sim_sense(ug_sim *sim, const float *amplitude_um_pp, const float *normal_force_n,
                    const float *lateral_force_n, size_t n) {
    return ug_core_adc_block(&sim->core, amplitude_um_pp, normal_force_n, lateral_force_n, n);
}

void ug_sim_dac(ug_sim *sim, int16_t *out, size_t n_dac) { ug_core_dac_block(&sim->core, out, n_dac); }

void ug_sim_set_stage_hot(ug_sim *sim, int hot) { ug_core_set_stage_hot(&sim->core, hot != 0); }

/* the simulator itself did not run for ms (a loaded machine): that time is not the host's silence */
void ug_sim_excuse(ug_sim *sim, uint32_t ms) {
    ug_core *core = &sim->core;
    uint32_t since = core->now_ms - core->last_frame_ms;
    core->last_frame_ms += ms < since ? ms : since;
    sim->quiet_until_ms = core->now_ms + ms;
    sim->quiet = 1;
}

void ug_sim_status(const ug_sim *sim, ug_status *out) { ug_core_status(&sim->core, out); }

int ug_sim_next_event(ug_sim *sim, ug_event *out) { return ug_core_next_event(&sim->core, out) ? 1 : 0; }

int ug_sim_take_fault(ug_sim *sim, uint8_t *kind, uint16_t *duration_ms) {
    if (sim->faults_queued == 0u) {
        return 0;
    }
    *kind = sim->fault_kind[0];
    *duration_ms = sim->fault_ms[0];
    sim->faults_queued--;
    memmove(sim->fault_kind, sim->fault_kind + 1, sim->faults_queued);
    memmove(sim->fault_ms, sim->fault_ms + 1, sim->faults_queued * sizeof sim->fault_ms[0]);
    return 1;
}
