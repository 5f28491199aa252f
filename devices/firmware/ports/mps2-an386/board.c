/*
 * The mps2-an386 board (board.h): the CMSDK UARTs, timers and watchdog joined to the shared glue
 * (ports/common/ug_board.h). QEMU's model only: the output is the emulated plate.
 */
#include "board.h"

#include "cmsdk.h"
#include "cortex_m.h"
#include "emulated_plate.h"
#include "port_logic.h"
#include "uart_ring.h"

#ifndef UG_BOARD_QEMU
#error "the mps2-an386 port is built for QEMU's model (make qemu): the board has no DAC or ADC to drive a plate"
#endif

#define TICKS_PER_BLOCK (BOARD_CORE_HZ / 1000u)

static volatile uint32_t millis;
static volatile uint32_t link_overruns;
static board_block_fn carrier_block;
static uint16_t dac_codes[2u * BOARD_BLOCK_SAMPLES] __attribute__((aligned(8)));  /* board_dac_blank: double words */
static uint16_t adc_codes[2u * BOARD_BLOCK_SAMPLES];
static volatile uint32_t late_blocks;
static ug_emulated_plate_t plate;
static volatile uint32_t block_ticks;  /* the board's clock when the next block is due (the block interrupt moves it) */
static uint32_t next_half;
static volatile uint32_t skipped_ms;
static volatile uint32_t injected;
static char command[32];
static uint32_t command_length;

static void irq_enable(uint32_t irq, uint8_t priority)
{
    NVIC_IPR_BYTE(irq) = priority;
    NVIC_ISER(irq / 32u) = 1u << (irq % 32u);
}

/* The board's clock: TIMER1 counts PCLK cycles down from 0xFFFFFFFF, so its complement counts them up (40 ns
   each; wraps every 171.8 s: differences of less than that). */
static uint32_t board_ticks(void)
{
    return ~TIMER_VALUE(TIMER1_BASE);
}

#ifdef UG_BOARD_BENCH
uint32_t board_bench_clock(void)
{
    return board_ticks();
}

void board_bench_start(void)
{
    TIMER_CTRL(TIMER0_BASE) = 0u;  /* no block interrupt counted into the figures; TIMER1 runs from board_init */
}
#endif

uint32_t board_time_us(void)
{
    return board_ticks() / BOARD_TICKS_PER_US;  /* wraps with the ticks: differences of less than 171 s */
}

uint32_t board_mask_blocks(void)
{
    uint32_t previous;
    __asm__ volatile("mrs %0, basepri" : "=r"(previous));
    __asm__ volatile("msr basepri_max, %0" :: "r"(BOARD_BLOCK_PRIORITY) : "memory");  /* only ever raises it */
    return previous;
}

void board_unmask_blocks(uint32_t previous)
{
    __asm__ volatile("msr basepri, %0" :: "r"(previous) : "memory");
}

/* ---- UART0: the host link, a byte an interrupt (QEMU's CMSDK UART holds one received byte) --------------- */
static void link_init(void)
{
    UART_BAUDDIV(UART0_BASE) = BOARD_CORE_HZ / BOARD_BAUD;  /* 27: 925 926 baud, +0.5 % */
    UART_CTRL(UART0_BASE) = UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_RXIE;
    irq_enable(UART0_RX_IRQn, BOARD_LINK_PRIORITY);
}

void UART0RX_Handler(void)
{
    UART_INTSTATUS(UART0_BASE) = UART_INT_RX;
    uint32_t state = UART_STATE(UART0_BASE);
    if (state & UART_STATE_RXOVR) {
        UART_STATE(UART0_BASE) = UART_STATE_RXOVR;  /* write 1 clears */
        link_overruns++;
    }
    if (state & UART_STATE_RXFULL) {
        uint8_t byte = (uint8_t)UART_DATA(UART0_BASE);
        board_link_received(&byte, 1u);
    }
}

/* What the main loop took from the transmit ring and has not yet handed the UART: it never waits for the UART.
   QEMU's UART is full only while its pty is (the host does not read): the main loop then goes on with its turn and
   sends the rest at a later one, and the ring behind fills and counts what it drops (tx_dropped) rather than the
   main loop stopping, which on a loaded host starved the watchdog of its mark (two false resets in a 90 s stream). */
static uint8_t link_pending[64];
static size_t link_pending_at, link_pending_end;

void board_link_service(void)
{
    for (;;) {
        if (link_pending_at == link_pending_end) {
            link_pending_at = 0u;
            link_pending_end = board_link_take(link_pending, sizeof link_pending);
            if (link_pending_end == 0u) {
                return;
            }
        }
        while (link_pending_at < link_pending_end) {
            if (UART_STATE(UART0_BASE) & UART_STATE_TXFULL) {
                return;  /* the pty is full: the rest at the next turn */
            }
            UART_DATA(UART0_BASE) = link_pending[link_pending_at++];
            ug_marks_main();  /* each byte sent is the main loop's progress (QEMU writes it to the pty there and then) */
        }
    }
}

uint32_t board_link_overruns(void)
{
    return link_overruns;
}

/* ---- UART1: the debug console; it takes one command, `fault KIND` (ug_safety.h) ---------------------------- */
static void console_init(void)
{
    UART_BAUDDIV(UART1_BASE) = BOARD_CORE_HZ / BOARD_CONSOLE_BAUD;
    UART_CTRL(UART1_BASE) = UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_RXIE;
    irq_enable(UART1_RX_IRQn, BOARD_CONSOLE_PRIORITY);
}

uint32_t board_injected_fault(void)
{
    return injected;
}

void UART1RX_Handler(void)
{
    UART_INTSTATUS(UART1_BASE) = UART_INT_RX;
    if (!(UART_STATE(UART1_BASE) & UART_STATE_RXFULL)) {
        return;
    }
    uint8_t byte = (uint8_t)UART_DATA(UART1_BASE);
    if (byte == '\n' || byte == '\r') {
        command[command_length] = '\0';
        uint32_t kind = ug_inject_parse(command);
        if (kind != UG_INJECT_NONE) {
            injected = kind;
        }
        command_length = 0u;
    } else if (command_length + 1u < sizeof command) {
        command[command_length++] = (char)byte;
    }
}

/* A line, sent at once: QEMU's UART takes each byte synchronously (TXFULL only while its output is full). */
void board_console_write(const char *text)
{
    uint32_t sent = 0u;
    for (const char *at = text; *at != '\0'; at++) {
        while (UART_STATE(UART1_BASE) & UART_STATE_TXFULL) {
        }
        UART_DATA(UART1_BASE) = (uint8_t)*at;
        if ((++sent & 7u) == 0u) {
            ug_marks_main();  /* progress of the main loop: a line can take a millisecond of the host's time */
        }
    }
}

/* ---- the carrier's buffers and the output ---------------------------------------------------------------- */
uint16_t *board_dac_half(uint32_t half)
{
    return &dac_codes[(half & 1u) * BOARD_BLOCK_SAMPLES];
}

const uint16_t *board_adc_half(uint32_t half)
{
    return &adc_codes[(half & 1u) * BOARD_BLOCK_SAMPLES];
}

_Static_assert(BOARD_BLOCK_SAMPLES % 4u == 0u, "board_dac_blank writes four codes a store");
typedef uint64_t __attribute__((may_alias)) four_codes;  /* the DAC buffer seen four codes at a time */

void board_dac_blank(uint32_t half)
{
    /* unrolled into 60 double-word stores, as the netduinoplus2's: ENABLE 0 blanks both halves inside its masked
       section, whose bound ug_port.h states (the loop of them GCC made ran 180 instructions a half) */
    four_codes *codes = (four_codes *)(void *)board_dac_half(half);
#pragma GCC unroll 60
    for (uint32_t i = 0; i < BOARD_BLOCK_SAMPLES / 4u; i++) {
        codes[i] = 0x8000800080008000ull;  /* left-aligned mid-scale: no drive */
    }
}

void board_output_safe(void)
{
    board_dac_blank(0u);
    board_dac_blank(1u);
}

void board_output_off(void)
{
    board_dac_stopped = 1u;  /* the emulated plate hears mid-scale from its next block on */
    board_silent_at = board_ticks();
    board_output_safe();
}

void board_emulate_plate(float resonance_hz, float q, float drift_hz_per_s, float full_scale_um_pp,
                         float um_pp_per_code)
{
    ug_emulated_plate_init(&plate, resonance_hz, q, drift_hz_per_s, full_scale_um_pp, (float)BOARD_DAC_RATE_HZ,
                           um_pp_per_code);
}

float board_plate_peak_um_pp(void)
{
    return plate.peak_um_pp;
}

uint32_t board_skipped_ms(void)
{
    return skipped_ms;
}

void board_emulate_block(uint32_t half)
{
    if (board_dac_stopped) {
        board_dac_blank(half);
    }
    ug_emulated_plate_run(&plate, board_dac_half(half), &adc_codes[(half & 1u) * BOARD_BLOCK_SAMPLES],
                          BOARD_BLOCK_SAMPLES);
}

uint32_t board_late_blocks(void)
{
    return late_blocks;
}

uint32_t board_dma_errors(void)
{
    return 0u;  /* no DMA on this board */
}

uint32_t board_dac_underruns(void)
{
    return 0u;  /* no DAC on this board: the emulated plate is fed each block by the block interrupt itself */
}


/* ---- the CMSDK watchdog ----------------------------------------------------------------------------------- */
static uint32_t watchdog_refreshed_at, watchdog_warm;
static volatile uint32_t watchdog_refreshes, watchdog_stalls;

static void watchdog_write(volatile uint32_t *reg, uint32_t value)
{
    WDOG_LOCK = WDOG_UNLOCK_KEY;
    *reg = value;
    WDOG_LOCK = 0u;  /* any other value locks it again */
}

void board_watchdog_start(void)
{
    watchdog_refreshed_at = board_ticks();
    watchdog_write(&WDOG_LOAD, BOARD_WATCHDOG_BOOT_US * BOARD_TICKS_PER_US);
    watchdog_write(&WDOG_CONTROL, WDOG_CONTROL_INTEN | (BOARD_WATCHDOG_RESEN ? WDOG_CONTROL_RESEN : 0u));
}

/* The block interrupt, after its mark: refresh only when the main loop's was set too. The boot window stays until
   BOARD_WATCHDOG_WARM_REFRESHES refreshes, then shortens to the timeout (writing LOAD reloads the counter).
   QEMU is not a board: it runs this image with its instruction counter (devices/firmware/qemu.py), on which a busy
   processor's clock moves only with the instructions it runs (a stall of its host pauses it) but a sleeping one's
   keeps real time (board_wait_for_interrupt), so a stall of the host while the board slept is a jump of the clock
   when QEMU runs again. The block interrupt then comes this much later than the last (`stalled`), or has blocks to
   catch up that fell due meanwhile while the main loop had no turn through no fault of its own (`catching_up`,
   excused up to BOARD_WATCHDOG_BUSY_US since both marks were last seen): the window restarts, counted in
   board_watchdog_stalls (the statistics' watchdog_stalls). A hung block interrupt never gets here; a hang keeps the
   processor busy (it never sleeps), so the clock never jumps under it. */
static uint32_t watchdog_ok_at;
static uint32_t watchdog_excuses;  /* NMIs excused in a row (board_watchdog_expired) */
static uint32_t watchdog_millis;   /* the blocks run when the window last started */
static volatile uint32_t block_irq_at;  /* the board's clock when the block interrupt last started */

static uint32_t watchdog_warm_refreshes;

/* The counter restarted from a whole window, whatever stopped it. A jump of the clock of more than two windows
   passes both of the watchdog's expiries at once, and the second stops the counter (its reset is off under QEMU,
   BOARD_WATCHDOG_RESEN): QEMU 7.2's model (up to 9.1) starts it again only when LOAD is written, later ones only when
   CONTROL's INTEN goes from 0 to 1; a hardware watchdog reloads on either. Both, after every excused stall: without
   them the board ran on with no watchdog after one such jump (injected hangs never caught; docs/firmware.md). */
static void watchdog_rearm(void)
{
    uint32_t window_us = watchdog_warm ? BOARD_WATCHDOG_US : BOARD_WATCHDOG_BOOT_US;
    uint32_t control = WDOG_CONTROL_INTEN | (BOARD_WATCHDOG_RESEN ? WDOG_CONTROL_RESEN : 0u);
    watchdog_write(&WDOG_INTCLR, 1u);
    watchdog_write(&WDOG_CONTROL, 0u);
    watchdog_write(&WDOG_CONTROL, control);
    watchdog_write(&WDOG_LOAD, window_us * BOARD_TICKS_PER_US);
}

static void watchdog_refresh(uint32_t now)
{
    if (!watchdog_warm && ++watchdog_warm_refreshes >= BOARD_WATCHDOG_WARM_REFRESHES) {
        watchdog_warm = 1u;
        watchdog_write(&WDOG_LOAD, BOARD_WATCHDOG_US * BOARD_TICKS_PER_US);
    } else {
        watchdog_write(&WDOG_INTCLR, 1u);
    }
    watchdog_refreshed_at = now;
    watchdog_millis = millis;
}

static void watchdog_service(bool stalled, bool catching_up)
{
    uint32_t now = board_ticks();
    if (ug_marks_take()) {
        watchdog_refresh(now);
        watchdog_ok_at = now;
        watchdog_refreshes++;
        watchdog_excuses = 0u;
    } else if (stalled || (catching_up && (ug_marks_peek() & 1u)
                                             && now - watchdog_ok_at < BOARD_WATCHDOG_BUSY_US * BOARD_TICKS_PER_US)) {
        watchdog_refresh(now);
        watchdog_rearm();  /* a jump of the clock may have stopped the counter (watchdog_rearm) */
        watchdog_stalls++;
    }
}

void board_watchdog_service(void)
{
    watchdog_service(false, false);
}

uint32_t board_watchdog_looks(void)
{
    return watchdog_refreshes;
}

uint32_t board_watchdog_stalls(void)
{
    return watchdog_stalls;
}

/* The NMI: the watchdog's first expiry (startup.c passes the exception frame). A mark was missing: the output
   silent, the record written (where the processor was), the board reset. Unless QEMU's clock jumped (on the host's
   clock, or through a stall of its host while the board slept; see watchdog_service): then the NMI comes much later than the
   timeout, or the main loop ran in the window while the block interrupt is not running (the jump raised the NMI and
   the block interrupt together: the NMI is taken first), or the block interrupt is running and played blocks in the
   window or has just started (catching up the blocks that fell due in the jump; a hung one does neither); the
   window restarts, counted, at most BOARD_WATCHDOG_EXCUSES times in a row without a refresh on both marks. A hung
   block interrupt or main loop keeps the processor busy, so the clock moves only with the instructions it runs and
   the NMI comes exactly at the window's end: never late. A hung main loop leaves its mark clear. */
void board_watchdog_expired(const uint32_t *frame)
{
    uint32_t now = board_ticks();
    uint32_t window_us = watchdog_warm ? BOARD_WATCHDOG_US : BOARD_WATCHDOG_BOOT_US;
    uint32_t block_bit = 1u << (TIMER0_IRQn % 32u);
    bool late = now - watchdog_refreshed_at > (window_us + BOARD_WATCHDOG_STALL_US) * BOARD_TICKS_PER_US;
    bool block_running = (NVIC_IABR(TIMER0_IRQn / 32u) & block_bit) != 0u;
    bool main_alive = (ug_marks_peek() & 2u) != 0u;
    /* blocks played in this window, or the block interrupt started in it less than a block and a half ago (a hung
       one stopped before its first block: by the NMI it has played nothing for longer) */
    bool block_progress = millis != watchdog_millis
                          || (block_irq_at - watchdog_refreshed_at < 0x80000000u
                              && now - block_irq_at < BOARD_BLOCK_SLOW_US * BOARD_TICKS_PER_US);
    if ((late || (!block_running && main_alive) || (block_running && block_progress))
        && watchdog_excuses < BOARD_WATCHDOG_EXCUSES) {
        watchdog_excuses++;
        watchdog_rearm();  /* the interrupt cleared; the counter restarted should the jump have stopped it */
        watchdog_refreshed_at = now;
        watchdog_millis = millis;
        watchdog_stalls++;
        return;
    }
    board_output_off();  /* first: the plate silent before anything else */
    ug_reset_record.where = frame[6];
    board_reset(UG_RESET_WATCHDOG, ug_marks_peek() | (watchdog_excuses & 0xFFu) << 8 | (watchdog_stalls & 0xFFFFu) << 16);
}

/* ---- the block clock: TIMER0 every millisecond runs the blocks due by TIMER1 ----------------------------- */
void board_inject_now(uint32_t kind);

void TIMER0_Handler(void)
{
    TIMER_INTCLEAR(TIMER0_BASE) = 1u;
    if (carrier_block == 0) {
        return;
    }
    uint32_t started = board_ticks();
    bool stalled = started - block_irq_at > BOARD_WATCHDOG_STALL_US * BOARD_TICKS_PER_US;
    block_irq_at = started;
    bool catching_up = false;
    uint32_t late = board_ticks() - block_ticks;  /* how long ago the next block fell due */
    if (late < 0x80000000u) {
        uint32_t due = late / TICKS_PER_BLOCK + 1u;
        if (injected == UG_INJECT_ISR_HANG) {
            board_inject_now(UG_INJECT_ISR_HANG);  /* the block interrupt stops here */
        }
        if (due > BOARD_STALL_BLOCKS) {  /* QEMU itself did not run: nor did the board */
            skipped_ms += due - 1u;
            block_ticks += (due - 1u) * TICKS_PER_BLOCK;
            due = 1u;
        }
        if (due > 1u) {
            late_blocks += due - 1u;
            catching_up = true;
        }
        for (uint32_t i = 0; i < due && i < BOARD_CATCH_UP; i++) {
            uint32_t half = next_half;
            board_emulate_block(half);
            carrier_block(half);
            next_half = half ^ 1u;
            block_ticks += TICKS_PER_BLOCK;
            millis++;
        }
    }
    ug_marks_block();  /* the block interrupt ran to its end */
    watchdog_service(stalled, catching_up);
}

/* Where the ADC would be within its block: TIMER1's count past the end of the block last run (block_ticks is when
   the next one falls due), the clock TIMER0's handler runs the blocks by. (TIMER0's own VALUE is no better: it
   interrupts every millisecond but the blocks run by TIMER1, and a late interrupt leaves the two apart.) Called
   from the main loop with the blocks masked, so block_ticks and the blocks the core has are the same blocks. */
static board_clock_read_t clock_read;  /* the main loop's only (ug_core_poll writes, port_service reads) */
_Static_assert((uint64_t)TICKS_PER_BLOCK * BOARD_BLOCK_DRIVE < 0x100000000ull, "the samples' product fits 32 bits");

uint32_t board_samples_since_block(void)
{
    if (carrier_block == 0) {
        return 0u;
    }
    uint32_t now = board_ticks();
    clock_read.reads++;
    clock_read.ticks = now;
    clock_read.due = block_ticks;
    clock_read.blocks = millis;
    return ug_clock_samples_since_block(now, block_ticks, TICKS_PER_BLOCK, BOARD_BLOCK_DRIVE);
}

void board_last_clock_read(board_clock_read_t *out)
{
    *out = clock_read;
}

void board_run_due_blocks(void)
{
    if (carrier_block != 0 && board_ticks() - block_ticks < 0x80000000u) {
        NVIC_ISPR(TIMER0_IRQn / 32u) = 1u << (TIMER0_IRQn % 32u);  /* runs before the next instruction */
        __asm__ volatile("dsb\n\tisb" ::: "memory");
    }
}

void board_carrier_start(board_block_fn block, board_lost_fn lost)
{
    (void)lost;  /* no DMA here: a late block interrupt runs the blocks due late (counted), never loses them */
    board_output_safe();
    /* TIMER0 restarted here, after the clock was read: it interrupts just as each block falls due. Left running
       from board_init, its phase was wherever the boot left it, and each block ran up to a block late (its CLOCK
       replies with it: bench/bench_board_clock.py found 98 of 100 answered with a block due and not run). */
    block_ticks = board_ticks() + TICKS_PER_BLOCK;
    TIMER_VALUE(TIMER0_BASE) = TICKS_PER_BLOCK - 1u;
    block_irq_at = board_ticks();
    carrier_block = block;
}

uint32_t board_millis(void)
{
    return millis;
}

/* ---- injected faults --------------------------------------------------------------------------------------- */
void board_inject_now(uint32_t kind)
{
    board_console_write(kind == UG_INJECT_ISR_HANG ? "ev fault_injected kind=isr-hang\n"
                        : kind == UG_INJECT_MAIN_HANG ? "ev fault_injected kind=main-hang\n"
                        : kind == UG_INJECT_STACK_OVERFLOW ? "ev fault_injected kind=stack-overflow\n"
                        : "ev fault_injected kind=hard-fault\n");
    ug_reset_note_injection(kind, board_ticks());  /* the clock from which the silence is timed */
    if (kind == UG_INJECT_STACK_OVERFLOW) {
        extern void board_overflow_stack(uint32_t depth);
        board_overflow_stack(0u);
    }
    if (kind == UG_INJECT_HARD_FAULT) {
        (void)*(volatile uint32_t *)0xF0000000u;  /* nothing answers there: a bus fault, escalated to HardFault */
    }
    for (;;) {
        __asm__ volatile("nop");
    }
}

static volatile uint32_t overflow_depth = 0xFFFFFFFFu;

__attribute__((noinline)) void board_overflow_stack(uint32_t depth)
{
    volatile uint32_t frame[16];
    frame[depth % 16u] = depth;
    if (depth < overflow_depth) {
        board_overflow_stack(frame[depth % 16u] + 1u);
    }
    __asm__ volatile("" ::: "memory");
}

/* ---- start-up ---------------------------------------------------------------------------------------------- */
extern uint32_t _stack_guard;

/* The MPU forbids the stack's lowest 256 bytes (the linker script's guard): an overflow faults there. The
   default map covers the rest; the fault handlers and the NMI run with the MPU off (HFNMIENA clear). */
static void stack_guard_init(void)
{
    MPU_RNR = 0u;
    MPU_RBAR = (uint32_t)(uintptr_t)&_stack_guard;
    MPU_RASR = MPU_RASR_XN | MPU_RASR_SIZE(8u) | MPU_RASR_ENABLE;  /* 256 bytes (mps2_an386.ld) */
    MPU_CTRL = MPU_CTRL_ENABLE | MPU_CTRL_PRIVDEFENA;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
}

void board_init(void)
{
    board_output_safe();
    /* neither the AN386's SCC and FPGAIO nor QEMU's model of them hold a reset cause: the record, else the RAM */
    (void)cortex_m_reset_read(1);
    stack_guard_init();
    console_init();
    link_init();
    TIMER_CTRL(TIMER1_BASE) = 0u;  /* the board's clock: free-running from 0xFFFFFFFF down */
    TIMER_RELOAD(TIMER1_BASE) = 0xFFFFFFFFu;
    TIMER_VALUE(TIMER1_BASE) = 0xFFFFFFFFu;
    TIMER_CTRL(TIMER1_BASE) = TIMER_CTRL_EN;
    TIMER_CTRL(TIMER0_BASE) = 0u;  /* the block clock: every millisecond */
    TIMER_RELOAD(TIMER0_BASE) = TICKS_PER_BLOCK - 1u;
    TIMER_VALUE(TIMER0_BASE) = TICKS_PER_BLOCK - 1u;
    TIMER_CTRL(TIMER0_BASE) = TIMER_CTRL_EN | TIMER_CTRL_IRQEN;
    irq_enable(TIMER0_IRQn, BOARD_BLOCK_PRIORITY);
}

void board_fault_stop(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
    board_output_off();
    TIMER_CTRL(TIMER0_BASE) = 0u;
    for (;;) {
        __asm__ volatile("wfi");
    }
}

/* The board sleeps until its next interrupt, as a hardware image does. Under QEMU's instruction counter
   (devices/firmware/qemu.py: sleep=on) a sleeping board's clock keeps real time, so a stall of QEMU's host while it
   sleeps is a jump of the clock when QEMU runs again; the watchdog survives one (watchdog_rearm). An image that spun
   here instead held one of the host's cores with QEMU's processor thread at SCHED_FIFO all the time, starving the
   kernel's ordinary-priority work that carries the link's bytes (a pseudo-terminal's flip-buffer kworker: up to
   297 ms), so that a loaded host's stream to the board ran dry (docs/performance.md). */
void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi");
}
