/* dispatch.h - which handler answers each operation (call.h): the transports run a call
 * through here and never name a handler themselves. */
#ifndef SDFD_DISPATCH_H
#define SDFD_DISPATCH_H

#include "ops/call.h"

/* Whether call.h answers `op` (queries, binary connection frames and the page do not). */
int sdfd_dispatches(const sdfd_op *op);

/* Run call->op's handler: SDFD_CALL_READY with call->result filled, or SDFD_CALL_PENDING and
 * call->done comes once it is (operations flagged SDFD_OP_ASYNC only). */
int sdfd_dispatch(sdfd_call *call);

#endif
