/*
 * jsonl.h — one entity as a JSON line, both ways: the parser behind
 * `vantage import` and the formatter behind `export` and `get`. Pure
 * functions (no I/O, no connection), so the fuzz target
 * tests/fuzz/fuzz_jsonl.c runs exactly what the CLI runs.
 */
#ifndef VANTAGE_JSONL_H
#define VANTAGE_JSONL_H

#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>

/* Room for any line jsonl_entity_format writes, '\n' and NUL included: a
 * 255-byte sub-level name escaped at up to 6 bytes a byte, plus at most
 * about 400 bytes of numbers and keys. */
#define JSONL_LINE_MAX (512 + 6 * VP_MAX_NAME)

/*
 * One line of an import file, line[0..len) without its newline (it need not
 * end in a NUL), to a record. Returns true, or false with a message for the
 * user in err (the caller adds the file and line number).
 *
 * An accepted record has: an id (a JSON integer >= 0; json-c saturates one
 * above 2^64-1), class and sublevel 0..65535, flags 0 or VP_ENT_DYNAMIC,
 * handle 0, a sphere and an AABB of finite numbers (the one left out all
 * 0); or, with any of "pos" [x,y,z], "rot" [x,y,z,w] (identity if left
 * out), "scale" [x,y,z] (1,1,1), an entity with VP_ENT_TRANSFORM whose
 * sphere and AABB (written by export as the derived bounds) are not read;
 * "material" 0..2^32-1 in either. sub gets the sub-level's name when "sublevel" is a name (1..255
 * bytes, none below 32 or 127; the caller resolves it to an id), else "".
 * The scene's record rules (r >= 0, min <= max, |x| <= 1e12, r <= 1e9) are
 * not checked here: the daemon checks them and refuses the whole batch.
 */
bool jsonl_entity_parse(const char *line, size_t len, vp_entity *e, char sub[VP_MAX_NAME + 1], char *err,
                        size_t errlen);

/* e as an export line, '\n' included, into buf (cap bytes, NUL-terminated
 * when cap > 0). sublevel_json: the sub-level's name already escaped
 * (cli_json_escape), or NULL to write its number; handle adds the daemon's
 * handle. Returns the length of the whole line, as snprintf does (>= cap:
 * cut short). jsonl_entity_parse reads the line back to the same record
 * (the handle aside; a -0 comes back as 0). */
int jsonl_entity_format(char *buf, size_t cap, const vp_entity *e, bool handle, const char *sublevel_json);

/* JSON string contents of src[0..n): quotes, backslashes and control bytes
 * escaped into dst (room for 6 n + 1); returns the length written. */
size_t cli_json_escape(char *dst, const char *src, size_t n);

#endif
