/* exact.c - the EXACT re-distancing solver (exact.h). The band's nodes are gathered into
 * batches of up to CHUNK points, each one call of sdf_query on all threads (a call orders its
 * points and traverses them in packets: one big call is far faster than many small ones). */
#include "field/exact.h"

#include <math.h>
#include <stdlib.h>


int sdf__exact_surface(const sdf__field_grid *g, const float *f, sdf_mesh **out)
{
    sdf_volume_info in = {.dims = {g->n[0], g->n[1], g->n[2]},
                          .spacing = {g->h[0], g->h[1], g->h[2]}};
    sdf_volume *v = NULL;
    sdf_surface *s = NULL;
    sdf_extract_options o = {.method = SDF_EXTRACT_DUAL, .threads = g->threads};
    int rc = sdf_volume_create(&in, f, &v, NULL);
    if (!rc)
        rc = sdf_volume_extract(v, &o, &s, NULL);
    sdf_volume_destroy(v);
    size_t triangles = 0;
    if (!rc)
        sdf_surface_triangles(s, &triangles);
    if (!rc && !triangles)
        rc = SDF_EINVAL;
    if (!rc)
        rc = sdf_surface_to_mesh(s, NULL, out, NULL);
    sdf_surface_destroy(s);
    return rc == SDF_EINVAL || rc == SDF_ENOMEM ? rc : rc ? SDF_ENOMEM : 0;
}

#define CHUNK ((size_t)1 << 21) /* points per query: big batches keep the packets coherent */

typedef struct batch {
    float *points, *dist;
    size_t *node;
    size_t n;
} batch;

/* Query the gathered points (all threads), and put their distances in place. */
static int flush(const sdf__field_grid *g, const sdf_mesh *surface, batch *b, float *phi)
{
    sdf_query_options qo = {.sign = SDF_SIGN_NONE, .threads = g->threads};
    sdf_query_result qr = {.distance = b->dist};
    if (b->n && sdf_query(surface, b->points, b->n, &qo, &qr))
        return SDF_ENOMEM;
    for (size_t m = 0; m < b->n; m++)
        phi[b->node[m]] = b->dist[m];
    b->n = 0;
    return 0;
}

int sdf__exact_solve(const sdf__field_grid *g, const sdf_mesh *surface, const uint8_t *state,
                     float cap, float *phi)
{
    size_t room = g->nodes < CHUNK ? g->nodes : CHUNK;
    batch b = {malloc(3 * room * sizeof(float)), malloc(room * sizeof(float)),
               malloc(room * sizeof(size_t)), 0};
    int rc = b.points && b.dist && b.node ? 0 : SDF_ENOMEM;
    for (size_t at = 0; !rc && at < g->nodes; at++) {
        phi[at] = cap;
        if (!(state[at] & SDF__NODE_ACTIVE))
            continue;
        size_t i = at % g->n[0], j = at / g->n[0] % g->n[1], k = at / g->n[0] / g->n[1];
        float *p = b.points + 3 * b.n;
        p[0] = (float)((double)i * g->h[0]), p[1] = (float)((double)j * g->h[1]);
        p[2] = (float)((double)k * g->h[2]);
        b.node[b.n++] = at;
        if (b.n == room)
            rc = flush(g, surface, &b, phi);
    }
    if (!rc)
        rc = flush(g, surface, &b, phi);
    free(b.points), free(b.dist), free(b.node);
    return rc;
}
