/* Host build of the netduinoplus2 port's pure logic, for tests/test_firmware_board.py: the ring's and the
   DAC words' static inline functions given addresses so that ctypes can call them. */
#include "uart_ring.h"

static ug_ring_t ring;

void shim_ring_init(void) { ug_ring_init(&ring); }
int shim_ring_put(unsigned char byte) { return ug_ring_put(&ring, byte); }
int shim_ring_get(unsigned char *byte) { return ug_ring_get(&ring, byte); }
int shim_ring_write(const unsigned char *data, unsigned long length) { return ug_ring_write(&ring, data, length); }
unsigned int shim_ring_used(void) { return ug_ring_used(&ring); }
unsigned int shim_ring_dropped(void) { return ring.dropped; }
void shim_ring_set_indices(unsigned int head, unsigned int tail) { ring.head = head; ring.tail = tail; }
unsigned int shim_ring_size(void) { return UG_RING_SIZE; }

/* the DAC word conversions are static inline in port_logic.h: given addresses here */
#include "port_logic.h"

unsigned short shim_dac_word(short sample) { return ug_dac_word(sample); }
unsigned short shim_dac_code(unsigned short word) { return ug_dac_code(word); }
