// A renderer-style loop: worker threads take tiles from a shared counter and query one
// shared tree, single rays for the camera and the calling thread's arrays for shadows:
//
//     threads MESH.ply THREADS [DUMP]
//
// With DUMP it writes DUMP.rays, DUMP.hits, DUMP.shadow_rays and DUMP.shadowed as the C
// example does, which the crate's tests compare with the Rust library's answers.
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "sahkd.h"

namespace {

void check(sahkd_status status, const char *what) {
    if (status != SAHKD_OK) {
        throw std::runtime_error(std::string(what) + ": " + sahkd_status_name(status) + ": " +
                                 sahkd_last_error());
    }
}

struct TreeFree {
    void operator()(sahkd_tree *t) const { sahkd_tree_free(t); }
};
struct MeshFree {
    void operator()(sahkd_mesh *m) const { sahkd_mesh_free(m); }
};
using Tree = std::unique_ptr<sahkd_tree, TreeFree>;
using Mesh = std::unique_ptr<sahkd_mesh, MeshFree>;

Tree build(const char *path, unsigned threads) {
    sahkd_mesh *m = nullptr;
    check(sahkd_mesh_load(path, &m), "sahkd_mesh_load");
    Mesh mesh(m);
    sahkd_build_options options;
    check(sahkd_build_options_preset("default", &options), "sahkd_build_options_preset");
    options.threads = threads;
    sahkd_tree *t = nullptr;
    check(sahkd_tree_build(mesh.get(), &options, &t), "sahkd_tree_build");
    return Tree(t);
}

template <class T>
void dump(const std::string &prefix, const char *suffix, const std::vector<T> &v) {
    std::string path = prefix + "." + suffix;
    FILE *f = std::fopen(path.c_str(), "wb");
    if (!f || std::fwrite(v.data(), sizeof(T), v.size(), f) != v.size() || std::fclose(f) != 0) {
        throw std::runtime_error("cannot write " + path);
    }
}

}  // namespace

int main(int argc, char **argv) try {
    if (argc != 3 && argc != 4) {
        std::fprintf(stderr, "usage: %s MESH THREADS [DUMP]\n", argv[0]);
        return 2;
    }
    const unsigned threads = static_cast<unsigned>(std::atoi(argv[2]));
    if (threads == 0) throw std::runtime_error("THREADS must be at least 1");
    Tree tree = build(argv[1], threads);

    float lo[3], hi[3];
    check(sahkd_tree_bounds(tree.get(), lo, hi), "sahkd_tree_bounds");
    const int width = 192, height = 128, tile = 16;
    const int tiles_x = width / tile, tiles = tiles_x * (height / tile);
    // An orthographic camera looking down -z over the box, rays starting in front of it.
    std::vector<sahkd_ray> rays(width * height);
    std::vector<sahkd_hit> hits(width * height);
    std::vector<sahkd_ray> shadow(width * height);
    std::vector<unsigned char> shadowed(width * height);
    std::atomic<int> next{0};

    auto worker = [&]() {
        std::vector<sahkd_ray> tile_shadow;
        bool tile_shadowed[tile * tile];
        for (int t; (t = next.fetch_add(1)) < tiles;) {
            const int x0 = (t % tiles_x) * tile, y0 = (t / tiles_x) * tile;
            tile_shadow.clear();
            for (int y = y0; y < y0 + tile; y++) {
                for (int x = x0; x < x0 + tile; x++) {
                    const int i = y * width + x;
                    sahkd_ray &r = rays[i];
                    r.origin[0] = lo[0] + (hi[0] - lo[0]) * (x + 0.5f) / width;
                    r.origin[1] = lo[1] + (hi[1] - lo[1]) * (y + 0.5f) / height;
                    r.origin[2] = hi[2] + 1.0f;
                    r.direction[0] = 0.05f;
                    r.direction[1] = -0.1f;
                    r.direction[2] = -1.0f;
                    r.t_min = 0.0f;
                    r.t_max = INFINITY;
                    check(sahkd_tree_intersect(tree.get(), &r, &hits[i]), "sahkd_tree_intersect");
                    sahkd_ray s = r;
                    const bool hit = hits[i].prim != SAHKD_INVALID_ID;
                    for (int k = 0; k < 3; k++) {
                        s.origin[k] = r.origin[k] + (hit ? hits[i].t : 0.0f) * r.direction[k];
                    }
                    s.direction[0] = 0.4f;
                    s.direction[1] = 0.3f;
                    s.direction[2] = 1.0f;
                    s.t_min = 1e-3f;
                    s.t_max = hit ? INFINITY : 0.0f;
                    shadow[i] = s;
                    tile_shadow.push_back(s);
                }
            }
            // The tile's shadow rays in one call, on this thread (no flags).
            check(sahkd_tree_occluded_aos(tree.get(), tile_shadow.data(), tile_shadow.size(), 0,
                                          tile_shadowed, 0, 0),
                  "sahkd_tree_occluded_aos");
            for (int k = 0; k < tile * tile; k++) {
                shadowed[(y0 + k / tile) * width + x0 + k % tile] = tile_shadowed[k];
            }
        }
    };
    std::vector<std::thread> pool;
    for (unsigned i = 0; i < threads; i++) pool.emplace_back(worker);
    for (auto &t : pool) t.join();

    size_t hit_count = 0, dark = 0;
    for (size_t i = 0; i < hits.size(); i++) {
        hit_count += hits[i].prim != SAHKD_INVALID_ID;
        dark += shadowed[i];
    }
    if (argc == 4) {
        dump(argv[3], "rays", rays);
        dump(argv[3], "hits", hits);
        dump(argv[3], "shadow_rays", shadow);
        dump(argv[3], "shadowed", shadowed);
    }
    std::printf("%d threads: %zu rays, %zu hits, %zu in shadow\n", threads, hits.size(),
                hit_count, dark);
    return 0;
} catch (const std::exception &e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
