/*
 * auth.h — roles and tokens. A token file (vantaged --tokens FILE) holds
 * one line per token, "ROLE TOKEN" (ROLE: viewer, commander or editor;
 * TOKEN: 16..255 printable characters without spaces), '#' comments and
 * blank lines; a role may have several tokens (rotation). The file must be
 * a regular file that only its owner can read or write (mode 0600 or
 * tighter): the daemon will not start otherwise.
 *
 * A client asking for a role must present a token of that role or a
 * higher one (editor > commander > viewer); a viewer needs none when the
 * file has no viewer line (public viewing). Tokens are compared in time
 * independent of their content and of where they differ.
 */
#ifndef VANTAGE_AUTH_H
#define VANTAGE_AUTH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define AUTH_MAX_TOKENS 64u
#define AUTH_MIN_TOKEN 16u
#define AUTH_TOKEN_CAP 256u  /* VP_MAX_TOKEN + 1: every token padded to this */

typedef struct auth_tokens {
    uint32_t n;
    uint8_t role[AUTH_MAX_TOKENS];
    uint8_t len[AUTH_MAX_TOKENS];
    uint8_t tok[AUTH_MAX_TOKENS][AUTH_TOKEN_CAP];
    bool public_viewer;      /* no viewer line: viewers need no token */
} auth_tokens;

/* Reads and checks a token file. 0, or -1 with err filled (the file, its
 * mode, or the line that is wrong). */
int auth_load(const char *path, auth_tokens *t, char *err, size_t errlen);

/* Parses a token file's text (what auth_load does after its checks). */
int auth_parse(const char *text, size_t len, auth_tokens *t, char *err, size_t errlen);

/* Whether tok[0..len) grants role (VP_ROLE_*). Constant time in the
 * token's content: every stored token is compared in full. */
bool auth_grants(const auth_tokens *t, int role, const uint8_t *tok, size_t len);

/* a and b (each AUTH_TOKEN_CAP bytes) equal, in time independent of their
 * content. */
bool auth_ct_equal(const uint8_t *a, const uint8_t *b);

/* Whether a TCP bind address only reaches this machine (127.0.0.0/8, ::1,
 * localhost). */
bool auth_loopback(const char *addr);

#endif
