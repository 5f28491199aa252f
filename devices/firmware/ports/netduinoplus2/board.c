#include "board.h"

#include "port_logic.h"
#include "stm32f405.h"
#include "uart_ring.h"

typedef struct {
    uint32_t base;
    uint32_t irq;
    ug_ring_t rx;
    ug_ring_t tx;
    volatile uint32_t overruns;
} board_usart_t;

static board_usart_t link;     /* set up in board_init: an initialiser would put the rings' 8 KiB in .data */
static board_usart_t console;
static volatile uint32_t millis;
static board_refill_fn carrier_refill;
static uint16_t carrier_codes[2u * BOARD_BLOCK_SAMPLES];  /* the DMA's circular buffer: two blocks */
#ifndef UG_BOARD_QEMU
static uint16_t sense_codes[BOARD_SENSE_SAMPLES];
#endif

static void irq_enable(uint32_t irq, uint8_t priority)
{
    NVIC_IPR_BYTE(irq) = priority;
    NVIC_ISER(irq / 32u) = 1u << (irq % 32u);
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

/* USART1 on PA9 (TX) / PA10 (RX) and USART2 on PA2 (TX), alternate function 7, 8N1, by interrupt. */
static void usart_init(board_usart_t *usart, uint32_t base, uint32_t irq, uint32_t pclk_hz, uint32_t baud,
                       uint32_t receive)
{
    usart->base = base;
    usart->irq = irq;
    usart->overruns = 0u;
    ug_ring_init(&usart->rx);
    ug_ring_init(&usart->tx);
    USART_BRR(usart->base) = ug_usart_brr(pclk_hz, baud);
    USART_CR2(usart->base) = 0u;
    USART_CR3(usart->base) = 0u;
    USART_CR1(usart->base) = USART_CR1_UE | USART_CR1_TE | (receive ? USART_CR1_RE | USART_CR1_RXNEIE : 0u);
    irq_enable(usart->irq, 0x40u);  /* above the carrier (0x60) and tick (0x80): a byte never waits for a block */
}

static void usart_interrupt(board_usart_t *usart)
{
    uint32_t status = USART_SR(usart->base);
    if (status & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t byte = (uint8_t)USART_DR(usart->base);  /* reading DR clears RXNE and ORE */
        if (status & USART_SR_ORE) {
            usart->overruns++;
        }
        (void)ug_ring_put(&usart->rx, byte);
    }
    if ((USART_CR1(usart->base) & USART_CR1_TXEIE) && (status & USART_SR_TXE)) {
        uint8_t byte;
        if (ug_ring_get(&usart->tx, &byte)) {
            USART_DR(usart->base) = byte;
        } else {
            USART_CR1(usart->base) &= ~USART_CR1_TXEIE;
        }
    }
}

/* Queue bytes, then prime the transmitter: write while the data register is empty and leave the rest to
   the TXE interrupt. On the chip TXE clears at once, so one byte goes here and the interrupt sends the
   rest. QEMU (7.2) transmits synchronously, keeps TXE set and raises no interrupt when TXEIE is set, so
   there the whole queue goes here: a TXE-interrupt-only driver sends nothing under QEMU until a byte
   arrives. */
static bool usart_write(board_usart_t *usart, const uint8_t *data, size_t length)
{
    if (!ug_ring_write(&usart->tx, data, length)) {
        return false;
    }
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask) :: "memory");  /* keep the consumer out */
    uint8_t byte;
    while ((USART_SR(usart->base) & USART_SR_TXE) && ug_ring_get(&usart->tx, &byte)) {
        USART_DR(usart->base) = byte;
    }
    if (ug_ring_used(&usart->tx) != 0u) {
        USART_CR1(usart->base) |= USART_CR1_TXEIE;
    }
    __asm__ volatile("msr primask, %0" :: "r"(primask) : "memory");
    return true;
}

void USART1_IRQHandler(void)
{
    usart_interrupt(&link);
}

void USART2_IRQHandler(void)
{
    usart_interrupt(&console);
}

void SysTick_Handler(void)
{
    millis++;
}

#ifdef UG_BOARD_QEMU
/* QEMU: TIM2 (modelled, 48 MHz) interrupts once a block and the refill runs on a RAM buffer. */
static void carrier_clock_start(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_TIM2EN;
    TIM_PSC(TIM2_BASE) = 0u;
    TIM_ARR(TIM2_BASE) = ug_timer_arr(BOARD_QEMU_TIMER_HZ, BOARD_DAC_RATE_HZ / BOARD_BLOCK_SAMPLES);
    TIM_EGR(TIM2_BASE) = TIM_EGR_UG;
    TIM_SR(TIM2_BASE) = 0u;
    TIM_DIER(TIM2_BASE) = TIM_DIER_UIE;
    irq_enable(TIM2_IRQn, 0x60u);
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;
}

void TIM2_IRQHandler(void)
{
    TIM_SR(TIM2_BASE) = 0u;
    static uint32_t half;
    if (carrier_refill) {
        carrier_refill(&carrier_codes[half * BOARD_BLOCK_SAMPLES], BOARD_BLOCK_SAMPLES, 0u);
    }
    half ^= 1u;
}
#else
/* Hardware: DAC1 on PA4, triggered by TIM6's update at BOARD_DAC_RATE_HZ, fed by DMA1 stream 5
   channel 7 from the two-block circular buffer. ADC1 (PA1, the sensing piezo) converts continuously
   at ADCCLK 21 MHz, 15 + 12 cycles a sample (778 kS/s), into DMA2 stream 0's circular buffer. */
static void carrier_clock_start(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN | RCC_AHB1ENR_DMA1EN | RCC_AHB1ENR_DMA2EN;
    RCC_APB1ENR |= RCC_APB1ENR_TIM6EN | RCC_APB1ENR_DACEN;
    RCC_APB2ENR |= RCC_APB2ENR_ADC1EN;
    GPIO_MODER(GPIOA_BASE) |= GPIOA_PIN_ANALOG(4) | GPIOA_PIN_ANALOG(1);
    for (uint32_t i = 0; i < 2u * BOARD_BLOCK_SAMPLES; i++) {
        carrier_codes[i] = 2048u;
    }
    DAC_DHR12R1 = 2048u;
    DMA_HIFCR(DMA1_BASE) = DMA_HIFCR_ALL5;
    DMA_SxPAR(DMA1_BASE, 5) = DAC_DHR12R1_ADDRESS;
    DMA_SxM0AR(DMA1_BASE, 5) = (uint32_t)(uintptr_t)carrier_codes;
    DMA_SxNDTR(DMA1_BASE, 5) = 2u * BOARD_BLOCK_SAMPLES;
    DMA_SxCR(DMA1_BASE, 5) = DMA_SxCR_CHSEL(7) | DMA_SxCR_MSIZE_16 | DMA_SxCR_PSIZE_16 | DMA_SxCR_MINC
                             | DMA_SxCR_CIRC | DMA_SxCR_DIR_M2P | DMA_SxCR_HTIE | DMA_SxCR_TCIE | DMA_SxCR_EN;
    DAC_CR = DAC_CR_EN1 | DAC_CR_TEN1 | DAC_CR_TSEL1_TIM6 | DAC_CR_DMAEN1;
    irq_enable(DMA1_Stream5_IRQn, 0x60u);

    ADC_CCR = ADC_CCR_ADCPRE_DIV4;
    ADC_SMPR2(ADC1_BASE) = 1u << 3;  /* channel 1: 15 cycles */
    ADC_SQR3(ADC1_BASE) = 1u;        /* one conversion: channel 1 */
    DMA_LIFCR(DMA2_BASE) = DMA_LIFCR_ALL0;
    DMA_SxPAR(DMA2_BASE, 0) = ADC1_BASE + 0x4Cu;
    DMA_SxM0AR(DMA2_BASE, 0) = (uint32_t)(uintptr_t)sense_codes;
    DMA_SxNDTR(DMA2_BASE, 0) = BOARD_SENSE_SAMPLES;
    DMA_SxCR(DMA2_BASE, 0) = DMA_SxCR_CHSEL(0) | DMA_SxCR_MSIZE_16 | DMA_SxCR_PSIZE_16 | DMA_SxCR_MINC
                             | DMA_SxCR_CIRC | DMA_SxCR_DIR_P2M | DMA_SxCR_EN;
    ADC_CR2(ADC1_BASE) = ADC_CR2_ADON | ADC_CR2_CONT | ADC_CR2_DMA | ADC_CR2_DDS;
    ADC_CR2(ADC1_BASE) |= ADC_CR2_SWSTART;

    TIM_PSC(TIM6_BASE) = 0u;
    TIM_ARR(TIM6_BASE) = ug_timer_arr(BOARD_TIMER_APB1_HZ, BOARD_DAC_RATE_HZ);
    TIM_CR2(TIM6_BASE) = TIM_CR2_MMS_UPDATE;
    TIM_CR1(TIM6_BASE) = TIM_CR1_CEN;
}

void DMA1_Stream5_IRQHandler(void)
{
    uint32_t status = DMA_HISR(DMA1_BASE);
    DMA_HIFCR(DMA1_BASE) = DMA_HIFCR_ALL5;
    uint32_t sensed = ug_adc_peak_to_peak(sense_codes, BOARD_SENSE_SAMPLES);
    if (carrier_refill && (status & DMA_HISR_HTIF5)) {  /* the first half has played: refill it */
        carrier_refill(&carrier_codes[0], BOARD_BLOCK_SAMPLES, sensed);
    }
    if (carrier_refill && (status & DMA_HISR_TCIF5)) {
        carrier_refill(&carrier_codes[BOARD_BLOCK_SAMPLES], BOARD_BLOCK_SAMPLES, sensed);
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
    usart_init(&link, USART1_BASE, USART1_IRQn, BOARD_APB2_HZ, BOARD_BAUD, 1u);
    usart_init(&console, USART2_BASE, USART2_IRQn, BOARD_APB1_HZ, BOARD_CONSOLE_BAUD, 0u);
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24);  /* SysTick priority 0x80 */
    SYST_RVR = BOARD_CORE_HZ / BOARD_TICK_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

void board_carrier_start(board_refill_fn refill)
{
    carrier_refill = refill;
    carrier_clock_start();
}

uint32_t board_millis(void)
{
    return millis;
}

size_t board_uart_read(uint8_t *data, size_t capacity)
{
    size_t n = 0;
    while (n < capacity && ug_ring_get(&link.rx, &data[n])) {
        n++;
    }
    return n;
}

bool board_uart_write(const uint8_t *data, size_t length)
{
    return usart_write(&link, data, length);
}

uint32_t board_uart_rx_dropped(void)
{
    return link.rx.dropped + link.overruns;
}

uint32_t board_uart_tx_dropped(void)
{
    return link.tx.dropped;
}

void board_console_write(const char *text)
{
    size_t length = 0;
    while (text[length] != '\0') {
        length++;
    }
    (void)usart_write(&console, (const uint8_t *)text, length);
}

void board_fault_stop(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
#ifndef UG_BOARD_QEMU
    TIM_CR1(TIM6_BASE) = 0u;
    DMA_SxCR(DMA1_BASE, 5) = 0u;
    DAC_DHR12R1 = 2048u;  /* mid-scale: no drive reaches the amplifier */
#endif
    TIM_CR1(TIM2_BASE) = 0u;
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi");
}
