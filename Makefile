# Vantage — build, test and benchmark.
#
#   make run               build and start vantaged on the demo city
#                          (daemon flags: make run VANTAGED_ARGS="--port 7471 --data-dir /tmp/scene")
#   make demo              the culling core on the city scene (tests/data/scenes) + a short benchmark
#   make test              unit + property tests (release, then ASan+UBSan),
#                          the scalar-only build, and a bench smoke run
#   make bench             the full culling, occlusion, render, pad-parser and H.264 benchmarks
#                          (bench_cull, bench_occlusion, bench_render, bench_pad, bench_h264)
#   make bench-cycles      the renderer against Blender Cycles (SSIM per scene, minutes)
#   make docs-renders      the demo city pictures in docs/ (day, night, street, aerial, ...)
#   make report            run time against error of the culling configurations and a
#                          numerical stress table: docs/report/ (tables, CSV, SVG plot)
#   make deps              install the Debian packages the build needs
#   CONFIG=release|debug|asan|scalar   out-of-tree in build/$(CONFIG)/
#
# CI=true adds -Werror.

CONFIG ?= release
BUILD  := build/$(CONFIG)
CC     ?= cc
SHELL  := /bin/bash

# Debian packages and the pkg-config modules that prove them installed.
DEB_PKGS := build-essential pkg-config libcmocka-dev libjson-c-dev libopenexr-dev openexr \
            libpng-dev libjpeg62-turbo-dev libegl-dev libepoxy-dev libegl-mesa0 libgl1-mesa-dri libassimp-dev \
            zlib1g-dev libhidapi-dev libusb-1.0-0-dev libsdl2-dev libsdl2-ttf-dev fonts-dejavu-core xvfb \
            gnuplot-nox blender python3-numpy libwslay-dev libssl-dev openssl chromium \
            libx264-dev libavcodec-dev libavutil-dev clang lld wasi-libc libclang-rt-14-dev-wasm32 \
            libnats-dev nats-server haproxy
# (libnats-dev: --cluster, daemon/cluster.c; nats-server and haproxy: the cluster's tests, tests/cluster)
# (blender and python3-numpy: the Blender live-link's tests in make test (tests/blender, skipped when
# blender is missing) and make bench-cycles, the renderer against Cycles)
# Node.js and npm (the browser tests, tests/web): Debian's nodejs and npm, unless a node and an npm
# are there already (a NodeSource nodejs carries its own npm and conflicts with Debian's)
NODE_PKGS := nodejs npm
# (libx264-dev: H.264 browser frames, render/vt_h264.c; libavcodec-dev and libavutil-dev: the
# tests' and bench_h264's independent H.264 decoder, linked into nothing else)
PC_MODS  := cmocka json-c OpenEXR libpng libjpeg egl epoxy assimp zlib hidapi-hidraw libusb-1.0 sdl2 SDL2_ttf \
            libcrypto libssl x264 libavcodec libavutil libnats
# (libwslay-dev ships no pkg-config file: check-deps looks for its header;
# clang, lld, wasi-libc and libclang-rt-14-dev-wasm32 build web/js/cmdr.wasm:
# check-deps looks for wasm-ld and wasi-libc's libc.a)

WARN     := -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes
ifeq ($(CI),true)
WARN     += -Werror
endif
# client/ has one folder per part (lib, cli, pad, commander, loadgen, import; client/README.md)
CLIENT_DIRS := lib cli pad commander loadgen import
CPPFLAGS := -D_GNU_SOURCE -Iculling -Iprotocol -Idaemon $(CLIENT_DIRS:%=-Iclient/%) -Irender -MMD -MP
CFLAGS   := -std=c11 $(WARN) -g -pthread
LDLIBS   := -lm -pthread
ISA_AVX2 := -mavx2 -mfma -mf16c -mpopcnt
# the AVX2 kernels' EVEX builds (run only where CPUID says so: cull_isa_evex)
ISA_EVEX := $(ISA_AVX2) -mavx512f -mavx512vl -mavx512dq -mavx512bw -mprefer-vector-width=256
ISA_SSE41:= -msse4.1

ifeq ($(CONFIG),release)
CFLAGS   += -O2
# the renderer: -O3 unrolls the kernels' per-channel and per-corner loops
# (the city frame 7 % fewer instructions than -O2, shading 13 %, set-up
# 26 %, SSAO 18 %: callgrind). Floats unchanged: -std=c11 keeps
# contraction off and nothing here reassociates.
RENDER_O := -O3
else ifeq ($(CONFIG),debug)
CFLAGS   += -O0
else ifeq ($(CONFIG),asan)
CFLAGS   += -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
LDFLAGS  += -fsanitize=address,undefined
else ifeq ($(CONFIG),scalar)
CFLAGS   += -O2
CPPFLAGS += -DCULL_SCALAR_ONLY
ISA_AVX2 :=
ISA_SSE41:=
else
$(error CONFIG must be release, debug, asan or scalar)
endif

CULL_SRC := $(wildcard culling/*.c)
CULL_OBJ := $(CULL_SRC:%.c=$(BUILD)/%.o)
CULL_LIB := $(BUILD)/libvculling.a

PROTO_SRC:= $(wildcard protocol/*.c)
PROTO_OBJ:= $(PROTO_SRC:%.c=$(BUILD)/%.o)
PROTO_LIB:= $(BUILD)/libvproto.a

DAEMON_SRC:= $(wildcard daemon/*.c)
DAEMON_OBJ:= $(DAEMON_SRC:%.c=$(BUILD)/%.o)
DAEMON_BIN:= $(BUILD)/vantaged

CLIENT_LIB:= $(BUILD)/libvantage.a
CLIENT_OBJ:= $(BUILD)/client/lib/libvantage.o $(BUILD)/client/lib/vtc_view.o $(BUILD)/client/lib/vtc_endpoints.o
# game pads (issue 8): pure parsers and the hid-recorder format (pad.h), the
# devices through hidapi (hidraw flavour) and libusb (pad_io.h), the
# commander's input mapping; linked into the CLI and the tests
PAD_OBJ  := $(BUILD)/client/pad/pad.o $(BUILD)/client/pad/pad_parse.o $(BUILD)/client/pad/pad_line.o \
            $(BUILD)/client/pad/pad_hub.o $(BUILD)/client/pad/pad_hidraw.o $(BUILD)/client/pad/pad_libusb.o \
            $(BUILD)/client/pad/pad_replay.o $(BUILD)/client/pad/pad_record.o $(BUILD)/client/pad/pad_io_real.o \
            $(BUILD)/client/commander/pad_map.o
PAD_LIBS := $$(pkg-config --libs hidapi-hidraw libusb-1.0)
SDL_LIBS := $$(pkg-config --libs sdl2 SDL2_ttf)
# load-test scenarios (issue 9): the format and the histogram, pure (the
# tests link them); the runner is cli_scenario.c
SCN_OBJ  := $(BUILD)/client/loadgen/scenario.o $(BUILD)/client/loadgen/lat_hist.o
# level import (client/import/README.md): the walk, in-memory files, the
# child process and the level's bytes on its pipe
IMPORT_OBJ := $(BUILD)/client/import/import_walk.o $(BUILD)/client/import/import_memio.o \
            $(BUILD)/client/import/import_child.o $(BUILD)/client/import/import_pack.o \
            $(BUILD)/client/import/import_material.o
CLI_OBJ  := $(BUILD)/client/cli/vantage_cli.o $(BUILD)/client/cli/cli_jsonl.o $(BUILD)/client/cli/cli_bench.o \
            $(BUILD)/client/cli/cli_render.o $(BUILD)/client/cli/cli_frames.o $(BUILD)/client/cli/cli_sublevel.o \
            $(BUILD)/client/cli/cli_scene.o \
            $(BUILD)/client/cli/cli_env.o $(BUILD)/client/cli/cli_stats.o \
            $(BUILD)/client/cli/cli_export.o \
            $(IMPORT_OBJ) $(BUILD)/client/import/jsonl.o $(BUILD)/client/cli/cli_pad.o \
            $(BUILD)/client/commander/commander.o $(BUILD)/client/commander/commander_sdl.o \
            $(BUILD)/client/loadgen/cli_scenario.o $(BUILD)/client/loadgen/scenario_events.o \
            $(BUILD)/client/loadgen/scenario_report.o $(SCN_OBJ) $(PAD_OBJ)
CLI_BIN  := $(BUILD)/vantage

# render/: the EXR writer needs only OpenEXRCore, the C layer; `pkg-config
# --libs OpenEXR` would also link the five C++ libraries
# (listed, not globbed: modules join the build when they are integrated)
# the image files of vt_image.h: tone mapping, the encoders' sink, PNG, JPEG
IMAGE_SRC := render/vt_tonemap.c render/vt_tonemap_avx2.c render/vt_lut.c render/vt_sink.c render/vt_png.c render/vt_jpeg.c \
             render/vt_resize.c
IMAGE_OBJ := $(IMAGE_SRC:%.c=$(BUILD)/%.o)
RENDER_SRC:= render/vt_exr.c render/vt_picture.c render/vt_scene.c render/vt_texsample.c render/vt_texlin.c render/vt_span.c render/vt_shadow.c render/vt_shadow_tiles.c render/vt_shadow_sse41.c render/vt_shadow_avx2.c render/vt_ssao.c render/vt_ssao_base.c render/vt_ssao_sse41.c render/vt_ssao_avx2.c render/vt_ssao_avx2_evex.c render/vt_post.c render/vt_post_avx2.c render/vt_overlay.c render/vt_soft.c render/vt_raster.c render/vt_shade_base.c render/vt_shade_sse41.c \
            render/vt_shade_avx2.c render/vt_shade_avx2_evex.c render/vt_brdf.c render/vt_brdf_glsl.c $(IMAGE_SRC) render/vt_egl.c render/vt_gl_target.c render/vt_gl_shader.c \
            render/vt_gldraw.c render/vt_gldraw_glsl.c render/vt_shadow_gl.c render/vt_ssao_gl.c render/vt_gltex.c render/vt_file.c render/vt_err.c \
            render/vt_texture.c
RENDER_OBJ:= $(RENDER_SRC:%.c=$(BUILD)/%.o)
EXR_LIBS := -lOpenEXRCore$$(pkg-config --variable=libsuffix OpenEXR)
# PNG and JPEG (vt_png.c, vt_jpeg.c): libpng 1.6 and the libjpeg API of libjpeg-turbo
# (libjpeg.so.62); every binary that links RENDER_OBJ needs both
IMG_LIBS := $$(pkg-config --libs libpng libjpeg)
# the daemon's --web (daemon/web.c): WebSocket framing by libwslay (Debian's
# libwslay-dev has no .pc file), SHA-1 and base64 of the handshake by libcrypto
WEB_LIBS := -lwslay $$(pkg-config --libs libssl libcrypto)
# headless OpenGL (vt_egl.c, vt_gl_*.c): libglvnd's libEGL and libepoxy; at run time
# Mesa's EGL vendor library and drivers (libegl-mesa0, libgl1-mesa-dri:
# llvmpipe where there is no GPU) or NVIDIA's. Every binary that links
# RENDER_OBJ needs these; the GL tests skip when no context can be made
GL_LIBS  := $$(pkg-config --libs egl epoxy)
# H.264 for browser frames (issue 21): vt_h264.c on libx264 (GPL-2+), apart from
# RENDER_OBJ so that only what encodes video links it; the tests and bench_h264
# check it with libavcodec's decoder (never linked into the daemon)
H264_OBJ := $(BUILD)/render/vt_h264.o $(BUILD)/render/vt_h264_avx2.o
X264_LIBS := $$(pkg-config --libs x264)
AVCODEC_LIBS := $$(pkg-config --libs libavcodec libavutil)
# level import (client/import/import_*.c, the CLI and the tests): assimp's C API
ASSIMP_LIBS := $$(pkg-config --libs assimp)
# the daemon's journal and snapshots (daemon/journal.c, snapshot.c): zlib's CRC-32
ZLIB_LIBS := $$(pkg-config --libs zlib)
# --cluster (daemon/cluster.c): NATS JetStream through Debian's libnats
NATS_LIBS := $$(pkg-config --libs libnats)

TEST_SRC := $(wildcard tests/test_*.c) tests/cull_ref.c tests/occ_ref.c tests/scene_file.c tests/pad_fake.c tests/h264_ref.c
TEST_OBJ := $(TEST_SRC:%.c=$(BUILD)/%.o)
TEST_BIN := $(BUILD)/vantage_tests

BENCH_SRC:= tests/bench/bench_cull.c tests/cull_ref.c tests/scene_file.c
BENCH_OBJ:= $(BENCH_SRC:%.c=$(BUILD)/%.o)
BENCH_BIN:= $(BUILD)/bench_cull

OCCB_SRC := tests/bench/bench_occlusion.c tests/occ_ref.c tests/scene_file.c
OCCB_OBJ := $(OCCB_SRC:%.c=$(BUILD)/%.o)
OCCB_BIN := $(BUILD)/bench_occlusion

RENDB_SRC:= tests/bench/bench_render.c tests/bench/bench_city.c
RENDB_OBJ:= $(RENDB_SRC:%.c=$(BUILD)/%.o)
RENDB_BIN:= $(BUILD)/bench_render

# H.264 against JPEG on the demo city (issue 21): bytes, PSNR, encode ms
H264B_SRC:= tests/bench/bench_h264.c tests/bench/bench_city.c tests/h264_ref.c
H264B_OBJ:= $(H264B_SRC:%.c=$(BUILD)/%.o)
H264B_BIN:= $(BUILD)/bench_h264

# the pad parsers alone (pure C: the parsers and their tables, no hidapi/libusb)
PADB_OBJ := $(BUILD)/tests/bench/bench_pad.o
PADB_BIN := $(BUILD)/bench_pad
PADB_PAD := $(BUILD)/client/pad/pad.o $(BUILD)/client/pad/pad_parse.o $(BUILD)/client/pad/pad_line.o $(PROTO_OBJ)

# the cluster tests' editor (tests/cluster): libvantage across failovers
CLED_OBJ := $(BUILD)/tests/cluster/cluster_editor.o
CLED_BIN := $(BUILD)/cluster_editor
CLBN_OBJ := $(BUILD)/tests/cluster/cluster_bench.o
CLBN_BIN := $(BUILD)/cluster_bench

SUBB_OBJ := $(BUILD)/tests/bench/bench_sublevel.o
SUBB_BIN := $(BUILD)/bench_sublevel

DESB_OBJ := $(BUILD)/tests/bench/bench_destruct.o
DESB_BIN := $(BUILD)/bench_destruct

# the commander's rules in the browser (client/commander/cmdr_wasm.c, web/js/cmdr.js):
# the same pad_map.c, view builders, protocol encoder and button names as the
# native client, compiled to WebAssembly by Debian's clang (--target=wasm32-wasi),
# linked by wasm-ld against wasi-libc (snprintf, strtod, libm) as a reactor
# (no main; _initialize runs the constructors). One build for every CONFIG:
# build/wasm/, and the module in web/js/ where the pages load it (gitignored).
WASM_CC  ?= clang
WASM_SRC := client/commander/cmdr_wasm.c client/commander/pad_map.c client/pad/pad.c client/lib/vtc_view.c \
            protocol/protocol.c protocol/vp_query.c
WASM_OBJ := $(WASM_SRC:%.c=build/wasm/%.o)
WASM_BIN := web/js/cmdr.wasm
WASM_FLAGS := --target=wasm32-wasi -std=c11 $(WARN) -O2 -D_GNU_SOURCE -Iculling -Iprotocol -Iclient/lib \
            -Iclient/pad -Iclient/commander -MMD -MP

SCENE    ?= tests/data/scenes/city_scene.txt

# the Blender add-on (client/blender/vantage_link, pure Python) as the zip
# Blender's "Install add-on" takes: one folder vantage_link/ inside
BLENDER_ZIP := build/vantage_link.zip
BLENDER_SRC := $(wildcard client/blender/vantage_link/*.py)

.PHONY: all run demo test test-web test-cluster bench-cluster test-blender bench-blender docs-blender-shot bench-web deps-npm docs-web-shots test-full bench bench-persist bench-commander bench-cycles docs-renders deps check-deps clean test-one install install-check \
        report report-smoke
all: check-deps $(CULL_LIB) $(DAEMON_BIN) $(CLI_BIN) $(TEST_BIN) $(BENCH_BIN) $(OCCB_BIN) $(RENDB_BIN) $(SUBB_BIN) $(DESB_BIN) $(PADB_BIN) $(H264B_BIN) \
     $(CLED_BIN) $(CLBN_BIN) $(WASM_BIN) $(BLENDER_ZIP)


$(BLENDER_ZIP): $(BLENDER_SRC)
	@mkdir -p $(@D)
	rm -f $@
	cd client/blender && python3 -c 'import sys, zipfile; z = zipfile.ZipFile(sys.argv[1], "w", zipfile.ZIP_DEFLATED); [z.write(f) for f in sys.argv[2:]]; z.close()' \
	  $(abspath $@) $(patsubst client/blender/%,%,$(BLENDER_SRC))

# ---- dependencies -----------------------------------------------------------
# check-deps runs before every build: it calls `make deps` only when a tool or
# a pkg-config module is missing, so a provisioned machine never touches apt.
check-deps:
	@if ! command -v $(CC) >/dev/null 2>&1 || ! command -v pkg-config >/dev/null 2>&1 || \
	    ! pkg-config --exists $(PC_MODS) || ! command -v Xvfb >/dev/null 2>&1 || [ ! -f /usr/include/wslay/wslay.h ] || \
	    ! command -v chromium >/dev/null 2>&1 || ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1 || \
	    [ ! -f /usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf ] || ! command -v $(WASM_CC) >/dev/null 2>&1 || \
	    ! command -v wasm-ld >/dev/null 2>&1 || [ ! -f /usr/lib/wasm32-wasi/libc.a ] || ! command -v nats-server >/dev/null 2>&1 || \
	    [ ! -x /usr/sbin/haproxy ]; then $(MAKE) --no-print-directory deps; \
	elif [ ! -d tests/web/node_modules/puppeteer-core ]; then $(MAKE) --no-print-directory deps-npm; fi

deps:
	@node=; command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || node="$(NODE_PKGS)"; \
	echo "make deps: installing $(DEB_PKGS) $$node"; \
	SUDO=; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	export DEBIAN_FRONTEND=noninteractive; \
	$$SUDO apt-get update -qq && \
	$$SUDO apt-get install -y -qq --no-install-recommends $(DEB_PKGS) $$node >/dev/null && \
	pkg-config --exists $(PC_MODS) && echo "make deps: Debian packages done"
	@$(MAKE) --no-print-directory deps-npm

deps-npm:
	npm ci --prefix tests/web --no-audit --no-fund --loglevel=error
# (npm ci: puppeteer-core, pinned in tests/web/package-lock.json, drives Debian's
# /usr/bin/chromium in tests/web/browser.test.mjs; it downloads no browser)

# ---- build --------------------------------------------------------------------
$(BUILD)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

# `bench --scenario NAME` finds the shipped scenarios here when run from the
# source tree (installed: PREFIX/share/vantage/scenarios, next to bin/)
$(BUILD)/client/loadgen/cli_scenario.o: CPPFLAGS += -DVANTAGE_SCENARIO_DIR='"$(CURDIR)/client/loadgen/scenarios"'
# `vantaged --web` serves the pages from here when run from the source tree
# (installed: PREFIX/share/vantage/web)
$(BUILD)/daemon/vantaged.o: CPPFLAGS += -DVANTAGE_WEB_DIR='"$(CURDIR)/web"'

$(BUILD)/culling/cull_kernels_avx2.o:   CFLAGS += $(ISA_AVX2)
$(BUILD)/culling/cull_occ_raster_avx2.o: CFLAGS += $(ISA_AVX2)
$(BUILD)/culling/cull_kernels_sse41.o:  CFLAGS += $(ISA_SSE41)
$(BUILD)/culling/cull_kernels_scalar.o: CFLAGS += -fno-tree-vectorize
# the distance volume's fold: vectorised by the compiler, sqrtf inline
$(BUILD)/culling/cull_dvol.o: CFLAGS += -O3 -fno-math-errno
# the renderer at RENDER_O (release: -O3; the flags below come after it)
$(BUILD)/render/%.o: CFLAGS += $(RENDER_O)
# the shading kernel, per instruction set as the culling kernels
$(BUILD)/render/vt_shade_avx2.o:  CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_shade_avx2_evex.o: CFLAGS += $(ISA_EVEX)
$(BUILD)/render/vt_shade_sse41.o: CFLAGS += $(ISA_SSE41)
$(BUILD)/render/vt_ssao_avx2.o:   CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_ssao_avx2_evex.o: CFLAGS += $(ISA_EVEX)
$(BUILD)/render/vt_tonemap_avx2.o: CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_post_avx2.o:    CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_h264_avx2.o:    CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_shadow_avx2.o: CFLAGS += $(ISA_AVX2)
$(BUILD)/render/vt_shadow_sse41.o: CFLAGS += $(ISA_SSE41)
$(BUILD)/render/vt_ssao_sse41.o:  CFLAGS += $(ISA_SSE41)
$(BUILD)/render/vt_ssao_base.o:   CFLAGS += -fno-tree-vectorize
$(BUILD)/render/vt_shade_base.o:  CFLAGS += -fno-tree-vectorize -fno-math-errno
# per-pixel shading of the scene model: sqrtf inline, no errno
$(BUILD)/render/vt_scene.o $(BUILD)/render/vt_texsample.o $(BUILD)/render/vt_texlin.o $(BUILD)/render/vt_span.o: CFLAGS += -fno-math-errno

build/wasm/%.o: %.c
	@mkdir -p $(@D)
	$(WASM_CC) $(WASM_FLAGS) -c $< -o $@

# exports are cmdr_wasm.c's export_name functions and the memory; wasm-ld
# drops what they do not reach (cmdr_map_load's fopen, the protocol's other
# messages); -s: no names section (the page needs none)
$(WASM_BIN): $(WASM_OBJ)
	$(WASM_CC) --target=wasm32-wasi -mexec-model=reactor -O2 -s -o $@ $(WASM_OBJ) -lm

$(CULL_LIB): $(CULL_OBJ)
	@rm -f $@
	ar rcs $@ $^

# the tests inject allocation failures through wrapped allocators (test_alloc.c)
TEST_WRAP := -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=aligned_alloc

$(PROTO_LIB): $(PROTO_OBJ)
	@rm -f $@
	ar rcs $@ $^

# the end-to-end tests run this configuration's vantaged and vantage; the
# recovery tests (test_recover.c) drive the journal and snapshots in-process
# every daemon module but the server's (the tests drive scenes, journals and edits in-process)
PERSIST_OBJ := $(filter-out $(addprefix $(BUILD)/daemon/,vantaged.o server.o handlers.o frames.o metrics.o metrics_http.o httpd.o web.o tls.o video.o auth.o upload.o readback.o cluster.o cluster_open.o cluster_snap.o),$(DAEMON_OBJ))
# (the wasm: test_cmdr_wasm.c runs it through node; order-only, it is not linked)
$(TEST_BIN): $(TEST_OBJ) $(RENDER_OBJ) $(H264_OBJ) $(IMPORT_OBJ) $(BUILD)/daemon/auth.o $(PERSIST_OBJ) $(PAD_OBJ) $(SCN_OBJ) $(CLIENT_LIB) $(CULL_LIB) $(DAEMON_BIN) $(CLI_BIN) | $(WASM_BIN)
	$(CC) $(LDFLAGS) $(TEST_WRAP) -o $@ $(TEST_OBJ) $(RENDER_OBJ) $(H264_OBJ) $(IMPORT_OBJ) $(BUILD)/daemon/auth.o $(PERSIST_OBJ) $(PAD_OBJ) $(SCN_OBJ) $(CLIENT_LIB) $(CULL_LIB) $$(pkg-config --libs cmocka json-c libssl libcrypto) $(EXR_LIBS) $(IMG_LIBS) $(GL_LIBS) $(ASSIMP_LIBS) $(PAD_LIBS) $(ZLIB_LIBS) $(X264_LIBS) $(AVCODEC_LIBS) $(LDLIBS)

# the daemon renders with the software path or OpenGL (vt_gldraw on vt_gl) and encodes JPEG; it
# decodes uploaded textures (vt_texture: PNG, JPEG, and EXR through OpenEXRCore)
DAEMON_RENDER := $(BUILD)/render/vt_picture.o $(BUILD)/render/vt_scene.o $(BUILD)/render/vt_texsample.o $(BUILD)/render/vt_texlin.o $(BUILD)/render/vt_span.o $(BUILD)/render/vt_shadow.o $(BUILD)/render/vt_shadow_tiles.o $(BUILD)/render/vt_shadow_sse41.o $(BUILD)/render/vt_shadow_avx2.o $(BUILD)/render/vt_ssao.o $(BUILD)/render/vt_ssao_base.o $(BUILD)/render/vt_ssao_sse41.o $(BUILD)/render/vt_ssao_avx2.o $(BUILD)/render/vt_ssao_avx2_evex.o $(BUILD)/render/vt_post.o $(BUILD)/render/vt_post_avx2.o $(BUILD)/render/vt_overlay.o \
                 $(BUILD)/render/vt_brdf.o $(BUILD)/render/vt_brdf_glsl.o \
                 $(BUILD)/render/vt_soft.o $(BUILD)/render/vt_raster.o $(IMAGE_OBJ) $(BUILD)/render/vt_file.o \
                 $(BUILD)/render/vt_err.o $(BUILD)/render/vt_texture.o $(BUILD)/render/vt_exr.o \
                 $(BUILD)/render/vt_egl.o $(BUILD)/render/vt_gl_target.o $(BUILD)/render/vt_gl_shader.o \
                 $(BUILD)/render/vt_gldraw.o $(BUILD)/render/vt_gldraw_glsl.o $(BUILD)/render/vt_shadow_gl.o $(BUILD)/render/vt_ssao_gl.o $(BUILD)/render/vt_gltex.o \
                 $(BUILD)/render/vt_shade_base.o \
                 $(BUILD)/render/vt_shade_sse41.o $(BUILD)/render/vt_shade_avx2.o $(BUILD)/render/vt_shade_avx2_evex.o
$(DAEMON_BIN): $(DAEMON_OBJ) $(DAEMON_RENDER) $(H264_OBJ) $(CULL_LIB) $(PROTO_LIB)
	$(CC) $(LDFLAGS) -o $@ $(DAEMON_OBJ) $(DAEMON_RENDER) $(H264_OBJ) $(CULL_LIB) $(PROTO_LIB) $(EXR_LIBS) $(IMG_LIBS) $(GL_LIBS) $(ZLIB_LIBS) $(WEB_LIBS) $(X264_LIBS) $(NATS_LIBS) $(LDLIBS)

# libvantage carries the protocol; its matrix helpers are culling/cull_mat.h
# (header-only), so the culling core is not in it
$(CLIENT_LIB): $(CLIENT_OBJ) $(PROTO_OBJ)
	@rm -f $@
	ar rcs $@ $^

# the CLI writes EXR and PNG from raw frames
CLI_RENDER := $(BUILD)/render/vt_exr.o $(IMAGE_OBJ) $(BUILD)/render/vt_file.o $(BUILD)/render/vt_err.o \
              $(BUILD)/render/vt_texture.o
$(CLI_BIN): $(CLI_OBJ) $(CLI_RENDER) $(CLIENT_LIB)
	$(CC) $(LDFLAGS) -o $@ $(CLI_OBJ) $(CLI_RENDER) $(CLIENT_LIB) $$(pkg-config --libs json-c) $(EXR_LIBS) $(IMG_LIBS) $(ASSIMP_LIBS) $(PAD_LIBS) $(SDL_LIBS) $(LDLIBS)

$(BUILD)/client/import/jsonl.o $(BUILD)/client/cli/cli_export.o $(BUILD)/tests/test_import.o: CPPFLAGS += $$(pkg-config --cflags json-c)
$(BUILD)/client/pad/pad_io_real.o $(BUILD)/client/cli/cli_pad.o: CPPFLAGS += $$(pkg-config --cflags hidapi-hidraw libusb-1.0)
$(BUILD)/client/commander/commander_sdl.o: CPPFLAGS += $$(pkg-config --cflags sdl2 SDL2_ttf) -Irender

$(BENCH_BIN): $(BENCH_OBJ) $(CULL_LIB)
	$(CC) $(LDFLAGS) -o $@ $(BENCH_OBJ) $(CULL_LIB) $(LDLIBS)

$(OCCB_BIN): $(OCCB_OBJ) $(RENDER_OBJ) $(CULL_LIB)
	$(CC) $(LDFLAGS) -o $@ $(OCCB_OBJ) $(RENDER_OBJ) $(CULL_LIB) $(EXR_LIBS) $(IMG_LIBS) $(GL_LIBS) $(LDLIBS)

# the demo city (bench_city.c) is the daemon's: its scene and edit modules linked in, as the tests link them
$(RENDB_BIN): $(RENDB_OBJ) $(RENDER_OBJ) $(PERSIST_OBJ) $(CULL_LIB) $(PROTO_LIB)
	$(CC) $(LDFLAGS) -o $@ $(RENDB_OBJ) $(RENDER_OBJ) $(PERSIST_OBJ) $(CULL_LIB) $(PROTO_LIB) $(EXR_LIBS) $(IMG_LIBS) $(GL_LIBS) $(ZLIB_LIBS) $(LDLIBS)

$(H264B_BIN): $(H264B_OBJ) $(RENDER_OBJ) $(H264_OBJ) $(PERSIST_OBJ) $(CULL_LIB) $(PROTO_LIB)
	$(CC) $(LDFLAGS) -o $@ $(H264B_OBJ) $(RENDER_OBJ) $(H264_OBJ) $(PERSIST_OBJ) $(CULL_LIB) $(PROTO_LIB) $(EXR_LIBS) $(IMG_LIBS) $(GL_LIBS) $(ZLIB_LIBS) $(X264_LIBS) $(AVCODEC_LIBS) $(LDLIBS)

$(PADB_BIN): $(PADB_OBJ) $(PADB_PAD)
	$(CC) $(LDFLAGS) -o $@ $(PADB_OBJ) $(PADB_PAD) $(LDLIBS)

$(CLED_BIN): $(CLED_OBJ) $(CLIENT_LIB)
	$(CC) $(LDFLAGS) -o $@ $(CLED_OBJ) $(CLIENT_LIB) $(LDLIBS)

$(CLBN_BIN): $(CLBN_OBJ) $(CLIENT_LIB)
	$(CC) $(LDFLAGS) -o $@ $(CLBN_OBJ) $(CLIENT_LIB) $(LDLIBS)

$(SUBB_BIN): $(SUBB_OBJ) $(CLIENT_LIB)
	$(CC) $(LDFLAGS) -o $@ $(SUBB_OBJ) $(CLIENT_LIB) $(LDLIBS)

$(DESB_BIN): $(DESB_OBJ) $(CLIENT_LIB) $(CULL_LIB)
	$(CC) $(LDFLAGS) -o $@ $(DESB_OBJ) $(CLIENT_LIB) $(CULL_LIB) $(LDLIBS)

$(BUILD)/tests/%.o: CPPFLAGS += $$(pkg-config --cflags cmocka epoxy) -Itests
$(BUILD)/render/%.o: CPPFLAGS += $$(pkg-config --cflags OpenEXR libpng libjpeg egl epoxy)
$(BUILD)/render/vt_h264.o: CPPFLAGS += $$(pkg-config --cflags x264)
$(BUILD)/tests/test_h264.o $(BUILD)/tests/test_web.o $(BUILD)/tests/h264_ref.o $(BUILD)/tests/bench/bench_h264.o: CPPFLAGS += $$(pkg-config --cflags x264 libavcodec libavutil)

# ---- the two commands ---------------------------------------------------------
run: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	@port=7470; sock=/tmp/vantaged.sock; bind=127.0.0.1; set -- $(VANTAGED_ARGS); \
	while [ $$# -gt 0 ]; do case "$$1" in \
	  --port) port=$$2; shift ;; --port=*) port=$${1#--port=} ;; \
	  --bind) bind=$$2; shift ;; --bind=*) bind=$${1#--bind=} ;; \
	  --unix) sock=$$2; shift ;; --unix=*) sock=$${1#--unix=} ;; esac; shift; done; \
	c=build/release/vantage; [ "$$bind" = 127.0.0.1 ] || c="$$c -h $$bind"; [ "$$port" = 7470 ] || c="$$c -p $$port"; \
	[ -n "$$bind" ] || c="build/release/vantage -s $$sock"; \
	echo "starting vantaged $(VANTAGED_ARGS) (Ctrl-C stops it; daemon flags: make run VANTAGED_ARGS=\"...\"). In another terminal:"; \
	echo "  $$c ping"; echo "  $$c stats"; echo "  $$c query --eye 0,2,-300 --at 0,2,0"; \
	if [ -n "$$sock" ]; then echo "  build/release/vantage -s $$sock watch"; else echo "  $$c watch"; fi
	./build/release/vantaged $(VANTAGED_ARGS)

# the culling core on the city scene (tests/data/scenes), then a short benchmark
demo: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/bench_cull build/release/bench_occlusion
	./build/release/bench_cull --demo --scene $(SCENE)
	./build/release/bench_cull --quick
	./build/release/bench_occlusion --scene $(SCENE) --quick --frames 4

# test-one: this CONFIG's test binary
test-one: check-deps $(TEST_BIN)
	VANTAGE_BIN_DIR=$(BUILD) $(TEST_BIN)

# make test builds its three configurations with every core (a plain `make
# test`, as CI runs it, compiled one file at a time); the tests themselves
# run one binary after another
BUILD_JOBS ?= $(shell nproc 2>/dev/null || echo 1)
test: check-deps
	@$(MAKE) --no-print-directory -j$(BUILD_JOBS) CONFIG=release build/release/vantage_tests build/release/bench_cull $(BLENDER_ZIP) \
	  build/release/bench_occlusion build/release/bench_render build/release/bench_h264 build/release/cluster_editor \
	  build/release/cluster_bench
	@$(MAKE) --no-print-directory -j$(BUILD_JOBS) CONFIG=scalar build/scalar/vantage_tests
	@$(MAKE) --no-print-directory -j$(BUILD_JOBS) CONFIG=asan build/asan/vantage_tests
	@$(MAKE) --no-print-directory -j$(BUILD_JOBS) CONFIG=asan fuzz-replay
	@$(MAKE) --no-print-directory CONFIG=release install-check
	@$(MAKE) --no-print-directory report-smoke
	./build/release/bench_cull --smoke
	./build/release/bench_occlusion --smoke --scene $(SCENE)
	./build/release/bench_render --smoke
	./build/release/bench_h264 --smoke
	VANTAGE_TEST_SCALE=$(SIDE_SCALE) VANTAGE_BIN_DIR=build/scalar ./build/scalar/vantage_tests
	VANTAGE_BIN_DIR=build/release ./build/release/vantage_tests
	VANTAGE_BIN_DIR=build/release tests/web/run.sh
	VANTAGE_BIN_DIR=build/release tests/blender/run.sh
	VANTAGE_BIN_DIR=build/release python3 tests/cluster/run.py
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  VANTAGE_TEST_SCALE=$(SIDE_SCALE) VANTAGE_BIN_DIR=build/asan ./build/asan/vantage_tests

# the browser client (web/js/vproto.js) against this configuration's vantaged and vantage
# (tests/web/run.sh: Node's test runner, each file with its own daemon; about 3 s)
test-web: check-deps
	@$(MAKE) --no-print-directory CONFIG=$(CONFIG) $(DAEMON_BIN) $(CLI_BIN)
	VANTAGE_BIN_DIR=$(BUILD) tests/web/run.sh

# the cluster (vantaged --cluster, daemon/cluster.c): a 3-node NATS JetStream cluster on
# loopback, a writer and replicas under faults, split brain, bad stream data (tests/cluster/run.py;
# about 30 s)
test-cluster: check-deps
	@$(MAKE) --no-print-directory CONFIG=$(CONFIG) $(DAEMON_BIN) $(CLI_BIN) $(CLED_BIN) $(CLBN_BIN)
	VANTAGE_BIN_DIR=$(BUILD) python3 tests/cluster/run.py

# the cluster's numbers (BENCHMARKS.md, Scale-out): lag, throughput, catch-up of 1M records,
# bootstrap of 1M entities, failover, frames from 7 daemons against 1 (several minutes)
bench-cluster: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage \
	  build/release/cluster_editor build/release/cluster_bench
	VANTAGE_BIN_DIR=build/release python3 tests/cluster/bench.py

# the Blender live-link (client/blender) in headless Blender against this configuration's
# vantaged and vantage (tests/blender/run.sh; skipped when blender is missing; about 15 s)
test-blender: check-deps
	@$(MAKE) --no-print-directory CONFIG=$(CONFIG) $(DAEMON_BIN) $(CLI_BIN) $(BLENDER_ZIP)
	VANTAGE_BIN_DIR=$(BUILD) tests/blender/run.sh

# the live-link's latency: Blender's depsgraph handler to the ACK of the daemon epoch
# holding the edit, p50/p99 over 1,000 edits (tests/blender/bench_link.py; not in make test)
bench-blender: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	VANTAGE_BIN_DIR=build/release blender -b --factory-startup --python-exit-code 1 \
	  --python tests/blender/bench_link.py -- --edits $(or $(BENCH_EDITS),1000)

# docs/blender_link.png: a scene in headless Blender, Cycles (CPU) beside vantaged's frame of the
# same camera, mirrored by the live-link (tests/blender/screenshot.py; about 15 s)
docs-blender-shot: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	VANTAGE_BIN_DIR=build/release blender -b --factory-startup --python-exit-code 1 \
	  --python tests/blender/screenshot.py -- $(CURDIR)/docs/blender_link.png

# make test runs the randomized tests whole in the release build and at
# half size in the scalar and ASan builds, and the every-bit damage
# campaigns (tests/test_recover.c) on every 3rd byte in release (every 5th
# or 16th in the others); make test-full runs all three whole and the
# campaigns on every byte (about 6 minutes more)
SIDE_SCALE ?= 0.5
test-full:
	@VANTAGE_TEST_EXHAUSTIVE=1 $(MAKE) --no-print-directory test SIDE_SCALE=1

bench: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/bench_cull build/release/bench_occlusion \
	  build/release/bench_render build/release/bench_pad build/release/bench_h264
	./build/release/bench_cull --scene $(SCENE) $(BENCH_ARGS)
	./build/release/bench_occlusion --scene $(SCENE) $(BENCH_ARGS)
	./build/release/bench_render $(BENCH_ARGS)
	./build/release/bench_pad $(BENCH_ARGS)
	./build/release/bench_h264 $(H264_BENCH_ARGS)

# recovery time and edit throughput per durability policy (a few minutes)
bench-persist: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	tests/bench/bench_persist.sh build/release

# input-to-photon latency of the commander client per tick rate (about a minute)
bench-commander: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	tests/bench/bench_commander.sh build/release $(or $(BENCH_SECONDS),15)

# the browser viewer in headless Chromium on the demo city: frames a second
# and input-to-photon for 1, 4 and 16 viewers (tests/web/bench_viewer.mjs;
# about a minute; not part of make test)
bench-web: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged
	for n in 1 4 16; do VANTAGE_BIN_DIR=build/release node tests/web/bench_viewer.mjs --viewers $$n \
	    --seconds $(or $(BENCH_SECONDS),10) --size $(or $(BENCH_SIZE),1280x720) || exit 1; done

# the browser pages' screenshots in docs/ (tests/web/screenshots.mjs: the
# demo city, headless Chromium)
docs-web-shots: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged
	VANTAGE_BIN_DIR=build/release node tests/web/screenshots.mjs docs

# the renderer against Blender Cycles on three scenes: SSIM and luminance
# differences, side-by-side pictures in build/bench-cycles (minutes; needs
# blender and python3-numpy; not part of make test)
bench-cycles: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	tests/bench/cycles/bench_cycles.sh build/release build/bench-cycles

# the demo city pictures in docs/ (day, night, street, aerial, top-down, destruction)
docs-renders: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/vantaged build/release/vantage
	tests/bench/docs_renders.sh build/release docs

# ---- install: the binaries, libvantage, its headers and pkg-config file ----------
PREFIX ?= /usr/local
install: check-deps
	@$(MAKE) --no-print-directory CONFIG=$(CONFIG) $(DAEMON_BIN) $(CLI_BIN) $(CLIENT_LIB) $(WASM_BIN)
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/include/vantage
	install -m 755 $(DAEMON_BIN) $(CLI_BIN) $(DESTDIR)$(PREFIX)/bin/
	install -m 644 $(CLIENT_LIB) $(DESTDIR)$(PREFIX)/lib/
	install -m 644 client/lib/vantage.h protocol/protocol.h protocol/vp_err.h protocol/vp_bytes.h protocol/vp_grow.h $(DESTDIR)$(PREFIX)/include/vantage/
	install -d $(DESTDIR)$(PREFIX)/share/vantage/scenarios
	install -m 644 client/loadgen/scenarios/*.scn $(DESTDIR)$(PREFIX)/share/vantage/scenarios/
	install -d $(DESTDIR)$(PREFIX)/share/vantage/web/js
	install -m 644 web/*.html web/*.css $(DESTDIR)$(PREFIX)/share/vantage/web/
	install -m 644 web/js/*.js $(WASM_BIN) $(DESTDIR)$(PREFIX)/share/vantage/web/js/
	sed 's|@PREFIX@|$(PREFIX)|' client/lib/vantage.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/vantage.pc
	@$(MAKE) --no-print-directory $(BLENDER_ZIP)
	install -m 644 $(BLENDER_ZIP) $(DESTDIR)$(PREFIX)/share/vantage/
	install -m 644 docs/scale-out/haproxy.cfg $(DESTDIR)$(PREFIX)/share/vantage/

# installs into build/<config>/stage and builds a program with pkg-config
install-check:
	@$(MAKE) --no-print-directory CONFIG=$(CONFIG) install PREFIX=$(abspath $(BUILD))/stage > /dev/null
	PKG_CONFIG_PATH=$(BUILD)/stage/lib/pkgconfig $(CC) -std=c11 -o $(BUILD)/install_check tests/install_check.c \
	  $$(PKG_CONFIG_PATH=$(BUILD)/stage/lib/pkgconfig pkg-config --cflags --libs --static vantage)
	$(BUILD)/install_check
	@# the client library stands alone: no culling core in it (cull_mat.h is header-only)
	@! nm $(BUILD)/stage/lib/libvantage.a | grep ' [TDB] cull_' || { echo "install-check: libvantage.a carries culling symbols"; exit 1; }

clean:
	rm -rf build $(WASM_BIN)

include tests/fuzz/fuzz.mk
include tests/bench/report.mk

-include $(RENDER_OBJ:.o=.d) $(H264_OBJ:.o=.d) $(CULL_OBJ:.o=.d) $(PROTO_OBJ:.o=.d) $(DAEMON_OBJ:.o=.d) $(CLIENT_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(TEST_OBJ:.o=.d) $(BENCH_OBJ:.o=.d) $(OCCB_OBJ:.o=.d) $(RENDB_OBJ:.o=.d) $(H264B_OBJ:.o=.d) $(PADB_OBJ:.o=.d) $(SUBB_OBJ:.o=.d) $(DESB_OBJ:.o=.d) \
         $(WASM_OBJ:.o=.d)
