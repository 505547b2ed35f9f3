/* binary.h - the binary protocol front end (PROTOCOL.md). See binary.c. */
#ifndef SDFD_BINARY_H
#define SDFD_BINARY_H

#include "state/server.h"

typedef struct sdfd_binary sdfd_binary;

int sdfd_binary_start(sdfd_server *srv, sdfd_binary **out);
/* Stop accepting connections and reading new requests; replies still go out. */
void sdfd_binary_quiesce(sdfd_binary *b);
/* Close every connection and stop the thread. NULL is a no-op. */
void sdfd_binary_stop(sdfd_binary *b);

#endif
