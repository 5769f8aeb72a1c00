/* tessel_mpi_cloud_read against tessel_cloud_read: for every file named on
 * the command line, every process's cloud is exactly the one-process read
 * (points, order, offset, floats, normals, colours, grid, viewpoint, points
 * dropped) on every process or on the one it is joined on (the others'
 * empty), or both fail with the same status and message. Run by
 * tests/mpi/run.sh under mpirun -np 1..4. */
#include "tessel_mpi.h"

#include <stdio.h>
#include <string.h>

static int same_arrays(const void *a, const void *b, size_t bytes)
{
    return (!a && !b) || (a && b && memcmp(a, b, bytes) == 0);
}

static const char *compare(const tessel_cloud *m, const tessel_cloud *s)
{
    if (m->count != s->count)
        return "point count";
    if (m->dropped_nonfinite != s->dropped_nonfinite)
        return "points dropped";
    if (memcmp(m->offset, s->offset, sizeof m->offset) != 0)
        return "offset";
    if (!same_arrays(m->xyz, s->xyz, 3 * s->count * sizeof *s->xyz))
        return "positions";
    if (!same_arrays(m->normals, s->normals, 3 * s->count * sizeof *s->normals))
        return "normals";
    if (!same_arrays(m->rgb, s->rgb, 3 * s->count))
        return "colours";
    if (m->width != s->width || m->height != s->height ||
        !same_arrays(m->grid, s->grid, (size_t)s->width * s->height * sizeof *s->grid))
        return "grid";
    if (m->has_viewpoint != s->has_viewpoint ||
        memcmp(m->viewpoint, s->viewpoint, sizeof m->viewpoint) != 0)
        return "viewpoint";
    return NULL;
}

/* A box around the middle of the cloud's extent along x, for LAS and LAZ
 * files (NULL for others): a COPC file then decodes some chunks only. */
static const double *middle_box(const char *path, const tessel_cloud *c, double box[6])
{
    size_t len = strlen(path);
    if (c->count == 0 || len < 4 ||
        (strcmp(path + len - 4, ".las") != 0 && strcmp(path + len - 4, ".laz") != 0))
        return NULL;
    for (int k = 0; k < 3; k++) {
        box[k] = 1e300;
        box[k + 3] = -1e300;
    }
    for (size_t i = 0; i < c->count; i++)
        for (int k = 0; k < 3; k++) {
            double w = c->offset[k] + (double)c->xyz[3 * i + (size_t)k];
            box[k] = w < box[k] ? w : box[k];
            box[k + 3] = w > box[k + 3] ? w : box[k + 3];
        }
    double lo = box[0], hi = box[3];
    box[0] = lo + 0.25 * (hi - lo);
    box[3] = lo + 0.75 * (hi - lo);
    return box;
}

/* One read of path both ways, joined on root (every process: root < 0);
 * returns whether any process saw a difference. */
static int check(const char *path, const tessel_read_params *params, int root, int rank,
                 int size, tessel_cloud *kept)
{
    tessel_cloud m, s;
    tessel_diag dm = {0}, ds = {0};
    tessel_status sm = tessel_mpi_cloud_read(MPI_COMM_WORLD, root, path, params, &m, &dm);
    tessel_status ss = tessel_cloud_read(&s, path, params, &ds);
    const char *why = NULL;
    if (sm != ss)
        why = "status";
    else if (ss != TESSEL_OK && (strcmp(dm.message, ds.message) != 0 ||
                                 dm.offset != ds.offset || dm.line != ds.line))
        why = "message";
    else if (ss == TESSEL_OK && (root < 0 || rank == root))
        why = compare(&m, &s);
    else if (ss == TESSEL_OK && (m.count || m.xyz))
        why = "an empty cloud";
    int bad = why != NULL, any = 0;
    MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_LOR, MPI_COMM_WORLD);
    if (bad)
        fprintf(stderr, "FAIL -np %d, process %d, root %d: %s%s: %s differs (%s | %s)\n", size,
                rank, root, path, params ? " in a box" : "", why, dm.message, ds.message);
    else if (rank == 0)
        printf("ok   -np %d, root %d: %s%s: %zu points%s%s\n", size, root, path,
               params ? " in a box" : "", s.count, ss != TESSEL_OK ? ", fails alike: " : "",
               ss != TESSEL_OK ? ds.message : "");
    tessel_cloud_free(&m);
    if (kept)
        *kept = s;
    else
        tessel_cloud_free(&s);
    return any;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    int rank, size, failed = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    for (int i = 1; i < argc; i++) {
        tessel_cloud whole = {0};
        failed += check(argv[i], NULL, TESSEL_MPI_ALL, rank, size, &whole);
        failed += check(argv[i], NULL, size - 1, rank, size, NULL);
        double box[6];
        tessel_read_params p = tessel_read_params_default();
        if ((p.bbox = middle_box(argv[i], &whole, box)) != NULL)
            failed += check(argv[i], &p, TESSEL_MPI_ALL, rank, size, NULL);
        tessel_cloud_free(&whole);
    }
    MPI_Finalize();
    return failed ? 1 : 0;
}
