#include "board.h"

#include "port_logic.h"
#include "stm32f405.h"
#include "uart_ring.h"

static ug_ring_t rx_ring;
static ug_ring_t tx_ring;
static volatile uint32_t millis;
static volatile uint32_t usart_overruns;

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
        return;  /* no crystal: stay on the 16 MHz HSI (the link's baud rate will be wrong: say so by silence) */
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

/* USART1 on PA9 (TX) and PA10 (RX), alternate function 7, 8N1 at BOARD_BAUD, receive and transmit
   by interrupt into the rings. */
static void usart1_init(void)
{
    ug_ring_init(&rx_ring);
    ug_ring_init(&tx_ring);
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    GPIO_MODER(GPIOA_BASE) = (GPIO_MODER(GPIOA_BASE) & ~((3u << 18) | (3u << 20)))
                             | (GPIO_MODE_AF << 18) | (GPIO_MODE_AF << 20);
    GPIO_AFRH(GPIOA_BASE) = (GPIO_AFRH(GPIOA_BASE) & ~((0xFu << 4) | (0xFu << 8))) | (7u << 4) | (7u << 8);
    USART_BRR(USART1_BASE) = ug_usart_brr(BOARD_APB2_HZ, BOARD_BAUD);
    USART_CR2(USART1_BASE) = 0u;
    USART_CR3(USART1_BASE) = 0u;
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;
    NVIC_IPR_BYTE(USART1_IRQn) = 0x40u;  /* above the tick (0x80): a byte must not wait behind a block */
    NVIC_ISER(USART1_IRQn / 32u) = 1u << (USART1_IRQn % 32u);
}

void USART1_IRQHandler(void)
{
    uint32_t status = USART_SR(USART1_BASE);
    if (status & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t byte = (uint8_t)USART_DR(USART1_BASE);  /* reading DR clears RXNE and ORE */
        if (status & USART_SR_ORE) {
            usart_overruns++;
        }
        (void)ug_ring_put(&rx_ring, byte);
    }
    if ((USART_CR1(USART1_BASE) & USART_CR1_TXEIE) && (status & USART_SR_TXE)) {
        uint8_t byte;
        if (ug_ring_get(&tx_ring, &byte)) {
            USART_DR(USART1_BASE) = byte;
        } else {
            USART_CR1(USART1_BASE) &= ~USART_CR1_TXEIE;
        }
    }
}

void SysTick_Handler(void)
{
    millis++;
}

void board_init(void)
{
    clock_init();
    usart1_init();
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | (0x80u << 24);  /* SysTick priority 0x80 */
    SYST_RVR = BOARD_CORE_HZ / BOARD_TICK_HZ - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

uint32_t board_millis(void)
{
    return millis;
}

size_t board_uart_read(uint8_t *data, size_t capacity)
{
    size_t n = 0;
    while (n < capacity && ug_ring_get(&rx_ring, &data[n])) {
        n++;
    }
    return n;
}

bool board_uart_write(const uint8_t *data, size_t length)
{
    if (!ug_ring_write(&tx_ring, data, length)) {
        return false;
    }
    USART_CR1(USART1_BASE) |= USART_CR1_TXEIE;  /* the interrupt drains the ring (TXE is set while idle) */
    return true;
}

uint32_t board_uart_rx_dropped(void)
{
    return rx_ring.dropped + usart_overruns;
}

uint32_t board_uart_tx_dropped(void)
{
    return tx_ring.dropped;
}

void board_fault_stop(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi");
}
