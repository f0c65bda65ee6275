# tests/fuzz/fuzz.mk — fuzzing the decoders; included by the top-level
# Makefile (after its variables: CC, CFLAGS, CPPFLAGS, LDFLAGS, LDLIBS, WARN,
# BUILD, PROTO_SRC, PROTO_OBJ, CONFIG). See tests/fuzz/README.md.
#
# Targets (FUZZ_ALL), each fuzz_<name>.c with corpus/<name>/ and crashes/<name>/:
#   protocol   the wire-protocol decoders (protocol/)
#   jsonl      the JSON lines parser of `vantage import` (client/import/jsonl.c, json-c)
#   gltf       the level import of `vantage sublevel load` (client/import/import_*.c, assimp)
#   pad        the game-pad report parsers (client/pad/pad.c, pad_parse.c)
#   replay     hid-recorder's text format and the replay path (client/pad/pad_line.c)
#   query      the culling core past the decoders: occluders, entities, lights
#              and views from the bytes -> cull_query, cull_occ_render,
#              cull_lights_bin (culling/)
#   render     the software renderer (render/vt_soft.c) on small frames, its
#              cancel, and the scale-up of dynamic resolution (vt_resize.c)
#   render_gl  the same inputs through the GL path (render/vt_gldraw.c; skips
#              every input where no EGL context can be made)
#   http       the daemon's HTTP/1.x head parser (daemon/http.c: --metrics,
#              the web viewer)
#
#   make fuzz-replay     replay every target's corpus + saved crashes through
#                        the plain driver built with $(CC) in this CONFIG
#                        (make test runs it with CONFIG=asan)
#   make fuzz            libFuzzer (clang), each target FUZZ_SECONDS in turn,
#                        on a working copy of its corpus in build/fuzz/corpus/<name>
#   make fuzz-merge      merge coverage-increasing inputs from the working
#                        copies into the committed corpora
#   make fuzz-corpus     regenerate the protocol's seed-*.bin files with the encoders
#
# FUZZ_TARGETS=jsonl (or "jsonl gltf") limits fuzz, fuzz-replay and fuzz-merge
# to those targets.

# an include above the first target must not change the default goal
FUZZ_SAVED_GOAL := $(.DEFAULT_GOAL)

FUZZ_DIR        := tests/fuzz
FUZZ_OUT        := build/fuzz
FUZZ_ALL        := protocol jsonl gltf pad replay query render render_gl http
FUZZ_TARGETS    ?= $(FUZZ_ALL)
FUZZ_CRASH_DIR  ?= $(FUZZ_DIR)/crashes
FUZZ_SECONDS    ?= 60
FUZZ_MAX_LEN    ?=
FUZZ_ARGS       ?=
FUZZ_CLANG      ?= clang
# Debian 12 packages for `make fuzz` (libclang-rt is only a Recommends of
# clang-14, and `make deps` installs without recommends)
FUZZ_DEB_PKGS   := clang libclang-rt-14-dev

ifneq ($(filter-out $(FUZZ_ALL),$(FUZZ_TARGETS)),)
$(error FUZZ_TARGETS: unknown target(s) $(filter-out $(FUZZ_ALL),$(FUZZ_TARGETS)); there are $(FUZZ_ALL))
endif

# ---- per target ----------------------------------------------------------------------
# _OBJ: what the replay driver links besides the target (this CONFIG's objects);
# _SRC: the same as sources, for the libFuzzer build; _CFLAGS, _LIBS: pkg-config;
# _MAX_LEN: libFuzzer's -max_len; _ARGS: more libFuzzer flags (_RUN_ARGS: for
# fuzz only); _CRASH_DIR: where fuzz saves failing inputs; _BUDGET: the
# committed corpus's limit, files and KiB (fuzz-merge warns past it)
FUZZ_protocol_OBJ     := $(PROTO_OBJ)
FUZZ_protocol_SRC     := $(PROTO_SRC)
FUZZ_protocol_MAX_LEN := 8192
FUZZ_protocol_BUDGET  := 300 1024

FUZZ_jsonl_OBJ        := $(BUILD)/client/import/jsonl.o $(PROTO_OBJ)
FUZZ_jsonl_SRC        := client/import/jsonl.c $(PROTO_SRC)
FUZZ_jsonl_CFLAGS     := $$(pkg-config --cflags json-c)
FUZZ_jsonl_LIBS       := $$(pkg-config --libs json-c)
FUZZ_jsonl_MAX_LEN    := 2048
FUZZ_jsonl_BUDGET     := 100 256

FUZZ_gltf_OBJ         := $(IMPORT_OBJ) $(PROTO_OBJ)
FUZZ_gltf_SRC         := $(wildcard client/import/import_*.c) $(PROTO_SRC)
FUZZ_gltf_CFLAGS      := $$(pkg-config --cflags assimp json-c)
FUZZ_gltf_LIBS        := $$(pkg-config --libs assimp json-c)
FUZZ_gltf_MAX_LEN     := 16384
# Debian's assimp 5.2 crashes, leaks and asks for gigabytes on some broken
# files (README: "assimp"), so this target fuzzes in fork mode and goes on
# past those (_RUN_ARGS: fuzz only, not fuzz-merge); what it saves goes to
# build/fuzz/crashes/gltf/ for triage, not to the replayed folder. One input
# is one import: 10 s is a hang.
FUZZ_gltf_ARGS        := -timeout=10
FUZZ_gltf_RUN_ARGS    := -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1
FUZZ_gltf_CRASH_DIR   := $(FUZZ_OUT)/crashes/gltf
FUZZ_gltf_BUDGET      := 100 512

# the pad parsers: pure C, no library; one input is a protocol byte and a
# sequence of length-prefixed reports (fuzz_pad.c)
FUZZ_pad_OBJ          := $(BUILD)/client/pad/pad.o $(BUILD)/client/pad/pad_parse.o $(BUILD)/client/pad/pad_line.o $(PROTO_OBJ)
FUZZ_pad_SRC          := client/pad/pad.c client/pad/pad_parse.c client/pad/pad_line.c $(PROTO_SRC)
FUZZ_pad_MAX_LEN      := 1024
FUZZ_pad_BUDGET       := 100 256

# hid-recorder files, their E: reports fed to the parser their I: line names
FUZZ_replay_OBJ       := $(FUZZ_pad_OBJ)
FUZZ_replay_SRC       := $(FUZZ_pad_SRC)
FUZZ_replay_MAX_LEN   := 4096
# each way a line is refused is its own edge: a merge from the seeds keeps
# ~130 small files (28 KiB)
FUZZ_replay_BUDGET    := 150 256

# the culling core and the renderers (issue 18: crashes past the decoders).
# Their libFuzzer builds link objects compiled with clang per source (the
# per-ISA kernels need their own -m flags): FUZZ_<name>_SRC lists those
# objects, built by the rule below into $(FUZZ_OUT)/obj/.
FUZZ_OBJ_DIR          := $(FUZZ_OUT)/obj
FUZZ_COMMA            := ,
FUZZ_CULL_FOBJ        := $(CULL_SRC:%.c=$(FUZZ_OBJ_DIR)/%.o)
FUZZ_SOFT_SRC         := render/vt_soft.c render/vt_picture.c render/vt_scene.c render/vt_texsample.c render/vt_texlin.c render/vt_span.c render/vt_shadow.c render/vt_shadow_tiles.c render/vt_shadow_sse41.c render/vt_shadow_avx2.c render/vt_ssao.c render/vt_ssao_base.c render/vt_ssao_sse41.c render/vt_ssao_avx2.c render/vt_ssao_avx2_evex.c render/vt_post.c render/vt_post_avx2.c render/vt_overlay.c render/vt_brdf.c render/vt_raster.c render/vt_shade_base.c render/vt_shade_sse41.c \
                         render/vt_shade_avx2.c render/vt_shade_avx2_evex.c render/vt_resize.c
FUZZ_query_OBJ        := $(CULL_OBJ)
FUZZ_query_SRC        := $(FUZZ_CULL_FOBJ)
FUZZ_query_CFLAGS     := -Iculling
# one input is a scene of <= 4 occluders, 24 entities, 6 lights, 3 views;
# a merge after a 2.4M-execution campaign keeps 190 small files (20 KiB)
FUZZ_query_MAX_LEN    := 1024
FUZZ_query_BUDGET     := 250 256
FUZZ_render_OBJ       := $(FUZZ_SOFT_SRC:%.c=$(BUILD)/%.o) $(CULL_OBJ)
FUZZ_render_SRC       := $(FUZZ_SOFT_SRC:%.c=$(FUZZ_OBJ_DIR)/%.o) $(FUZZ_CULL_FOBJ)
FUZZ_render_CFLAGS    := -Iculling -Irender
FUZZ_render_MAX_LEN   := 1024
FUZZ_render_BUDGET    := 300 256
FUZZ_GL_SRC           := render/vt_egl.c render/vt_gl_target.c render/vt_gl_shader.c render/vt_gldraw.c render/vt_gldraw_glsl.c render/vt_shadow_gl.c render/vt_ssao_gl.c render/vt_brdf_glsl.c render/vt_gltex.c
FUZZ_render_gl_OBJ    := $(FUZZ_GL_SRC:%.c=$(BUILD)/%.o) $(FUZZ_render_OBJ)
FUZZ_render_gl_SRC    := $(FUZZ_GL_SRC:%.c=$(FUZZ_OBJ_DIR)/%.o) $(FUZZ_render_SRC)
FUZZ_render_gl_CFLAGS := -Iculling -Irender
FUZZ_render_gl_LIBS   := $(GL_LIBS)
FUZZ_render_gl_MAX_LEN := 1024
FUZZ_render_gl_BUDGET := 150 256

# the HTTP head parser: pure C over bytes; one input is what a connection
# sends (a head and whatever follows it)
FUZZ_http_OBJ         := $(BUILD)/daemon/http.o
FUZZ_http_SRC         := daemon/http.c
FUZZ_http_CFLAGS      := -Idaemon
FUZZ_http_MAX_LEN     := 4096
FUZZ_http_BUDGET      := 150 256

$(FUZZ_OBJ_DIR)/%.o: %.c $(wildcard culling/*.h culling/*.inl render/*.h render/*.inl)
	@mkdir -p $(@D)
	$(FUZZ_CLANG) $(subst -fsanitize=fuzzer$(FUZZ_COMMA),-fsanitize=fuzzer-no-link$(FUZZ_COMMA),$(FUZZ_CFLAGS)) \
	  -Iculling -Irender $(if $(findstring _avx2,$*),$(ISA_AVX2)) $(if $(findstring _sse41,$*),$(ISA_SSE41)) -c $< -o $@

# ---- replay driver and corpus generator: $(CC), this CONFIG -------------------
FUZZ_REPLAY_MAIN := $(BUILD)/fuzz/replay_main.o
FUZZ_GEN_BIN     := $(BUILD)/fuzz_gen_corpus
FUZZ_GEN_OBJ     := $(BUILD)/fuzz/gen_corpus.o

$(BUILD)/fuzz/%.o: $(FUZZ_DIR)/%.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

$(FUZZ_GEN_BIN): $(FUZZ_GEN_OBJ) $(PROTO_OBJ)
	$(CC) $(CFLAGS) $(LDFLAGS) -o $@ $^ $(LDLIBS)

fuzz-corpus: $(FUZZ_GEN_BIN)
	@mkdir -p $(FUZZ_DIR)/corpus/protocol
	$(FUZZ_GEN_BIN) $(FUZZ_DIR)/corpus/protocol

# ---- libFuzzer: clang, its own build dir ------------------------------------------
FUZZ_CFLAGS     := -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
                   -std=c11 $(WARN) -D_GNU_SOURCE -Iprotocol $(CLIENT_DIRS:%=-Iclient/%)

# $(1): a target's name. Its replay driver and its libFuzzer binary.
define FUZZ_RULES
$(BUILD)/fuzz_$(1)_replay: $(BUILD)/fuzz/fuzz_$(1).o $(FUZZ_REPLAY_MAIN) $(FUZZ_$(1)_OBJ)
	$$(CC) $$(CFLAGS) $$(LDFLAGS) -o $$@ $$^ $$(FUZZ_$(1)_LIBS) $$(LDLIBS)

$(FUZZ_OUT)/fuzz_$(1): $(FUZZ_DIR)/fuzz_$(1).c $(FUZZ_$(1)_SRC) $(wildcard protocol/*.h client/*/*.h)
	@mkdir -p $$(@D)
	@command -v $$(FUZZ_CLANG) >/dev/null 2>&1 || \
	  { echo "make fuzz: $$(FUZZ_CLANG) not found; install: $$(FUZZ_DEB_PKGS)"; exit 1; }
	$$(FUZZ_CLANG) $$(FUZZ_CFLAGS) $$(FUZZ_$(1)_CFLAGS) -o $$@ $(FUZZ_DIR)/fuzz_$(1).c $(FUZZ_$(1)_SRC) \
	  $$(FUZZ_$(1)_LIBS) -lm || \
	  { echo "make fuzz: build failed (libFuzzer itself comes with Debian package libclang-rt-14-dev)"; exit 1; }
endef
$(foreach t,$(FUZZ_ALL),$(eval $(call FUZZ_RULES,$(t))))

# Each target in turn; every one runs even when one fails, and the status says
# whether any failed. A crashes/<name>/ folder that does not exist holds nothing.
fuzz-replay: $(foreach t,$(FUZZ_TARGETS),$(BUILD)/fuzz_$(t)_replay)
	@rc=0; for t in $(FUZZ_TARGETS); do \
	  c=$(FUZZ_DIR)/crashes/$$t; [ -d $$c ] || c=; \
	  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	    $(BUILD)/fuzz_$${t}_replay $(FUZZ_DIR)/corpus/$$t $$c || rc=1; \
	done; exit $$rc

# $(1): a target's name. Where its libFuzzer runs save inputs that fail:
# FUZZ_<name>_CRASH_DIR, else $(FUZZ_CRASH_DIR)/<name>/ (the replayed folder).
fuzz_crash_dir = $(or $(FUZZ_$(1)_CRASH_DIR),$(FUZZ_CRASH_DIR)/$(1))

# $(1): a target's name. One libFuzzer run over a working copy of its corpus,
# as one shell command for fuzz's loop; a failed run, or one that saved new
# inputs (fork mode goes on past them), is added to $$failed.
FUZZ_RUN = mkdir -p $(FUZZ_OUT)/corpus/$(1) $(call fuzz_crash_dir,$(1)) && \
  cp $(FUZZ_DIR)/corpus/$(1)/* $(FUZZ_OUT)/corpus/$(1)/ && \
  saved=$$(ls $(call fuzz_crash_dir,$(1)) | wc -l) && \
  cmd="$(FUZZ_OUT)/fuzz_$(1) -max_total_time=$(FUZZ_SECONDS) -max_len=$(or $(FUZZ_MAX_LEN),$(FUZZ_$(1)_MAX_LEN)) \
    -print_final_stats=1 -artifact_prefix=$(call fuzz_crash_dir,$(1))/ \
    $(if $(wildcard $(FUZZ_DIR)/$(1).dict),-dict=$(FUZZ_DIR)/$(1).dict) $(FUZZ_$(1)_ARGS) $(FUZZ_$(1)_RUN_ARGS) \
    $(FUZZ_ARGS) $(FUZZ_OUT)/corpus/$(1)" && \
  echo "make fuzz: $(1): $$cmd" && { $$cmd || failed="$$failed $(1)"; } && \
  new=$$(( $$(ls $(call fuzz_crash_dir,$(1)) | wc -l) - saved )) && \
  { [ $$new -le 0 ] || { echo "make fuzz: $(1): $$new new input(s) in $(call fuzz_crash_dir,$(1))/"; \
                         failed="$$failed $(1)"; }; } && \
  echo "make fuzz: $(1): working corpus $(FUZZ_OUT)/corpus/$(1) ($$(ls $(FUZZ_OUT)/corpus/$(1) | wc -l) files)"

# the targets one after the other (one process: pass FUZZ_ARGS=-fork=N for more)
fuzz: $(foreach t,$(FUZZ_TARGETS),$(FUZZ_OUT)/fuzz_$(t))
	@failed=; $(foreach t,$(FUZZ_TARGETS),$(call FUZZ_RUN,$(t)) &&) \
	  echo "make fuzz: make fuzz-merge adds what is new to $(FUZZ_DIR)/corpus/<name>/" && \
	  if [ -n "$$failed" ]; then echo "make fuzz: FAILED:$$failed"; exit 1; fi

# adds only inputs that reach edges the committed corpus does not (-use_counters=0:
# hit counts alone do not qualify, which keeps the corpus at tens of files)
FUZZ_MERGE = mkdir -p $(FUZZ_OUT)/corpus/$(1) && \
  $(FUZZ_OUT)/fuzz_$(1) -merge=1 -use_counters=0 -max_len=$(or $(FUZZ_MAX_LEN),$(FUZZ_$(1)_MAX_LEN)) \
    $(FUZZ_$(1)_ARGS) $(FUZZ_DIR)/corpus/$(1) $(FUZZ_OUT)/corpus/$(1) && \
  n=$$(ls $(FUZZ_DIR)/corpus/$(1) | wc -l) && kb=$$(( $$(cat $(FUZZ_DIR)/corpus/$(1)/* | wc -c) / 1024 )) && \
  echo "make fuzz-merge: $(FUZZ_DIR)/corpus/$(1) has $$n files, $$kb KiB" && \
  { [ $$n -le $(word 1,$(FUZZ_$(1)_BUDGET)) ] && [ $$kb -le $(word 2,$(FUZZ_$(1)_BUDGET)) ] || \
    echo "make fuzz-merge: over $(1)'s budget of $(word 1,$(FUZZ_$(1)_BUDGET)) files / $(word 2,$(FUZZ_$(1)_BUDGET)) KiB; prune before committing"; }

fuzz-merge: $(foreach t,$(FUZZ_TARGETS),$(FUZZ_OUT)/fuzz_$(t))
	@$(foreach t,$(FUZZ_TARGETS),$(call FUZZ_MERGE,$(t)) &&) true

.PHONY: fuzz fuzz-replay fuzz-corpus fuzz-merge

-include $(foreach t,$(FUZZ_ALL),$(BUILD)/fuzz/fuzz_$(t).d) $(FUZZ_REPLAY_MAIN:.o=.d) $(FUZZ_GEN_OBJ:.o=.d)

.DEFAULT_GOAL := $(FUZZ_SAVED_GOAL)
