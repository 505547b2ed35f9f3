/* log.c - JSON-lines logging (see log.h). */
#include "core/log.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "core/utf8.h"

size_t sdfd_json_escape(char *dst, size_t cap, size_t len, const char *s)
{
    for (; s && *s && len + 7 < cap; s++) {
        unsigned char c = (unsigned char)*s;
        size_t n = c >= 0x80 ? sdfd_utf8_sequence((const unsigned char *)s) : 1;
        if (c == '"' || c == '\\') {
            len += (size_t)snprintf(dst + len, cap - len, "\\%c", c);
        } else if (c < 0x20 || !n) { /* a byte of no UTF-8 character: U+FFFD */
            len += (size_t)snprintf(dst + len, cap - len, "\\u%04x", c < 0x20 ? c : 0xFFFD);
        } else {
            memcpy(dst + len, s, n);
            len += n, s += n - 1;
        }
    }
    if (len < cap)
        dst[len] = '\0';
    return len;
}

static size_t begin(char *line, size_t cap, const char *level, const char *event)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (size_t)snprintf(line, cap, "{\"ts\":%lld.%03ld,\"level\":\"%s\",\"event\":\"%s\"",
                            (long long)ts.tv_sec, ts.tv_nsec / 1000000, level, event);
}

static void emit(char *line, size_t len, size_t cap)
{
    if (len > cap - 3)
        len = cap - 3;
    line[len++] = '}';
    line[len++] = '\n';
    /* One write(2): lines from concurrent threads stay whole. */
    ssize_t unused = write(STDERR_FILENO, line, len);
    (void)unused;
}

void sdfd_log(const char *level, const char *event, const char *fmt, ...)
{
    char line[1024], message[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    size_t len = begin(line, sizeof line, level, event);
    len += (size_t)snprintf(line + len, sizeof line - len, ",\"message\":\"");
    len = sdfd_json_escape(line, sizeof line - 2, len, message);
    line[len++] = '"';
    emit(line, len, sizeof line);
}

void sdfd_log_request(const char *proto, const char *method, const char *route, int status,
                      size_t points, double microseconds, size_t bytes_in, size_t bytes_out)
{
    char line[512];
    size_t len = begin(line, sizeof line, status >= 500 ? "error" : "info", "request");
    len += (size_t)snprintf(line + len, sizeof line - len,
                            ",\"proto\":\"%s\",\"method\":\"%s\",\"route\":\"", proto, method);
    len = sdfd_json_escape(line, sizeof line - 200, len, route);
    len += (size_t)snprintf(line + len, sizeof line - len,
                            "\",\"status\":%d,\"points\":%zu,\"us\":%.0f,\"bytes_in\":%zu,"
                            "\"bytes_out\":%zu",
                            status, points, microseconds, bytes_in, bytes_out);
    emit(line, len, sizeof line);
}

void sdfd_log_listening(const char *proto, const char *address, int port)
{
    char line[256];
    size_t len = begin(line, sizeof line, "info", "listening");
    len += (size_t)snprintf(line + len, sizeof line - len, ",\"proto\":\"%s\",\"address\":\"", proto);
    len = sdfd_json_escape(line, sizeof line - 40, len, address);
    len += (size_t)snprintf(line + len, sizeof line - len, "\",\"port\":%d", port);
    emit(line, len, sizeof line);
}
