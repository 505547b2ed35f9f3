/* binrequests.h - what the binary front end answers (binrequests.c), frame by frame. */
#ifndef SDFD_BINREQUESTS_H
#define SDFD_BINREQUESTS_H

#include "transport/binconn.h"

/* Answer or start one complete frame of connection c; the payload is valid only during the
 * call. */
void sdfd_bin_handle_frame(sdfd_binary *b, connection *c, const sdf_proto_header *h,
                           const unsigned char *payload);

#endif
