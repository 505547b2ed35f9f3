/* log.h - one JSON object per line on stderr: machine-readable, greppable, and written with
 * a single write so lines from different threads never interleave. */
#ifndef SDFD_LOG_H
#define SDFD_LOG_H

#include <stddef.h>

/* {"ts":..., "level":"info", "event":"<event>", "message":"..."} */
void sdfd_log(const char *level, const char *event, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* {"ts":..., "level":"info", "event":"request", "proto":..., "route":..., "status":...,
 *  "points":..., "us":..., "bytes_in":..., "bytes_out":...} */
void sdfd_log_request(const char *proto, const char *method, const char *route, int status,
                      size_t points, double microseconds, size_t bytes_in, size_t bytes_out);

/* {"ts":..., "level":"info", "event":"listening", "proto":..., "address":..., "port":N} */
void sdfd_log_listening(const char *proto, const char *address, int port);

/* Append `s` JSON-escaped (without quotes) to dst; returns the new length (truncates). */
size_t sdfd_json_escape(char *dst, size_t cap, size_t len, const char *s);

#endif
