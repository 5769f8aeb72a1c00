/* Rendering: a software rasterizer for inspecting meshes and clouds.
 *
 * Orthographic views fitted to the drawn vertices, a z-buffer, flat shading
 * with a headlight (brightness from |cos| between the face normal and the
 * viewing direction), front and back faces in different colours. Triangles
 * are scan-converted with edge functions over their pixel bounding box,
 * sampling pixel centres (Pineda, "A parallel algorithm for polygon
 * rasterization", SIGGRAPH 1988); lines with a DDA and a depth bias so that
 * edges lying on the surface win against it. Boundary edges come from the
 * same bucketing of half-edges on their smaller vertex that the mesh check
 * uses (src/check/).
 *
 * Threads split the image into horizontal bands; every band walks all
 * triangles in index order, so each pixel sees the same sequence of writes
 * whatever the thread count and the image is deterministic. A per-triangle
 * row range computed once lets each band skip the others' triangles with a
 * sequential scan. Lines and splats are drawn serially after the fill. */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

#define RENDER_MAX_SIDE 16384u

tessel_render_params tessel_render_params_default(void)
{
    tessel_render_params p;
    memset(&p, 0, sizeof p);
    p.view = TESSEL_VIEW_ISO;
    p.width = 1024;
    p.height = 768;
    p.z_up = 0;
    p.edges = 0;
    p.points = 0;
    p.boundary = 1;
    p.point_size = 0;
    const uint8_t bg[3] = {38, 38, 46}, front[3] = {214, 208, 196}, back[3] = {70, 120, 235};
    const uint8_t bnd[3] = {255, 0, 0}, edge[3] = {20, 20, 20}, pt[3] = {250, 200, 60};
    memcpy(p.background, bg, 3);
    memcpy(p.front_color, front, 3);
    memcpy(p.back_color, back, 3);
    memcpy(p.boundary_color, bnd, 3);
    memcpy(p.edge_color, edge, 3);
    memcpy(p.point_color, pt, 3);
    p.threads = 0;
    return p;
}

int tessel_view_from_name(const char *name)
{
    static const char *const names[] = {"front", "back", "left", "right", "top", "iso", "all"};
    static const tessel_view views[] = {TESSEL_VIEW_FRONT, TESSEL_VIEW_BACK, TESSEL_VIEW_LEFT,
                                        TESSEL_VIEW_RIGHT, TESSEL_VIEW_TOP,  TESSEL_VIEW_ISO,
                                        TESSEL_VIEW_ALL};
    if (!name)
        return -1;
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        if (strcmp(name, names[i]) == 0)
            return (int)views[i];
    return -1;
}

/* A camera: right, up and forward (into the scene) unit vectors. */
typedef struct camera {
    double r[3], u[3], f[3];
} camera;

static void make_camera(tessel_view view, int z_up, camera *c)
{
    /* Eye direction (from the scene towards the viewer) and up hint. */
    double e[3] = {0, 0, 0}, h[3] = {0, 0, 0};
    int up = z_up ? 2 : 1, depth = z_up ? 1 : 2;
    double depth_sign = z_up ? -1.0 : 1.0; /* "front" eye: +Z (Y up), -Y (Z up) */
    h[up] = 1.0;
    switch (view) {
    case TESSEL_VIEW_FRONT:
        e[depth] = depth_sign;
        break;
    case TESSEL_VIEW_BACK:
        e[depth] = -depth_sign;
        break;
    case TESSEL_VIEW_RIGHT:
        e[0] = 1.0;
        break;
    case TESSEL_VIEW_LEFT:
        e[0] = -1.0;
        break;
    case TESSEL_VIEW_TOP:
        e[up] = 1.0;
        h[up] = 0.0;
        /* image up points away from the front viewer */
        h[depth] = -depth_sign;
        break;
    default: /* ISO */
        e[0] = 1.0;
        e[up] = 1.0;
        e[depth] = depth_sign;
        break;
    }
    for (int k = 0; k < 3; k++)
        c->f[k] = -e[k];
    tsl_normalize(c->f);
    tsl_cross(c->f, h, c->r);
    tsl_normalize(c->r);
    tsl_cross(c->r, c->f, c->u);
}

/* One view being drawn into a viewport of the output image. */
typedef struct viewport {
    uint8_t *rgb;       /* whole image */
    size_t stride;      /* bytes per image row */
    uint32_t x0, y0, w, h;
    float *depth;       /* w*h */
    camera cam;
    double center[3];   /* scene point at the viewport's centre */
    double scale;       /* pixels per world unit */
    double bias;        /* depth slack for lines and splats, world units */
} viewport;

static inline void put_pixel(viewport *v, int x, int y, const uint8_t c[3])
{
    size_t row = (size_t)(v->y0 + (uint32_t)y), col = (size_t)(v->x0 + (uint32_t)x);
    uint8_t *p = v->rgb + row * v->stride + 3 * col;
    p[0] = c[0];
    p[1] = c[1];
    p[2] = c[2];
}

static inline void shade(const uint8_t base[3], double k, uint8_t out[3])
{
    for (int i = 0; i < 3; i++) {
        double x = base[i] * k;
        out[i] = (uint8_t)(x > 255.0 ? 255 : x < 0.0 ? 0 : (int)(x + 0.5));
    }
}

/* Projected vertices: pixel x, y (y down) and depth (world units along f,
 * larger is farther). */
typedef struct projected {
    float *x, *y, *z;
} projected;

static void project_all(const tessel_mesh *m, const viewport *v, projected *p, int threads)
{
    ptrdiff_t n = (ptrdiff_t)m->vertex_count;
    double cx = 0.5 * v->w, cy = 0.5 * v->h;
#pragma omp parallel for schedule(static) num_threads(threads)
    for (ptrdiff_t i = 0; i < n; i++) {
        double q[3], d[3];
        tsl_load(m->xyz + 3 * i, q);
        tsl_sub(q, v->center, d);
        p->x[i] = (float)(cx + v->scale * tsl_dot(d, v->cam.r));
        p->y[i] = (float)(cy - v->scale * tsl_dot(d, v->cam.u));
        p->z[i] = (float)tsl_dot(d, v->cam.f);
    }
}

/* Fills the triangles of rows [row0, row1) of the viewport. */
static void fill_band(const tessel_mesh *m, const tessel_render_params *prm, viewport *v,
                      const projected *p, const int32_t *rows, int row0, int row1)
{
    for (size_t t = 0; t < m->triangle_count; t++) {
        int ty0 = rows[2 * t], ty1 = rows[2 * t + 1];
        if (ty1 < row0 || ty0 >= row1 || ty0 > ty1)
            continue;
        const uint32_t *tri = m->triangles + 3 * t;
        float ax = p->x[tri[0]], ay = p->y[tri[0]], az = p->z[tri[0]];
        float bx = p->x[tri[1]], by = p->y[tri[1]], bz = p->z[tri[1]];
        float cx = p->x[tri[2]], cy = p->y[tri[2]], cz = p->z[tri[2]];
        double area = (double)(bx - ax) * (cy - ay) - (double)(by - ay) * (cx - ax);
        if (!(area != 0.0 && isfinite(area) && isfinite(az) && isfinite(bz) && isfinite(cz)))
            continue; /* edge-on, or a vertex that is not finite */
        /* Colour: facing from the 3D normal, brightness from the headlight. */
        double a3[3], b3[3], c3[3], e1[3], e2[3], n[3];
        tsl_load(m->xyz + 3 * (size_t)tri[0], a3);
        tsl_load(m->xyz + 3 * (size_t)tri[1], b3);
        tsl_load(m->xyz + 3 * (size_t)tri[2], c3);
        tsl_sub(b3, a3, e1);
        tsl_sub(c3, a3, e2);
        tsl_cross(e1, e2, n);
        if (!tsl_normalize(n))
            continue;
        double cosv = tsl_dot(n, v->cam.f);
        uint8_t col[3];
        shade(cosv < 0.0 ? prm->front_color : prm->back_color, 0.25 + 0.75 * fabs(cosv), col);

        int x0 = (int)floor(fminf(ax, fminf(bx, cx)));
        int x1 = (int)ceil(fmaxf(ax, fmaxf(bx, cx)));
        if (x0 < 0)
            x0 = 0;
        if (x1 > (int)v->w - 1)
            x1 = (int)v->w - 1;
        int y0 = ty0 > row0 ? ty0 : row0, y1 = ty1 < row1 - 1 ? ty1 : row1 - 1;
        double inv = 1.0 / area;
        for (int y = y0; y <= y1; y++) {
            double py = y + 0.5;
            for (int x = x0; x <= x1; x++) {
                double px = x + 0.5;
                /* Barycentric weights of the pixel centre (edge functions). */
                double w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv;
                double w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv;
                double w2 = 1.0 - w0 - w1;
                if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0)
                    continue;
                float z = (float)(w0 * az + w1 * bz + w2 * cz);
                float *zb = &v->depth[(size_t)y * v->w + (size_t)x];
                if (z < *zb) {
                    *zb = z;
                    put_pixel(v, x, y, col);
                }
            }
        }
    }
}

/* A line from vertex a to vertex b, w pixels wide, where it is not hidden by
 * more than the bias. */
static void draw_line(viewport *v, const projected *p, uint32_t a, uint32_t b, int w,
                      const uint8_t col[3])
{
    double ax = p->x[a], ay = p->y[a], az = p->z[a];
    double dx = p->x[b] - ax, dy = p->y[b] - ay, dz = p->z[b] - az;
    if (!isfinite(ax) || !isfinite(ay) || !isfinite(dx) || !isfinite(dy) || !isfinite(dz))
        return;
    double len = fmax(fabs(dx), fabs(dy));
    if (!(len < 4.0 * RENDER_MAX_SIDE))
        len = 4.0 * RENDER_MAX_SIDE; /* far off-screen ends: bounded work */
    int steps = (int)ceil(len) + 1;
    for (int s = 0; s <= steps; s++) {
        double t = (double)s / steps;
        int x = (int)floor(ax + t * dx), y = (int)floor(ay + t * dy);
        double z = az + t * dz;
        for (int oy = 0; oy < w; oy++)
            for (int ox = 0; ox < w; ox++) {
                int xx = x + ox, yy = y + oy;
                if (xx < 0 || yy < 0 || xx >= (int)v->w || yy >= (int)v->h)
                    continue;
                if (z <= v->depth[(size_t)yy * v->w + (size_t)xx] + v->bias)
                    put_pixel(v, xx, yy, col);
            }
    }
}

/* Boundary edges (a triangle of their own) as vertex pairs, ascending.
 * Triangles with a repeated index are left out, as in the check. */
static tessel_status boundary_edges(const tessel_mesh *m, uint32_t **out, size_t *count)
{
    size_t nv = m->vertex_count, nf = m->triangle_count;
    *out = NULL;
    *count = 0;
    size_t *start = tsl_calloc_array(nv + 1, sizeof *start);
    uint32_t *hi = tsl_alloc_array(nf, 3 * sizeof *hi);
    uint32_t *list = NULL;
    size_t n = 0, cap = 0;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!start || !hi)
        goto done;
    for (int pass = 0; pass < 2; pass++)
        for (size_t f = 0; f < nf; f++) {
            const uint32_t *t = m->triangles + 3 * f;
            if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
                continue;
            for (int k = 0; k < 3; k++) {
                uint32_t a = t[k], b = t[(k + 1) % 3];
                uint32_t lo = a < b ? a : b;
                if (pass == 0)
                    start[lo + 1]++;
                else
                    hi[start[lo]++] = a < b ? b : a;
            }
            if (pass == 0 && f + 1 == nf)
                for (size_t v = 0; v < nv; v++)
                    start[v + 1] += start[v];
        }
    /* start[v] now ends bucket v. */
    size_t begin = 0;
    for (size_t v = 0; v < nv; v++) {
        size_t end = start[v];
        uint32_t *b = hi + begin;
        size_t k = end - begin;
        for (size_t i = 1; i < k; i++) { /* insertion sort: stars are small */
            uint32_t x = b[i];
            size_t j = i;
            while (j > 0 && b[j - 1] > x) {
                b[j] = b[j - 1];
                j--;
            }
            b[j] = x;
        }
        for (size_t i = 0; i < k;) {
            size_t j = i;
            while (j < k && b[j] == b[i])
                j++;
            if (j - i == 1) {
                if (tsl_grow((void **)&list, &cap, 2 * (n + 1), sizeof *list) != TESSEL_OK)
                    goto done;
                list[2 * n] = (uint32_t)v;
                list[2 * n + 1] = b[i];
                n++;
            }
            i = j;
        }
        begin = end;
    }
    *out = list;
    *count = n;
    list = NULL;
    st = TESSEL_OK;
done:
    free(start);
    free(hi);
    free(list);
    return st;
}

/* Splat width: about the spacing of n points spread over a third of the
 * viewport, so a cloud reads as a closed surface. */
static int auto_splat(size_t n, const viewport *v)
{
    if (n == 0)
        return 1;
    double s = 1.2 * sqrt(0.33 * (double)v->w * (double)v->h / (double)n);
    int w = (int)ceil(s);
    return w < 1 ? 1 : w > 8 ? 8 : w;
}

static tessel_status render_view(const tessel_mesh *m, const tessel_render_params *prm,
                                 tessel_view view, const uint8_t *used, const uint32_t *bnd,
                                 size_t nbnd, viewport *v, int threads)
{
    make_camera(view, prm->z_up, &v->cam);
    /* Fit: extents of the drawn vertices along the camera axes. */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    size_t drawn = 0;
    for (size_t i = 0; i < m->vertex_count; i++) {
        if (used && !used[i])
            continue;
        double q[3];
        tsl_load(m->xyz + 3 * i, q);
        if (!isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2]))
            continue;
        double c[3] = {tsl_dot(q, v->cam.r), tsl_dot(q, v->cam.u), tsl_dot(q, v->cam.f)};
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], c[k]);
            hi[k] = fmax(hi[k], c[k]);
        }
        drawn++;
    }
    size_t npix = (size_t)v->w * v->h;
    for (uint32_t y = 0; y < v->h; y++)
        for (uint32_t x = 0; x < v->w; x++)
            put_pixel(v, (int)x, (int)y, prm->background);
    if (drawn == 0)
        return TESSEL_OK;
    double ext_x = hi[0] - lo[0], ext_y = hi[1] - lo[1];
    double size = fmax(ext_x / v->w, ext_y / v->h);
    double diag = sqrt(ext_x * ext_x + ext_y * ext_y + (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(size > 0.0))
        size = diag > 0.0 ? diag / fmin(v->w, v->h) : 1.0 / fmin(v->w, v->h);
    v->scale = 0.9 / size;
    /* centre = r*(mid x) + u*(mid y) + f*(mid z) */
    for (int k = 0; k < 3; k++)
        v->center[k] = v->cam.r[k] * 0.5 * (lo[0] + hi[0]) +
                       v->cam.u[k] * 0.5 * (lo[1] + hi[1]) +
                       v->cam.f[k] * 0.5 * (lo[2] + hi[2]);
    v->bias = 3.0 / v->scale;

    projected p;
    p.x = tsl_alloc_array(m->vertex_count, sizeof *p.x);
    p.y = tsl_alloc_array(m->vertex_count, sizeof *p.y);
    p.z = tsl_alloc_array(m->vertex_count, sizeof *p.z);
    int32_t *rows = tsl_alloc_array(m->triangle_count, 2 * sizeof *rows);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!p.x || !p.y || !p.z || !rows)
        goto done;
    for (size_t i = 0; i < npix; i++)
        v->depth[i] = INFINITY;
    project_all(m, v, &p, threads);

    /* Row range of every triangle; empty (y0 > y1) when off-screen. */
    ptrdiff_t nt = (ptrdiff_t)m->triangle_count;
#pragma omp parallel for schedule(static) num_threads(threads)
    for (ptrdiff_t t = 0; t < nt; t++) {
        const uint32_t *tri = m->triangles + 3 * t;
        float ymin = fminf(p.y[tri[0]], fminf(p.y[tri[1]], p.y[tri[2]]));
        float ymax = fmaxf(p.y[tri[0]], fmaxf(p.y[tri[1]], p.y[tri[2]]));
        int32_t y0 = 1, y1 = 0;
        if (ymax >= 0.0f && ymin < (float)v->h) {
            y0 = ymin < 0.0f ? 0 : (int32_t)ymin;
            y1 = ymax >= (float)v->h ? (int32_t)v->h - 1 : (int32_t)ymax;
        }
        rows[2 * t] = y0;
        rows[2 * t + 1] = y1;
    }
    int bands = 4 * threads;
    if (bands > (int)v->h)
        bands = (int)v->h;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int b = 0; b < bands; b++) {
        int r0 = (int)((int64_t)v->h * b / bands), r1 = (int)((int64_t)v->h * (b + 1) / bands);
        fill_band(m, prm, v, &p, rows, r0, r1);
    }

    if (prm->edges)
        for (size_t t = 0; t < m->triangle_count; t++)
            for (int k = 0; k < 3; k++)
                draw_line(v, &p, m->triangles[3 * t + k], m->triangles[3 * t + (k + 1) % 3], 1,
                          prm->edge_color);
    for (size_t e = 0; e < nbnd; e++)
        draw_line(v, &p, bnd[2 * e], bnd[2 * e + 1], 2, prm->boundary_color);

    /* Splats: every point of a cloud; the used vertices of a mesh with
     * --points. */
    if (m->triangle_count == 0 || prm->points) {
        int w = prm->point_size ? (int)prm->point_size
                                : m->triangle_count ? 3 : auto_splat(m->vertex_count, v);
        double zspan = hi[2] - lo[2], zc = tsl_dot(v->center, v->cam.f);
        /* Vertices drawn over a surface need the allowance to show; points
         * of a cloud hide each other by plain depth. */
        double slack = m->triangle_count ? v->bias : 0.0;
        for (size_t i = 0; i < m->vertex_count; i++) {
            if (used && !used[i])
                continue;
            float fx = p.x[i], fy = p.y[i], fz = p.z[i];
            if (!(fx > -w && fy > -w && fx < (float)v->w + w && fy < (float)v->h + w))
                continue; /* also skips NaN */
            uint8_t col[3];
            if (m->rgb) {
                memcpy(col, m->rgb + 3 * i, 3);
            } else if (m->normals && m->triangle_count == 0) {
                double n[3];
                tsl_load(m->normals + 3 * i, n);
                shade(prm->point_color, 0.25 + 0.75 * fabs(tsl_dot(n, v->cam.f)), col);
            } else if (m->triangle_count == 0) {
                /* depth cue: near points bright, far ones darker */
                double rel = zspan > 0.0 ? ((double)fz + zc - lo[2]) / zspan : 0.0;
                shade(prm->point_color, 1.0 - 0.6 * fmin(1.0, fmax(0.0, rel)), col);
            } else {
                memcpy(col, prm->point_color, 3);
            }
            int x0 = (int)floor(fx - 0.5 * w + 0.5), y0 = (int)floor(fy - 0.5 * w + 0.5);
            for (int y = y0; y < y0 + w; y++)
                for (int x = x0; x < x0 + w; x++) {
                    if (x < 0 || y < 0 || x >= (int)v->w || y >= (int)v->h)
                        continue;
                    float *zb = &v->depth[(size_t)y * v->w + (size_t)x];
                    if (fz <= *zb + slack) {
                        if (fz < *zb)
                            *zb = fz;
                        put_pixel(v, x, y, col);
                    }
                }
        }
    }
    st = TESSEL_OK;
done:
    free(p.x);
    free(p.y);
    free(p.z);
    free(rows);
    return st;
}

tessel_status tessel_render(const tessel_mesh *mesh, const tessel_render_params *params,
                            uint8_t *rgb)
{
    tessel_render_params prm = params ? *params : tessel_render_params_default();
    if (!mesh || !rgb || prm.width == 0 || prm.height == 0 || prm.width > RENDER_MAX_SIDE ||
        prm.height > RENDER_MAX_SIDE || (unsigned)prm.view > (unsigned)TESSEL_VIEW_ALL ||
        prm.point_size > 64)
        return TESSEL_ERR_INVALID_ARG;
    if ((mesh->vertex_count > 0 && !mesh->xyz) || (mesh->triangle_count > 0 && !mesh->triangles))
        return TESSEL_ERR_INVALID_ARG;
    if (mesh->vertex_count >= UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    for (size_t i = 0; i < 3 * mesh->triangle_count; i++)
        if (mesh->triangles[i] >= mesh->vertex_count)
            return TESSEL_ERR_INVALID_ARG;
    int threads = tsl_threads(prm.threads);

    uint8_t *used = NULL;
    uint32_t *bnd = NULL;
    size_t nbnd = 0;
    float *depth = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (mesh->triangle_count > 0) {
        used = tsl_calloc_array(mesh->vertex_count, 1);
        if (!used)
            goto done;
        for (size_t i = 0; i < 3 * mesh->triangle_count; i++)
            used[mesh->triangles[i]] = 1;
        if (prm.boundary) {
            st = boundary_edges(mesh, &bnd, &nbnd);
            if (st != TESSEL_OK)
                goto done;
            st = TESSEL_ERR_NOMEM;
        }
    }
    depth = tsl_alloc_array((size_t)prm.width * prm.height, sizeof *depth);
    if (!depth)
        goto done;

    viewport v;
    memset(&v, 0, sizeof v);
    v.rgb = rgb;
    v.stride = 3 * (size_t)prm.width;
    v.depth = depth;
    if (prm.view != TESSEL_VIEW_ALL) {
        v.w = prm.width;
        v.h = prm.height;
        st = render_view(mesh, &prm, prm.view, used, bnd, nbnd, &v, threads);
        goto done;
    }
    /* Contact sheet: four cells separated by a one-pixel line of the
     * background darkened. */
    static const tessel_view sheet[4] = {TESSEL_VIEW_FRONT, TESSEL_VIEW_RIGHT, TESSEL_VIEW_TOP,
                                         TESSEL_VIEW_ISO};
    uint32_t cw = prm.width / 2, ch = prm.height / 2;
    uint8_t line[3];
    shade(prm.background, 0.5, line);
    for (size_t i = 0; i < (size_t)prm.width * prm.height; i++)
        memcpy(rgb + 3 * i, line, 3);
    st = TESSEL_OK;
    for (int c = 0; c < 4 && st == TESSEL_OK; c++) {
        uint32_t gx = (uint32_t)(c % 2), gy = (uint32_t)(c / 2);
        v.x0 = gx * cw + gx;
        v.y0 = gy * ch + gy;
        v.w = (gx ? prm.width - v.x0 : cw);
        v.h = (gy ? prm.height - v.y0 : ch);
        if (v.w == 0 || v.h == 0)
            continue;
        st = render_view(mesh, &prm, sheet[c], used, bnd, nbnd, &v, threads);
    }
done:
    free(used);
    free(bnd);
    free(depth);
    return st;
}
