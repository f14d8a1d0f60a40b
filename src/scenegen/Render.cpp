// renderFrame / renderReference: primary rays through pixel centres, AOVs, threading over rows.
#include <algorithm>
#include <stdexcept>

#include "Integrator.h"
#include "RenderUtil.h"
#include "StreetRender.h"
#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

namespace {

void checkOptions(const SceneOptions& o) {
    if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
        throw std::invalid_argument("scenegen: width and height must be in 1..16384");
    if (o.referenceSpp < 1) throw std::invalid_argument("scenegen: referenceSpp must be >= 1");
    if (o.bounces < 1 || o.bounces > 16)
        throw std::invalid_argument("scenegen: bounces must be in 1..16");
    if (!(o.pixelFilterWidth >= 0.f && o.pixelFilterWidth <= 8.f))
        throw std::invalid_argument("scenegen: pixelFilterWidth must be in 0..8 pixels");
    if (o.kind == SceneOptions::Kind::Room && o.pixelFilterWidth > 0.f)
        throw std::invalid_argument("scenegen: the room scene has no pixel filter (use a street)");
    if (o.kind == SceneOptions::Kind::Room && o.lightChangeFrame >= 0)
        throw std::invalid_argument("scenegen: the room scene has no light change (use a street)");
    if (!(o.lightSwing >= 0.f && o.lightSwing <= 1.3f))
        throw std::invalid_argument("scenegen: lightSwing must be in 0..1.3 (the room is 4 wide)");
    if (o.kind != SceneOptions::Kind::Room && o.lightSwing > 0.f)
        throw std::invalid_argument("scenegen: only the room's light swings (use the room)");
    if (!(o.lightChangeScale >= 0.f && o.lightChangeScale <= 1e6f))
        throw std::invalid_argument("scenegen: lightChangeScale must be in 0..1e6");
}

}  // namespace

int objectCount() {
    return kObjectCount;
}

int objectCount(const SceneOptions& options) {
    return options.kind == SceneOptions::Kind::Room ? int(kObjectCount) : int(kStreetObjectCount);
}

FrameAovs renderFrame(const SceneOptions& opt, int frame) {
    checkOptions(opt);
    if (opt.kind != SceneOptions::Kind::Room) return renderStreetFrame(opt, frame);
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
    allocFrame(f, n);
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
                const auto& w2p = prev.camera.worldToPixel.m;
                const float qw = pw - w2p[3][3];  // direction: w component 0
                const V3 qd = q - V3{w2p[0][3], w2p[1][3], w2p[2][3]};
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
            // Every room surface is Lambertian: all of the light is diffuse.
            set3(f.diffuse, k, L.direct + L.indirect);
            set3(f.diffuseAlbedo, k, sp.albedo);
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
    if (opt.kind != SceneOptions::Kind::Room) return renderStreetReference(opt, frame);
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
