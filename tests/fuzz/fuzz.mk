# tests/fuzz/fuzz.mk — protocol fuzzing; included by the top-level Makefile
# (after its variables: CC, CFLAGS, CPPFLAGS, LDFLAGS, LDLIBS, WARN, BUILD,
# PROTO_SRC, CONFIG). See tests/fuzz/README.md.
#
#   make fuzz-replay     replay corpus + saved crashes through the plain
#                        driver built with $(CC) in this CONFIG (make test
#                        runs it with CONFIG=asan)
#   make fuzz            libFuzzer (clang) for FUZZ_SECONDS on a working copy
#                        of the corpus in build/fuzz/corpus/protocol
#   make fuzz-merge      merge coverage-increasing inputs from the working
#                        copy into the committed corpus
#   make fuzz-corpus     regenerate the seed-*.bin files with the encoders

# an include above the first target must not change the default goal
FUZZ_SAVED_GOAL := $(.DEFAULT_GOAL)

FUZZ_DIR        := tests/fuzz
FUZZ_CORPUS     := $(FUZZ_DIR)/corpus/protocol
FUZZ_CRASHES    := $(FUZZ_DIR)/crashes/protocol
FUZZ_CRASH_DIR  ?= $(FUZZ_CRASHES)
FUZZ_SECONDS    ?= 60
FUZZ_MAX_LEN    ?= 8192
FUZZ_ARGS       ?=
FUZZ_CLANG      ?= clang
# Debian 12 packages for `make fuzz` (libclang-rt is only a Recommends of
# clang-14, and `make deps` installs without recommends)
FUZZ_DEB_PKGS   := clang libclang-rt-14-dev

# ---- replay driver and corpus generator: $(CC), this CONFIG -------------------
FUZZ_PROTO_OBJ  := $(PROTO_SRC:%.c=$(BUILD)/%.o)
FUZZ_REPLAY_BIN := $(BUILD)/fuzz_protocol_replay
FUZZ_REPLAY_OBJ := $(BUILD)/fuzz/fuzz_protocol.o $(BUILD)/fuzz/replay_main.o
FUZZ_GEN_BIN    := $(BUILD)/fuzz_gen_corpus
FUZZ_GEN_OBJ    := $(BUILD)/fuzz/gen_corpus.o

$(BUILD)/fuzz/%.o: $(FUZZ_DIR)/%.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

$(FUZZ_REPLAY_BIN): $(FUZZ_REPLAY_OBJ) $(FUZZ_PROTO_OBJ)
	$(CC) $(CFLAGS) $(LDFLAGS) -o $@ $^ $(LDLIBS)

$(FUZZ_GEN_BIN): $(FUZZ_GEN_OBJ) $(FUZZ_PROTO_OBJ)
	$(CC) $(CFLAGS) $(LDFLAGS) -o $@ $^ $(LDLIBS)

fuzz-replay: $(FUZZ_REPLAY_BIN)
	@ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  $(FUZZ_REPLAY_BIN) $(FUZZ_CORPUS) $(wildcard $(FUZZ_CRASHES))

fuzz-corpus: $(FUZZ_GEN_BIN)
	@mkdir -p $(FUZZ_CORPUS)
	$(FUZZ_GEN_BIN) $(FUZZ_CORPUS)

# ---- libFuzzer: clang, its own build dir ------------------------------------------
FUZZ_OUT        := build/fuzz
FUZZ_BIN        := $(FUZZ_OUT)/fuzz_protocol
FUZZ_WORK       := $(FUZZ_OUT)/corpus/protocol
FUZZ_CFLAGS     := -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
                   -std=c11 $(WARN) -D_GNU_SOURCE -Iprotocol

$(FUZZ_BIN): $(FUZZ_DIR)/fuzz_protocol.c $(PROTO_SRC) $(wildcard protocol/*.h)
	@mkdir -p $(@D)
	@command -v $(FUZZ_CLANG) >/dev/null 2>&1 || \
	  { echo "make fuzz: $(FUZZ_CLANG) not found; install: $(FUZZ_DEB_PKGS)"; exit 1; }
	$(FUZZ_CLANG) $(FUZZ_CFLAGS) -o $@ $(FUZZ_DIR)/fuzz_protocol.c $(PROTO_SRC) -lm || \
	  { echo "make fuzz: build failed (libFuzzer itself comes with Debian package libclang-rt-14-dev)"; exit 1; }

fuzz: $(FUZZ_BIN)
	@mkdir -p $(FUZZ_WORK) $(FUZZ_CRASH_DIR)
	@cp $(FUZZ_CORPUS)/* $(FUZZ_WORK)/
	$(FUZZ_BIN) -max_total_time=$(FUZZ_SECONDS) -max_len=$(FUZZ_MAX_LEN) -print_final_stats=1 \
	  -artifact_prefix=$(FUZZ_CRASH_DIR)/ $(FUZZ_ARGS) $(FUZZ_WORK)
	@echo "make fuzz: working corpus $(FUZZ_WORK) ($$(ls $(FUZZ_WORK) | wc -l) files);" \
	  "make fuzz-merge adds what is new to $(FUZZ_CORPUS)"

# adds only inputs that reach edges the committed corpus does not (-use_counters=0:
# hit counts alone do not qualify, which keeps the corpus at tens of files)
fuzz-merge: $(FUZZ_BIN)
	$(FUZZ_BIN) -merge=1 -use_counters=0 -max_len=$(FUZZ_MAX_LEN) $(FUZZ_CORPUS) $(FUZZ_WORK)
	@n=$$(ls $(FUZZ_CORPUS) | wc -l); kb=$$(( $$(cat $(FUZZ_CORPUS)/* | wc -c) / 1024 )); \
	  echo "make fuzz-merge: $(FUZZ_CORPUS) has $$n files, $$kb KiB"; \
	  if [ $$n -gt 300 ] || [ $$kb -gt 1024 ]; then \
	    echo "make fuzz-merge: over the 300 files / 1 MiB budget; prune before committing"; fi

.PHONY: fuzz fuzz-replay fuzz-corpus fuzz-merge

-include $(FUZZ_REPLAY_OBJ:.o=.d) $(FUZZ_GEN_OBJ:.o=.d)

.DEFAULT_GOAL := $(FUZZ_SAVED_GOAL)
