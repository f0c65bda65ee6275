# tests/bench/report.mk — run time against error of the culling configurations
# (issue 9); included by the top-level Makefile (after its variables: CC,
# CFLAGS, CPPFLAGS, LDFLAGS, LDLIBS, BUILD, CULL_LIB, SCENE). See
# docs/report/README.md.
#
#   make report          build report_cull (CONFIG=release), run it over the city
#                        walk, random towns and the stress cases, then gnuplot:
#                        docs/report/{report.md, time_vs_error.svg/.png/.csv/.gp,
#                        stress.csv}; a few minutes. Needs gnuplot (make deps).
#   make report-smoke    a few-second run into a temporary folder (no gnuplot);
#                        fails on any false invisible (an entity culled that the
#                        references see, other than by a screen-area threshold)
#
# REPORT_DIR (docs/report) and REPORT_ARGS (more report_cull options, e.g.
# --reps 40) change what `make report` does.

# an include above the first target must not change the default goal
REPORT_SAVED_GOAL := $(.DEFAULT_GOAL)

REPORT_DIR  ?= docs/report
REPORT_ARGS ?=
REPORT_SRC  := tests/bench/report.c tests/cull_ref.c tests/occ_ref.c tests/scene_file.c
REPORT_OBJ  := $(REPORT_SRC:%.c=$(BUILD)/%.o)
REPORT_BIN  := $(BUILD)/report_cull

$(REPORT_BIN): $(REPORT_OBJ) $(CULL_LIB)
	$(CC) $(LDFLAGS) -o $@ $(REPORT_OBJ) $(CULL_LIB) $(LDLIBS)

# gnuplot first: a missing plotter should not cost the whole run. The plot is
# drawn even when the run found a false invisible (exit 3); make fails after.
report: check-deps
	@command -v gnuplot >/dev/null 2>&1 || \
	  { echo "make report: gnuplot not found: make deps (Debian package gnuplot-nox)"; $(MAKE) --no-print-directory deps; }
	@command -v gnuplot >/dev/null 2>&1 || { echo "make report: still no gnuplot after make deps"; exit 1; }
	@$(MAKE) --no-print-directory CONFIG=release build/release/report_cull
	./build/release/report_cull --scene $(SCENE) --out $(REPORT_DIR) $(REPORT_ARGS); rc=$$?; \
	  [ $$rc = 0 ] || [ $$rc = 3 ] || exit $$rc; \
	  (cd $(REPORT_DIR) && gnuplot time_vs_error.gp) || exit 1; \
	  echo "make report: $(REPORT_DIR)/report.md, $(REPORT_DIR)/time_vs_error.svg"; exit $$rc

report-smoke: check-deps
	@$(MAKE) --no-print-directory CONFIG=release build/release/report_cull
	@dir=$$(mktemp -d) && \
	  { ./build/release/report_cull --smoke --scene $(SCENE) --out $$dir; rc=$$?; \
	    [ $$rc = 0 ] || cat $$dir/report.md 2>/dev/null | grep -A3 FAILED; rm -rf $$dir; exit $$rc; }

.PHONY: report report-smoke

-include $(REPORT_OBJ:.o=.d)

.DEFAULT_GOAL := $(REPORT_SAVED_GOAL)
