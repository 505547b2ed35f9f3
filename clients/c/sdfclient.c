/* sdfclient.c - libsdfclient's public calls (sdfclient.h): connecting, HELLO, AUTH,
 * LIST_MESHES, the two query kinds and waiting for replies. Each builds its frame (the
 * points straight from the caller's array, never copied), and pipeline.c sends it, reads the
 * replies into their buffers and replaces a lost connection. */
#include "sdfclient.h"

#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline.h"
#include "proto.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "libsdfclient passes points and results through as the protocol's little-endian words"
#endif

/* The shared codes must keep libsdf's values (sdfclient.h promises it). */
_Static_assert((int)SDFC_EINVAL == (int)SDF_EINVAL && (int)SDFC_ENOMEM == (int)SDF_ENOMEM &&
                   (int)SDFC_EIO == (int)SDF_EIO && (int)SDFC_ELIMIT == (int)SDF_ELIMIT &&
                   (int)SDFC_EPROTO == (int)SDF_EPROTO,
               "SDFC_E* codes shared with sdf.h must have its values");
_Static_assert((int)SDFC_CLOSEST == (int)SDF_MODE_CLOSEST &&
                   (int)SDFC_FILTERED_GRADIENT == (int)SDF_MODE_FILTERED_GRADIENT &&
                   (int)SDFC_SIGN_NONE == (int)SDF_SIGN_NONE,
               "sdfc modes and signs are the wire codes");

const char *sdfc_strerror(int err)
{
    switch (err) {
    case SDFC_OK: return "success";
    case SDFC_EINVAL: return "invalid argument";
    case SDFC_ENOMEM: return "out of memory";
    case SDFC_EIO: return "socket error";
    case SDFC_ELIMIT: return "size limit exceeded";
    case SDFC_EPROTO: return "malformed reply from the server";
    case SDFC_ESERVER: return "the server refused the request";
    case SDFC_ECONNECT: return "cannot connect to the server";
    case SDFC_ETIMEDOUT: return "timed out";
    case SDFC_ECLOSED: return "the server closed the connection";
    case SDFC_ENOREQUEST: return "no such request in flight";
    case SDFC_ETLS: return "the TLS handshake or a TLS record failed";
    case SDFC_ECERT: return "the server's certificate is not trusted (not signed by the CA "
                            "file's CAs, expired, or for another host)";
    default: return "unknown error";
    }
}

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

/* ---- modes and names --------------------------------------------------------------------- */

int sdfc_mode_from_name(const char *name, sdfc_mode *out)
{
    sdf_proto_mode m;
    if (!out || sdf_proto_mode_from_name(name, &m))
        return SDFC_EINVAL;
    *out = (sdfc_mode)m;
    return 0;
}

/* sdfc_interpolation's names, in wire order. */
static const char *const interpolation_names[] = {"trilinear", "nearest", "hermite", "default"};

int sdfc_interpolation_from_name(const char *name, sdfc_interpolation *out)
{
    for (int i = 0; name && out && i < 4; i++) {
        if (!strcmp(name, interpolation_names[i])) {
            *out = (sdfc_interpolation)i;
            return 0;
        }
    }
    return SDFC_EINVAL;
}

int sdfc_sign_from_name(const char *name, sdfc_sign *out)
{
    static const char *const names[] = {"auto", "pseudonormal", "winding", "raycast", "none"};
    for (int i = 0; name && out && i < 5; i++) {
        if (!strcmp(name, names[i])) {
            *out = (sdfc_sign)i;
            return 0;
        }
    }
    return SDFC_EINVAL;
}

unsigned sdfc_words(sdfc_mode mode) { return sdf_proto_words((sdf_proto_mode)mode); }

size_t sdfc_result_size(sdfc_mode mode, uint32_t count)
{
    return (size_t)4 * sdfc_words(mode) * count;
}

/* ---- connecting -------------------------------------------------------------------------- */

int sdfc_connect(const char *host, int port, const sdfc_options *opts, sdfc_client **out)
{
    if (!out)
        return SDFC_EINVAL;
    *out = NULL;
    sdfc_options o = opts ? *opts : (sdfc_options){0};
    if (!host || !*host || port <= 0 || port > 65535 || (o.ca_file && !o.tls))
        return SDFC_EINVAL;
    sdfc_client *c = calloc(1, sizeof *c);
    if (!c || !(c->host = strdup(host))) {
        free(c);
        return SDFC_ENOMEM;
    }
    c->conn.fd = -1;
    c->port = port;
    c->resend = !!o.resend;
    c->connect_timeout_ms = o.connect_timeout_ms ? o.connect_timeout_ms : 10000;
    c->reply_timeout_ms = o.reply_timeout_ms ? o.reply_timeout_ms : 120000;
    c->next_id = c->base_id = 1;
    int rc = o.tls ? sdfc__tls_new(o.ca_file, &c->tls) : 0;
    if (!rc && o.token) { /* kept only if the server takes it: a refusal closes the handle */
        c->token_len = strlen(o.token);
        if (!(c->token = strdup(o.token)))
            rc = SDFC_ENOMEM;
    }
    if (!rc)
        rc = sdfc__open(c, 0);
    if (rc) {
        int saved = errno;
        sdfc_close(c);
        errno = saved;
        return rc;
    }
    *out = c;
    return 0;
}

int sdfc_get_stats(const sdfc_client *c, sdfc_stats *out)
{
    if (!c || !out)
        return SDFC_EINVAL;
    *out = c->stats;
    return 0;
}

void sdfc_close(sdfc_client *c)
{
    if (!c)
        return;
    sdfc__conn_close(&c->conn);
    sdfc__tls_free(c->tls);
    for (size_t i = 0; i < c->n; i++)
        sdfc__free_entry(&c->pend[c->head + i]);
    free(c->pend);
    free(c->rx.buf);
    free(c->host);
    free(c->token);
    free(c);
}

const sdfc_server_err *sdfc_server_error(const sdfc_client *c) { return c ? &c->err : NULL; }

size_t sdfc_in_flight(const sdfc_client *c) { return c ? c->in_flight : 0; }

/* Start of every call: the error of the last one is gone, unless the handle is broken. */
static int begin(sdfc_client *c)
{
    if (!c)
        return SDFC_EINVAL;
    if (!c->broken)
        c->err = (sdfc_server_err){0};
    return c->broken;
}

/* ---- waiting ----------------------------------------------------------------------------- */

int sdfc_wait(sdfc_client *c, uint32_t request_id)
{
    int rc = begin(c);
    if (rc)
        return rc;
    sdfc__pending *p = sdfc__lookup(c, request_id);
    if (!p)
        return SDFC_ENOREQUEST;
    while (p->state != SDFC__DONE) {
        if ((rc = sdfc__rx_one(c)))
            return rc;
        p = sdfc__lookup(c, request_id); /* the table may have moved */
    }
    return sdfc__claim(c, p);
}

int sdfc_wait_any(sdfc_client *c, uint32_t *request_id)
{
    int rc = begin(c);
    if (rc || !request_id)
        return rc ? rc : SDFC_EINVAL;
    if (c->in_flight == 0)
        return SDFC_ENOREQUEST;
    for (;;) {
        sdfc__pending *best = NULL;
        for (size_t i = 0; i < c->n; i++) {
            sdfc__pending *p = &c->pend[c->head + i];
            if (p->state == SDFC__DONE && (!best || p->done_seq < best->done_seq))
                best = p;
        }
        if (best) {
            *request_id = c->base_id + (uint32_t)(best - (c->pend + c->head));
            return sdfc__claim(c, best);
        }
        if ((rc = sdfc__rx_one(c)))
            return rc;
    }
}


/* ---- HELLO, AUTH, LIST_MESHES ------------------------------------------------------------ */

int sdfc_hello(sdfc_client *c, sdfc_hello_info *out)
{
    int rc = begin(c);
    if (rc || !out)
        return rc ? rc : SDFC_EINVAL;
    static const char name[] = "libsdfclient";
    sdfc__pending *p;
    if ((rc = sdfc__call(c, SDF_PROTO_HELLO, name, sizeof name - 1, SDF_PROTO_HELLO_OK, &p)))
        return rc;
    return sdfc__decode_hello(c, p, out);
}


int sdfc_auth(sdfc_client *c, const char *token, size_t len)
{
    int rc = begin(c);
    if (rc || (!token && len))
        return rc ? rc : SDFC_EINVAL;
    sdfc__pending *p;
    rc = sdfc__call(c, SDF_PROTO_AUTH, token, len, SDF_PROTO_AUTH_OK, &p);
    if (rc == SDFC_ESERVER)
        sdfc__set_broken(c, SDFC_ECLOSED); /* the server closes after a wrong token */
    if (rc)
        return rc;
    char *kept = malloc(len ? len : 1); /* for the connections that replace this one */
    if (!kept) {
        sdfc__claim(c, p);
        return sdfc__set_broken(c, SDFC_ENOMEM);
    }
    if (len)
        memcpy(kept, token, len);
    free(c->token);
    c->token = kept;
    c->token_len = len;
    return sdfc__claim(c, p);
}

int sdfc_list_meshes(sdfc_client *c, sdfc_mesh *out, size_t cap, size_t *count)
{
    int rc = begin(c);
    if (rc || !count || (cap && !out))
        return rc ? rc : SDFC_EINVAL;
    sdfc__pending *p;
    if ((rc = sdfc__call(c, SDF_PROTO_LIST_MESHES, NULL, 0, SDF_PROTO_MESHES, &p)))
        return rc;
    uint32_t n;
    size_t off = 0;
    const char *why;
    rc = sdf_proto_meshes_count(p->payload, p->payload_len, &n);
    for (uint32_t i = 0; !rc && i < n; i++) {
        sdf_proto_mesh_entry e;
        if ((rc = sdf_proto_meshes_next(p->payload, p->payload_len, &off, &e, &why)))
            break;
        if (e.name_len > SDF_PROTO_MAX_NAME) {
            rc = SDFC_EPROTO;
        } else if (i < cap) {
            out[i] = (sdfc_mesh){.triangles = e.triangles, .closed = e.closed,
                                 .auto_sign = e.auto_sign};
            sdfc__copy_str(out[i].name, sizeof out[i].name, e.name, e.name_len);
        }
    }
    if (!rc && (n ? off : 4) != p->payload_len)
        rc = SDFC_EPROTO;
    sdfc__claim(c, p);
    if (rc)
        return sdfc__set_broken(c, SDFC_EPROTO);
    *count = n;
    return 0;
}

/* ---- queries ----------------------------------------------------------------------------- */

static int to_filter(const sdfc_filter *in, sdf_proto_query *q)
{
    sdfc_filter f = in ? *in : (sdfc_filter){0};
    unsigned known = SDFC_FILTER_GRID | SDFC_FILTER_UNSIGNED | SDFC_FILTER_WIDE_BUMP |
                     SDFC_FILTER_SAMPLE_GRADIENT;
    if ((f.flags & ~known) || f.kernel < 0 || f.kernel > 255 || f.smooth < 0 ||
        f.smooth > SDFC_SMOOTH_MESH)
        return SDFC_EINVAL;
    sdf_filter_options *o = &q->filter;
    o->kernel = (sdf_kernel)f.kernel;
    o->grid = !!(f.flags & SDFC_FILTER_GRID);
    o->unsigned_integrand = !!(f.flags & SDFC_FILTER_UNSIGNED);
    o->allow_wide_bump = !!(f.flags & SDFC_FILTER_WIDE_BUMP);
    o->sample_gradient = !!(f.flags & SDFC_FILTER_SAMPLE_GRADIENT);
    /* values past int go out as INT_MAX, which the server refuses with its bound */
    o->samples = f.samples > INT_MAX ? INT_MAX : (int)f.samples;
    o->min_samples = f.min_samples > INT_MAX ? INT_MAX : (int)f.min_samples;
    o->cap = f.cap;
    o->a = f.a;
    o->b = f.b;
    o->medial = f.medial;
    o->seed = f.seed;
    o->smooth.shape = (sdf_volume_shape)f.smooth;
    o->smooth.depth = f.depth;
    o->smooth.scale = f.scale;
    if (f.smooth == SDFC_SMOOTH_SPHERE) {
        memcpy(o->smooth.center, f.shape, sizeof o->smooth.center);
        o->smooth.radius = f.shape[3];
    } else if (f.smooth == SDFC_SMOOTH_BOX) {
        memcpy(o->smooth.lo, f.shape, sizeof o->smooth.lo);
        memcpy(o->smooth.hi, f.shape + 3, sizeof o->smooth.hi);
    } else if (f.smooth == SDFC_SMOOTH_MESH) {
        if (!f.smooth_mesh)
            return SDFC_EINVAL;
        q->volume_name = f.smooth_mesh;
        q->volume_name_len = strlen(f.smooth_mesh);
    }
    return 0;
}

/* Checks common to both query kinds, before anything is sent. */
static int check_query(sdfc_client *c, const char *name, const float *points, uint32_t count,
                       const void *result, size_t result_size, size_t need, uint32_t *id)
{
    int rc = begin(c);
    if (rc)
        return rc;
    if (!name || !id || (count && (!points || !result)))
        return SDFC_EINVAL;
    size_t len = strlen(name);
    if (len == 0 || len > SDF_PROTO_MAX_NAME)
        return SDFC_EINVAL;
    if (result_size < need || (c->max_points && count > c->max_points))
        return SDFC_ELIMIT;
    return 0;
}

/* Register the request and send `frame` (header and prefix, its length and count fields
 * still to set) followed by the points, straight from the caller's array. */
static int send_points(sdfc_client *c, unsigned char *frame, size_t frame_len, size_t payload,
                       uint8_t mode, const float *points, uint32_t count, void *result,
                       size_t need, uint32_t *request_id)
{
    if (payload > UINT32_MAX || (c->max_payload && payload > c->max_payload))
        return SDFC_ELIMIT;
    uint32_t id;
    sdfc__pending *p = sdfc__add_entry(c, &id);
    if (!p)
        return c->next_id == UINT32_MAX ? SDFC_ELIMIT : SDFC_ENOMEM;
    p->reply_type = SDF_PROTO_RESULT;
    p->result = result;
    p->expect = need;
    sdf_proto_encode_result_head(p->head, id, (sdf_proto_mode)mode, count);
    put32(frame + 8, id);
    put32(frame + 12, (uint32_t)payload);
    put32(frame + SDF_PROTO_HEADER_SIZE + 4, count);
    struct iovec iov[2] = {{frame, frame_len}, {(void *)points, 12 * (size_t)count}};
    int rc = c->resend ? sdfc__keep_frame(p, frame, frame_len, points, 12 * (size_t)count) : 0;
    if (!rc)
        rc = sdfc__tx(c, iov, count ? 2 : 1);
    if (rc) {
        sdfc__drop(c, sdfc__lookup(c, id));
        return rc;
    }
    *request_id = id;
    return 0;
}

/* Header and prefix room: 16 + 8 + 256 (name) + 120 (FILTER) + 256 (its mesh name). */
#define PREFIX_MAX 664

/* The codec copies zero points from here when it writes a frame's prefix (memcpy wants a
 * valid pointer even for no bytes). */
static const float no_points[3];

int sdfc_send_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
                    const sdfc_filter *filter, const float *points, uint32_t count,
                    void *result, size_t result_size, uint32_t *request_id)
{
    if ((unsigned)mode > SDF_MODE_LAST || (unsigned)sign > SDF_SIGN_NONE)
        return c && c->broken ? c->broken : SDFC_EINVAL;
    int rc = check_query(c, mesh, points, count, result, result_size,
                         sdfc_result_size(mode, count), request_id);
    if (rc)
        return rc;
    sdf_proto_query q = {.mode = (sdf_proto_mode)mode, .sign = (sdf_sign_method)sign,
                         .name = mesh, .name_len = strlen(mesh), .count = 0,
                         .points = no_points};
    if (sdf_proto_mode_filtered(q.mode) && (rc = to_filter(filter, &q)))
        return rc;
    /* the codec writes the frame for zero points; its length and count are set later */
    unsigned char frame[PREFIX_MAX];
    size_t frame_len = sdf_proto_encode_query(frame, sizeof frame, 0, &q);
    if (!frame_len)
        return SDFC_EINVAL;
    q.count = count;
    return send_points(c, frame, frame_len, sdf_proto_query_size(&q), (uint8_t)mode, points,
                       count, result, sdfc_result_size(mode, count), request_id);
}

int sdfc_send_volume_query(sdfc_client *c, const char *volume, int gradient,
                           sdfc_interpolation interpolation, const float *points,
                           uint32_t count, void *result, size_t result_size,
                           uint32_t *request_id)
{
    /* the codec's terms for the wire codes (sdfc_interpolation's values) */
    static const sdf_volume_filter filters[] = {SDF_VOLUME_TRILINEAR, SDF_VOLUME_NEAREST,
                                                SDF_VOLUME_HERMITE, SDF_VOLUME_DEFAULT};
    sdfc_mode mode = gradient ? SDFC_GRADIENT : SDFC_SIGNED;
    if ((unsigned)interpolation >= sizeof filters / sizeof filters[0])
        return SDFC_EINVAL;
    int rc = check_query(c, volume, points, count, result, result_size,
                         sdfc_result_size(mode, count), request_id);
    if (rc)
        return rc;
    sdf_proto_volume_query q = {.gradient = !!gradient,
                                .interpolation = filters[interpolation],
                                .name = volume, .name_len = strlen(volume), .count = 0,
                                .points = no_points};
    unsigned char frame[PREFIX_MAX];
    size_t frame_len = sdf_proto_encode_volume_query(frame, sizeof frame, 0, &q);
    if (!frame_len)
        return SDFC_EINVAL;
    q.count = count;
    return send_points(c, frame, frame_len, sdf_proto_volume_query_size(&q), (uint8_t)mode,
                       points, count, result, sdfc_result_size(mode, count), request_id);
}

int sdfc_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
               const sdfc_filter *filter, const float *points, uint32_t count, void *result,
               size_t result_size)
{
    uint32_t id;
    int rc = sdfc_send_query(c, mesh, mode, sign, filter, points, count, result, result_size, &id);
    return rc ? rc : sdfc_wait(c, id);
}