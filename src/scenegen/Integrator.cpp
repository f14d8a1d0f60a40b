#include "Integrator.h"

#include <algorithm>

namespace kestrel::scenegen {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kInvPi = 1.f / kPi;
constexpr float kRayOffset = 1e-4f;
constexpr float kPickAreaLight = 0.75f;  // probability of sampling the ceiling light in NEE

V3 cosineSample(V3 n, float u1, float u2) {
    V3 t, b;
    basis(n, t, b);
    const float r = std::sqrt(u1), phi = 2.f * kPi * u2;
    return t * (r * std::cos(phi)) + b * (r * std::sin(phi)) +
           n * std::sqrt(std::max(0.f, 1.f - u1));
}

// Reflected radiance divided by albedo (i.e. irradiance / pi) from one light sample.
V3 nextEvent(const SceneState& s, V3 p, V3 n, Rng& rng) {
    const float pick = rng.next(), u1 = rng.next(), u2 = rng.next();
    const V3 origin = p + n * kRayOffset;
    if (pick < kPickAreaLight) {
        // Uniform area sampling of the rectangle (pdf 1/A), light facing down.
        const V3 q{s.lightX0 + u1 * (s.lightX1 - s.lightX0), s.lightY,
                   s.lightZ0 + u2 * (s.lightZ1 - s.lightZ0)};
        const V3 w = q - origin;
        const float d2 = std::max(dot(w, w), 1e-6f), d = std::sqrt(d2);
        const V3 wi = w * (1.f / d);
        const float cosS = dot(n, wi), cosL = wi.y;
        if (cosS <= 0.f || cosL <= 0.f) return {};
        if (occluded(s, makeRay(origin, wi), d * (1.f - 1e-4f))) return {};
        return s.lightRadiance * (cosS * cosL * s.lightArea / d2 * kInvPi / kPickAreaLight);
    }
    // Uniform sampling of the cone the glowing sphere subtends (PBRT 3rd ed., 14.2.2).
    const V3 wc = s.glowCenter - origin;
    const float dc2 = dot(wc, wc), r2 = s.glowRadius * s.glowRadius;
    if (dc2 <= r2) return {};
    const float dc = std::sqrt(dc2);
    const float sin2Max = r2 / dc2, cosMax = std::sqrt(std::max(0.f, 1.f - sin2Max));
    const float oneMinusCosMax = sin2Max / (1.f + cosMax);  // 1 - cosMax without cancellation
    const float cosT = 1.f - u1 * oneMinusCosMax;
    const float sinT = std::sqrt(std::max(0.f, 1.f - cosT * cosT)), phi = 2.f * kPi * u2;
    const V3 axis = wc * (1.f / dc);
    V3 t, b;
    basis(axis, t, b);
    const V3 wi = normalize(t * (sinT * std::cos(phi)) + b * (sinT * std::sin(phi)) + axis * cosT);
    const float cosS = dot(n, wi);
    if (cosS <= 0.f) return {};
    // Distance to the sphere along wi (near root).
    const float bq = -dot(wc, wi), disc = bq * bq - (dc2 - r2);
    const float tHit = -bq - std::sqrt(std::max(disc, 0.f));
    if (occluded(s, makeRay(origin, wi), tHit * (1.f - 1e-3f))) return {};
    const float invPdf = 2.f * kPi * oneMinusCosMax;
    return s.glowRadiance * (cosS * invPdf * kInvPi / (1.f - kPickAreaLight));
}

}  // namespace

V3 primaryDirection(const Camera& c, int i, int j) {
    const float nx = (float(i) + 0.5f) / float(c.width) * 2.f - 1.f;
    const float ny = 1.f - (float(j) + 0.5f) / float(c.height) * 2.f;
    return normalize(xformDir(c.cameraToWorld, {nx * c.tanX, ny * c.tanY, -1.f}));
}

SurfacePoint makeSurfacePoint(const Hit& hit, V3 p, V3 rayDir) {
    SurfacePoint sp;
    sp.p = p;
    sp.n = dot(hit.normal, rayDir) > 0.f ? -hit.normal : hit.normal;  // two-sided
    sp.albedo = albedoAt(hit, p);
    return sp;
}

PathRadiance tracePath(const SceneState& s, const SurfacePoint& first, int indirectBounces,
                       Rng& rng) {
    PathRadiance out;
    out.direct = first.albedo * nextEvent(s, first.p, first.n, rng);
    V3 throughput = first.albedo;
    SurfacePoint v = first;
    for (int b = 0; b < indirectBounces; ++b) {
        const float u1 = rng.next(), u2 = rng.next();
        // Cosine sampling: the Lambertian BRDF * cos / pdf is the albedo.
        const V3 dir = cosineSample(v.n, u1, u2);
        Hit hit;
        if (!intersect(s, makeRay(v.p + v.n * kRayOffset, dir), 1e30f, hit, true)) break;
        if (hit.id == kAreaLight || hit.id == kGlowSphere) break;  // counted by NEE
        v = makeSurfacePoint(hit, v.p + v.n * kRayOffset + dir * hit.t, dir);
        throughput = throughput * v.albedo;
        out.indirect += throughput * nextEvent(s, v.p, v.n, rng);
    }
    return out;
}

}  // namespace kestrel::scenegen
