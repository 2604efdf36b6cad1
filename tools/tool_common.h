/* What the four tools share: messages, exit codes, number parsing. Only the
 * public API is used here. */
#ifndef AS_TOOL_COMMON_H
#define AS_TOOL_COMMON_H

#include "as/as.h"

#include <stdbool.h>

/* Exit codes (as in the KTX tools), documented in every --help. */
enum {
    EXIT_OK = 0,
    EXIT_USAGE = 1,
    EXIT_IO = 2,
    EXIT_INVALID_INPUT = 3,
    EXIT_RUNTIME = 4,
    EXIT_UNSUPPORTED = 5
};

#define TOOL_EXIT_CODES_HELP \
    "Exit codes: 0 success, 1 usage error, 2 I/O error (missing or unwritable file),\n" \
    "            3 invalid input file (unparseable, corrupt, checksum, invalid structure),\n" \
    "            4 runtime or library error, 5 unsupported (newer version, unknown kind).\n"

/* Prints "TOOL: error: MESSAGE" for the last libas error and returns the exit
 * code that belongs to it. */
int tool_fail(const char *tool);
/* Prints "TOOL: MESSAGE" and the --help hint; returns EXIT_USAGE. */
int tool_usage_error(const char *tool, const char *fmt, ...);
void tool_print_version(const char *tool);

bool tool_parse_u32(const char *s, unsigned *out);
bool tool_parse_float(const char *s, float *out);
bool tool_parse_vec3(const char *s, float out[3]);

/* Prints s as a JSON string: quotes, backslashes and control characters
 * escaped. */
void tool_print_json_string(const char *s);

/* Progress on stderr, only when stderr is a terminal. */
bool tool_progress(void *user, double fraction);

#endif
