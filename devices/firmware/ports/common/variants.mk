# Each image variant of a board compiles every source with its own flags into its own folder, O/VARIANT.
# Included by a board's Makefile after it sets O, CC, CFLAGS, LDFLAGS, SIZE, NAME, PORT_DIR, COMMON_DIR,
# FIRMWARE_DIR, PORT_SOURCES, COMMON_SOURCES, CORE_SOURCES, HEADERS (every header a source may include) and
# LINKER_SCRIPT. $(call variant,NAME,EXTRA_CFLAGS,APPLICATION_OBJECT) then defines O/BOARD-NAME.elf.
define variant
$(O)/$(1)/%.o: $(PORT_DIR)/%.c $(HEADERS) | $(O)/$(1)
	$(CC) $(CFLAGS) $(2) -c $$< -o $$@
$(O)/$(1)/common_%.o: $(COMMON_DIR)/%.c $(HEADERS) | $(O)/$(1)
	$(CC) $(CFLAGS) $(2) -c $$< -o $$@
$(O)/$(1)/core_%.o: $(FIRMWARE_DIR)/core/%.c $(HEADERS) | $(O)/$(1)
	$(CC) $(CFLAGS) $(2) -c $$< -o $$@
$(O)/$(1):
	mkdir -p $$@
$(1)_OBJECTS := $(patsubst $(PORT_DIR)/%.c,$(O)/$(1)/%.o,$(PORT_SOURCES)) $(addprefix $(O)/$(1)/,$(3)) \
                $(patsubst $(COMMON_DIR)/%.c,$(O)/$(1)/common_%.o,$(COMMON_SOURCES)) \
                $(patsubst $(FIRMWARE_DIR)/core/%.c,$(O)/$(1)/core_%.o,$(CORE_SOURCES))
$(O)/$(NAME)-$(1).elf: $$($(1)_OBJECTS) $(LINKER_SCRIPT)
	$(CC) $(LDFLAGS) -Wl,-Map=$(O)/$(NAME)-$(1).map $$($(1)_OBJECTS) -lm -o $$@
	$(SIZE) $$@
endef
