/*
 * ug_force.c - the force correction (docs/protocol.md, "The force correction"; docs/design.md, "Steps and
 * the force's age").
 *
 * A host computes each amplitude from the model's inverse at a normal force it measured 15-25 ms before the
 * value plays (the sensors' lag, a SENSORS frame, the link, the jitter buffer); the press moves meanwhile.
 * SETPOINTS_FORCE frames carry, beside their values, the force the host assumed (F_h), the model's local
 * force exponent there (e = d ln a / d ln F) and the host's own limit. At play the core scales the value by
 * (F / F_h)^e, F its own normal force of the last ADC block (about a millisecond old), and caps it at the
 * smaller of the host's and its own limit. A reading outside F_h / 2 .. 2 F_h (or not finite) is a sensor
 * fault or a lift, not a press the model can follow: the value plays as sent.
 *
 * The buffer's values carry their frame's reference through marks (ordinal of the first value, reference),
 * one where the reference changes; the playing reference changes when its first value is popped. Cost: one
 * powf per ADC block and per reference change; per drive sample a multiply and a compare.
 */
#include <math.h>

#include "ug_internal.h"

static void update_gain(ug_core *core) {
    float gain = 1.0f;
    if (core->force_exponent != 0.0f && isfinite(core->force_now_n)) {
        float ratio = core->force_now_n / core->force_ref_n;
        if (ratio >= 1.0f / UG_FORCE_SPAN && ratio <= UG_FORCE_SPAN) {
            gain = powf(ratio, core->force_exponent);
        }
    }
    core->force_gain = gain;
}

static void set_reference(ug_core *core, float force_n, float exponent, float limit) {
    core->force_ref_n = force_n;
    core->force_exponent = exponent;
    core->force_limit = limit;
    update_gain(core);
}

void ug_force_clear(ug_core *core) {
    core->force_mark_head = 0;
    core->force_mark_count = 0;
    core->force_tail_exponent = 0.0f;
    core->force_tail_ref_n = 1.0f;
    core->force_tail_limit = 1.0f;
    set_reference(core, 1.0f, 0.0f, 1.0f);
}

/* the values pushed next (from ordinal `at`) carry this reference; exponent 0: none (a plain SETPOINTS) */
void ug_force_mark(ug_core *core, uint32_t at, float force_n, float exponent, float limit) {
    if (force_n == core->force_tail_ref_n && exponent == core->force_tail_exponent && limit == core->force_tail_limit) {
        return;
    }
    core->force_tail_ref_n = force_n;
    core->force_tail_exponent = exponent;
    core->force_tail_limit = limit;
    unsigned slot;
    if (core->force_mark_count < UG_FORCE_MARKS) {
        slot = (core->force_mark_head + core->force_mark_count) & (UG_FORCE_MARKS - 1u);
        core->force_mark_count++;
    } else { /* a backlog of changes: the newest mark takes the newest reference */
        slot = (core->force_mark_head + UG_FORCE_MARKS - 1u) & (UG_FORCE_MARKS - 1u);
        at = core->force_marks[slot].at;
    }
    core->force_marks[slot].at = at;
    core->force_marks[slot].force_n = force_n;
    core->force_marks[slot].exponent = exponent;
    core->force_marks[slot].limit = limit;
}

/* the value of ordinal `ordinal` is popped: the reference it carries becomes the playing one */
void ug_force_popped(ug_core *core, uint32_t ordinal) {
    while (core->force_mark_count > 0u &&
           (int32_t)(ordinal - core->force_marks[core->force_mark_head].at) >= 0) {
        const unsigned head = core->force_mark_head;
        set_reference(core, core->force_marks[head].force_n, core->force_marks[head].exponent,
                      core->force_marks[head].limit);
        core->force_mark_head = (uint8_t)((head + 1u) & (UG_FORCE_MARKS - 1u));
        core->force_mark_count--;
    }
}

/* the normal force over an ADC block: its mean, NaN if any sample is not finite */
void ug_force_measured(ug_core *core, const float *normal_force_n, size_t n) {
    float sum = 0.0f;
    for (size_t i = 0; i < n; i++) {
        sum += normal_force_n[i];
    }
    core->force_now_n = n > 0u && isfinite(sum) ? sum / (float)n : NAN;
    if (core->force_exponent != 0.0f) {
        update_gain(core);
    }
}

/* a target (fraction of full scale) of the value playing, corrected for the force now and capped */
float ug_force_correct(const ug_core *core, float requested) {
    if (core->force_exponent == 0.0f) {
        return requested;
    }
    float value = requested * core->force_gain;
    float cap = core->force_limit < core->limit_fraction ? core->force_limit : core->limit_fraction;
    return value < cap ? value : cap;
}
