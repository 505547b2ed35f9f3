/* opstatus.h - the operations that describe the server itself: liveness (/healthz),
 * readiness (/readyz: loading, draining, an unreadable store) and the metrics (/metrics, the
 * Prometheus text with the gauges read from each part) and the API's description
 * (/openapi.json, docs/openapi.yaml as built in). Handlers of call.h. */
#ifndef SDFD_OPSTATUS_H
#define SDFD_OPSTATUS_H

#include "ops/call.h"

int sdfd_op_health(sdfd_call *call);
int sdfd_op_ready(sdfd_call *call);
int sdfd_op_metrics(sdfd_call *call);
int sdfd_op_openapi(sdfd_call *call);

#endif
