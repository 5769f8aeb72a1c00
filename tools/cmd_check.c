/* tessel check MESH: is the mesh a valid manifold, and how close is it to
 * its input and to a reference. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char check_help[] =
    "usage: tessel check MESH [--input CLOUD] [--ref REFMESH] [options]\n"
    "\n"
    "Measures a mesh: vertices, triangles, components, boundary edges and\n"
    "loops, non-manifold edges and vertices, orientation, self-intersecting\n"
    "triangle pairs (decided exactly), duplicate and degenerate triangles,\n"
    "Euler characteristic and genus, angles. Definitions: docs/check.md.\n"
    "\n"
    "Options:\n"
    "  --input CLOUD   also: input points that are vertices, and the distance\n"
    "                  of every input point to the mesh\n"
    "  --ref REFMESH   also: Chamfer and Hausdorff distance to a reference\n"
    "                  surface, precision, recall and F-score at tau\n"
    "  --tau T         F-score threshold, absolute length (default: 1% of the\n"
    "                  reference's bounding-box diagonal)\n"
    "  --tau-rel F     the threshold as a fraction of that diagonal\n"
    "  --samples N     points sampled on each surface for --ref (200000)\n"
    "  --no-self-intersections  skip the self-intersection test\n"
    "\n"
    "Exit status: 0 the mesh is a valid manifold (boundaries allowed), 4 it is\n"
    "not (non-manifold, inconsistently oriented, self-intersecting, duplicate\n"
    "or degenerate triangles, or no triangle at all), 2 a file could not be\n"
    "read, 1 bad command line.\n";

static void json_num(const char *key, double v)
{
    if (isfinite(v))
        printf(",\n  \"%s\": %.10g", key, v);
    else
        printf(",\n  \"%s\": null", key);
}
static void json_int(const char *key, size_t v) { printf(",\n  \"%s\": %zu", key, v); }
static void json_bool(const char *key, bool v) { printf(",\n  \"%s\": %s", key, v ? "true" : "false"); }

/* Key names follow meshcheck where the definition is the same. */
static void print_json(const char *mesh, const char *input, const char *ref,
                       const tessel_mesh_report *r, const tessel_check_params *p, double secs)
{
    bool si = r->self_intersections != SIZE_MAX;
    bool closed = r->triangles > 0 && r->boundary_edges == 0;
    bool manifold = r->nonmanifold_edges == 0 && r->nonmanifold_vertices == 0;
    printf("{\n  \"mesh\": ");
    cli_json_string(stdout, mesh);
    json_bool("valid", tessel_mesh_report_valid(r));
    json_int("vertices", r->vertices);
    json_int("unreferenced_vertices", r->unreferenced_vertices);
    json_int("faces", r->triangles);
    json_int("degenerate_faces", r->degenerate_triangles);
    json_int("duplicate_faces", r->duplicate_triangles);
    json_num("bbox_diag", r->bbox_diagonal);
    json_int("edges", r->edges);
    json_int("boundary_edges", r->boundary_edges);
    json_int("nonmanifold_edges", r->nonmanifold_edges);
    json_int("nonmanifold_vertices", r->nonmanifold_vertices);
    json_int("boundary_loops", r->boundary_loops);
    json_int("components", r->components);
    json_bool("orientable", r->orientable);
    json_bool("oriented", r->oriented);
    json_int("inconsistently_oriented_edges", r->orientation_conflicts);
    printf(",\n  \"euler\": %ld", r->euler);
    json_bool("closed", closed);
    json_bool("manifold", manifold);
    if (r->genus >= 0)
        printf(",\n  \"genus\": %ld", r->genus);
    else
        printf(",\n  \"genus\": null");
    if (si) {
        json_int("self_intersecting_pairs", r->self_intersections);
        json_int("self_intersecting_faces", r->self_intersecting_triangles);
    } else {
        printf(",\n  \"self_intersecting_pairs\": null,\n  \"self_intersecting_faces\": null");
    }
    json_num("area", r->area);
    json_num("min_angle_deg_min", r->min_angle_deg);
    json_num("min_angle_deg_mean", r->mean_min_angle_deg);
    json_num("max_angle_deg_max", r->max_angle_deg);
    if (input) {
        double d = r->input_bbox_diagonal;
        printf(",\n  \"input\": ");
        cli_json_string(stdout, input);
        json_int("input_points", r->input_points);
        json_num("input_bbox_diag", d);
        json_int("input_points_used", r->input_as_vertices);
        json_num("pct_input_used", r->input_points ? 100.0 * (double)r->input_as_vertices /
                                                         (double)r->input_points
                                                   : NAN);
        json_num("dist_input_to_mesh_mean", r->input_distance_mean);
        json_num("dist_input_to_mesh_rms", r->input_distance_rms);
        json_num("dist_input_to_mesh_max", r->input_distance_max);
        json_num("dist_input_to_mesh_mean_rel", r->input_distance_mean / d);
        json_num("dist_input_to_mesh_rms_rel", r->input_distance_rms / d);
        json_num("dist_input_to_mesh_max_rel", r->input_distance_max / d);
    }
    if (ref) {
        double d = r->reference_bbox_diagonal;
        printf(",\n  \"ref\": ");
        cli_json_string(stdout, ref);
        json_num("ref_bbox_diag", d);
        json_int("samples", p->samples);
        json_num("tau", r->tau);
        json_num("tau_rel", r->tau / d);
        json_num("dist_out_to_ref_mean", r->accuracy);
        json_num("dist_ref_to_out_mean", r->completeness);
        json_num("chamfer", r->chamfer);
        json_num("hausdorff", r->hausdorff);
        json_num("dist_out_to_ref_mean_rel", r->accuracy / d);
        json_num("dist_ref_to_out_mean_rel", r->completeness / d);
        json_num("chamfer_rel", r->chamfer / d);
        json_num("hausdorff_rel", r->hausdorff / d);
        json_num("precision", r->precision);
        json_num("recall", r->recall);
        json_num("fscore", r->fscore);
        json_num("normal_consistency", r->normal_consistency);
        json_num("normal_consistency_ref_to_out", r->normal_consistency_ref);
    }
    json_num("seconds", secs);
    printf("\n}\n");
}

/* Bounding-box diagonal of the vertices used by triangles, as the check
 * measures the reference (for --tau-rel). */
static double used_diagonal(const tessel_mesh *m)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    size_t n = m->triangle_count ? 3 * m->triangle_count : m->vertex_count;
    for (size_t i = 0; i < n; i++) {
        const float *p = m->xyz + 3 * (size_t)(m->triangle_count ? m->triangles[i] : i);
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], p[k]);
            hi[k] = fmax(hi[k], p[k]);
        }
    }
    double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static const char *yes_no(bool b) { return b ? "yes" : "no"; }

static void print_text(const char *mesh, const char *input, const char *ref,
                       const tessel_mesh_report *r, double secs)
{
    printf("mesh                %s\n", mesh);
    printf("vertices            %zu (%zu unreferenced)\n", r->vertices,
           r->unreferenced_vertices);
    printf("triangles           %zu (%zu degenerate, %zu duplicate)\n", r->triangles,
           r->degenerate_triangles, r->duplicate_triangles);
    printf("components          %zu\n", r->components);
    printf("edges               %zu (%zu boundary in %zu loops, %zu non-manifold)\n", r->edges,
           r->boundary_edges, r->boundary_loops, r->nonmanifold_edges);
    printf("non-manifold verts  %zu\n", r->nonmanifold_vertices);
    printf("oriented            %s (%zu conflicting edges; orientable: %s)\n",
           yes_no(r->oriented), r->orientation_conflicts, yes_no(r->orientable));
    if (r->self_intersections == SIZE_MAX)
        printf("self-intersections  not checked\n");
    else
        printf("self-intersections  %zu pairs (%zu triangles)\n", r->self_intersections,
               r->self_intersecting_triangles);
    printf("euler               %ld\n", r->euler);
    if (r->genus >= 0)
        printf("genus               %ld\n", r->genus);
    else
        printf("genus               - (not a closed orientable manifold)\n");
    printf("angles              min %.2f, max %.2f, mean of minima %.2f degrees\n",
           r->min_angle_deg, r->max_angle_deg, r->mean_min_angle_deg);
    printf("area                %.6g (bbox diagonal %.6g)\n", r->area, r->bbox_diagonal);
    if (input) {
        printf("input               %s: %zu points, %zu are vertices (%.2f%%)\n", input,
               r->input_points, r->input_as_vertices,
               r->input_points ? 100.0 * (double)r->input_as_vertices / (double)r->input_points
                               : 0.0);
        printf("input to mesh       mean %.6g, rms %.6g, max %.6g (%.4f%% / %.4f%% of the "
               "input's diagonal)\n",
               r->input_distance_mean, r->input_distance_rms, r->input_distance_max,
               100.0 * r->input_distance_mean / r->input_bbox_diagonal,
               100.0 * r->input_distance_max / r->input_bbox_diagonal);
    }
    if (ref) {
        double d = r->reference_bbox_diagonal;
        printf("reference           %s (bbox diagonal %.6g)\n", ref, d);
        printf("chamfer             %.6g (%.4f%% of the diagonal; mesh->ref %.6g, ref->mesh "
               "%.6g)\n",
               r->chamfer, 100.0 * r->chamfer / d, r->accuracy, r->completeness);
        printf("hausdorff           %.6g (%.4f%%)\n", r->hausdorff, 100.0 * r->hausdorff / d);
        printf("f-score             %.2f%% at tau %.6g (precision %.2f%%, recall %.2f%%)\n",
               r->fscore, r->tau, r->precision, r->recall);
        printf("normal consistency  %.4f (mesh->ref), %.4f (ref->mesh)\n", r->normal_consistency,
               r->normal_consistency_ref);
    }
    printf("valid manifold      %s\n", yes_no(tessel_mesh_report_valid(r)));
    printf("time                %.3f s\n", secs);
}

int cmd_check(int argc, char **argv)
{
    cli_common common = {0};
    tessel_check_params params = tessel_check_params_default();
    const char *mesh_path = NULL, *input_path = NULL, *ref_path = NULL;
    double tau_rel = 0.0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int c = cli_common_option(&common, argc, argv, &i);
        if (c < 0)
            return CLI_USAGE;
        if (c > 0)
            continue;
        bool has_value = i + 1 < argc;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            fputs(check_help, stdout);
            fputs(cli_common_help, stdout);
            return CLI_OK;
        } else if (strcmp(a, "--input") == 0 && has_value) {
            input_path = argv[++i];
        } else if (strcmp(a, "--ref") == 0 && has_value) {
            ref_path = argv[++i];
        } else if ((strcmp(a, "--tau") == 0 || strcmp(a, "--tau-rel") == 0) && has_value) {
            double v;
            if (!cli_parse_double(a, argv[++i], &v))
                return CLI_USAGE;
            if (!(v > 0.0)) {
                cli_error("%s must be positive, got '%s'", a, argv[i]);
                return CLI_USAGE;
            }
            if (a[5] == '-') {
                tau_rel = v;
                params.tau = 0.0;
            } else {
                params.tau = v;
                tau_rel = 0.0;
            }
        } else if (strcmp(a, "--samples") == 0 && has_value) {
            long n;
            if (!cli_parse_int(a, argv[++i], 1, 100000000, &n))
                return CLI_USAGE;
            params.samples = (uint32_t)n;
        } else if (strcmp(a, "--no-self-intersections") == 0) {
            params.self_intersections = 0;
        } else if (a[0] == '-' && a[1] != '\0') {
            if (!has_value && (strcmp(a, "--input") == 0 || strcmp(a, "--ref") == 0 ||
                               strcmp(a, "--tau") == 0 || strcmp(a, "--tau-rel") == 0 ||
                               strcmp(a, "--samples") == 0))
                cli_error("%s needs a value", a);
            else
                cli_error("unknown option '%s' (see tessel check --help)", a);
            return CLI_USAGE;
        } else if (!mesh_path) {
            mesh_path = a;
        } else {
            cli_error("too many arguments: '%s' (see tessel check --help)", a);
            return CLI_USAGE;
        }
    }
    if (!mesh_path) {
        cli_error("check needs a MESH (see tessel check --help)");
        return CLI_USAGE;
    }
    if ((params.tau > 0.0 || tau_rel > 0.0) && !ref_path) {
        cli_error("--tau and --tau-rel need --ref");
        return CLI_USAGE;
    }
    cli_apply_threads(&common);
    params.threads = common.threads;

    tessel_mesh mesh, ref;
    tessel_cloud cloud;
    memset(&mesh, 0, sizeof mesh);
    memset(&ref, 0, sizeof ref);
    memset(&cloud, 0, sizeof cloud);
    tessel_diag diag;
    memset(&diag, 0, sizeof diag);
    int rc = CLI_OK;
    const char *failed = mesh_path;
    tessel_status st = tessel_mesh_read(&mesh, mesh_path, NULL, &diag);
    if (st == TESSEL_OK && input_path) {
        failed = input_path;
        st = tessel_cloud_read(&cloud, input_path, NULL, &diag);
    }
    if (st == TESSEL_OK && ref_path) {
        failed = ref_path;
        st = tessel_mesh_read(&ref, ref_path, NULL, &diag);
    }
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, failed);
        rc = cli_exit_for_read(st);
        goto done;
    }
    params.input = input_path ? &cloud : NULL;
    params.reference = ref_path ? &ref : NULL;
    if (tau_rel > 0.0)
        params.tau = tau_rel * used_diagonal(&ref);
    double t0 = cli_now();
    tessel_mesh_report report;
    st = tessel_mesh_check(&mesh, &params, &report);
    double secs = cli_now() - t0;
    if (st != TESSEL_OK) {
        if (st == TESSEL_ERR_INVALID_ARG) {
            /* The readers validate indices and drop non-finite points, so
             * this is the reference; confirm by checking the mesh alone. */
            tessel_check_params alone = params;
            alone.input = NULL;
            alone.reference = NULL;
            alone.self_intersections = 0;
            bool mesh_ok = ref_path && tessel_mesh_check(&mesh, &alone, &report) == TESSEL_OK;
            cli_error("%s: %s", mesh_ok ? ref_path : mesh_path,
                      mesh_ok ? "the reference has no non-degenerate triangle"
                              : "a triangle uses a missing or non-finite vertex");
            rc = CLI_INPUT_ERROR;
        } else {
            cli_error("%s: %s", mesh_path, tessel_status_str(st));
            rc = st == TESSEL_ERR_LIMIT ? CLI_INPUT_ERROR : CLI_FAILURE;
        }
        goto done;
    }
    if (common.json)
        print_json(mesh_path, input_path, ref_path, &report, &params, secs);
    else if (!common.quiet)
        print_text(mesh_path, input_path, ref_path, &report, secs);
    rc = tessel_mesh_report_valid(&report) ? CLI_OK : CLI_FAILURE;
done:
    tessel_mesh_free(&mesh);
    tessel_mesh_free(&ref);
    tessel_cloud_free(&cloud);
    return rc;
}
