/* ug_safety.c - see ug_safety.h. Board-independent; compiled for the host too (tests/test_firmware_watchdog.py). */
#include "ug_safety.h"

#include <stdatomic.h>
#include <stddef.h>

#ifdef UG_HOST_BUILD
ug_reset_record_t ug_reset_record; /* the host's tests have no linker section to keep */
uint32_t ug_power_mark[2];
#else
__attribute__((section(".noinit"))) ug_reset_record_t ug_reset_record;
__attribute__((section(".noinit"))) uint32_t ug_power_mark[2];
#endif

#define UG_POWER_MARK 0x55475057u /* "UGPW" */

static atomic_uint mark_block, mark_main;

static uint32_t check_of(const volatile ug_reset_record_t *r)
{
    return ~(r->magic ^ r->reason ^ r->detail ^ r->injected ^ r->silent_after_us);
}

void ug_reset_note(uint32_t reason, uint32_t detail, uint32_t silent_after_us)
{
    volatile ug_reset_record_t *r = &ug_reset_record;
    if (r->magic != UG_RESET_MAGIC || r->reason != UG_RESET_SOFTWARE || r->check != 0u) {
        r->injected = 0u; /* no injection noted just before: none */
    }
    r->magic = UG_RESET_MAGIC;
    r->reason = reason;
    r->detail = detail;
    r->silent_after_us = r->injected != 0u ? silent_after_us : UG_NOT_INJECTED;
    if (reason != UG_RESET_WATCHDOG) {
        r->where = 0u;
    }
    r->check = check_of(r);
}

void ug_reset_note_injection(uint32_t kind, uint32_t at)
{
    volatile ug_reset_record_t *r = &ug_reset_record;
    /* a pending record: reason SOFTWARE with check 0 marks "injected, no reset yet" for ug_reset_note */
    r->magic = UG_RESET_MAGIC;
    r->reason = UG_RESET_SOFTWARE;
    r->detail = 0u;
    r->injected = kind;
    r->fault_at = at;
    r->silent_after_us = UG_NOT_INJECTED;
    r->check = 0u;
}

uint32_t ug_reset_take(ug_reset_record_t *out)
{
    volatile ug_reset_record_t *r = &ug_reset_record;
    bool valid = r->magic == UG_RESET_MAGIC && r->check == check_of(r) && r->reason < UG_RESET_REASONS;
    out->magic = UG_RESET_MAGIC;
    out->reason = valid ? r->reason : UG_RESET_POWER_ON;
    out->detail = valid ? r->detail : 0u;
    out->injected = valid ? r->injected : 0u;
    out->fault_at = valid ? r->fault_at : 0u;
    out->silent_after_us = valid ? r->silent_after_us : UG_NOT_INJECTED;
    out->where = valid ? r->where : 0u;
    out->check = 0u;
    r->magic = 0u;
    r->check = 0u;
    r->injected = 0u;
    return out->reason;
}

bool ug_reset_power_kept(void)
{
    volatile uint32_t *mark = ug_power_mark;
    bool kept = mark[0] == UG_POWER_MARK && mark[1] == ~UG_POWER_MARK;
    mark[0] = UG_POWER_MARK;
    mark[1] = ~UG_POWER_MARK;
    return kept;
}

uint32_t ug_reset_take_from_ram(ug_reset_record_t *out)
{
    uint32_t reason = ug_reset_take(out);
    bool kept = ug_reset_power_kept();
    if (reason == UG_RESET_POWER_ON) {
        out->reason = kept ? UG_RESET_PIN : UG_RESET_POWER_ON;
        out->detail = UG_RESET_DETAIL_FROM_RAM;
    }
    return out->reason;
}

const char *ug_reset_name(uint32_t reason)
{
    static const char *const names[UG_RESET_REASONS] = {"power-on", "watchdog", "fault", "software", "pin"};
    return reason < UG_RESET_REASONS ? names[reason] : "unknown";
}

void ug_marks_block(void)
{
    atomic_store_explicit(&mark_block, 1u, memory_order_release);
}

void ug_marks_main(void)
{
    atomic_store_explicit(&mark_main, 1u, memory_order_release);
}

uint32_t ug_marks_peek(void)
{
    return (atomic_load_explicit(&mark_block, memory_order_acquire) ? 1u : 0u)
           | (atomic_load_explicit(&mark_main, memory_order_acquire) ? 2u : 0u);
}

bool ug_marks_take(void)
{
    if (atomic_load_explicit(&mark_block, memory_order_acquire) == 0u
        || atomic_load_explicit(&mark_main, memory_order_acquire) == 0u) {
        return false;
    }
    atomic_store_explicit(&mark_block, 0u, memory_order_relaxed);
    atomic_store_explicit(&mark_main, 0u, memory_order_relaxed);
    return true;
}

static const char *const inject_names[UG_INJECT_KINDS] = {"none", "isr-hang", "main-hang", "stack-overflow",
                                                          "hard-fault"};

const char *ug_inject_name(uint32_t kind)
{
    return kind < UG_INJECT_KINDS ? inject_names[kind] : "unknown";
}

static bool same_word(const char *a, const char *b)
{
    size_t i = 0;
    for (; b[i] != '\0'; i++) {
        if (a[i] != b[i]) {
            return false;
        }
    }
    return a[i] == '\0' || a[i] == '\n' || a[i] == '\r' || a[i] == ' ';
}

uint32_t ug_inject_parse(const char *line)
{
    static const char prefix[] = "fault ";
    for (size_t i = 0; i + 1u < sizeof prefix; i++) {
        if (line[i] != prefix[i]) {
            return UG_INJECT_NONE;
        }
    }
    for (uint32_t kind = 1u; kind < UG_INJECT_KINDS; kind++) {
        if (same_word(line + sizeof prefix - 1u, inject_names[kind])) {
            return kind;
        }
    }
    return UG_INJECT_NONE;
}
