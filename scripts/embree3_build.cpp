// Times Embree 3's BVH build at a chosen build quality, for the build table beside sahkd's
// `quality` preset: `high` is Embree's spatial-split BVH builder (SBVH), the closest peer of a
// kd-tree built with clipped ("perfect") splits.
//
//     c++ -O2 -std=c++17 scripts/embree3_build.cpp -lembree3 -o target/embree3_build
//     target/embree3_build MESH.bin low|medium|high THREADS REPEAT
//
// MESH.bin is an indexed mesh as scripts/build_table.py writes it from the file trimesh reads:
// two little-endian uint32 counts (vertices V, faces F), V x 3 float32 coordinates, F x 3
// uint32 indices. The timed region is `rtcCommitScene` of a fresh scene whose one triangle
// geometry shares those buffers (Embree copies nothing); the device is made once with
// `threads=THREADS`, as Embree's users set it. Prints the median, min and max of REPEAT builds
// after one warm-up, in ms, in the line format scripts/embree_build.py prints.
#include <embree3/rtcore.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Mesh {
    std::vector<float> vertices;  // padded by one float: Embree reads 16 bytes per vertex
    std::vector<uint32_t> faces;
    uint32_t vertex_count = 0, face_count = 0;
};

bool read_mesh(const char* path, Mesh& mesh) {
    FILE* f = std::fopen(path, "rb");
    if (!f) return false;
    uint32_t counts[2];
    bool ok = std::fread(counts, sizeof counts, 1, f) == 1;
    if (ok) {
        mesh.vertex_count = counts[0];
        mesh.face_count = counts[1];
        mesh.vertices.assign(size_t(counts[0]) * 3 + 1, 0.0f);
        mesh.faces.resize(size_t(counts[1]) * 3);
        ok = std::fread(mesh.vertices.data(), sizeof(float), size_t(counts[0]) * 3, f) ==
                 size_t(counts[0]) * 3 &&
             std::fread(mesh.faces.data(), sizeof(uint32_t), mesh.faces.size(), f) ==
                 mesh.faces.size();
    }
    std::fclose(f);
    return ok;
}

double build_once(RTCDevice device, const Mesh& mesh, RTCBuildQuality quality) {
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, quality);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, quality);
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                               mesh.vertices.data(), 0, 3 * sizeof(float), mesh.vertex_count);
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                               mesh.faces.data(), 0, 3 * sizeof(uint32_t), mesh.face_count);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    auto start = std::chrono::steady_clock::now();
    rtcCommitScene(scene);
    auto stop = std::chrono::steady_clock::now();
    rtcReleaseScene(scene);
    return std::chrono::duration<double, std::milli>(stop - start).count();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 5) {
        std::fprintf(stderr, "usage: %s MESH.bin low|medium|high THREADS REPEAT\n", argv[0]);
        return 2;
    }
    const std::string level = argv[2];
    RTCBuildQuality quality;
    if (level == "low") quality = RTC_BUILD_QUALITY_LOW;
    else if (level == "medium") quality = RTC_BUILD_QUALITY_MEDIUM;
    else if (level == "high") quality = RTC_BUILD_QUALITY_HIGH;
    else {
        std::fprintf(stderr, "quality must be low, medium or high, not %s\n", argv[2]);
        return 2;
    }
    const int threads = std::atoi(argv[3]), repeat = std::atoi(argv[4]);
    if (threads < 1 || repeat < 1) {
        std::fprintf(stderr, "THREADS and REPEAT must be positive whole numbers\n");
        return 2;
    }
    Mesh mesh;
    if (!read_mesh(argv[1], mesh)) {
        std::fprintf(stderr, "cannot read the mesh %s\n", argv[1]);
        return 1;
    }
    const std::string config = "threads=" + std::to_string(threads);
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) {
        std::fprintf(stderr, "Embree refused the device (%s)\n", config.c_str());
        return 1;
    }
    build_once(device, mesh, quality);
    std::vector<double> times;
    for (int i = 0; i < repeat; ++i) times.push_back(build_once(device, mesh, quality));
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) {
        std::fprintf(stderr, "Embree reported an error while building\n");
        return 1;
    }
    std::vector<double> sorted = times;
    std::sort(sorted.begin(), sorted.end());
    const size_t n = sorted.size();
    const double median = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
    std::printf("embree3 %s: %u triangles, %u vertices, %s quality, %d threads, build median %.1f ms "
                "(min %.1f, max %.1f, %d builds)\n",
                argv[1], mesh.face_count, mesh.vertex_count, level.c_str(), threads, median,
                sorted.front(), sorted.back(), repeat);
    rtcReleaseDevice(device);
    return 0;
}
