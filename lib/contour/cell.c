/* cell.c - one cell's loops and triangles from the face rule (see cell.h). */
#include "contour/cell.h"

#include <string.h>

/* Each face's corners, counter-clockwise seen from outside the cell: -x, +x, -y, +y, -z, +z. */
static const uint8_t FACES[6][4] = {
    {0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6},
};

static int edge_of(int a, int b)
{
    int lo = a < b ? a : b, axis = (a ^ b) == 1 ? 0 : (a ^ b) == 2 ? 1 : 2;
    int x = lo & 1, y = lo >> 1 & 1, z = lo >> 2 & 1;
    return axis == 0 ? y + 2 * z : axis == 1 ? 4 + x + 2 * z : 8 + x + 2 * y;
}

void sdf__cell_edge_corners(int e, int *a, int *b)
{
    int axis = e / 4, u = e & 1, w = e >> 1 & 1;
    int lo = axis == 0 ? 2 * u + 4 * w : axis == 1 ? u + 4 * w : u + 2 * w;
    *a = lo, *b = lo | 1 << axis;
}

/* The faces (bit f: FACES[f]) that edge e lies on. */
static unsigned faces_of(int e)
{
    unsigned mask = 0;
    for (int f = 0; f < 6; f++)
        for (int m = 0; m < 4; m++)
            if (edge_of(FACES[f][m], FACES[f][(m + 1) & 3]) == e)
                mask |= 1u << f;
    return mask;
}

/* Are a face's diagonal inside corners joined through it? Its bilinear interpolant's saddle
 * value (f0 f2 - f1 f3) / (f0 + f2 - f1 - f3) is < 0 (corners in order around the face).
 * The products of floats are exact in double and the denominator's terms share one sign,
 * so both cells sharing the face, listing its corners from another start or the other way
 * round, decide alike. */
static int insides_joined(float f0, float f1, float f2, float f3)
{
    double num = (double)f0 * f2 - (double)f1 * f3;
    double den = (double)f0 + f2 - f1 - f3;
    return num != 0 && (num < 0) != (den < 0);
}

/* The face's segments: next[crossing where the boundary enters the inside] = the crossing
 * where it leaves (cell.h); face[that entry] = f. */
static void face_segments(const float v[8], int f, int next[12], int8_t face[12])
{
    const uint8_t *q = FACES[f];
    int cross[4], entry[4], n = 0;
    for (int m = 0; m < 4; m++) {
        int a = q[m], b = q[(m + 1) & 3];
        if ((v[a] < 0) != (v[b] < 0)) {
            cross[n] = edge_of(a, b);
            entry[n++] = v[b] < 0;
        }
    }
    if (n == 2) {
        int e = entry[0] ? 0 : 1;
        next[cross[e]] = cross[1 - e], face[cross[e]] = (int8_t)f;
    } else if (n == 4) {
        int joined = insides_joined(v[q[0]], v[q[1]], v[q[2]], v[q[3]]);
        for (int m = 0; m < 4; m++)
            if (entry[m]) {
                next[cross[m]] = cross[joined ? (m + 3) & 3 : (m + 1) & 3];
                face[cross[m]] = (int8_t)f;
            }
    }
}

static double area2(const double a[3], const double b[3], const double c[3])
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                   u[0] * w[1] - u[1] * w[0]};
    return n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
}

/* The apex whose fan's smallest triangle is largest among those whose diagonals join no two
 * crossings of one face; -1 when there is none. */
static int best_apex(const int *loop, int n, const double p[12][3])
{
    unsigned faces[12];
    for (int i = 0; i < n; i++)
        faces[i] = faces_of(loop[i]);
    int best = -1;
    double best_min = -1;
    for (int a = 0; a < n; a++) {
        int ok = 1;
        double smallest = -1;
        for (int i = 2; ok && i < n - 1; i++)
            ok = !(faces[a] & faces[(a + i) % n]);
        for (int i = 1; ok && i < n - 1; i++) {
            double s = area2(p[loop[a]], p[loop[(a + i) % n]], p[loop[(a + i + 1) % n]]);
            smallest = smallest < 0 || s < smallest ? s : smallest;
        }
        if (ok && smallest > best_min)
            best = a, best_min = smallest;
    }
    return best;
}

static void add(sdf__cell_out *out, int a, int b, int c)
{
    uint8_t *t = out->tri[out->triangles++];
    t[0] = (uint8_t)a, t[1] = (uint8_t)b, t[2] = (uint8_t)c;
}

static void emit_loop(const int *loop, int n, const double p[12][3], sdf__cell_out *out)
{
    int a = n == 3 ? 0 : best_apex(loop, n, p);
    if (a >= 0) {
        for (int i = 1; i < n - 1; i++)
            add(out, loop[a], loop[(a + i) % n], loop[(a + i + 1) % n]);
        return;
    }
    int m = out->centroids++;
    out->centroid_count[m] = n;
    for (int i = 0; i < n; i++) {
        out->centroid_edges[m][i] = (uint8_t)loop[i];
        add(out, SDF__CELL_CENTROID + m, loop[i], loop[(i + 1) % n]);
    }
}

int sdf__cell_loops(const float value[8], int8_t loop_of[12], uint8_t loops[4][12],
                    int count[4])
{
    int next[12], n = 0;
    int8_t face[12];
    memset(next, -1, sizeof next);
    memset(loop_of, -1, 12);
    for (int f = 0; f < 6; f++)
        face_segments(value, f, next, face);
    for (int e = 0; e < 12; e++) {
        if (next[e] < 0 || loop_of[e] >= 0)
            continue;
        count[n] = 0;
        for (int c = e; loop_of[c] < 0; c = next[c])
            loop_of[c] = (int8_t)n, loops[n][count[n]++] = (uint8_t)c;
        n++;
    }
    return n;
}

int sdf__cell_triangulate(const float value[8], const double crossing[12][3],
                          const double scale[3], sdf__cell_out *out)
{
    int8_t loop_of[12];
    uint8_t loops[4][12];
    int count[4], loop[12];
    double p[12][3];
    int n = sdf__cell_loops(value, loop_of, loops, count);
    out->triangles = out->centroids = 0;
    for (int e = 0; e < 12; e++)
        for (int a = 0; a < 3; a++)
            p[e][a] = loop_of[e] >= 0 ? crossing[e][a] * scale[a] : 0;
    for (int m = 0; m < n; m++) {
        for (int i = 0; i < count[m]; i++)
            loop[i] = loops[m][i];
        emit_loop(loop, count[m], p, out);
    }
    return out->triangles;
}

/* ---- polygons for dual contouring ------------------------------------------------------- */

/* Two segments of polygon m on one face: their starts' places in it (a < b); 0 if none. */
static int same_face_pair(const sdf__cell_polys *p, const int8_t *seg_face, int m, int *a,
                          int *b)
{
    for (int i = 0; i < p->size[m]; i++)
        for (int j = i + 2; j < p->size[m]; j++) {
            int8_t fi = seg_face[m * SDF__CELL_MAX_POLY_SIZE + i];
            if (fi >= 0 && fi == seg_face[m * SDF__CELL_MAX_POLY_SIZE + j])
                return *a = i, *b = j, 1;
        }
    return 0;
}

/* Split polygon m by the chord from its a-th to its b-th crossing into m (a..b) and a new
 * one (b..a): each keeps one of the two segments that start there. The chord is no face's
 * segment (its face -1). */
static void split(sdf__cell_polys *p, int8_t *seg_face, int m, int a, int b)
{
    enum { W = SDF__CELL_MAX_POLY_SIZE };
    int n = p->size[m], k = p->count++;
    uint8_t v[W];
    int8_t f[W];
    memcpy(v, p->vert[m], W), memcpy(f, seg_face + m * W, W);
    p->size[m] = b - a + 1;
    for (int i = 0; i <= b - a; i++)
        p->vert[m][i] = v[a + i], seg_face[m * W + i] = f[a + i];
    seg_face[m * W + b - a] = -1;
    p->size[k] = n - (b - a) + 1;
    for (int i = 0; i < p->size[k]; i++)
        p->vert[k][i] = v[(b + i) % n], seg_face[k * W + i] = f[(b + i) % n];
    seg_face[k * W + p->size[k] - 1] = -1;
}

int sdf__cell_polygons(const float value[8], sdf__cell_polys *p)
{
    enum { W = SDF__CELL_MAX_POLY_SIZE };
    int next[12];
    int8_t face[12], loop_of[12], seg_face[SDF__CELL_MAX_POLYS * W];
    uint8_t loops[4][12];
    int count[4];
    memset(next, -1, sizeof next);
    memset(face, -1, sizeof face);
    for (int f = 0; f < 6; f++)
        face_segments(value, f, next, face);
    p->count = sdf__cell_loops(value, loop_of, loops, count);
    for (int m = 0; m < p->count; m++) {
        p->size[m] = count[m];
        for (int i = 0; i < count[m]; i++)
            p->vert[m][i] = loops[m][i], seg_face[m * W + i] = face[loops[m][i]];
    }
    for (int m = 0, a, b; m < p->count; m++)
        while (p->count < SDF__CELL_MAX_POLYS && same_face_pair(p, seg_face, m, &a, &b))
            split(p, seg_face, m, a, b);
    memset(p->out, -1, sizeof p->out), memset(p->in, -1, sizeof p->in);
    for (int m = 0; m < p->count; m++)
        for (int i = 0; i < p->size[m]; i++)
            if (seg_face[m * W + i] >= 0) { /* a face's segment, not a chord */
                p->out[p->vert[m][i]] = (int8_t)m;
                p->in[p->vert[m][(i + 1) % p->size[m]]] = (int8_t)m;
            }
    memcpy(p->out_face, face, sizeof face);
    return p->count;
}
