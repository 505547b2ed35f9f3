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
 * where it leaves (cell.h). */
static void face_segments(const float v[8], const uint8_t q[4], int next[12])
{
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
        next[cross[e]] = cross[1 - e];
    } else if (n == 4) {
        int joined = insides_joined(v[q[0]], v[q[1]], v[q[2]], v[q[3]]);
        for (int m = 0; m < 4; m++)
            if (entry[m])
                next[cross[m]] = cross[joined ? (m + 3) & 3 : (m + 1) & 3];
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

int sdf__cell_triangulate(const float value[8], const double crossing[12][3],
                          const double scale[3], sdf__cell_out *out)
{
    int next[12], seen[12] = {0};
    double p[12][3];
    memset(next, -1, sizeof next);
    out->triangles = out->centroids = 0;
    for (int f = 0; f < 6; f++)
        face_segments(value, FACES[f], next);
    for (int e = 0; e < 12; e++)
        for (int a = 0; a < 3; a++)
            p[e][a] = next[e] >= 0 ? crossing[e][a] * scale[a] : 0;
    for (int e = 0; e < 12; e++) {
        if (next[e] < 0 || seen[e])
            continue;
        int loop[12], n = 0;
        for (int c = e; !seen[c]; c = next[c])
            seen[c] = 1, loop[n++] = c;
        emit_loop(loop, n, p, out);
    }
    return out->triangles;
}
