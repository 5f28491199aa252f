/* A recording register file for the host's tests of register sequences (tests/test_firmware_watchdog.py):
   every write is logged (address, value) in order; reads of a status register return "busy" a chosen number of
   times before reading 0, and every read is logged too (value 0xFFFFFFFF marks a read). */
#include <stdint.h>

#define LOG_SIZE 256u

static uint32_t log_address[LOG_SIZE], log_value[LOG_SIZE];
static uint32_t log_count;
static uint32_t busy_reads, busy_value;

void ug_host_register_write(uint32_t address, uint32_t value)
{
    if (log_count < LOG_SIZE) {
        log_address[log_count] = address;
        log_value[log_count] = value;
        log_count++;
    }
}

uint32_t ug_host_register_read(uint32_t address)
{
    uint32_t value = 0u;
    if (busy_reads > 0u) {
        busy_reads--;
        value = busy_value;
    }
    if (log_count < LOG_SIZE) {
        log_address[log_count] = address;
        log_value[log_count] = 0xFFFFFFFFu;
        log_count++;
    }
    return value;
}

void shim_registers_reset(uint32_t reads_busy, uint32_t value_while_busy)
{
    log_count = 0u;
    busy_reads = reads_busy;
    busy_value = value_while_busy;
}

uint32_t shim_registers_count(void) { return log_count; }
uint32_t shim_registers_address(uint32_t i) { return log_address[i]; }
uint32_t shim_registers_value(uint32_t i) { return log_value[i]; }
