#include "board.h"
#include "cortex_m.h"

#include "emulated_plate.h"
#include "iwdg.h"
#include "port_logic.h"
#include "stm32f405.h"
#include "uart_ring.h"

typedef struct {
    uint32_t base;
    uint32_t irq;
    ug_ring_t tx;
} board_console_t;

static board_console_t console;  /* set up in board_init: an initialiser would put its ring in .data */
static volatile uint32_t millis;
static volatile uint32_t link_overruns;
static board_block_fn carrier_block;
static board_lost_fn carrier_lost;
static uint16_t dac_codes[2u * BOARD_BLOCK_SAMPLES] __attribute__((aligned(8)));  /* circular: the DMA plays one half while we fill the other */
static uint16_t adc_codes[2u * BOARD_BLOCK_SAMPLES];
static volatile uint32_t late_blocks, dma_errors, dac_underruns;

static void irq_enable(uint32_t irq, uint8_t priority)
{
    NVIC_IPR_BYTE(irq) = priority;
    NVIC_ISER(irq / 32u) = 1u << (irq % 32u);
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

/* Clock tree: HSE 25 MHz (the Netduino Plus 2's crystal) → PLL (M 25, N 336, P 2, Q 7) → 168 MHz,
   APB1 42 MHz, APB2 84 MHz, flash at 5 wait states. QEMU models no RCC (its registers read 0) and runs
   the core at 168 MHz whatever is written, so the QEMU image skips this; the waits are bounded anyway. */
static void clock_init(void)
{
#ifndef UG_BOARD_QEMU
    RCC_CR |= RCC_CR_HSEON;
    for (uint32_t i = 0; i < 1000000u && !(RCC_CR & RCC_CR_HSERDY); i++) {
    }
    if (!(RCC_CR & RCC_CR_HSERDY)) {
        return;  /* no crystal: stay on the 16 MHz HSI; the link's baud rate is then wrong and the host hears nothing */
    }
    FLASH_ACR = FLASH_ACR_LATENCY_5WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    RCC_PLLCFGR = 25u | (336u << 6) | (0u << 16) | RCC_PLLCFGR_PLLSRC_HSE | (7u << 24);
    RCC_CR |= RCC_CR_PLLON;
    for (uint32_t i = 0; i < 1000000u && !(RCC_CR & RCC_CR_PLLRDY); i++) {
    }
    RCC_CFGR = RCC_CFGR_PPRE1_DIV4 | RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_SW_PLL;
    for (uint32_t i = 0; i < 1000000u && (RCC_CFGR & RCC_CFGR_SWS_MASK) != RCC_CFGR_SWS_PLL; i++) {
    }
#endif
}

/* ---- USART1: the host link (PA9 TX, PA10 RX, alternate function 7), 8N1 ------------------------------------
   Hardware: both directions by DMA2 (RM0090 table 43: stream 2 channel 4 receives into a circular buffer,
   stream 7 channel 4 sends a chunk at a time), so a 921 600 baud link costs no interrupt a byte; the main
   loop hands what arrived to the core in bulk, and USART1's idle-line interrupt (the end of a burst) wakes it.
   QEMU models no DMA: there RXNE's interrupt hands each byte over, and the main loop sends by writing the
   data register, which QEMU (7.2) transmits at once, TXE staying set. */
#ifdef UG_BOARD_QEMU
static void link_init(void)
{
    USART_BRR(USART1_BASE) = ug_usart_brr(BOARD_APB2_HZ, BOARD_BAUD);
    USART_CR2(USART1_BASE) = 0u;
    USART_CR3(USART1_BASE) = 0u;
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;
    irq_enable(USART1_IRQn, BOARD_LINK_PRIORITY);
}

void USART1_IRQHandler(void)
{
    uint32_t status = USART_SR(USART1_BASE);
    if (status & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t byte = (uint8_t)USART_DR(USART1_BASE);  /* reading DR clears RXNE and ORE */
        if (status & USART_SR_ORE) {
            link_overruns++;
        }
        board_link_received(&byte, 1u);
    }
}

void board_link_service(void)
{
    uint8_t chunk[64];
    size_t n;
    while ((n = board_link_take(chunk, sizeof chunk)) != 0u) {
        for (size_t i = 0; i < n; i++) {
            while (!(USART_SR(USART1_BASE) & USART_SR_TXE)) {  /* never waits under QEMU */
            }
            USART_DR(USART1_BASE) = chunk[i];
            /* each byte sent is the main loop's progress: QEMU's USART writes it to the pty there and then, which
               on a loaded host can take a large part of a millisecond */
            ug_marks_main();
        }
    }
}
#else
#define LINK_RX_DMA_BYTES 1024u  /* 11 ms of a full 921 600 baud link: the main loop takes them every turn */
#define LINK_TX_DMA_BYTES 256u
static uint8_t link_rx_dma[LINK_RX_DMA_BYTES];
static uint8_t link_tx_dma[LINK_TX_DMA_BYTES];
static uint32_t link_rx_taken;  /* where the main loop stopped reading the circular buffer */

static void link_init(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_DMA2EN;
    USART_BRR(USART1_BASE) = ug_usart_brr(BOARD_APB2_HZ, BOARD_BAUD);
    USART_CR2(USART1_BASE) = 0u;
    USART_CR3(USART1_BASE) = USART_CR3_DMAR | USART_CR3_DMAT;
    DMA_LIFCR(DMA2_BASE) = DMA_LIFCR_ALL2;
    DMA_SxPAR(DMA2_BASE, 2) = USART1_BASE + 0x04u;
    DMA_SxM0AR(DMA2_BASE, 2) = (uint32_t)(uintptr_t)link_rx_dma;
    DMA_SxNDTR(DMA2_BASE, 2) = LINK_RX_DMA_BYTES;
    DMA_SxCR(DMA2_BASE, 2) = DMA_SxCR_CHSEL(4) | DMA_SxCR_MINC | DMA_SxCR_CIRC | DMA_SxCR_DIR_P2M | DMA_SxCR_EN;
    DMA_SxPAR(DMA2_BASE, 7) = USART1_BASE + 0x04u;
    DMA_SxM0AR(DMA2_BASE, 7) = (uint32_t)(uintptr_t)link_tx_dma;
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_IDLEIE;
    irq_enable(USART1_IRQn, BOARD_LINK_PRIORITY);
}

void USART1_IRQHandler(void)
{
    uint32_t status = USART_SR(USART1_BASE);
    if (status & (USART_SR_IDLE | USART_SR_ORE)) {
        (void)USART_DR(USART1_BASE);  /* SR then DR clears IDLE and ORE; the DMA has the bytes */
        if (status & USART_SR_ORE) {
            link_overruns++;
        }
        board_link_received(0, 0u);  /* nothing handed over here: it wakes the main loop */
    }
}

void board_link_service(void)
{
    uint32_t head = ug_dma_ring_head(DMA_SxNDTR(DMA2_BASE, 2), LINK_RX_DMA_BYTES);
    if (head < link_rx_taken) {  /* wrapped: the end of the buffer first */
        board_link_received(&link_rx_dma[link_rx_taken], LINK_RX_DMA_BYTES - link_rx_taken);
        link_rx_taken = 0u;
    }
    if (head > link_rx_taken) {
        board_link_received(&link_rx_dma[link_rx_taken], head - link_rx_taken);
        link_rx_taken = head;
    }
    if (!(DMA_SxCR(DMA2_BASE, 7) & DMA_SxCR_EN)) {  /* the last chunk has gone: the next one */
        size_t n = board_link_take(link_tx_dma, LINK_TX_DMA_BYTES);
        if (n != 0u) {
            DMA_HIFCR(DMA2_BASE) = DMA_HIFCR_ALL7;
            DMA_SxNDTR(DMA2_BASE, 7) = (uint32_t)n;
            DMA_SxCR(DMA2_BASE, 7) = DMA_SxCR_CHSEL(4) | DMA_SxCR_MINC | DMA_SxCR_DIR_M2P | DMA_SxCR_EN;
        }
    }
}
#endif

uint32_t board_link_overruns(void)
{
    return link_overruns;
}

/* ---- USART2: the debug console (PA2 TX), transmit only, from its own ring ------------------------------ */
static void console_init(void)
{
    console.base = USART2_BASE;
    console.irq = USART2_IRQn;
    ug_ring_init(&console.tx);
    USART_BRR(USART2_BASE) = ug_usart_brr(BOARD_APB1_HZ, BOARD_CONSOLE_BAUD);
    USART_CR2(USART2_BASE) = 0u;
    USART_CR3(USART2_BASE) = 0u;
    USART_CR1(USART2_BASE) = USART_CR1_UE | USART_CR1_TE;
#ifdef UG_BOARD_QEMU
    USART_CR1(USART2_BASE) = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;  /* fault commands */
#endif
    irq_enable(USART2_IRQn, BOARD_CONSOLE_PRIORITY);  /* below everything: a console line can wait */
}

#ifdef UG_BOARD_QEMU
/* The QEMU image's console takes one command, `fault KIND` (ug_safety.h): the fault injection of
   `plate-sim --board-fault`. The hardware image's console has no receiver. */
static char command[32];
static uint32_t command_length;
static volatile uint32_t injected;

uint32_t board_injected_fault(void)
{
    return injected;
}

static void console_received(uint8_t byte)
{
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
#endif

void USART2_IRQHandler(void)
{
#ifdef UG_BOARD_QEMU
    if (USART_SR(USART2_BASE) & (USART_SR_RXNE | USART_SR_ORE)) {
        console_received((uint8_t)USART_DR(USART2_BASE));
    }
#endif
    if ((USART_CR1(USART2_BASE) & USART_CR1_TXEIE) && (USART_SR(USART2_BASE) & USART_SR_TXE)) {
        uint8_t byte;
        if (ug_ring_get(&console.tx, &byte)) {
            USART_DR(USART2_BASE) = byte;
        } else {
            USART_CR1(USART2_BASE) &= ~USART_CR1_TXEIE;
        }
    }
}

void board_console_write(const char *text)
{
    size_t length = 0;
    while (text[length] != '\0') {
        length++;
    }
    /* the main loop writes, USART2's interrupt drains: mask that interrupt only (BASEPRI at its priority), never
       the link's or the blocks' */
    uint32_t previous;
    __asm__ volatile("mrs %0, basepri" : "=r"(previous));
    __asm__ volatile("msr basepri_max, %0" :: "r"(BOARD_CONSOLE_PRIORITY) : "memory");
    bool queued = ug_ring_write(&console.tx, (const uint8_t *)text, length);
    if (queued && !(USART_CR1(USART2_BASE) & USART_CR1_TXEIE)) {
        uint8_t byte;
        uint32_t sent = 0u;
        while ((USART_SR(USART2_BASE) & USART_SR_TXE) && ug_ring_get(&console.tx, &byte)) {
            USART_DR(USART2_BASE) = byte;
            if ((++sent & 7u) == 0u) {
                ug_marks_main();  /* progress of the main loop (QEMU takes each byte synchronously: a line can
                                     take milliseconds of the host's time) */
            }
        }
        if (ug_ring_used(&console.tx) != 0u) {
            USART_CR1(USART2_BASE) |= USART_CR1_TXEIE;
        }
    }
    __asm__ volatile("msr basepri, %0" :: "r"(previous) : "memory");
}

/* ---- the carrier's buffers -------------------------------------------------------------------------- */
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
    /* unrolled into 60 double-word stores: ENABLE 0 blanks both halves inside its masked section, whose bound
       ug_port.h states (a loop of them took 180 instructions a half) */
    four_codes *codes = (four_codes *)(void *)board_dac_half(half);
#pragma GCC unroll 60
    for (uint32_t i = 0; i < BOARD_BLOCK_SAMPLES / 4u; i++) {
        codes[i] = 0x8000800080008000ull;  /* DHR12L1's mid-scale: no drive */
    }
}

void board_output_safe(void)
{
    board_dac_blank(0u);
    board_dac_blank(1u);
}

#ifdef UG_BOARD_BENCH
uint32_t board_bench_clock(void)
{
    return TIM_CNT(TIM5_BASE);
}

void board_bench_start(void)
{
    SYST_CSR = 0u;  /* no interrupt counted into the figures */
    RCC_APB1ENR |= RCC_APB1ENR_TIM5EN;
    TIM_PSC(TIM5_BASE) = 0u;
    TIM_ARR(TIM5_BASE) = 0xFFFFFFFFu;
    TIM_CR1(TIM5_BASE) = TIM_CR1_CEN;
}
#endif

uint32_t board_time_us(void)
{
#ifdef UG_BOARD_QEMU
    return TIM_CNT(TIM5_BASE) / 1000u;  /* virtual ns; wraps every 4.29 s: differences of less than that */
#else
    return millis * 1000u;
#endif
}

static uint32_t board_clock(void)
{
#ifdef UG_BOARD_QEMU
    return TIM_CNT(TIM5_BASE);  /* ns */
#else
    return millis * 1000000u;
#endif
}

void board_output_off(void)
{
#ifndef UG_BOARD_QEMU
    DMA_SxCR(DMA1_BASE, 5) = 0u;   /* the DAC's DMA stops */
    TIM_CR1(TIM2_BASE) = 0u;       /* and its trigger */
    DAC_CR = DAC_CR_EN1;           /* no trigger: a write to DHR reaches the output one APB1 clock later */
    DAC_DHR12L1 = 0x8000u;         /* mid-scale: no drive */
#endif
    board_dac_stopped = 1u;
    board_silent_at = board_clock();
    board_output_safe();
}


static void reset_reason_read(void)
{
#ifdef UG_BOARD_QEMU
    /* QEMU's STM32F405 models no RCC (RCC_CSR reads 0): the record, else the RAM (ug_safety.h) */
    (void)cortex_m_reset_read(1);
#else
    uint32_t reset_reason = cortex_m_reset_read(0);
    /* the hardware's own flags decide where no record was left (the IWDG resets without warning) */
    uint32_t flags = RCC_CSR;
    RCC_CSR = flags | RCC_CSR_RMVF;
    if (reset_reason == UG_RESET_POWER_ON) {
        if (flags & (RCC_CSR_IWDGRSTF | RCC_CSR_WWDGRSTF)) {
            cortex_m_reset_reason_set(UG_RESET_WATCHDOG);
        } else if ((flags & RCC_CSR_PINRSTF) && !(flags & RCC_CSR_PORRSTF)) {
            cortex_m_reset_reason_set(UG_RESET_PIN);
        }
    }
#endif
}

uint32_t board_late_blocks(void)
{
    return late_blocks;
}

uint32_t board_dma_errors(void)
{
    return dma_errors;
}

uint32_t board_dac_underruns(void)
{
    return dac_underruns;
}

#ifdef UG_BOARD_QEMU
/* ---- QEMU: SysTick runs the blocks due by TIM5's count of virtual nanoseconds ------------------------ */
#define TICKS_PER_BLOCK (BOARD_QEMU_TIMER_HZ / 1000u)

static ug_emulated_plate_t plate;
static volatile uint32_t block_ticks;  /* TIM5's count when the next block is due (the block interrupt moves it) */
static uint32_t next_half;
static volatile uint32_t skipped_ms;

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
        board_dac_blank(half);  /* the DAC's DMA is stopped: it holds mid-scale */
    }
    ug_emulated_plate_run(&plate, board_dac_half(half), &adc_codes[(half & 1u) * BOARD_BLOCK_SAMPLES],
                          BOARD_BLOCK_SAMPLES);
}

static void carrier_clock_start(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_TIM5EN;
    TIM_PSC(TIM5_BASE) = 0u;
    TIM_ARR(TIM5_BASE) = 0xFFFFFFFFu;
    TIM_CR1(TIM5_BASE) = TIM_CR1_CEN;
    board_dac_blank(0u);
    board_dac_blank(1u);
    block_ticks = TIM_CNT(TIM5_BASE) + TICKS_PER_BLOCK;
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | ((uint32_t)BOARD_WATCHDOG_PRIORITY << 24);
    irq_enable(DMA2_Stream0_IRQn, BOARD_BLOCK_PRIORITY);  /* the block interrupt, pended by SysTick */
}

/* ---- QEMU: the watchdog's stand-in ---------------------------------------------------------------------
   QEMU's netduinoplus2 models no IWDG (and its TIM2..5 cannot interrupt periodically: QEMU 7.2 re-arms them
   further away each time). SysTick, at the highest priority, looks at the two marks every millisecond of virtual
   time: both set since its last look, and the board is alive; BOARD_WATCHDOG_MISSES looks in a row without,
   spanning BOARD_WATCHDOG_US of virtual time (one look after QEMU itself stalled is not the board's fault), and it
   does what the IWDG's expiry does on hardware (a reset), after silencing the output first.
   Until both marks have been seen BOARD_WATCHDOG_WARM_TAKES times (about as many ms), the window is
   BOARD_WATCHDOG_BOOT_US: QEMU translates each code path the
   first time it runs, and the first blocks after boot took 4-10 ms of the host's time on a loaded machine (the
   false reset CI saw), while the looks, already translated, came on time. */
static uint32_t watchdog_ok_at, watchdog_misses, watchdog_on, watchdog_excused, watchdog_last_look, watchdog_warm;
static volatile uint32_t watchdog_stalls;
static volatile uint32_t block_busy;  /* the block interrupt is running */
static volatile uint32_t interrupted_pc;  /* where SysTick found the processor (the last look) */
static uint32_t busy_pc;  /* where the last look found the block interrupt running (0: not running) */
static volatile uint32_t watchdog_looks;

uint32_t board_watchdog_looks(void)
{
    return watchdog_looks;
}

static void watchdog_look(void)
{
    if (!watchdog_on) {
        return;
    }
    watchdog_looks++;
    uint32_t now = TIM_CNT(TIM5_BASE);
    uint32_t since_look = now - watchdog_last_look;
    watchdog_last_look = now;
    if (since_look > BOARD_WATCHDOG_STALL_US * 1000u) {
        /* this look came late: QEMU itself did not run (its host descheduled it), nor did the board, whose
           marks had no chance: the window starts again (as the blocks skip such a stall) */
        watchdog_ok_at = now;
        watchdog_misses = 0u;
        watchdog_stalls++;
        return;
    }
    if (ug_marks_take()) {
        watchdog_ok_at = now;
        watchdog_misses = 0u;
        if (watchdog_warm < BOARD_WATCHDOG_WARM_TAKES) {
            watchdog_warm++;
        }
        return;
    }
    if (watchdog_warm < BOARD_WATCHDOG_WARM_TAKES && now - watchdog_ok_at < BOARD_WATCHDOG_BOOT_US * 1000u) {
        return;
    }
    uint32_t pc = interrupted_pc, moved = pc - busy_pc + BOARD_HANG_SPAN_BYTES > 2u * BOARD_HANG_SPAN_BYTES;
    busy_pc = block_busy ? pc : 0u;
    if (block_busy && (ug_marks_peek() == 1u || moved) && now - watchdog_ok_at < BOARD_WATCHDOG_BUSY_US * 1000u) {
        /* the block interrupt is running, catching up blocks that fell due while QEMU ran slower than real time
           (a loaded host): the main loop had no turn, through no fault of its own; or, its mark not set yet, it
           is still in its first block but has moved on since the last look (QEMU starved by its host runs the
           guest slower than its clock; a hung interrupt spins in one place). Excused up to a bound */
        watchdog_misses = 0u;
        watchdog_excused++;
        return;
    }
    watchdog_misses++;
    if (watchdog_misses >= BOARD_WATCHDOG_MISSES && now - watchdog_ok_at >= BOARD_WATCHDOG_US * 1000u) {
        ug_reset_record.where = interrupted_pc;
        board_reset(UG_RESET_WATCHDOG, ug_marks_peek() | (watchdog_misses & 0xFFu) << 8 | watchdog_stalls << 16);
    }
}

uint32_t board_watchdog_stalls(void)
{
    return watchdog_stalls;
}

void board_watchdog_start(void)
{
    watchdog_ok_at = TIM_CNT(TIM5_BASE);
    watchdog_last_look = watchdog_ok_at;
    watchdog_on = 1u;
}

void board_watchdog_service(void)
{
}

/* SysTick, at the highest priority, is the QEMU image's clock: each millisecond it looks at the watchdog's marks
   (the stand-in above) and pends the block interrupt (DMA2 stream 0's, as on hardware, at the blocks' priority),
   which runs the blocks due. A hung block interrupt does not stop it. */
__attribute__((used)) static void systick(uint32_t *frame)
{
    interrupted_pc = frame[6];
    watchdog_look();
    if (carrier_block == 0) {
        millis++;
        return;
    }
    NVIC_ISPR(DMA2_Stream0_IRQn / 32u) = 1u << (DMA2_Stream0_IRQn % 32u);
}

__attribute__((naked)) void SysTick_Handler(void)
{
    __asm__ volatile("mov r0, sp\n\t"  /* the exception frame: r0-r3, r12, lr, pc, xpsr (no FP context stacked lazily) */
                     "push {r4, lr}\n\t"
                     "bl systick\n\t"
                     "pop {r4, pc}\n\t");
}

/* Where the ADC is within its block: TIM5's count past the end of the block last run (block_ticks is when the next
   one falls due), the clock the blocks themselves are run by. Called from the main loop with the blocks masked, so
   block_ticks and the blocks the core has are the same blocks. */
static board_clock_read_t clock_read;  /* the main loop's only (ug_core_poll writes, port_service reads) */
_Static_assert((uint64_t)TICKS_PER_BLOCK * BOARD_BLOCK_DRIVE < 0x100000000ull, "the samples' product fits 32 bits");

uint32_t board_samples_since_block(void)
{
    if (carrier_block == 0) {
        return 0u;
    }
    uint32_t now = TIM_CNT(TIM5_BASE);
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
    if (carrier_block != 0 && TIM_CNT(TIM5_BASE) - block_ticks < 0x80000000u) {
        NVIC_ISPR(DMA2_Stream0_IRQn / 32u) = 1u << (DMA2_Stream0_IRQn % 32u);  /* runs before the next instruction */
        __asm__ volatile("dsb\n\tisb" ::: "memory");
    }
}

static void run_blocks(void);

void DMA2_Stream0_IRQHandler(void)
{
    if (carrier_block == 0) {
        return;
    }
    block_busy = 1u;
    run_blocks();
    block_busy = 0u;
    ug_marks_block();  /* the block interrupt ran to its end (blocks due or not) */
}

static void run_blocks(void)
{
    uint32_t late = TIM_CNT(TIM5_BASE) - block_ticks;  /* how long ago the next block fell due */
    if (late >= 0x80000000u) {
        return;  /* not due yet */
    }
    uint32_t due = late / TICKS_PER_BLOCK + 1u;
    if (injected == UG_INJECT_ISR_HANG) {
        board_inject_now(UG_INJECT_ISR_HANG);  /* the block interrupt stops here */
    }
    if (due > BOARD_STALL_BLOCKS) {  /* QEMU itself did not run (its host descheduled it): nor did the board */
        skipped_ms += due - 1u;
        block_ticks += (due - 1u) * TICKS_PER_BLOCK;
        due = 1u;
    }
    if (due > 1u) {
        late_blocks += due - 1u;  /* blocks that ran late (each still plays its own fresh half) */
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

void board_inject_now(uint32_t kind)
{
    board_console_write(kind == UG_INJECT_ISR_HANG ? "ev fault_injected kind=isr-hang\n"
                        : kind == UG_INJECT_MAIN_HANG ? "ev fault_injected kind=main-hang\n"
                        : kind == UG_INJECT_STACK_OVERFLOW ? "ev fault_injected kind=stack-overflow\n"
                        : "ev fault_injected kind=hard-fault\n");
    ug_reset_note_injection(kind, TIM_CNT(TIM5_BASE));  /* the clock from which the silence is timed */
    if (kind == UG_INJECT_STACK_OVERFLOW) {
        extern void board_overflow_stack(uint32_t depth);
        board_overflow_stack(0u);
    }
    if (kind == UG_INJECT_HARD_FAULT) {
        (void)*(volatile uint32_t *)0xF0000000u;  /* nothing answers there: a bus fault, escalated to HardFault */
    }
    for (;;) {
        __asm__ volatile("nop");  /* the hangs: interrupts stay on (main-hang) or this one never returns (isr-hang) */
    }
}

/* Recurse with a frame the compiler cannot drop until the stack runs off the bottom of RAM (the stack sits
   below .data and .bss: it faults instead of writing over the core's state). */
static volatile uint32_t overflow_depth = 0xFFFFFFFFu;  /* volatile: the compiler may not prove it endless */

__attribute__((noinline)) void board_overflow_stack(uint32_t depth)
{
    volatile uint32_t frame[16];
    frame[depth % 16u] = depth;
    if (depth < overflow_depth) {
        board_overflow_stack(frame[depth % 16u] + 1u);
    }
    __asm__ volatile("" ::: "memory");
}
#else
/* ---- hardware: TIM2 triggers DAC1 and ADC1 together; DMA2's interrupt runs each block --------------- */
void SysTick_Handler(void)
{
    millis++;
}

static void carrier_clock_start(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN | RCC_AHB1ENR_DMA1EN | RCC_AHB1ENR_DMA2EN;
    RCC_APB1ENR |= RCC_APB1ENR_TIM2EN | RCC_APB1ENR_DACEN;
    RCC_APB2ENR |= RCC_APB2ENR_ADC1EN;
    GPIO_MODER(GPIOA_BASE) |= GPIOA_PIN_ANALOG(4) | GPIOA_PIN_ANALOG(1);
    board_dac_blank(0u);
    board_dac_blank(1u);
    DAC_DHR12L1 = 0x8000u;

    /* DAC1 (PA4): converts on TIM2's TRGO, fed by DMA1 stream 5 channel 7 over both halves, 16-bit words into
       its left-aligned holding register */
    DMA_HIFCR(DMA1_BASE) = DMA_HIFCR_ALL5;
    DMA_SxPAR(DMA1_BASE, 5) = DAC_DHR12L1_ADDRESS;
    DMA_SxM0AR(DMA1_BASE, 5) = (uint32_t)(uintptr_t)dac_codes;
    DMA_SxNDTR(DMA1_BASE, 5) = 2u * BOARD_BLOCK_SAMPLES;
    DMA_SxCR(DMA1_BASE, 5) = DMA_SxCR_CHSEL(7) | DMA_SxCR_MSIZE_16 | DMA_SxCR_PSIZE_16 | DMA_SxCR_MINC
                             | DMA_SxCR_CIRC | DMA_SxCR_DIR_M2P | DMA_SxCR_EN;
    DAC_CR = DAC_CR_EN1 | DAC_CR_TEN1 | DAC_CR_TSEL1_TIM2 | DAC_CR_DMAEN1;

    /* ADC1 (PA1, the sensing piezo): one conversion on each TRGO (ADCCLK 21 MHz, 15 + 12 cycles: 1.3 us of the
       4.2 us between triggers), drained by DMA2 stream 0 channel 0 over both halves; its half- and
       full-transfer interrupts are the block clock */
    ADC_CCR = ADC_CCR_ADCPRE_DIV4;
    ADC_SMPR2(ADC1_BASE) = 1u << 3;  /* channel 1: 15 cycles */
    ADC_SQR3(ADC1_BASE) = 1u;        /* one conversion: channel 1 */
    DMA_LIFCR(DMA2_BASE) = DMA_LIFCR_ALL0;
    DMA_SxPAR(DMA2_BASE, 0) = ADC1_BASE + 0x4Cu;
    DMA_SxM0AR(DMA2_BASE, 0) = (uint32_t)(uintptr_t)adc_codes;
    DMA_SxNDTR(DMA2_BASE, 0) = 2u * BOARD_BLOCK_SAMPLES;
    DMA_SxCR(DMA2_BASE, 0) = DMA_SxCR_CHSEL(0) | DMA_SxCR_MSIZE_16 | DMA_SxCR_PSIZE_16 | DMA_SxCR_MINC
                             | DMA_SxCR_CIRC | DMA_SxCR_DIR_P2M | DMA_SxCR_HTIE | DMA_SxCR_TCIE | DMA_SxCR_EN;
    ADC_CR2(ADC1_BASE) = ADC_CR2_ADON | ADC_CR2_DMA | ADC_CR2_DDS | ADC_CR2_EXTSEL_TIM2_TRGO | ADC_CR2_EXTEN_RISING;
    irq_enable(DMA2_Stream0_IRQn, BOARD_BLOCK_PRIORITY);

    /* TIM2 at 84 MHz: an update (TRGO) every 350 counts, 240 kHz; both converters start on its first */
    TIM_PSC(TIM2_BASE) = 0u;
    TIM_ARR(TIM2_BASE) = ug_timer_arr(BOARD_TIMER_APB1_HZ, BOARD_DAC_RATE_HZ);
    TIM_CR2(TIM2_BASE) = TIM_CR2_MMS_UPDATE;
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;
}

/* The hardware watchdog: the IWDG (iwdg.h), refreshed by the block interrupt when both marks were set. */
void board_watchdog_start(void)
{
    (void)ug_iwdg_start(BOARD_WATCHDOG_US, IWDG_LSI_HZ);
}

void board_watchdog_service(void)
{
    if (ug_marks_take()) {
        ug_iwdg_refresh();
    }
}

/* Where the ADC is within its block: DMA2 stream 0's conversions left in its lap (NDTR, counting down over both
   halves) place it within the half it fills now; a half's completion flagged and not yet taken (the main loop has
   the blocks masked) means the core is a block behind the DMA, which can then say no more than a block less one.
   NDTR first: a half completing between the two reads is then seen as pending (behind, never ahead). */
uint32_t board_samples_since_block(void)
{
    if (carrier_block == 0) {
        return 0u;
    }
    uint32_t ndtr = DMA_SxNDTR(DMA2_BASE, 0);
    uint32_t pending = DMA_LISR(DMA2_BASE) & (DMA_LISR_HTIF0 | DMA_LISR_TCIF0);
    return ug_dma_samples_since_block(ndtr, BOARD_BLOCK_SAMPLES, BOARD_OVERSAMPLE, pending);
}

void DMA2_Stream0_IRQHandler(void)
{
    uint32_t status = DMA_LISR(DMA2_BASE);
    DMA_LIFCR(DMA2_BASE) = DMA_LIFCR_ALL0;
    uint32_t dac_dma = DMA_HISR(DMA1_BASE);
    if (dac_dma & DMA_HISR_TEIF5) {
        DMA_HIFCR(DMA1_BASE) = DMA_HIFCR_ALL5;
        dma_errors++;
        board_output_off();  /* the DAC's DMA stopped itself on the error: the DAC holds mid-scale, not its last word */
    }
    if (status & DMA_LISR_TEIF0) {
        dma_errors++;
    }
    if (DAC_SR & DAC_SR_DMAUDR1) {
        DAC_SR = DAC_SR_DMAUDR1;
        dac_underruns++;
    }
    if ((status & DMA_LISR_HTIF0) && (status & DMA_LISR_TCIF0)) {
        /* late: both halves finished since the last interrupt, so the DMA is already replaying a half that was
           not refilled. Neither is refilled now (we cannot know which plays): both silent, and the core told
           that these two blocks' time is lost. */
        late_blocks += 2u;
        board_output_safe();
        if (carrier_lost) {
            carrier_lost(2u);
        }
    } else if (carrier_block && (status & DMA_LISR_HTIF0)) {  /* the first half has been measured (and played) */
        carrier_block(0u);
    } else if (carrier_block && (status & DMA_LISR_TCIF0)) {
        carrier_block(1u);
    }
    board_watchdog_service();
}
#endif

void board_init(void)
{
    board_output_safe();  /* power-up: both DAC halves silent before anything can start the output */
    reset_reason_read();
    clock_init();
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    RCC_APB1ENR |= RCC_APB1ENR_USART2EN;
    /* PA2 (USART2 TX), PA9 (USART1 TX), PA10 (USART1 RX): alternate function 7 */
    GPIO_MODER(GPIOA_BASE) = (GPIO_MODER(GPIOA_BASE) & ~((3u << 4) | (3u << 18) | (3u << 20)))
                             | (GPIO_MODE_AF << 4) | (GPIO_MODE_AF << 18) | (GPIO_MODE_AF << 20);
    GPIO_AFRL(GPIOA_BASE) = (GPIO_AFRL(GPIOA_BASE) & ~(0xFu << 8)) | (7u << 8);
    GPIO_AFRH(GPIOA_BASE) = (GPIO_AFRH(GPIOA_BASE) & ~((0xFu << 4) | (0xFu << 8))) | (7u << 4) | (7u << 8);
    console_init();
    link_init();
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24);  /* SysTick below the blocks (QEMU: raised above all) */
    SYST_RVR = BOARD_CORE_HZ / BOARD_TICK_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

void board_carrier_start(board_block_fn block, board_lost_fn lost)
{
    carrier_lost = lost;
    carrier_clock_start();
    carrier_block = block;
}

uint32_t board_millis(void)
{
    return millis;
}

void board_fault_stop(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
    board_output_off();
    SYST_CSR = 0u;
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi");
}
