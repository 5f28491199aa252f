/*
 * ug_playback.c - the jitter buffer (setpoints in, one value out per step, forward jumps of the stream
 * index kept) and its playback: one drive sample at a time, phase-accumulator stepping at the stream's rate
 * inside the drive clock, linear interpolation between values, the dry hold and the watchdog's ramp.
 */
#include "ug_internal.h"

/* ---- the buffer ------------------------------------------------------------------------------------ */
void ug_buffer_clear(ug_core *core) {
    core->buf_epoch++; /* values staged before this clear are not where a push would put them now */
    core->buf_head = 0;
    core->buf_count = 0;
    core->jump_count = 0;
    ug_force_clear(core);
}

static uint16_t buffer_pop(ug_core *core) {
    uint16_t value = core->buf[core->buf_head];
    core->buf_head = (uint16_t)((core->buf_head + 1u) % UG_BUFFER_CAPACITY);
    core->buf_count--;
    while (core->jump_count > 0u && core->jumps[core->jump_head].at == core->popped) {
        core->next_pop_index += core->jumps[core->jump_head].jump;
        core->jump_head = (uint8_t)((core->jump_head + 1u) & (UG_JUMPS - 1u));
        core->jump_count--;
    }
    core->play_index = core->next_pop_index++;
    ug_force_popped(core, core->popped);
    core->popped++;
    return value;
}

/* values of a frame, from stream index `first`, into the buffer (the caller checked the room) */
void ug_buffer_push(ug_core *core, const uint8_t *codes, uint32_t first, uint16_t n) {
    if (n == 0u) {
        return;
    }
    if (core->buf_count == 0u) {
        core->next_pop_index = first;
        core->jump_count = 0;
    } else if (first != core->tail_index && core->jump_count < UG_JUMPS) {
        unsigned slot = (core->jump_head + core->jump_count) & (UG_JUMPS - 1u);
        core->jumps[slot].at = core->popped + core->buf_count;
        core->jumps[slot].jump = first - core->tail_index;
        core->jump_count++;
    }
    uint16_t at = (uint16_t)((core->buf_head + core->buf_count) % UG_BUFFER_CAPACITY);
    bool staged = core->staged_codes == codes && core->staged_at == at && core->staged_n >= n &&
                  core->staged_epoch == core->buf_epoch;
    core->staged_n = 0;
    if (!staged) { /* not copied before the lock (a late frame's tail, a clear since): copy here */
        for (uint16_t i = 0; i < n; i++) {
            core->buf[at] = ug_get_u16(codes + 2u * i);
            at = (uint16_t)(at + 1u == UG_BUFFER_CAPACITY ? 0u : at + 1u);
        }
    }
    core->buf_count = (uint16_t)(core->buf_count + n);
    core->tail_index = first + n;
}

void ug_set_rate(ug_core *core, uint32_t rate) {
    core->rate = rate;
    core->step = ((uint64_t)rate << 32) / core->config.sample_rate_hz;
    uint32_t prefill = (UG_PREFILL_MS * rate + 999u) / 1000u;
    core->prefill = (uint16_t)(UG_BROKEN(core, UG_BREAK_PREFILL) ? 1u : prefill);
    uint32_t capacity = (uint32_t)core->config.buffer_ms * rate / 1000u;
    core->capacity = (uint16_t)(capacity > UG_BUFFER_CAPACITY ? UG_BUFFER_CAPACITY : capacity);
}


/* ---- playback: one drive sample ------------------------------------------------------------------- */
static float code_fraction(uint16_t code) { return (float)code * (1.0f / (float)UG_SETPOINT_SCALE); }

static void start_playing(ug_core *core) {
    core->current = code_fraction(buffer_pop(core));
    core->phase = 0;
    core->state = UG_PLAYING;
}

static float render_sample(ug_core *core) {
    float requested = 0.0f;
    bool playing = false;       /* a stream value or the dry hold is the target */
    bool value_playing = false; /* a stream value plays (not the hold) */
    uint32_t playing_index = core->play_index;
    switch (core->state) {
    case UG_PREFILL:
        if (core->rate != 0u && core->buf_count >= core->prefill) {
            start_playing(core);
            requested = core->current;
            playing = value_playing = true;
            playing_index = core->play_index;
        }
        break;
    case UG_PLAYING: {
        float next = core->buf_count > 0u ? code_fraction(core->buf[core->buf_head]) : core->current;
        requested = core->current + (next - core->current) * ((float)core->phase * (1.0f / 4294967296.0f));
        playing = value_playing = true;
        uint64_t phase = (uint64_t)core->phase + core->step; /* 33 bits: a stream at the drive rate steps 2^32 */
        bool due = phase > 0xFFFFFFFFu;
        core->phase = (uint32_t)phase;
        if (due) {
            if (core->buf_count > 0u) {
                core->current = code_fraction(buffer_pop(core));
            } else {
                core->state = UG_DRY;
                core->hold = core->current < core->limit_fraction ? core->current : core->limit_fraction;
                if (!UG_BROKEN(core, UG_BREAK_UNDERRUN)) {
                    ug_raise_fault(core, UG_FAULT_UNDERRUN, 0, 0.0f);
                }
            }
        }
        break;
    }
    case UG_DRY:
        if (core->buf_count >= core->prefill) {
            start_playing(core);
            requested = core->current;
            value_playing = true;
            playing_index = core->play_index;
        } else {
            requested = core->hold;
        }
        playing = true;
        break;
    case UG_RAMP: {
        float drive = core->ramp_samples ? core->ramp_from * (float)core->ramp_left / (float)core->ramp_samples : 0.0f;
        if (core->ramp_left > 0u) {
            core->ramp_left--;
        }
        if (core->ramp_left == 0u) {
            ug_port_output_safe(core->port, UG_SAFE_RAMP_END);
            if (core->rate != 0u && core->buf_count >= core->prefill) {
                start_playing(core);
            } else {
                core->state = UG_PREFILL;
            }
        }
        core->drive = ug_limit(core, drive, 0.0f);
        ug_loop_record(core, 0.0f, core->drive);
        core->hist_index[core->hist_head] = UG_NOT_PLAYING;
        return core->drive;
    }
    default:
        break;
    }
    if (playing) {
        requested = ug_force_correct(core, requested);
    }
    float wanted = requested;
    float floor = 0.0f;
    if (playing && core->loop_mode == 1u) {
        wanted = ug_loop_drive(core, requested);
        floor = ug_loop_brake_floor(core, requested);
    } else if (!playing) {
        wanted = 0.0f;
    }
    core->drive = ug_limit(core, wanted, floor);
    ug_loop_record(core, playing ? requested : 0.0f, core->drive);
    core->hist_index[core->hist_head] = value_playing ? playing_index : UG_NOT_PLAYING;
    return core->drive;
}

void ug_core_drive_block(ug_core *core, float *drive, size_t n) {
    for (size_t i = 0; i < n; i++) {
        drive[i] = render_sample(core);
        core->samples++;
    }
}
