/* Loads a mesh, builds its kd-tree, traces one camera ray per pixel and a shadow ray from
 * every hit, and writes the picture as a PPM:
 *
 *     render MESH.ply OUT.ppm [WIDTH HEIGHT [DUMP]]
 *
 * With DUMP, the rays and answers are written to DUMP.rays, DUMP.hits, DUMP.shadow_rays and
 * DUMP.shadowed (raw arrays of sahkd_ray, sahkd_hit, sahkd_ray and bytes), which the
 * crate's tests compare with the Rust library's answers to the same rays. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sahkd.h"

#define CHECK(call)                                                                      \
    do {                                                                                 \
        sahkd_status status_ = (call);                                                   \
        if (status_ != SAHKD_OK) {                                                       \
            fprintf(stderr, "%s failed: %s: %s\n", #call, sahkd_status_name(status_),    \
                    sahkd_last_error());                                                 \
            exit(1);                                                                     \
        }                                                                                \
    } while (0)

static void write_raw(const char *prefix, const char *suffix, const void *data, size_t bytes) {
    char path[4096];
    snprintf(path, sizeof path, "%s.%s", prefix, suffix);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, bytes, f) != bytes || fclose(f) != 0) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(1);
    }
}

static void normalize(float v[3]) {
    float n = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++) v[i] /= n;
}

static void cross(const float a[3], const float b[3], float out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

int main(int argc, char **argv) {
    if (argc != 3 && argc != 5 && argc != 6) {
        fprintf(stderr, "usage: %s MESH OUT.ppm [WIDTH HEIGHT [DUMP]]\n", argv[0]);
        return 2;
    }
    size_t width = argc >= 5 ? (size_t)atoi(argv[3]) : 320;
    size_t height = argc >= 5 ? (size_t)atoi(argv[4]) : 240;
    const char *dump = argc == 6 ? argv[5] : NULL;
    if (width == 0 || height == 0) {
        fprintf(stderr, "width and height must be positive\n");
        return 2;
    }

    sahkd_mesh *mesh = NULL;
    CHECK(sahkd_mesh_load(argv[1], &mesh));
    sahkd_build_options options;
    CHECK(sahkd_build_options_default(&options));
    sahkd_tree *tree = NULL;
    CHECK(sahkd_tree_build(mesh, &options, &tree));
    sahkd_mesh_free(mesh); /* the tree keeps its own triangles */

    /* A camera above and to the side of the box, looking at its centre. */
    float lo[3], hi[3], centre[3], eye[3], forward[3], right[3], up[3];
    const float world_up[3] = {0, 1, 0};
    CHECK(sahkd_tree_bounds(tree, lo, hi));
    float diagonal = 0;
    for (int i = 0; i < 3; i++) {
        centre[i] = 0.5f * (lo[i] + hi[i]);
        diagonal += (hi[i] - lo[i]) * (hi[i] - lo[i]);
    }
    diagonal = sqrtf(diagonal);
    const float offset[3] = {0.6f, 0.5f, 1.0f};
    for (int i = 0; i < 3; i++) {
        eye[i] = centre[i] + offset[i] * diagonal;
        forward[i] = centre[i] - eye[i];
    }
    normalize(forward);
    cross(forward, world_up, right);
    normalize(right);
    cross(right, forward, up);
    float scale = tanf(0.5f * 45.0f * 3.14159265f / 180.0f);
    float aspect = (float)width / (float)height;

    size_t n = width * height;
    sahkd_ray *rays = malloc(n * sizeof *rays);
    sahkd_hit *hits = malloc(n * sizeof *hits);
    sahkd_ray *shadow = malloc(n * sizeof *shadow);
    bool *shadowed = malloc(n * sizeof *shadowed);
    unsigned char *pixels = malloc(3 * n);
    if (!rays || !hits || !shadow || !shadowed || !pixels) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    for (size_t y = 0; y < height; y++) {
        for (size_t x = 0; x < width; x++) {
            float sx = (2.0f * ((float)x + 0.5f) / (float)width - 1.0f) * scale * aspect;
            float sy = (1.0f - 2.0f * ((float)y + 0.5f) / (float)height) * scale;
            sahkd_ray *r = &rays[y * width + x];
            for (int i = 0; i < 3; i++) {
                r->origin[i] = eye[i];
                r->direction[i] = forward[i] + sx * right[i] + sy * up[i];
            }
            r->t_min = 0.0f;
            r->t_max = INFINITY;
        }
    }
    /* Every core for the camera rays. */
    CHECK(sahkd_tree_intersect_aos(tree, rays, n, 0, hits, 0, SAHKD_QUERY_PARALLEL));

    /* Shadow rays toward a sun, from just off each hit; misses get an empty ray. */
    const float sun[3] = {0.3f, 1.0f, 0.4f};
    for (size_t i = 0; i < n; i++) {
        sahkd_ray *s = &shadow[i];
        for (int k = 0; k < 3; k++) {
            s->origin[k] = hits[i].prim == SAHKD_INVALID_ID
                               ? eye[k]
                               : rays[i].origin[k] + hits[i].t * rays[i].direction[k];
            s->direction[k] = sun[k];
        }
        s->t_min = 1e-4f * diagonal;
        s->t_max = hits[i].prim == SAHKD_INVALID_ID ? 0.0f : INFINITY;
    }
    CHECK(sahkd_tree_occluded_aos(tree, shadow, n, 0, shadowed, 0, SAHKD_QUERY_PARALLEL));

    float t_near = INFINITY, t_far = 0;
    for (size_t i = 0; i < n; i++) {
        if (hits[i].prim != SAHKD_INVALID_ID) {
            t_near = fminf(t_near, hits[i].t);
            t_far = fmaxf(t_far, hits[i].t);
        }
    }
    size_t hit_count = 0;
    for (size_t i = 0; i < n; i++) {
        unsigned char value = 40;
        if (hits[i].prim != SAHKD_INVALID_ID) {
            hit_count++;
            float depth = t_far > t_near ? (hits[i].t - t_near) / (t_far - t_near) : 0;
            value = (unsigned char)(255.0f * (1.0f - 0.7f * depth) * (shadowed[i] ? 0.5f : 1.0f));
        }
        pixels[3 * i] = pixels[3 * i + 1] = pixels[3 * i + 2] = value;
    }
    FILE *out = fopen(argv[2], "wb");
    if (!out || fprintf(out, "P6\n%zu %zu\n255\n", width, height) < 0 ||
        fwrite(pixels, 1, 3 * n, out) != 3 * n || fclose(out) != 0) {
        fprintf(stderr, "cannot write %s\n", argv[2]);
        return 1;
    }
    if (dump) {
        write_raw(dump, "rays", rays, n * sizeof *rays);
        write_raw(dump, "hits", hits, n * sizeof *hits);
        write_raw(dump, "shadow_rays", shadow, n * sizeof *shadow);
        write_raw(dump, "shadowed", shadowed, n * sizeof *shadowed);
    }
    printf("%zu x %zu rays, %zu hits, written to %s\n", width, height, hit_count, argv[2]);
    free(rays);
    free(hits);
    free(shadow);
    free(shadowed);
    free(pixels);
    sahkd_tree_free(tree);
    return 0;
}
