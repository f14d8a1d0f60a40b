// renderFrame / renderReference: primary rays through pixel centres, AOVs, threading over rows.
#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <thread>

#include "Integrator.h"
#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

namespace {

constexpr float kBackgroundDepth = 1e10f;  // kestrel::kBackgroundDepth (Conventions.h)
constexpr int32_t kBackgroundId = -1;

void checkOptions(const SceneOptions& o) {
    if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
        throw std::invalid_argument("scenegen: width and height must be in 1..16384");
    if (o.referenceSpp < 1) throw std::invalid_argument("scenegen: referenceSpp must be >= 1");
    if (o.bounces < 1 || o.bounces > 16)
        throw std::invalid_argument("scenegen: bounces must be in 1..16");
}

/// Runs fn(row) for every row on `threads` std::threads (rows handed out by an atomic counter;
/// every row's result depends only on the row, so the split does not matter).
template <class Fn>
void forEachRow(int height, int threads, Fn&& fn) {
    int n = threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
    n = std::min(n, height);
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int y = next++; y < height; y = next++) fn(y);
    };
    if (n <= 1) {
        worker();
        return;
    }
    std::vector<std::thread> pool;
    pool.reserve(size_t(n - 1));
    for (int t = 0; t < n - 1; ++t) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
}

void set3(std::array<std::vector<float>, 3>& img, size_t k, V3 v) {
    img[0][k] = v.x;
    img[1][k] = v.y;
    img[2][k] = v.z;
}

template <size_t N>
void alloc(std::array<std::vector<float>, N>& img, size_t n) {
    for (auto& c : img) c.assign(n, 0.f);
}

}  // namespace

int objectCount() {
    return kObjectCount;
}

FrameAovs renderFrame(const SceneOptions& opt, int frame) {
    checkOptions(opt);
    const SceneState cur = makeScene(opt, frame);
    // Motion vectors point to the previous frame by the same animation formula (also for the
    // first frame of a sequence).
    const SceneState prev = makeScene(opt, frame - 1);
    const int w = opt.width, h = opt.height;
    const size_t n = size_t(w) * size_t(h);

    FrameAovs f;
    f.width = w;
    f.height = h;
    f.frame = frame;
    alloc(f.color, n), alloc(f.albedo, n), alloc(f.emission, n), alloc(f.direct, n);
    alloc(f.indirect, n), alloc(f.normal, n), alloc(f.position, n), alloc(f.motion, n);
    f.depth.assign(n, kBackgroundDepth);
    f.objectId.assign(n, kBackgroundId);
    f.worldToCamera = cur.camera.worldToCamera;
    f.projection = cur.camera.projection;
    f.worldToPixel = cur.camera.worldToPixel;
    f.cameraToWorld = cur.camera.cameraToWorld;
    for (int id = 0; id < kObjectCount; ++id) f.objectToWorld[id] = cur.objectToWorld[id];

    const Camera& cam = cur.camera;
    const V3 forward = xformDir(cam.cameraToWorld, {0, 0, -1});
    forEachRow(h, opt.threads, [&](int j) {
        for (int i = 0; i < w; ++i) {
            const size_t k = size_t(j) * size_t(w) + size_t(i);
            const V3 d = primaryDirection(cam, i, j);
            Hit hit;
            if (!intersect(cur, makeRay(cam.pos, d), 1e30f, hit, false)) {
                // Background (black sky): motion of directions at infinity, from the rotations.
                float pw;
                const V3 q = xformPoint(prev.camera.worldToPixel, d, &pw);
                const float qw = pw - prev.camera.worldToPixel[15];  // direction: w component 0
                const V3 qd = q - V3{prev.camera.worldToPixel[3], prev.camera.worldToPixel[7],
                                     prev.camera.worldToPixel[11]};
                if (qw > 1e-6f) {
                    f.motion[0][k] = qd.x / qw - (float(i) + 0.5f);
                    f.motion[1][k] = qd.y / qw - (float(j) + 0.5f);
                }
                continue;
            }
            const V3 p = cam.pos + d * hit.t;
            f.objectId[k] = hit.id;
            f.depth[k] = dot(p - cam.pos, forward);
            set3(f.position, k, p);
            const V3 e = emissionAt(cur, hit, d);
            set3(f.emission, k, e);
            const SurfacePoint sp = makeSurfacePoint(hit, p, d);
            set3(f.normal, k, sp.n);
            set3(f.albedo, k, sp.albedo);
            PathRadiance L;
            if (sp.albedo.x > 0.f || sp.albedo.y > 0.f || sp.albedo.z > 0.f) {
                Rng rng(pixelKey(opt.seed, frame, uint32_t(k), Stream::Noisy), 0);
                L = tracePath(cur, sp, opt.bounces - 1, rng);
            }
            set3(f.direct, k, L.direct);
            set3(f.indirect, k, L.indirect);
            set3(f.color, k, L.direct + L.indirect + e);
            // Where the point was: through the object's motion, into the previous camera.
            const V3 pPrev =
                xformPoint(prev.objectToWorld[hit.id], xformPoint(cur.worldToObject[hit.id], p));
            float pw;
            const V3 q = xformPoint(prev.camera.worldToPixel, pPrev, &pw);
            if (pw > 1e-6f) {  // behind the previous camera: no valid motion, left at 0
                f.motion[0][k] = q.x / pw - (float(i) + 0.5f);
                f.motion[1][k] = q.y / pw - (float(j) + 0.5f);
            }
        }
    });
    return f;
}

std::vector<float> renderReference(const SceneOptions& opt, int frame) {
    checkOptions(opt);
    const SceneState cur = makeScene(opt, frame);
    const int w = opt.width, h = opt.height, spp = opt.referenceSpp;
    const size_t n = size_t(w) * size_t(h);
    std::vector<float> out(3 * n, 0.f);
    const Camera& cam = cur.camera;
    forEachRow(h, opt.threads, [&](int j) {
        for (int i = 0; i < w; ++i) {
            const size_t k = size_t(j) * size_t(w) + size_t(i);
            const V3 d = primaryDirection(cam, i, j);
            Hit hit;
            if (!intersect(cur, makeRay(cam.pos, d), 1e30f, hit, false)) continue;
            // The primary ray is the same for every sample: trace it once.
            const V3 p = cam.pos + d * hit.t;
            const SurfacePoint sp = makeSurfacePoint(hit, p, d);
            V3 sum{0, 0, 0};
            if (sp.albedo.x > 0.f || sp.albedo.y > 0.f || sp.albedo.z > 0.f) {
                const uint32_t key = pixelKey(opt.seed, frame, uint32_t(k), Stream::Reference);
                for (int s = 0; s < spp; ++s) {
                    Rng rng(key, uint32_t(s));
                    const PathRadiance L = tracePath(cur, sp, opt.bounces - 1, rng);
                    sum += L.direct + L.indirect;
                }
            }
            const V3 c = sum * (1.f / float(spp)) + emissionAt(cur, hit, d);
            out[k] = c.x;
            out[n + k] = c.y;
            out[2 * n + k] = c.z;
        }
    });
    return out;
}

}  // namespace kestrel::scenegen
