/* The one error model of libas: a per-thread last error with a message. */
#include "as_internal.h"

#include <stdio.h>
#include <string.h>

static _Thread_local as_error_t last_code;
static _Thread_local char last_message[1024];

as_error_t as_set_errorv(as_error_t code, const char *fmt, va_list ap)
{
    last_code = code;
    vsnprintf(last_message, sizeof last_message, fmt, ap);
    return code;
}

as_error_t as_set_error(as_error_t code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    as_set_errorv(code, fmt, ap);
    va_end(ap);
    return code;
}

as_error_t as_get_error(void) { return last_code; }

const char *as_get_error_message(void) { return last_code == AS_OK ? "" : last_message; }

void as_clear_error(void)
{
    last_code = AS_OK;
    last_message[0] = '\0';
}

const char *as_error_name(as_error_t code)
{
    switch (code) {
    case AS_OK: return "OK";
    case AS_ERROR_UNKNOWN: return "UNKNOWN";
    case AS_ERROR_INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case AS_ERROR_OUT_OF_MEMORY: return "OUT_OF_MEMORY";
    case AS_ERROR_CANCELLED: return "CANCELLED";
    case AS_ERROR_IO: return "IO";
    case AS_ERROR_FILE_NOT_FOUND: return "FILE_NOT_FOUND";
    case AS_ERROR_PARSE: return "PARSE";
    case AS_ERROR_INVALID_MESH: return "INVALID_MESH";
    case AS_ERROR_CORRUPT: return "CORRUPT";
    case AS_ERROR_CHECKSUM: return "CHECKSUM";
    case AS_ERROR_INVALID_STRUCTURE: return "INVALID_STRUCTURE";
    case AS_ERROR_VERSION: return "VERSION";
    case AS_ERROR_UNSUPPORTED: return "UNSUPPORTED";
    case AS_ERROR_NO_DEVICE: return "NO_DEVICE";
    case AS_ERROR_DEVICE: return "DEVICE";
    case AS_ERROR_MAX_STABLE: break;
    }
    return "UNKNOWN_CODE";
}

int as_error_exit_code(as_error_t code)
{
    switch (code) {
    case AS_OK: return 0;
    case AS_ERROR_INVALID_ARGUMENT: return 1;
    case AS_ERROR_IO:
    case AS_ERROR_FILE_NOT_FOUND: return 2;
    case AS_ERROR_PARSE:
    case AS_ERROR_INVALID_MESH:
    case AS_ERROR_CORRUPT:
    case AS_ERROR_CHECKSUM:
    case AS_ERROR_INVALID_STRUCTURE: return 3;
    case AS_ERROR_VERSION:
    case AS_ERROR_UNSUPPORTED: return 5;
    default: return 4;
    }
}
