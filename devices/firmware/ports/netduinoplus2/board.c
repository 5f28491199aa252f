#include "board.h"

#include "emulated_plate.h"
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
static uint16_t dac_codes[2u * BOARD_BLOCK_SAMPLES];  /* circular: the DMA plays one half while we fill the other */
static uint16_t adc_codes[2u * BOARD_BLOCK_SAMPLES];

static void irq_enable(uint32_t irq, uint8_t priority)
{
    NVIC_IPR_BYTE(irq) = priority;
    NVIC_ISER(irq / 32u) = 1u << (irq % 32u);
}

static uint32_t irq_save(void)
{
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask) :: "memory");
    return primask;
}

static void irq_restore(uint32_t primask)
{
    __asm__ volatile("msr primask, %0" :: "r"(primask) : "memory");
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
    irq_enable(USART2_IRQn, 0xA0u);  /* below everything: a console line can wait */
}

void USART2_IRQHandler(void)
{
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
    uint32_t primask = irq_save();  /* the main loop and an interrupt may both write lines */
    bool queued = ug_ring_write(&console.tx, (const uint8_t *)text, length);
    if (queued && !(USART_CR1(USART2_BASE) & USART_CR1_TXEIE)) {
        uint8_t byte;
        while ((USART_SR(USART2_BASE) & USART_SR_TXE) && ug_ring_get(&console.tx, &byte)) {
            USART_DR(USART2_BASE) = byte;
        }
        if (ug_ring_used(&console.tx) != 0u) {
            USART_CR1(USART2_BASE) |= USART_CR1_TXEIE;
        }
    }
    irq_restore(primask);
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

void board_dac_blank(uint32_t half)
{
    uint16_t *codes = board_dac_half(half);
    for (uint32_t i = 0; i < BOARD_BLOCK_SAMPLES; i++) {
        codes[i] = 0x8000u;  /* DHR12L1's mid-scale: no drive */
    }
}

#ifdef UG_BOARD_QEMU
/* ---- QEMU: SysTick runs the blocks due by TIM5's count of virtual nanoseconds ------------------------ */
#define TICKS_PER_BLOCK (BOARD_QEMU_TIMER_HZ / 1000u)

static ug_emulated_plate_t plate;
static uint32_t block_ticks;       /* TIM5's count when the next block is due */
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
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | ((uint32_t)BOARD_BLOCK_PRIORITY << 24);
}

void SysTick_Handler(void)
{
    if (carrier_block == 0) {
        millis++;
        return;
    }
    uint32_t late = TIM_CNT(TIM5_BASE) - block_ticks;  /* how long ago the next block fell due */
    if (late >= 0x80000000u) {
        return;  /* not due yet */
    }
    uint32_t due = late / TICKS_PER_BLOCK + 1u;
    if (due > BOARD_STALL_BLOCKS) {  /* QEMU itself did not run (its host descheduled it): nor did the board */
        skipped_ms += due - 1u;
        block_ticks += (due - 1u) * TICKS_PER_BLOCK;
        due = 1u;
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

void DMA2_Stream0_IRQHandler(void)
{
    uint32_t status = DMA_LISR(DMA2_BASE);
    DMA_LIFCR(DMA2_BASE) = DMA_LIFCR_ALL0;
    if (carrier_block && (status & DMA_LISR_HTIF0)) {  /* the first half has been measured (and played) */
        carrier_block(0u);
    }
    if (carrier_block && (status & DMA_LISR_TCIF0)) {
        carrier_block(1u);
    }
}
#endif

void board_init(void)
{
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
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24);  /* SysTick below the blocks (QEMU: raised to them) */
    SYST_RVR = BOARD_CORE_HZ / BOARD_TICK_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

void board_carrier_start(board_block_fn block)
{
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
#ifndef UG_BOARD_QEMU
    TIM_CR1(TIM2_BASE) = 0u;
    DMA_SxCR(DMA1_BASE, 5) = 0u;
    DAC_DHR12L1 = 0x8000u;  /* mid-scale: no drive reaches the amplifier */
#endif
    SYST_CSR = 0u;
    board_dac_blank(0u);
    board_dac_blank(1u);
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi");
}
