#include "emulation_config.h"

#ifdef UG_BOARD_QEMU
__attribute__((section(".emulation"), used))
const volatile ug_emulation_config_t ug_emulation = {
    UG_EMULATION_MAGIC, 25000.0f, 200.0f, 0.0f, 25000.0f, 200.0f, 8.0f, 6.0f, 8.0f, 20000.0f, 28000.0f,
};
#endif
