/*
 * STM32F405 registers used by the netduinoplus2 port: written for ultraglide from the reference
 * manual's register maps (RM0090) and the Cortex-M4 generic user guide. Only what the port touches.
 * No vendor header is copied; names follow the manual so its tables can be read beside this file.
 */
#ifndef UG_STM32F405_H
#define UG_STM32F405_H

#include <stdint.h>

#define UG_REG(address) (*(volatile uint32_t *)(address))

/* ---- Cortex-M4 core (ARMv7-M architecture reference) ---- */
#define SYST_CSR        UG_REG(0xE000E010u)  /* SysTick control and status */
#define SYST_RVR        UG_REG(0xE000E014u)  /* reload value */
#define SYST_CVR        UG_REG(0xE000E018u)  /* current value */
#define SYST_CSR_ENABLE    (1u << 0)
#define SYST_CSR_TICKINT   (1u << 1)
#define SYST_CSR_CLKSOURCE (1u << 2)         /* 1: the processor clock */
#define SYST_CSR_COUNTFLAG (1u << 16)

#define NVIC_ISER(n)    UG_REG(0xE000E100u + 4u * (n))
#define NVIC_ICER(n)    UG_REG(0xE000E180u + 4u * (n))
#define NVIC_ISPR(n)    UG_REG(0xE000E200u + 4u * (n))
#define NVIC_IPR_BYTE(irq) (*(volatile uint8_t *)(0xE000E400u + (irq)))
#define SCB_VTOR        UG_REG(0xE000ED08u)
#define SCB_AIRCR       UG_REG(0xE000ED0Cu)
#define SCB_SHPR3       UG_REG(0xE000ED20u)  /* priorities of PendSV (bits 23:16) and SysTick (31:24) */
#define SCB_CPACR       UG_REG(0xE000ED88u)  /* coprocessor access: CP10 and CP11 are the FPU */
#define SCB_CFSR        UG_REG(0xE000ED28u)  /* configurable fault status: MMFSR, BFSR, UFSR */
#define SCB_AIRCR_VECTKEY  (0x05FAu << 16)
#define SCB_AIRCR_SYSRESETREQ (1u << 2)

/* ---- Reset and clock control (RM0090 §7.3) ---- */
#define RCC_BASE        0x40023800u
#define RCC_CR          UG_REG(RCC_BASE + 0x00u)
#define RCC_PLLCFGR     UG_REG(RCC_BASE + 0x04u)
#define RCC_CFGR        UG_REG(RCC_BASE + 0x08u)
#define RCC_AHB1ENR     UG_REG(RCC_BASE + 0x30u)
#define RCC_APB1ENR     UG_REG(RCC_BASE + 0x40u)
#define RCC_APB2ENR     UG_REG(RCC_BASE + 0x44u)
#define RCC_CSR         UG_REG(RCC_BASE + 0x74u)  /* reset flags (RM0090 §7.3.21) */
#define RCC_CSR_RMVF       (1u << 24)
#define RCC_CSR_PINRSTF    (1u << 26)
#define RCC_CSR_PORRSTF    (1u << 27)
#define RCC_CSR_SFTRSTF    (1u << 28)
#define RCC_CSR_IWDGRSTF   (1u << 29)
#define RCC_CSR_WWDGRSTF   (1u << 30)
#define RCC_CR_HSEON       (1u << 16)
#define RCC_CR_HSERDY      (1u << 17)
#define RCC_CR_PLLON       (1u << 24)
#define RCC_CR_PLLRDY      (1u << 25)
#define RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define RCC_CFGR_SW_PLL    (2u << 0)
#define RCC_CFGR_SWS_MASK  (3u << 2)
#define RCC_CFGR_SWS_PLL   (2u << 2)
#define RCC_CFGR_PPRE1_DIV4 (5u << 10)
#define RCC_CFGR_PPRE2_DIV2 (4u << 13)
#define RCC_AHB1ENR_GPIOAEN (1u << 0)
#define RCC_AHB1ENR_DMA1EN  (1u << 21)
#define RCC_AHB1ENR_DMA2EN  (1u << 22)
#define RCC_APB1ENR_TIM2EN  (1u << 0)
#define RCC_APB1ENR_TIM5EN  (1u << 3)
#define RCC_APB1ENR_DACEN   (1u << 29)
#define RCC_APB2ENR_USART1EN (1u << 4)
#define RCC_APB2ENR_ADC1EN  (1u << 8)

/* ---- Flash interface (RM0090 §3.9) ---- */
#define FLASH_ACR       UG_REG(0x40023C00u)
#define FLASH_ACR_LATENCY_5WS (5u << 0)
#define FLASH_ACR_PRFTEN   (1u << 8)
#define FLASH_ACR_ICEN     (1u << 9)
#define FLASH_ACR_DCEN     (1u << 10)

/* ---- GPIO (RM0090 §8.4) ---- */
#define GPIOA_BASE      0x40020000u
#define GPIO_MODER(base)   UG_REG((base) + 0x00u)
#define GPIO_OSPEEDR(base) UG_REG((base) + 0x08u)
#define GPIO_PUPDR(base)   UG_REG((base) + 0x0Cu)
#define GPIO_AFRL(base)    UG_REG((base) + 0x20u)
#define GPIO_AFRH(base)    UG_REG((base) + 0x24u)
#define GPIO_MODE_ANALOG   3u
#define GPIO_MODE_AF       2u

/* ---- USART1 (RM0090 §30.6) ---- */
#define USART1_BASE     0x40011000u
#define USART1_IRQn     37u
#define USART_SR(base)  UG_REG((base) + 0x00u)
#define USART_DR(base)  UG_REG((base) + 0x04u)
#define USART_BRR(base) UG_REG((base) + 0x08u)
#define USART_CR1(base) UG_REG((base) + 0x0Cu)
#define USART_CR2(base) UG_REG((base) + 0x10u)
#define USART_CR3(base) UG_REG((base) + 0x14u)
#define USART_SR_ORE    (1u << 3)
#define USART_SR_IDLE   (1u << 4)
#define USART_SR_RXNE   (1u << 5)
#define USART_SR_TC     (1u << 6)
#define USART_SR_TXE    (1u << 7)
#define USART_CR1_RE    (1u << 2)
#define USART_CR1_TE    (1u << 3)
#define USART_CR1_IDLEIE (1u << 4)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TXEIE (1u << 7)
#define USART_CR1_UE    (1u << 13)
#define USART_CR3_DMAR  (1u << 6)
#define USART_CR3_DMAT  (1u << 7)

#define USART2_BASE     0x40004400u
#define USART2_IRQn     38u
#define RCC_APB1ENR_USART2EN (1u << 17)
#define ADC_CR2_DMA     (1u << 8)
#define ADC_CR2_DDS     (1u << 9)
#define ADC_CCR         UG_REG(0x40012304u)
#define ADC_CCR_ADCPRE_DIV4 (1u << 16)
#define DMA2_BASE       0x40026400u
#define DMA2_Stream0_IRQn 56u
#define DMA_LISR(base)  UG_REG((base) + 0x00u)
#define DMA_LIFCR(base) UG_REG((base) + 0x08u)
#define DMA_LIFCR_ALL0  (0x3Du << 0)
#define DMA_LIFCR_ALL2  (0x3Du << 16)   /* stream 2: bits 16 (FEIF) .. 21 (TCIF) */
#define DMA_SxCR_DIR_P2M (0u << 6)
#define DMA_LISR_HTIF0  (1u << 4)
#define DMA_LISR_TCIF0  (1u << 5)
#define DMA_LISR_TEIF0  (1u << 3)
#define DMA_HISR_TEIF5  (1u << 9)   /* DMA1 stream 5 (the DAC's): transfer error */
#define DMA_HISR_FEIF5  (1u << 6)
#define GPIOA_PIN_ANALOG(pin) (GPIO_MODE_ANALOG << (2u * (pin)))

/* ---- General-purpose timers TIM2..TIM5 (RM0090 §18.4): TIM2 and TIM5 are 32-bit ---- */
#define TIM2_BASE       0x40000000u
#define TIM2_IRQn       28u
#define TIM3_BASE       0x40000400u
#define TIM3_IRQn       29u
#define RCC_APB1ENR_TIM3EN  (1u << 1)
#define TIM5_BASE       0x40000C00u
#define TIM_CR1(base)   UG_REG((base) + 0x00u)
#define TIM_CR2(base)   UG_REG((base) + 0x04u)
#define TIM_DIER(base)  UG_REG((base) + 0x0Cu)
#define TIM_SR(base)    UG_REG((base) + 0x10u)
#define TIM_EGR(base)   UG_REG((base) + 0x14u)
#define TIM_CNT(base)   UG_REG((base) + 0x24u)
#define TIM_PSC(base)   UG_REG((base) + 0x28u)
#define TIM_ARR(base)   UG_REG((base) + 0x2Cu)
#define TIM_CR1_CEN     (1u << 0)
#define TIM_CR2_MMS_UPDATE (2u << 4)  /* TRGO on update: the DAC's conversion trigger */
#define TIM_DIER_UIE    (1u << 0)
#define TIM_SR_UIF      (1u << 0)
#define TIM_EGR_UG      (1u << 0)

/* ---- DAC (RM0090 §14.5) ---- */
#define DAC_BASE        0x40007400u
#define DAC_CR          UG_REG(DAC_BASE + 0x00u)
#define DAC_DHR12L1     UG_REG(DAC_BASE + 0x0Cu)  /* 12-bit left-aligned: bits 15:4 */
#define DAC_DHR12L1_ADDRESS (DAC_BASE + 0x0Cu)
#define DAC_CR_EN1      (1u << 0)
#define DAC_CR_TEN1     (1u << 2)
#define DAC_CR_TSEL1_TIM2 (4u << 3)  /* TIM2 TRGO */
#define DAC_CR_DMAEN1   (1u << 12)
#define DAC_CR_DMAUDRIE1 (1u << 13)
#define DAC_SR          UG_REG(DAC_BASE + 0x34u)
#define DAC_SR_DMAUDR1  (1u << 13)  /* a trigger came before the DMA delivered: written 1 to clear */

/* ---- DMA1 (RM0090 §10.5): stream 5 channel 7 is DAC1's request ---- */
#define DMA1_BASE       0x40026000u
#define DMA1_Stream5_IRQn 16u
#define DMA_HISR(base)  UG_REG((base) + 0x04u)
#define DMA_HIFCR(base) UG_REG((base) + 0x0Cu)
#define DMA_SxCR(base, s)   UG_REG((base) + 0x10u + 0x18u * (s))
#define DMA_SxNDTR(base, s) UG_REG((base) + 0x14u + 0x18u * (s))
#define DMA_SxPAR(base, s)  UG_REG((base) + 0x18u + 0x18u * (s))
#define DMA_SxM0AR(base, s) UG_REG((base) + 0x1Cu + 0x18u * (s))
#define DMA_SxCR_EN     (1u << 0)
#define DMA_SxCR_HTIE   (1u << 3)
#define DMA_SxCR_TCIE   (1u << 4)
#define DMA_SxCR_DIR_M2P (1u << 6)
#define DMA_SxCR_CIRC   (1u << 8)
#define DMA_SxCR_MINC   (1u << 10)
#define DMA_SxCR_PSIZE_16 (1u << 11)
#define DMA_SxCR_MSIZE_16 (1u << 13)
#define DMA_SxCR_CHSEL(c) ((uint32_t)(c) << 25)
#define DMA_HISR_HTIF5  (1u << 10)    /* stream 5 in the high register: bits 6 (FEIF) .. 11 (TCIF) */
#define DMA_HISR_TCIF5  (1u << 11)
#define DMA_HIFCR_ALL5  (0x3Du << 6)
#define DMA_HIFCR_ALL7  (0x3Du << 22)   /* stream 7: bits 22 (FEIF) .. 27 (TCIF) */

/* ---- ADC1 (RM0090 §13.13) ---- */
#define ADC1_BASE       0x40012000u
#define ADC_SR(base)    UG_REG((base) + 0x00u)
#define ADC_CR2(base)   UG_REG((base) + 0x08u)
#define ADC_SMPR2(base) UG_REG((base) + 0x10u)
#define ADC_SQR3(base)  UG_REG((base) + 0x34u)
#define ADC_DR(base)    UG_REG((base) + 0x4Cu)
#define ADC_SR_EOC      (1u << 1)
#define ADC_CR2_ADON    (1u << 0)
#define ADC_CR2_EXTSEL_TIM2_TRGO (6u << 24)
#define ADC_CR2_EXTEN_RISING (1u << 28)

#endif
