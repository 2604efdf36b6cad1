#include "tool_common.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

int tool_fail(const char *tool)
{
    const as_error_t e = as_get_error();
    fprintf(stderr, "%s: error: %s [%s]\n", tool, as_get_error_message(), as_error_name(e));
    const int code = as_error_exit_code(e);
    return code ? code : EXIT_RUNTIME;
}

int tool_usage_error(const char *tool, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", tool);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\nTry '%s --help'.\n", tool);
    return EXIT_USAGE;
}

void tool_print_version(const char *tool)
{
    printf("%s (libas) %s\n", tool, as_version_string());
}

bool tool_parse_u32(const char *s, unsigned *out)
{
    char *end;
    errno = 0;
    const unsigned long v = strtoul(s, &end, 10);
    if (errno || end == s || *end || v > 0xFFFFFFFFul || s[0] == '-') return false;
    *out = (unsigned)v;
    return true;
}

bool tool_parse_float(const char *s, float *out)
{
    char *end;
    errno = 0;
    const float v = strtof(s, &end);
    if (errno || end == s || *end || !isfinite(v)) return false;
    *out = v;
    return true;
}

bool tool_parse_vec3(const char *s, float out[3])
{
    char *end;
    const char *p = s;
    for (int i = 0; i < 3; ++i) {
        errno = 0;
        out[i] = strtof(p, &end);
        if (errno || end == p || !isfinite(out[i])) return false;
        if (i < 2) {
            if (*end != ',') return false;
            p = end + 1;
        }
    }
    return *end == '\0';
}

bool tool_progress(void *user, double fraction)
{
    (void)user;
    if (isatty(STDERR_FILENO)) {
        fprintf(stderr, "\r%5.1f%%", 100.0 * fraction);
        if (fraction >= 1.0) fprintf(stderr, "\r       \r");
        fflush(stderr);
    }
    return true;
}

/* A JSON string: quotes, backslashes and control characters escaped. */
void tool_print_json_string(const char *s)
{
    putchar('"');
    for (const unsigned char *p = (const unsigned char *)s; *p; ++p) {
        if (*p == '"' || *p == '\\') printf("\\%c", *p);
        else if (*p < 0x20) printf("\\u%04x", *p);
        else putchar(*p);
    }
    putchar('"');
}
