/* Hostile and careless callers: every misuse the C API can detect gets its status and a
 * message naming the argument, never a crash. Also hand-computed answers on a unit square,
 * so a status of SAHKD_OK is known to carry the right result. Run by tests/examples.rs
 * (with AddressSanitizer where the compiler has it). */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sahkd.h"

static int failures = 0;

#define EXPECT(cond)                                                                  \
    do {                                                                              \
        if (!(cond)) {                                                                \
            fprintf(stderr, "%s:%d: expected %s\n", __FILE__, __LINE__, #cond);       \
            failures++;                                                               \
        }                                                                             \
    } while (0)

/* `call` returns `status` and the thread's last error contains `word`. */
#define EXPECT_ERR(call, status, word)                                                \
    do {                                                                              \
        sahkd_status got_ = (call);                                                   \
        if (got_ != (status) || !strstr(sahkd_last_error(), (word))) {                \
            fprintf(stderr, "%s:%d: %s gave %s (%s), expected %s mentioning '%s'\n",  \
                    __FILE__, __LINE__, #call, sahkd_status_name(got_),               \
                    sahkd_last_error(), #status, (word));                             \
            failures++;                                                               \
        }                                                                             \
    } while (0)

#define OK(call) EXPECT_ERR(call, SAHKD_OK, "")

/* The unit square in the plane z = 1, as two triangles. */
static const float square_vertices[] = {0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
static const uint32_t square_indices[] = {0, 1, 2, 0, 2, 3};

static sahkd_ray ray_up(float x, float y) {
    sahkd_ray r = {{x, y, 0}, 0, {0, 0, 1}, INFINITY};
    return r;
}

static void *other_thread(void *arg) {
    (void)arg;
    /* The last error is per thread: this one has had no failure. */
    return (void *)(uintptr_t)(strcmp(sahkd_last_error(), "") == 0);
}

int main(void) {
    sahkd_mesh *mesh = NULL;
    sahkd_tree *tree = NULL;
    sahkd_ray ray = ray_up(0.25f, 0.5f);
    sahkd_hit hit;
    bool flag;

    /* Meshes: NULL arrays, bad indices, non-finite vertices, files that are not meshes. */
    EXPECT_ERR(sahkd_mesh_new(NULL, 4, square_indices, 2, &mesh), SAHKD_ERROR_NULL, "vertices");
    EXPECT(mesh == NULL);
    EXPECT_ERR(sahkd_mesh_new(square_vertices, 4, square_indices, 2, NULL), SAHKD_ERROR_NULL,
               "mesh");
    EXPECT_ERR(sahkd_mesh_new(square_vertices, 3, square_indices, 2, &mesh),
               SAHKD_ERROR_INVALID_MESH, "3");
    float nan_vertices[12];
    memcpy(nan_vertices, square_vertices, sizeof nan_vertices);
    nan_vertices[4] = NAN;
    EXPECT_ERR(sahkd_mesh_new(nan_vertices, 4, square_indices, 2, &mesh),
               SAHKD_ERROR_INVALID_MESH, "");
    EXPECT_ERR(sahkd_mesh_new((const float *)((const char *)square_vertices + 1), 4,
                              square_indices, 2, &mesh),
               SAHKD_ERROR_ALIGNMENT, "vertices");
    EXPECT_ERR(sahkd_mesh_new(square_vertices, SIZE_MAX / 4, square_indices, 2, &mesh),
               SAHKD_ERROR_INVALID_ARGUMENT, "overflow");
    EXPECT_ERR(sahkd_mesh_load("/nonexistent/mesh.ply", &mesh), SAHKD_ERROR_IO, "nonexistent");
    EXPECT_ERR(sahkd_mesh_load(NULL, &mesh), SAHKD_ERROR_NULL, "path");
    OK(sahkd_mesh_new(NULL, 0, NULL, 0, &mesh)); /* empty arrays may be NULL */
    sahkd_mesh_free(mesh);
    mesh = NULL;
    sahkd_mesh_free(NULL);

    OK(sahkd_mesh_new(square_vertices, 4, square_indices, 2, &mesh));
    size_t vertices = 0, triangles = 0;
    OK(sahkd_mesh_counts(mesh, &vertices, &triangles));
    EXPECT(vertices == 4 && triangles == 2);

    /* Options: unset size, values out of range, unknown names, an older caller's size. */
    sahkd_build_options options;
    memset(&options, 0, sizeof options);
    EXPECT_ERR(sahkd_tree_build(mesh, &options, &tree), SAHKD_ERROR_INVALID_ARGUMENT, "size");
    EXPECT(tree == NULL);
    OK(sahkd_build_options_default(&options));
    EXPECT(options.size == sizeof options && options.algorithm == SAHKD_ALGORITHM_HYBRID);
    struct {
        size_t offset;
        uint32_t value;
        const char *word;
    } bad[] = {
        {offsetof(sahkd_build_options, algorithm), 99, "algorithm"},
        {offsetof(sahkd_build_options, axes), 2, "axes"},
        {offsetof(sahkd_build_options, counting), 7, "counting"},
        {offsetof(sahkd_build_options, clip), 2, "clip"},
        {offsetof(sahkd_build_options, threads), 1000000, "threads"},
        {offsetof(sahkd_build_options, bins), 1, "bins"},
        {offsetof(sahkd_build_options, bins), (uint32_t)-5, "bins"},
        {offsetof(sahkd_build_options, max_depth), 61, "max_depth"},
        {offsetof(sahkd_build_options, size), sizeof options + 4, "size"},
        {offsetof(sahkd_build_options, size), 6, "size"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sahkd_build_options o;
        OK(sahkd_build_options_default(&o));
        memcpy((char *)&o + bad[i].offset, &bad[i].value, sizeof(uint32_t));
        EXPECT_ERR(sahkd_build_options_validate(&o), SAHKD_ERROR_INVALID_ARGUMENT, bad[i].word);
        EXPECT_ERR(sahkd_tree_build(mesh, &o, &tree), SAHKD_ERROR_INVALID_ARGUMENT, bad[i].word);
    }
    {
        sahkd_build_options o;
        OK(sahkd_build_options_default(&o));
        o.empty_bonus = 5.0f;
        EXPECT_ERR(sahkd_build_options_validate(&o), SAHKD_ERROR_INVALID_ARGUMENT, "empty_bonus");
        o.empty_bonus = 0.8f;
        o.intersection_cost = NAN;
        EXPECT_ERR(sahkd_build_options_validate(&o), SAHKD_ERROR_INVALID_ARGUMENT, "K_I");
        OK(sahkd_build_options_default(&o));
        o.algorithm = SAHKD_ALGORITHM_LEVEL;
        o.bins = 16;
        EXPECT_ERR(sahkd_build_options_validate(&o), SAHKD_ERROR_INVALID_ARGUMENT, "bins");
    }
    /* The library's edge values for each option (BuildOptions::validate): the last value
     * accepted and the first refused, each given the library's answer, traversal cost 0
     * (accepted) among them. */
    {
        struct {
            size_t offset;
            int is_float;
            double value;
            int accepted;
        } edges[] = {
            {offsetof(sahkd_build_options, traversal_cost), 1, 0.0, 1},
            {offsetof(sahkd_build_options, traversal_cost), 1, -1e-6, 0},
            {offsetof(sahkd_build_options, intersection_cost), 1, 1e-6, 1},
            {offsetof(sahkd_build_options, intersection_cost), 1, 0.0, 0},
            {offsetof(sahkd_build_options, empty_bonus), 1, 1.0, 1},
            {offsetof(sahkd_build_options, empty_bonus), 1, 0.0, 0},
            {offsetof(sahkd_build_options, max_duplication), 1, 1.0, 1},
            {offsetof(sahkd_build_options, max_duplication), 1, 0.999, 0},
            {offsetof(sahkd_build_options, max_depth), 0, 60, 1},
            {offsetof(sahkd_build_options, max_depth), 0, 61, 0},
            {offsetof(sahkd_build_options, leaf_size), 0, 0, 1},
            {offsetof(sahkd_build_options, threads), 0, 1, 1},
            {offsetof(sahkd_build_options, bins), 0, 0, 1},
            {offsetof(sahkd_build_options, bins), 0, 1, 0},
            {offsetof(sahkd_build_options, bins), 0, 2, 1},
            {offsetof(sahkd_build_options, bins), 0, 1024, 1},
            {offsetof(sahkd_build_options, bins), 0, 1025, 0},
        };
        for (size_t i = 0; i < sizeof edges / sizeof edges[0]; i++) {
            sahkd_build_options o;
            OK(sahkd_build_options_default(&o));
            float f = (float)edges[i].value;
            uint32_t u = (uint32_t)edges[i].value;
            memcpy((char *)&o + edges[i].offset, edges[i].is_float ? (void *)&f : (void *)&u,
                   sizeof(uint32_t));
            if (edges[i].accepted) {
                OK(sahkd_build_options_validate(&o));
                OK(sahkd_tree_build(mesh, &o, &tree));
                sahkd_tree_free(tree);
                tree = NULL;
            } else {
                EXPECT_ERR(sahkd_build_options_validate(&o), SAHKD_ERROR_INVALID_ARGUMENT, "");
                EXPECT_ERR(sahkd_tree_build(mesh, &o, &tree), SAHKD_ERROR_INVALID_ARGUMENT, "");
                EXPECT(tree == NULL);
            }
        }
    }
    /* The header's numbers are the library's names. */
    struct {
        const char *key, *value;
        size_t offset;
        uint32_t code;
    } names[] = {
        {"algorithm", "hybrid", offsetof(sahkd_build_options, algorithm), SAHKD_ALGORITHM_HYBRID},
        {"algorithm", "sweep", offsetof(sahkd_build_options, algorithm), SAHKD_ALGORITHM_SWEEP},
        {"algorithm", "level", offsetof(sahkd_build_options, algorithm), SAHKD_ALGORITHM_LEVEL},
        {"algorithm", "naive", offsetof(sahkd_build_options, algorithm), SAHKD_ALGORITHM_NAIVE},
        {"algorithm", "median", offsetof(sahkd_build_options, algorithm), SAHKD_ALGORITHM_MEDIAN},
        {"axes", "longest", offsetof(sahkd_build_options, axes), SAHKD_AXES_LONGEST},
        {"axes", "all", offsetof(sahkd_build_options, axes), SAHKD_AXES_ALL},
        {"counting", "space-tree", offsetof(sahkd_build_options, counting), SAHKD_COUNTING_SPACE_TREE},
        {"counting", "scan", offsetof(sahkd_build_options, counting), SAHKD_COUNTING_SCAN},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        sahkd_build_options o;
        OK(sahkd_build_options_default(&o));
        memset((char *)&o + names[i].offset, 0xff, sizeof(uint32_t));
        OK(sahkd_build_options_set(&o, names[i].key, names[i].value));
        uint32_t code;
        memcpy(&code, (char *)&o + names[i].offset, sizeof code);
        EXPECT(code == names[i].code);
    }
    EXPECT_ERR(sahkd_build_options_set(&options, "algorithm", "quick"),
               SAHKD_ERROR_INVALID_ARGUMENT, "hybrid, sweep");
    EXPECT_ERR(sahkd_build_options_set(&options, "colour", "red"), SAHKD_ERROR_INVALID_ARGUMENT,
               "colour");
    EXPECT_ERR(sahkd_build_options_preset("fastest", &options), SAHKD_ERROR_INVALID_ARGUMENT,
               "fastest");
    OK(sahkd_build_options_preset("quality", &options));
    EXPECT(options.axes == SAHKD_AXES_ALL && options.bins == 0);
    {
        /* A caller compiled when the struct ended after `algorithm`: the rest are defaults. */
        sahkd_build_options old;
        memset(&old, 0xee, sizeof old);
        old.size = offsetof(sahkd_build_options, axes);
        old.algorithm = SAHKD_ALGORITHM_SWEEP;
        OK(sahkd_tree_build(mesh, &old, &tree));
        sahkd_build_options back, defaults;
        OK(sahkd_tree_options(tree, &back));
        OK(sahkd_build_options_default(&defaults));
        EXPECT(back.algorithm == SAHKD_ALGORITHM_SWEEP && back.clip == defaults.clip &&
               back.traversal_cost == defaults.traversal_cost && back.bins == SAHKD_BINS_DEFAULT);
        sahkd_tree_free(tree);
        tree = NULL;
    }

    OK(sahkd_tree_build(mesh, NULL, &tree));

    /* Hand-computed answers: the ray at (0.25, 0.5) meets triangle 1 at t = 1. */
    OK(sahkd_tree_intersect(tree, &ray, &hit));
    EXPECT(hit.t == 1.0f && hit.prim == 1 && hit.geometry == 0);
    sahkd_ray miss = ray_up(2, 2);
    OK(sahkd_tree_intersect(tree, &miss, &hit));
    EXPECT(hit.prim == SAHKD_INVALID_ID && isinf(hit.t));
    OK(sahkd_tree_occluded(tree, &ray, &flag));
    EXPECT(flag);
    sahkd_ray short_ray = ray;
    short_ray.t_max = 0.5f;
    OK(sahkd_tree_occluded(tree, &short_ray, &flag));
    EXPECT(!flag);
    /* Through the shared diagonal: both triangles, once each. */
    sahkd_ray diagonal = ray_up(0.5f, 0.5f);
    sahkd_hit all[4];
    size_t count = 99;
    OK(sahkd_tree_all_hits(tree, &diagonal, all, 4, &count));
    EXPECT(count == 2 && all[0].prim == 0 && all[1].prim == 1);
    EXPECT_ERR(sahkd_tree_all_hits(tree, &diagonal, all, 1, &count), SAHKD_ERROR_BUFFER_TOO_SMALL,
               "2");
    EXPECT(count == 2 && all[0].prim == 0);
    uint32_t hits_count = 0;
    OK(sahkd_tree_count_hits(tree, &diagonal, &hits_count));
    EXPECT(hits_count == 2);
    const float point[3] = {0.25f, 0.5f, 3.0f};
    sahkd_closest closest;
    OK(sahkd_tree_closest_point(tree, point, 1, 0, &closest, 0, 0));
    EXPECT(closest.distance == 2.0 && closest.point[2] == 1.0 && closest.prim == 1);
    double distance = 0;
    OK(sahkd_tree_distance(tree, point, 1, 0, &distance, 0, SAHKD_QUERY_PARALLEL));
    EXPECT(distance == 2.0);

    /* Handles and outputs that are NULL; a freed handle set to NULL. */
    EXPECT_ERR(sahkd_tree_intersect(NULL, &ray, &hit), SAHKD_ERROR_NULL, "tree");
    EXPECT_ERR(sahkd_tree_intersect(tree, NULL, &hit), SAHKD_ERROR_NULL, "ray");
    EXPECT_ERR(sahkd_tree_intersect(tree, &ray, NULL), SAHKD_ERROR_NULL, "hit");
    EXPECT_ERR(sahkd_tree_occluded(tree, &ray, NULL), SAHKD_ERROR_NULL, "occluded");
    sahkd_tree *none = tree;
    EXPECT_ERR(sahkd_tree_build(NULL, NULL, &none), SAHKD_ERROR_NULL, "mesh");
    EXPECT(none == NULL); /* cleared on failure */
    EXPECT_ERR(sahkd_tree_bounds(tree, NULL, NULL), SAHKD_ERROR_NULL, "lo");
    EXPECT_ERR(sahkd_scene_tree_intersect(NULL, &ray, &hit), SAHKD_ERROR_NULL, "scene");

    /* Arrays: NULL, misaligned, bad strides, counts that overflow, unknown flags. */
    sahkd_ray rays[8];
    sahkd_hit hits[8];
    for (int i = 0; i < 8; i++) rays[i] = ray_up(0.1f * i + 0.05f, 0.3f);
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, NULL, 8, 0, hits, 0, 0), SAHKD_ERROR_NULL, "rays");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, 8, 0, NULL, 0, 0), SAHKD_ERROR_NULL, "hits");
    OK(sahkd_tree_intersect_aos(tree, NULL, 0, 0, NULL, 0, 0));
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, (const sahkd_ray *)((const char *)rays + 2), 4, 0,
                                        hits, 0, 0),
               SAHKD_ERROR_ALIGNMENT, "rays");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, 4, 33, hits, 0, 0), SAHKD_ERROR_ALIGNMENT,
               "stride");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, 4, 16, hits, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "stride");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, SIZE_MAX / 16, 0, hits, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "overflow");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, 8, 0, hits, SIZE_MAX / 2 - 3, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "overflow");
    EXPECT_ERR(sahkd_tree_intersect_aos(tree, rays, 8, 0, hits, 0, 6),
               SAHKD_ERROR_INVALID_ARGUMENT, "flags");
    EXPECT_ERR(sahkd_tree_contains(tree, point, 1, 0, 7, &flag, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "inside");
    EXPECT_ERR(sahkd_tree_closest_point(tree, point, 1, 0, NULL, 0, 0), SAHKD_ERROR_NULL, "out");

    /* The library's rule for input rays and points: non-finite parts are refused, named. */
    sahkd_ray nan_origin = ray_up(NAN, 0.5f);
    EXPECT_ERR(sahkd_tree_intersect(tree, &nan_origin, &hit), SAHKD_ERROR_INVALID_ARGUMENT,
               "origin");
    sahkd_ray bad_rays[2] = {ray_up(0.25f, 0.5f), ray_up(0.25f, 0.5f)};
    bad_rays[1].t_max = NAN;
    EXPECT_ERR(sahkd_tree_occluded_aos(tree, bad_rays, 2, 0, &flag, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "rays[1]: t_max is NaN");
    bad_rays[1].t_max = INFINITY;
    bad_rays[1].t_min = -INFINITY;
    EXPECT_ERR(sahkd_tree_count_hits_aos(tree, bad_rays, 2, 0, &hits_count, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "t_min");
    sahkd_ray empty = ray_up(0.25f, 0.5f);
    empty.t_min = 2.0f; /* an empty range hits nothing: not an error */
    OK(sahkd_tree_intersect(tree, &empty, &hit));
    EXPECT(hit.prim == SAHKD_INVALID_ID);
    const float far_point[3] = {0, INFINITY, 0};
    EXPECT_ERR(sahkd_tree_distance(tree, far_point, 1, 0, &distance, 0, 0),
               SAHKD_ERROR_INVALID_ARGUMENT, "points[0]");

    /* AoS with strides, SoA with strides and the single-ray call agree. */
    OK(sahkd_tree_intersect_aos(tree, rays, 8, 0, hits, 0, SAHKD_QUERY_PARALLEL));
    struct padded {
        sahkd_ray ray;
        float pad[3];
    } padded[8];
    struct {
        float t, u, v;
        uint32_t prim, geometry;
        double pad;
    } soa_out[8];
    float columns[8][8]; /* per ray: ox oy oz dx dy dz tmin tmax */
    for (int i = 0; i < 8; i++) {
        padded[i].ray = rays[i];
        for (int k = 0; k < 3; k++) {
            columns[i][k] = rays[i].origin[k];
            columns[i][3 + k] = rays[i].direction[k];
        }
        columns[i][6] = rays[i].t_min;
        columns[i][7] = rays[i].t_max;
    }
    sahkd_hit strided[16];
    OK(sahkd_tree_intersect_aos(tree, &padded[0].ray, 8, sizeof padded[0], strided,
                                2 * sizeof(sahkd_hit), 0));
    sahkd_rays_soa soa = {&columns[0][0], &columns[0][1], &columns[0][2], &columns[0][3],
                          &columns[0][4], &columns[0][5], &columns[0][6], NULL,
                          sizeof columns[0]};
    sahkd_hits_soa soa_hits = {&soa_out[0].t, &soa_out[0].u, &soa_out[0].v, &soa_out[0].prim,
                               &soa_out[0].geometry, sizeof soa_out[0]};
    OK(sahkd_tree_intersect_soa(tree, &soa, 8, &soa_hits, 0));
    for (int i = 0; i < 8; i++) {
        sahkd_hit one;
        OK(sahkd_tree_intersect(tree, &rays[i], &one));
        EXPECT(memcmp(&one, &hits[i], sizeof one) == 0);
        EXPECT(memcmp(&one, &strided[2 * i], sizeof one) == 0);
        EXPECT(one.t == soa_out[i].t && one.u == soa_out[i].u && one.v == soa_out[i].v &&
               one.prim == soa_out[i].prim && one.geometry == soa_out[i].geometry);
        EXPECT(one.t == 1.0f);
    }
    soa.origin_y = NULL;
    EXPECT_ERR(sahkd_tree_intersect_soa(tree, &soa, 8, &soa_hits, 0), SAHKD_ERROR_NULL,
               "origin_y");

    /* Save, load, bytes: the same answers; broken files and bytes are refused. */
    EXPECT_ERR(sahkd_tree_save(tree, "/nonexistent/dir/tree.sahkd"), SAHKD_ERROR_IO,
               "nonexistent");
    none = tree;
    EXPECT_ERR(sahkd_tree_load("/nonexistent/tree.sahkd", &none), SAHKD_ERROR_IO, "");
    EXPECT(none == NULL);
    uint8_t *bytes = NULL;
    size_t size = 0;
    OK(sahkd_tree_to_bytes(tree, &bytes, &size));
    EXPECT(bytes != NULL && size > 0);
    sahkd_tree *copy = NULL;
    EXPECT_ERR(sahkd_tree_from_bytes(bytes, size / 2, &copy), SAHKD_ERROR_INVALID_TREE, "");
    EXPECT(copy == NULL);
    bytes[size - 1] ^= 0x55;
    EXPECT_ERR(sahkd_tree_from_bytes(bytes, size, &copy), SAHKD_ERROR_INVALID_TREE, "checksum");
    bytes[size - 1] ^= 0x55;
    OK(sahkd_tree_from_bytes(bytes, size, &copy));
    sahkd_bytes_free(bytes, size);
    OK(sahkd_tree_validate(copy));
    OK(sahkd_tree_intersect(copy, &ray, &hit));
    EXPECT(hit.t == 1.0f && hit.prim == 1);
    sahkd_tree_free(copy);
    copy = NULL;
    EXPECT_ERR(sahkd_tree_intersect(copy, &ray, &hit), SAHKD_ERROR_NULL, "tree");
    sahkd_tree_free(copy); /* NULL: nothing */

    /* Scenes: unknown ids, singular transforms, then the geometry id in the answers. */
    sahkd_scene *scene = NULL;
    OK(sahkd_scene_new(&scene));
    uint32_t id = 0, instance = 0;
    OK(sahkd_scene_add_mesh(scene, mesh, &id));
    const double shift[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1}; /* z + 1 */
    const double flat[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0};
    EXPECT_ERR(sahkd_scene_add_instance(scene, 5, shift, &instance), SAHKD_ERROR_INVALID_ARGUMENT,
               "5");
    EXPECT_ERR(sahkd_scene_add_instance(scene, id, flat, &instance), SAHKD_ERROR_INVALID_ARGUMENT,
               "singular");
    EXPECT_ERR(sahkd_scene_add_instance(scene, id, NULL, &instance), SAHKD_ERROR_NULL,
               "transform");
    OK(sahkd_scene_add_instance(scene, id, shift, &instance));
    EXPECT(id == 0 && instance == 1);
    sahkd_scene_tree *built = NULL;
    OK(sahkd_scene_build(scene, NULL, &built));
    sahkd_scene_free(scene);
    sahkd_ray down = {{0.25f, 0.5f, 5.0f}, 0, {0, 0, -1}, INFINITY};
    OK(sahkd_scene_tree_intersect(built, &down, &hit));
    EXPECT(hit.geometry == 1 && hit.t == 3.0f);
    OK(sahkd_scene_tree_closest_point(built, point, 1, 0, &closest, 0, 0));
    EXPECT(closest.geometry == 1 && closest.distance == 1.0);
    sahkd_scene_tree_free(built);

    /* A closed unit cube, wound outwards: inside tests, signed distances, winding numbers,
     * every array call on the calling thread and on every core alike. */
    {
        const float cube_v[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,
                                0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
        const uint32_t cube_f[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                   3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
        sahkd_mesh *cube_mesh = NULL;
        sahkd_tree *cube = NULL;
        OK(sahkd_mesh_new(cube_v, 8, cube_f, 12, &cube_mesh));
        OK(sahkd_tree_build(cube_mesh, NULL, &cube));
        /* Inside at the centre, outside beyond a face; every point 0.5 from the surface. */
        const float pts[2][4] = {{0.5f, 0.5f, 0.5f, 0}, {0.5f, 0.5f, 1.5f, 0}};
        for (uint32_t flags = 0; flags <= SAHKD_QUERY_PARALLEL; flags++) {
            for (uint32_t test = SAHKD_INSIDE_PARITY; test <= SAHKD_INSIDE_WINDING; test++) {
                double sd[2] = {0, 0};
                bool in[2] = {false, true};
                OK(sahkd_tree_signed_distance(cube, &pts[0][0], 2, sizeof pts[0], test, sd, 0,
                                              flags));
                OK(sahkd_tree_contains(cube, &pts[0][0], 2, sizeof pts[0], test, in, 0, flags));
                EXPECT(sd[0] == -0.5 && sd[1] == 0.5 && in[0] && !in[1]);
            }
            double w[2] = {0, 0};
            OK(sahkd_tree_winding_number(cube, &pts[0][0], 2, sizeof pts[0], w, 0, flags));
            EXPECT(fabs(w[0] - 1.0) < 1e-9 && fabs(w[1]) < 1e-9);
            sahkd_closest c[2];
            OK(sahkd_tree_closest_point(cube, &pts[0][0], 2, sizeof pts[0], c, 0, flags));
            EXPECT(c[0].distance == 0.5 && c[1].distance == 0.5 && c[1].point[2] == 1.0);
        }
        /* A ray along x through the cube's middle crosses two faces; one stopping inside,
         * one. Every hit array and count agrees with the one-ray calls. */
        sahkd_ray through[3] = {{{-1, 0.3f, 0.6f}, 0, {1, 0, 0}, INFINITY},
                                {{-1, 0.3f, 0.6f}, 0, {1, 0, 0}, 1.5f},
                                {{-1, 5, 5}, 0, {1, 0, 0}, INFINITY}};
        uint32_t counts[3];
        size_t offsets[4], total = 0;
        sahkd_hit flat[4];
        for (uint32_t flags = 0; flags <= SAHKD_QUERY_PARALLEL; flags++) {
            OK(sahkd_tree_count_hits_aos(cube, through, 3, 0, counts, 0, flags));
            EXPECT(counts[0] == 2 && counts[1] == 1 && counts[2] == 0);
            EXPECT_ERR(sahkd_tree_all_hits_aos(cube, through, 3, 0, flat, 2, offsets, &total,
                                               flags),
                       SAHKD_ERROR_BUFFER_TOO_SMALL, "3");
            EXPECT(total == 3 && offsets[3] == 3);
            OK(sahkd_tree_all_hits_aos(cube, through, 3, 0, flat, 4, offsets, &total, flags));
            EXPECT(total == 3 && offsets[0] == 0 && offsets[1] == 2 && offsets[2] == 3 &&
                   offsets[3] == 3);
            EXPECT(flat[0].t == 1.0f && flat[1].t == 2.0f && flat[2].t == 1.0f);
            EXPECT(flat[0].prim == flat[2].prim && flat[0].prim != flat[1].prim);
        }
        for (int i = 0; i < 3; i++) {
            sahkd_hit one[4];
            size_t n = 0;
            uint32_t k = 0;
            OK(sahkd_tree_all_hits(cube, &through[i], one, 4, &n));
            OK(sahkd_tree_count_hits(cube, &through[i], &k));
            EXPECT(n == counts[i] && k == counts[i]);
            EXPECT(n == 0 || memcmp(one, &flat[offsets[i]], n * sizeof one[0]) == 0);
        }
        /* Occlusion from separate arrays. */
        float ox[3], oy[3], oz[3], dx[3], dy[3], dz[3], tmax[3];
        for (int i = 0; i < 3; i++) {
            ox[i] = through[i].origin[0], oy[i] = through[i].origin[1];
            oz[i] = through[i].origin[2], dx[i] = through[i].direction[0];
            dy[i] = through[i].direction[1], dz[i] = through[i].direction[2];
            tmax[i] = i == 1 ? 0.5f : INFINITY; /* stops before the cube */
        }
        sahkd_rays_soa columns = {ox, oy, oz, dx, dy, dz, NULL, tmax, 0};
        bool blocked[3] = {false, true, true};
        OK(sahkd_tree_occluded_soa(cube, &columns, 3, blocked, 0, SAHKD_QUERY_PARALLEL));
        EXPECT(blocked[0] && !blocked[1] && !blocked[2]);
        /* Counts and every hit from the same columns: ray 1 now stops before the cube. */
        uint32_t soa_counts[3] = {9, 9, 9};
        OK(sahkd_tree_count_hits_soa(cube, &columns, 3, soa_counts, 0, 0));
        EXPECT(soa_counts[0] == 2 && soa_counts[1] == 0 && soa_counts[2] == 0);
        size_t soa_offsets[4], soa_total = 0;
        sahkd_hit soa_flat[2];
        EXPECT_ERR(sahkd_tree_all_hits_soa(cube, &columns, 3, soa_flat, 1, soa_offsets,
                                           &soa_total, SAHKD_QUERY_PARALLEL),
                   SAHKD_ERROR_BUFFER_TOO_SMALL, "2");
        OK(sahkd_tree_all_hits_soa(cube, &columns, 3, soa_flat, 2, soa_offsets, &soa_total,
                                   SAHKD_QUERY_PARALLEL));
        EXPECT(soa_total == 2 && soa_offsets[1] == 2 && soa_offsets[3] == 2);
        EXPECT(memcmp(soa_flat, flat, 2 * sizeof flat[0]) == 0);
        EXPECT_ERR(sahkd_tree_count_hits_soa(cube, NULL, 3, soa_counts, 0, 0), SAHKD_ERROR_NULL,
                   "rays");

        /* Two cubes in a scene, the second moved 3 along x: arrays name the geometry. */
        sahkd_scene *two = NULL;
        uint32_t first = 0, second = 0;
        const double move[12] = {1, 0, 0, 3, 0, 1, 0, 0, 0, 0, 1, 0};
        OK(sahkd_scene_new(&two));
        OK(sahkd_scene_add_mesh(two, cube_mesh, &first));
        OK(sahkd_scene_add_instance(two, first, move, &second));
        size_t geometries = 0;
        OK(sahkd_scene_count(two, &geometries));
        EXPECT(geometries == 2);
        sahkd_scene_tree *both = NULL;
        OK(sahkd_scene_build(two, NULL, &both));
        sahkd_scene_free(two);
        sahkd_ray pair[2] = {{{-1, 0.5f, 0.5f}, 0, {1, 0, 0}, INFINITY},
                             {{10, 0.5f, 0.5f}, 0, {-1, 0, 0}, INFINITY}};
        sahkd_hit found[2];
        bool any[2] = {false, false};
        OK(sahkd_scene_tree_intersect_aos(both, pair, 2, 0, found, 0, SAHKD_QUERY_PARALLEL));
        EXPECT(found[0].geometry == 0 && found[0].t == 1.0f);
        EXPECT(found[1].geometry == 1 && found[1].t == 6.0f);
        uint32_t geometry_ids[2];
        float ts[2];
        sahkd_rays_soa pair_soa = {&pair[0].origin[0], &pair[0].origin[1], &pair[0].origin[2],
                                   &pair[0].direction[0], &pair[0].direction[1],
                                   &pair[0].direction[2], &pair[0].t_min, &pair[0].t_max,
                                   sizeof pair[0]};
        sahkd_hits_soa pair_hits = {ts, NULL, NULL, NULL, geometry_ids, 0};
        OK(sahkd_scene_tree_intersect_soa(both, &pair_soa, 2, &pair_hits, 0));
        EXPECT(ts[0] == 1.0f && ts[1] == 6.0f && geometry_ids[0] == 0 && geometry_ids[1] == 1);
        OK(sahkd_scene_tree_occluded_aos(both, pair, 2, 0, any, 0, 0));
        EXPECT(any[0] && any[1]);
        any[0] = any[1] = false;
        OK(sahkd_scene_tree_occluded_soa(both, &pair_soa, 2, any, 0, 0));
        EXPECT(any[0] && any[1]);
        OK(sahkd_scene_tree_occluded(both, &pair[0], &flag));
        EXPECT(flag);
        const float mid[3] = {3.5f, 0.5f, 0.5f};
        double d = 0, s = 0;
        bool inside = false;
        OK(sahkd_scene_tree_distance(both, mid, 1, 0, &d, 0, 0));
        OK(sahkd_scene_tree_signed_distance(both, mid, 1, 0, SAHKD_INSIDE_PARITY, &s, 0, 0));
        OK(sahkd_scene_tree_contains(both, mid, 1, 0, SAHKD_INSIDE_WINDING, &inside, 0, 0));
        EXPECT(d == 0.5 && s == -0.5 && inside);
        sahkd_scene_tree_free(both);
        sahkd_tree_free(cube);
        sahkd_mesh_free(cube_mesh);
    }

    /* Statuses have names; the last error belongs to the thread that failed. */
    EXPECT(strcmp(sahkd_status_name(SAHKD_ERROR_NULL), "SAHKD_ERROR_NULL") == 0);
    EXPECT(strcmp(sahkd_status_name(99), "unknown status") == 0);
    EXPECT(strlen(sahkd_version()) > 0);
    EXPECT_ERR(sahkd_tree_intersect(NULL, &ray, &hit), SAHKD_ERROR_NULL, "tree");
    pthread_t thread;
    void *clean = NULL;
    EXPECT(pthread_create(&thread, NULL, other_thread, NULL) == 0);
    EXPECT(pthread_join(thread, &clean) == 0);
    EXPECT(clean == (void *)1);
    EXPECT(strstr(sahkd_last_error(), "tree") != NULL);

    sahkd_tree_free(tree);
    sahkd_mesh_free(mesh);
    if (failures) {
        fprintf(stderr, "%d failures\n", failures);
        return 1;
    }
    printf("hostile: all checks passed\n");
    return 0;
}
