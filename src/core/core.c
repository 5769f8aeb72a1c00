/* Core: status strings, cloud and mesh ownership, diagnostics, checked
 * allocation, progress plumbing and the small symmetric eigen-solver every
 * PCA-based stage uses. */
/* madvise and MADV_HUGEPAGE are not POSIX. */
#define _DEFAULT_SOURCE
#include "core/core.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#if defined(__linux__)
#include <sys/mman.h>
#endif

const char *tessel_status_str(tessel_status status)
{
    static const char *const strings[] = {
#define TESSEL_X_STR(name, str) str,
        TESSEL_STATUS_LIST(TESSEL_X_STR)
#undef TESSEL_X_STR
    };
    if ((unsigned)status >= (unsigned)TESSEL_STATUS_COUNT)
        return "unknown status";
    return strings[status];
}

const char *tessel_version(void) { return TESSEL_VERSION_STRING; }

void tsl_diag_set(tessel_diag *diag, const char *file, uint64_t line, int has_offset,
                  uint64_t offset, const char *fmt, ...)
{
    if (!diag)
        return;
    snprintf(diag->file, sizeof diag->file, "%s", file ? file : "");
    diag->line = line;
    diag->has_offset = has_offset;
    diag->offset = has_offset ? offset : 0;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(diag->message, sizeof diag->message, fmt, ap);
    va_end(ap);
}

/* Arrays of this size or more ask for transparent huge pages. The stages
 * allocate arrays of tens of megabytes at 10^6 points and touch each page
 * once; with 4 KB pages, taking the page faults was a sixth of the noisy
 * pipeline's time at 10^6 points on a virtual machine (docs/smooth.md,
 * section A). Advice only: where the kernel has no huge pages (or they are
 * set to "never") nothing changes, and the contents are the same. */
#define HUGE_ADVICE_BYTES ((size_t)4 << 20)

static void *advise_huge(void *p, size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (p && bytes >= HUGE_ADVICE_BYTES) {
        /* The whole pages inside the block; the kernel uses huge pages
         * only for the 2 MB-aligned parts of them. */
        const uintptr_t page = 4096;
        uintptr_t lo = ((uintptr_t)p + page - 1) & ~(page - 1);
        uintptr_t hi = ((uintptr_t)p + bytes) & ~(page - 1);
        if (hi > lo)
            (void)madvise((void *)lo, hi - lo, MADV_HUGEPAGE);
    }
#else
    (void)bytes;
#endif
    return p;
}

void *tsl_alloc_array(size_t count, size_t size)
{
    size_t bytes;
    if (!tsl_mul_size(count, size, &bytes))
        return NULL;
    return advise_huge(malloc(bytes ? bytes : 1), bytes);
}

void *tsl_calloc_array(size_t count, size_t size)
{
    if (size != 0 && count > SIZE_MAX / size)
        return NULL;
    return advise_huge(calloc(count ? count : 1, size ? size : 1), count * size);
}

int tsl_cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

double tsl_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

tessel_status tsl_grow(void **ptr, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return TESSEL_OK;
    size_t new_cap = *cap ? *cap : 16;
    while (new_cap < need) {
        if (new_cap > SIZE_MAX / 2)
            return TESSEL_ERR_NOMEM;
        new_cap *= 2;
    }
    size_t bytes;
    if (!tsl_mul_size(new_cap, size, &bytes))
        return TESSEL_ERR_NOMEM;
    tessel_status st = tsl_resize(ptr, *cap * size, bytes);
    if (st == TESSEL_OK)
        *cap = new_cap;
    return st;
}

tessel_status tsl_resize(void **ptr, size_t old_bytes, size_t new_bytes)
{
    void *p;
    if (new_bytes < HUGE_ADVICE_BYTES || !*ptr) {
        p = realloc(*ptr, new_bytes ? new_bytes : 1);
        if (!p)
            return TESSEL_ERR_NOMEM;
        *ptr = advise_huge(p, new_bytes);
        return TESSEL_OK;
    }
    /* A new block advised before the copy touches it (realloc would fault
     * the copy in with small pages). */
    if (!(p = advise_huge(malloc(new_bytes), new_bytes)))
        return TESSEL_ERR_NOMEM;
    memcpy(p, *ptr, old_bytes < new_bytes ? old_bytes : new_bytes);
    free(*ptr);
    *ptr = p;
    return TESSEL_OK;
}

tessel_status tsl_progress(const tessel_callbacks *cb, const char *stage, double fraction)
{
    if (cb && cb->progress && cb->progress(cb->user_data, stage, fraction) != 0)
        return TESSEL_ERR_CANCELLED;
    return TESSEL_OK;
}

void tsl_log(const tessel_callbacks *cb, tessel_log_level level, const char *fmt, ...)
{
    if (!cb || !cb->log)
        return;
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    cb->log(cb->user_data, level, buf);
}

int tsl_threads(int requested)
{
#ifdef _OPENMP
    return requested > 0 ? requested : omp_get_max_threads();
#else
    (void)requested;
    return 1;
#endif
}

/* ---- clouds and meshes ---- */

tessel_status tessel_cloud_alloc(tessel_cloud *cloud, size_t count, int with_normals,
                                 int with_rgb)
{
    if (!cloud)
        return TESSEL_ERR_INVALID_ARG;
    memset(cloud, 0, sizeof *cloud);
    cloud->xyz = tsl_calloc_array(count, 3 * sizeof(float));
    if (with_normals)
        cloud->normals = tsl_calloc_array(count, 3 * sizeof(float));
    if (with_rgb)
        cloud->rgb = tsl_calloc_array(count, 3);
    if (!cloud->xyz || (with_normals && !cloud->normals) || (with_rgb && !cloud->rgb)) {
        tessel_cloud_free(cloud);
        return TESSEL_ERR_NOMEM;
    }
    cloud->count = count;
    return TESSEL_OK;
}

void tessel_cloud_free(tessel_cloud *cloud)
{
    if (!cloud)
        return;
    free(cloud->xyz);
    free(cloud->normals);
    free(cloud->rgb);
    free(cloud->grid);
    memset(cloud, 0, sizeof *cloud);
}

static void *dup_array(const void *src, size_t count, size_t size, int *failed)
{
    if (!src)
        return NULL;
    void *p = tsl_alloc_array(count, size);
    if (!p) {
        *failed = 1;
        return NULL;
    }
    memcpy(p, src, count * size);
    return p;
}

tessel_status tessel_cloud_copy(tessel_cloud *dst, const tessel_cloud *src)
{
    if (!dst || !src)
        return TESSEL_ERR_INVALID_ARG;
    int failed = 0;
    tessel_cloud c = *src;
    c.xyz = dup_array(src->xyz, src->count, 3 * sizeof(float), &failed);
    c.normals = dup_array(src->normals, src->count, 3 * sizeof(float), &failed);
    c.rgb = dup_array(src->rgb, src->count, 3, &failed);
    c.grid = dup_array(src->grid, (size_t)src->width * src->height, sizeof(uint32_t),
                       &failed);
    if (failed) {
        tessel_cloud_free(&c);
        memset(dst, 0, sizeof *dst);
        return TESSEL_ERR_NOMEM;
    }
    *dst = c;
    return TESSEL_OK;
}

tessel_status tessel_mesh_alloc(tessel_mesh *mesh, size_t vertex_count,
                                size_t triangle_count, int with_normals, int with_rgb)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    mesh->xyz = tsl_calloc_array(vertex_count, 3 * sizeof(float));
    mesh->triangles = tsl_calloc_array(triangle_count, 3 * sizeof(uint32_t));
    if (with_normals)
        mesh->normals = tsl_calloc_array(vertex_count, 3 * sizeof(float));
    if (with_rgb)
        mesh->rgb = tsl_calloc_array(vertex_count, 3);
    if (!mesh->xyz || !mesh->triangles || (with_normals && !mesh->normals) ||
        (with_rgb && !mesh->rgb)) {
        tessel_mesh_free(mesh);
        return TESSEL_ERR_NOMEM;
    }
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
    return TESSEL_OK;
}

void tessel_mesh_free(tessel_mesh *mesh)
{
    if (!mesh)
        return;
    free(mesh->xyz);
    free(mesh->normals);
    free(mesh->rgb);
    free(mesh->triangles);
    memset(mesh, 0, sizeof *mesh);
}

/* ---- 3x3 symmetric eigen-decomposition (cyclic Jacobi) ---- */

void tsl_eigen_sym3(const double a_in[9], double w[3], double v[9])
{
    double a[9];
    memcpy(a, a_in, sizeof a);
    for (int i = 0; i < 9; i++)
        v[i] = (i % 4 == 0) ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
        double diag = a[0] * a[0] + a[4] * a[4] + a[8] * a[8];
        if (off <= 1e-30 * diag || off == 0.0)
            break;
        for (int p = 0; p < 2; p++) {
            for (int q = p + 1; q < 3; q++) {
                double apq = a[3 * p + q];
                if (apq == 0.0)
                    continue;
                double app = a[3 * p + p], aqq = a[3 * q + q];
                double theta = (aqq - app) / (2.0 * apq);
                double t = (theta >= 0 ? 1.0 : -1.0) /
                           (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < 3; k++) {
                    double akp = a[3 * k + p], akq = a[3 * k + q];
                    a[3 * k + p] = c * akp - s * akq;
                    a[3 * k + q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = a[3 * p + k], aqk = a[3 * q + k];
                    a[3 * p + k] = c * apk - s * aqk;
                    a[3 * q + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[3 * k + p], vkq = v[3 * k + q];
                    v[3 * k + p] = c * vkp - s * vkq;
                    v[3 * k + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    w[0] = a[0];
    w[1] = a[4];
    w[2] = a[8];
    /* Sort ascending, moving eigenvector columns along. */
    for (int i = 0; i < 2; i++) {
        for (int j = 0; j < 2 - i; j++) {
            if (w[j] > w[j + 1]) {
                double t = w[j];
                w[j] = w[j + 1];
                w[j + 1] = t;
                for (int k = 0; k < 3; k++) {
                    t = v[3 * k + j];
                    v[3 * k + j] = v[3 * k + j + 1];
                    v[3 * k + j + 1] = t;
                }
            }
        }
    }
}

bool tsl_sym3_values(const double m[6], double l[3])
{
    double a00 = m[0], a01 = m[1], a02 = m[2], a11 = m[3], a12 = m[4], a22 = m[5];
    /* det(l I - m) = l^3 - tr l^2 + mi l - det */
    double tr = a00 + a11 + a22;
    double mi = a00 * a11 - a01 * a01 + a00 * a22 - a02 * a02 + a11 * a22 - a12 * a12;
    double det = a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02) +
                 a02 * (a01 * a12 - a11 * a02);
    if (!(tr > 0.0))
        return false;
    double l1 = 0.0;
    for (int it = 0; it < 100; it++) {
        double f = ((l1 - tr) * l1 + mi) * l1 - det;
        double df = (3.0 * l1 - 2.0 * tr) * l1 + mi;
        if (!(df > 0.0) || !(f < 0.0))
            break; /* at (or, by rounding, past) the root */
        double step = -f / df;
        l1 += step;
        if (step <= 1e-15 * tr)
            break;
    }
    /* l2, l3: roots of l^2 - (tr - l1) l + (mi - l1 (tr - l1)) */
    double bq = tr - l1, cq = mi - l1 * bq;
    double disc = bq * bq - 4.0 * cq;
    double sq = sqrt(disc > 0.0 ? disc : 0.0);
    double l3 = 0.5 * (bq + sq);
    l[0] = l1;
    l[1] = l3 > 0.0 ? cq / l3 : 0.0;
    l[2] = l3;
    return true;
}

bool tsl_sym3_vector(const double m[6], double l, double v[3])
{
    double r0[3] = {m[0] - l, m[1], m[2]}, r1[3] = {m[1], m[3] - l, m[4]};
    double r2[3] = {m[2], m[4], m[5] - l}, c[3][3];
    tsl_cross(r0, r1, c[0]);
    tsl_cross(r0, r2, c[1]);
    tsl_cross(r1, r2, c[2]);
    int best = 0;
    double bl = tsl_dot(c[0], c[0]);
    for (int i = 1; i < 3; i++) {
        double d = tsl_dot(c[i], c[i]);
        if (d > bl)
            bl = d, best = i;
    }
    if (!(bl > 0.0))
        return false;
    double inv = 1.0 / sqrt(bl);
    v[0] = c[best][0] * inv, v[1] = c[best][1] * inv, v[2] = c[best][2] * inv;
    return true;
}
