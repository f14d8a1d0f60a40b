// Street path tracer: Lambert + normalised Phong surfaces, a sun sampled by next-event estimation,
// the sky and the emitters found by BSDF sampling (each light by exactly one strategy, so the
// estimate is unbiased without MIS), and the primary ray through a pixel-filter sample.
#include "StreetRender.h"

#include <algorithm>

#include "PixelFilter.h"
#include "Random.h"
#include "RenderUtil.h"

namespace kestrel::scenegen {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kInvPi = 1.f / kPi;
constexpr float kRayOffset = 1e-4f;

// Direction at angle acos(cosT) from `axis`, azimuth 2 pi u.
V3 aroundAxis(V3 axis, float cosT, float u) {
    V3 t, b;
    basis(axis, t, b);
    const float sinT = std::sqrt(std::max(0.f, 1.f - cosT * cosT)), phi = 2.f * kPi * u;
    return normalize(t * (sinT * std::cos(phi)) + b * (sinT * std::sin(phi)) + axis * cosT);
}

float luminance(V3 c) {
    return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}
bool isZero(V3 c) {
    return c.x <= 0.f && c.y <= 0.f && c.z <= 0.f;
}

/// A scattering vertex: n faces the incoming ray, r is the incoming ray's mirror direction.
struct Vertex {
    V3 p, n, r;
    Material m;
};

Vertex makeVertex(const StreetState& s, const Hit& hit, V3 p, V3 d) {
    Vertex v;
    v.p = p;
    v.n = dot(hit.normal, d) > 0.f ? -hit.normal : hit.normal;  // two-sided
    v.r = d - v.n * (2.f * dot(d, v.n));
    v.m = materialAt(s, hit, p);
    return v;
}

// Normalised Phong lobe (e + 2) / (2 pi) cos^e(alpha) around the mirror direction.
float phong(V3 r, V3 wi, float e) {
    const float c = dot(r, wi);
    return c > 0.f ? (e + 2.f) / (2.f * kPi) * std::pow(c, e) : 0.f;
}

/// Light reflected by each lobe (already multiplied by kd and ks).
struct LobePair {
    V3 diffuse, specular;
};

// Light arriving from direction wi with radiance-times-solid-angle `Li`, reflected by v's lobes.
LobePair reflect(const Vertex& v, V3 wi, V3 li) {
    const float cosS = dot(v.n, wi);
    if (cosS <= 0.f) return {};
    return {v.m.kd * li * (cosS * kInvPi), v.m.ks * li * (cosS * phong(v.r, wi, v.m.exponent))};
}

LobePair sunLight(const StreetState& s, const Vertex& v) {
    if (!s.sun || dot(v.n, s.sunDir) <= 0.f) return {};
    if (occludedStreet(s, makeRay(v.p + v.n * kRayOffset, s.sunDir), 1e30f)) return {};
    return reflect(v, s.sunDir, s.sunIrradiance);
}

// Uniform sampling of the cone the lamp subtends (PBRT 3rd ed., 14.2.2): used by the reference
// only, so that it converges where the 1-spp frames have fireflies.
LobePair lampLight(const StreetState& s, const Vertex& v, Rng& rng) {
    const float u1 = rng.next(), u2 = rng.next();
    const V3 origin = v.p + v.n * kRayOffset, wc = s.lampCenter - origin;
    const float dc2 = dot(wc, wc), r2 = s.lampRadius * s.lampRadius;
    if (dc2 <= r2) return {};
    const float dc = std::sqrt(dc2), sin2Max = r2 / dc2;
    const float cosMax = std::sqrt(std::max(0.f, 1.f - sin2Max));
    const float oneMinusCosMax = sin2Max / (1.f + cosMax);  // without cancellation
    const V3 wi = aroundAxis(wc * (1.f / dc), 1.f - u1 * oneMinusCosMax, u2);
    if (dot(v.n, wi) <= 0.f) return {};
    const float bq = -dot(wc, wi), disc = bq * bq - (dc2 - r2);
    const float tHit = -bq - std::sqrt(std::max(disc, 0.f));
    if (occludedStreet(s, makeRay(origin, wi), tHit * (1.f - 1e-3f))) return {};
    return reflect(v, wi, s.lampRadiance * (2.f * kPi * oneMinusCosMax));
}

/// One sampled continuation: direction, throughput weight (BSDF * cos / pdf), lobe.
struct Bounce {
    V3 dir, weight;
    bool specular = false;
    bool valid = false;
};

// Picks a lobe in proportion to its tint's luminance, then samples it exactly: cosine for the
// diffuse lobe, cos^e around the mirror direction for the Phong lobe.
Bounce sampleBounce(const Vertex& v, Rng& rng) {
    const float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
    const float ld = luminance(v.m.kd), ls = luminance(v.m.ks);
    Bounce b;
    if (ld + ls <= 0.f) return b;
    const float pd = ld / (ld + ls);
    if (u0 < pd) {
        const float r = std::sqrt(u1), phi = 2.f * kPi * u2;
        V3 t, bt;
        basis(v.n, t, bt);
        b.dir = t * (r * std::cos(phi)) + bt * (r * std::sin(phi)) +
                v.n * std::sqrt(std::max(0.f, 1.f - u1));
        b.weight = v.m.kd * (1.f / pd);
    } else {
        const float e = v.m.exponent;
        b.dir = aroundAxis(v.r, std::pow(u1, 1.f / (e + 1.f)), u2);
        const float cosS = dot(v.n, b.dir);
        if (cosS <= 0.f) return b;  // below the surface: the lobe is cut off there
        b.weight = v.m.ks * ((e + 2.f) / (e + 1.f) * cosS / std::max(1.f - pd, 1e-6f));
        b.specular = true;
    }
    b.valid = true;
    return b;
}

/// Light of one path, split by the lobe at the first vertex and by direct/indirect.
struct SplitRadiance {
    V3 diffDir, diffInd, specDir, specInd;
    V3 diffuse() const { return diffDir + diffInd; }
    V3 specular() const { return specDir + specInd; }
};

// Radiance found by a BSDF ray leaving a vertex (sky or an emitter), or false to continue at the
// surface it hit. The lamp counts only when it is not sampled by next-event estimation.
bool escapeRadiance(const StreetState& s, const Ray& ray, bool lampNee, Hit& hit, V3& radiance) {
    if (!intersectStreet(s, ray, 1e30f, hit)) {
        radiance = skyRadiance(s, ray.d);
        return true;
    }
    if (hit.id == kSign) return radiance = s.signRadiance, true;
    if (hit.id == kLampHead) return radiance = lampNee ? V3{} : s.lampRadiance, true;
    return false;
}

/// Path from the first vertex, `vertices` scattering vertices in all (SceneOptions::bounces).
SplitRadiance tracePath(const StreetState& s, const Vertex& first, int vertices, bool lampNee,
                        Rng& rng) {
    SplitRadiance out;
    LobePair direct = sunLight(s, first);
    if (lampNee) {
        const LobePair lamp = lampLight(s, first, rng);
        direct = {direct.diffuse + lamp.diffuse, direct.specular + lamp.specular};
    }
    out.diffDir = direct.diffuse;
    out.specDir = direct.specular;
    Vertex v = first;
    V3 throughput{1, 1, 1};
    bool specularPath = false;
    for (int k = 0; k < vertices; ++k) {
        if (k > 0) {  // next-event estimation at a later vertex: indirect light
            LobePair l = sunLight(s, v);
            if (lampNee) {
                const LobePair lamp = lampLight(s, v, rng);
                l = {l.diffuse + lamp.diffuse, l.specular + lamp.specular};
            }
            (specularPath ? out.specInd : out.diffInd) += throughput * (l.diffuse + l.specular);
        }
        const Bounce b = sampleBounce(v, rng);
        if (!b.valid) break;
        if (k == 0) specularPath = b.specular;
        throughput = throughput * b.weight;
        const Ray ray = makeRay(v.p + v.n * kRayOffset, b.dir);
        Hit hit;
        V3 found;
        if (escapeRadiance(s, ray, lampNee, hit, found)) {
            V3& bucket = k == 0 ? (specularPath ? out.specDir : out.diffDir)
                                : (specularPath ? out.specInd : out.diffInd);
            bucket += throughput * found;
            break;
        }
        if (k + 1 == vertices) break;
        v = makeVertex(s, hit, ray.o + b.dir * hit.t, b.dir);
    }
    return out;
}

/// What the primary ray of one pixel sample sees.
struct Primary {
    float px = 0, py = 0;  // pixel coordinates of the sample (centre: i + 0.5)
    V3 d;
    bool hit = false;
    Hit h;
    Vertex v;
    V3 emission;  // emitter or sky radiance towards the camera
};

V3 directionThrough(const Camera& c, float px, float py) {
    const float nx = px / float(c.width) * 2.f - 1.f;
    const float ny = 1.f - py / float(c.height) * 2.f;
    return normalize(xformDir(c.cameraToWorld, {nx * c.tanX, ny * c.tanY, -1.f}));
}

// The filter offsets come first from the pixel's random stream (none without a filter).
Primary tracePrimary(const StreetState& s, const PixelFilter& filter, int i, int j, Rng& rng) {
    Primary pr;
    pr.px = float(i) + 0.5f;
    pr.py = float(j) + 0.5f;
    if (filter.active()) {
        pr.px += filter.sample(rng.next());
        pr.py += filter.sample(rng.next());
    }
    pr.d = directionThrough(s.camera, pr.px, pr.py);
    pr.hit = intersectStreet(s, makeRay(s.camera.pos, pr.d), 1e30f, pr.h);
    if (!pr.hit) {
        pr.emission = skyRadiance(s, pr.d);
        return pr;
    }
    pr.v = makeVertex(s, pr.h, s.camera.pos + pr.d * pr.h.t, pr.d);
    pr.emission = pr.v.m.emission;
    return pr;
}

SplitRadiance shade(const StreetState& s, const SceneOptions& opt, const Primary& pr, bool lampNee,
                    Rng& rng) {
    if (!pr.hit || (isZero(pr.v.m.kd) && isZero(pr.v.m.ks))) return {};
    return tracePath(s, pr.v, opt.bounces, lampNee, rng);
}

// Motion of the sample to the previous frame (pixels, y down): a scene point moves with its
// object; a sky direction only with the camera's rotation. 0 when behind the previous camera.
std::array<float, 2> sampleMotion(const StreetState& cur, const StreetState& prev,
                                  const Primary& pr) {
    const Mat4& w2p = prev.camera.worldToPixel;
    float pw;
    if (!pr.hit) {
        const V3 q = xformPoint(w2p, pr.d, &pw);
        const float qw = pw - w2p.m[3][3];  // direction: w component 0
        const V3 qd = q - V3{w2p.m[0][3], w2p.m[1][3], w2p.m[2][3]};
        if (qw <= 1e-6f) return {0.f, 0.f};
        return {qd.x / qw - pr.px, qd.y / qw - pr.py};
    }
    const int id = pr.h.id;
    const V3 p = pr.v.p;
    const V3 pPrev = xformPoint(prev.objectToWorld[id], xformPoint(cur.worldToObject[id], p));
    const V3 q = xformPoint(w2p, pPrev, &pw);
    if (pw <= 1e-6f) return {0.f, 0.f};
    return {q.x / pw - pr.px, q.y / pw - pr.py};
}

void writeGBuffer(FrameAovs& f, size_t k, const Camera& cam, const Primary& pr) {
    set3(f.emission, k, pr.emission);
    if (!pr.hit) return;  // sky: the background values allocFrame set
    f.objectId[k] = pr.h.id;
    f.depth[k] = dot(pr.v.p - cam.pos, xformDir(cam.cameraToWorld, {0, 0, -1}));
    set3(f.position, k, pr.v.p);
    set3(f.normal, k, pr.v.n);
    set3(f.albedo, k, pr.v.m.kd);
    set3(f.diffuseAlbedo, k, pr.v.m.kd);
    set3(f.specularAlbedo, k, pr.v.m.ks);
}

void writeLight(FrameAovs& f, size_t k, const Primary& pr, const SplitRadiance& L) {
    const V3 diffuse = L.diffuse(), specular = L.specular();
    set3(f.diffuse, k, diffuse);
    set3(f.specular, k, specular);
    set3(f.direct, k, L.diffDir + L.specDir);
    set3(f.indirect, k, L.diffInd + L.specInd);
    set3(f.color, k, diffuse + specular + pr.emission);
}

}  // namespace

FrameAovs renderStreetFrame(const SceneOptions& opt, int frame) {
    const StreetState cur = makeStreet(opt, frame), prev = makeStreet(opt, frame - 1);
    const PixelFilter filter(opt.pixelFilterWidth);
    const int w = opt.width, h = opt.height;
    FrameAovs f;
    f.width = w;
    f.height = h;
    f.frame = frame;
    allocFrame(f, size_t(w) * size_t(h));
    f.worldToCamera = cur.camera.worldToCamera;
    f.projection = cur.camera.projection;
    f.worldToPixel = cur.camera.worldToPixel;
    f.cameraToWorld = cur.camera.cameraToWorld;
    for (int id = 0; id < kStreetObjectCount; ++id) f.objectToWorld[id] = cur.objectToWorld[id];
    forEachRow(h, opt.threads, [&](int j) {
        for (int i = 0; i < w; ++i) {
            const size_t k = size_t(j) * size_t(w) + size_t(i);
            Rng rng(pixelKey(opt.seed, frame, uint32_t(k), Stream::Noisy), 0);
            const Primary pr = tracePrimary(cur, filter, i, j, rng);
            writeGBuffer(f, k, cur.camera, pr);
            const std::array<float, 2> m = sampleMotion(cur, prev, pr);
            f.motion[0][k] = m[0];
            f.motion[1][k] = m[1];
            writeLight(f, k, pr, shade(cur, opt, pr, false, rng));
        }
    });
    return f;
}

std::vector<float> renderStreetReference(const SceneOptions& opt, int frame) {
    const StreetState cur = makeStreet(opt, frame);
    const PixelFilter filter(opt.pixelFilterWidth);
    const int w = opt.width, h = opt.height, spp = opt.referenceSpp;
    const size_t n = size_t(w) * size_t(h);
    std::vector<float> out(3 * n, 0.f);
    forEachRow(h, opt.threads, [&](int j) {
        for (int i = 0; i < w; ++i) {
            const size_t k = size_t(j) * size_t(w) + size_t(i);
            const uint32_t key = pixelKey(opt.seed, frame, uint32_t(k), Stream::Reference);
            V3 sum{0, 0, 0};
            // Every sample has its own primary ray (through its own filter offset).
            for (int sIndex = 0; sIndex < spp; ++sIndex) {
                Rng rng(key, uint32_t(sIndex));
                const Primary pr = tracePrimary(cur, filter, i, j, rng);
                const SplitRadiance L = shade(cur, opt, pr, true, rng);
                sum += L.diffuse() + L.specular() + pr.emission;
            }
            const V3 c = sum * (1.f / float(spp));
            out[k] = c.x;
            out[n + k] = c.y;
            out[2 * n + k] = c.z;
        }
    });
    return out;
}

}  // namespace kestrel::scenegen
